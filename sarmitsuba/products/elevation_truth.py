"""The heights a tomographic inversion should find: where each pixel's iso-range circle meets the
scene's geometry that the antenna sees (docs/physics.md (G2), (TS2)).

A ground-plane image (plane ``z = z0``) shows at pixel ``G`` every point ``P`` with the same
distance to the straight track line as ``G``, in the plane through ``G`` normal to the track
(:func:`sarmitsuba.core.image.layover_position`): the ground at ``G`` itself, a facade where the
circle meets it, a roof that lays over onto ``G``. Of those, the ones the zero-Doppler antenna
``A`` of ``G``'s row sees are the scatterers of the cell.

:func:`iso_range_heights` casts, for every image row, a fan of rays from ``A`` in that plane,
``oversample`` rays per ground-range pixel from the image's near edge to beyond its far edge (as
far as the scene's top can lay over). Each ray's first hit ``H`` has a slant range ``|A - H|``
and a height ``H_z - z0``. Between two neighbouring rays that hit the same shape at points
closer than a few ray spacings (no jump across a depth edge), the pixels whose slant range
``|A - G|`` lies between the two hits' get the height interpolated linearly in slant range:
one crossing of the circle with that surface. A surface whose nearest or farthest point lies
within half a pixel's slant spacing of ``|A - G|`` without crossing it (a trihedral's apex)
gives the height of that point: it lays over into the pixel's cell. :func:`nearest_truth` matches detected
scatterers to them.

Rays are cast in float32 from just above the scene (their origins and the ranges are float64),
so the heights are good to millimetres for scenes within some kilometres of the origin.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core.geometry import acquisition_geometry
from ..core.image import SarImage

__all__ = ["MAX_CROSSINGS", "iso_range_heights", "nearest_truth"]

#: Crossings kept per pixel (the lowest, when a pixel has more).
MAX_CROSSINGS = 4
#: Two neighbouring hits belong to one surface when closer than this many ray spacings (on the ground).
_JUMP = 6.0
#: Rays in flight per batch.
_BATCH_RAYS = 2_000_000


def _cast(scene: Any, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest hits of float64 rays [n, 3]: (distance float64 [n], inf on a miss; shape id uint32 [n])."""
    import drjit as dr
    import mitsuba as mi
    o, d = origins.astype(np.float32), directions.astype(np.float32)
    ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
    si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.Minimal, coherent=False)
    shape = dr.reinterpret_array(mi.UInt32, si.shape)
    dr.eval(si.t, shape)
    return np.asarray(si.t).astype(np.float64), np.asarray(shape).copy()


def iso_range_heights(loaded: Any, image: SarImage, rows: np.ndarray | None = None, *,
                      max_crossings: int = MAX_CROSSINGS, oversample: int = 4) -> np.ndarray:
    """Heights above the grid plane where each pixel's iso-range circle meets visible geometry.

    Parameters
    ----------
    loaded : LoadedScene
        The scene as loaded for the pass whose track defines the circles
        (:func:`sarmitsuba.scene.loader.load_scene`; its Mitsuba scene is in the local frame,
        ``loaded.offset`` the world-minus-local offset).
    image : SarImage
        A ground-plane image of that pass (world frame), azimuth axis along the track.
    rows : int array, optional
        The azimuth rows to compute (default all).
    max_crossings : int
        Crossings kept per pixel, the lowest.
    oversample : int
        Rays per ground-range pixel spacing.

    Returns
    -------
    float64 [len(rows), n_rg, max_crossings], m
        Ascending, NaN-padded heights above ``z0 = image.origin[2]``.

    Raises
    ------
    ValueError
        The image is not on the ground plane, or its azimuth axis does not run along the track.
    """
    if image.plane != "ground":
        raise ValueError(f"iso-range heights need a ground-plane image, got plane = {image.plane!r}")
    geometry = acquisition_geometry(loaded.params)
    t = np.asarray(geometry.track_direction, np.float64)
    if abs(float(image.azimuth_direction @ t)) < 1.0 - 1e-6:
        raise ValueError(f"the image's azimuth axis {image.azimuth_direction.tolist()} must run along the track "
                         f"{t.tolist()}")
    offset = np.asarray(loaded.offset, np.float64)
    mid = np.asarray(geometry.positions, np.float64).mean(axis=0) + offset     # world frame
    rows = np.arange(image.data.shape[0]) if rows is None else np.asarray(rows, np.int64)
    out = np.full((rows.size, image.data.shape[1], max_crossings), np.nan)
    top = max(float(loaded.bbox_hi[2] + offset[2]), float(image.origin[2])) + 1.0
    per_row = _aims(image, mid, t, top, oversample, 0).shape[0]
    step = max(1, _BATCH_RAYS // per_row)
    for r0 in range(0, rows.size, step):
        batch = rows[r0:r0 + step]
        out[r0:r0 + batch.size] = _rows(loaded, image, batch, mid, t, top, offset, max_crossings, oversample)
    return out


def _length(v: np.ndarray) -> np.ndarray:
    """``|v|`` over the last axis (float64)."""
    return np.sqrt(np.einsum("...i,...i->...", v, v))


def _aims(image: SarImage, mid: np.ndarray, t: np.ndarray, top: float, oversample: int, row: int) -> np.ndarray:
    """Ground points [M, 3] (world, at azimuth 0) a row's fan aims at: the range axis, extended
    beyond its far edge by as far as ``top`` lays over, ``oversample`` per pixel spacing."""
    rg = image.range
    spacing = abs(float(rg[1] - rg[0])) / oversample
    antenna = mid + float((image.origin + image.azimuth[row] * image.azimuth_direction - mid) @ t) * t
    height = antenna[2] - float(image.origin[2])
    near = float(np.linalg.norm((image.origin - antenna) - ((image.origin - antenna) @ t) * t))
    reach = (top - float(image.origin[2])) * max(1.0, height / max(near, 1e-9)) * 1.5     # h tan(theta), widened
    lo, hi = float(min(rg[0], rg[-1])), float(max(rg[0], rg[-1])) + reach
    axis = np.arange(lo - 2 * spacing, hi + spacing, spacing)
    return image.origin + axis[:, None] * image.range_direction


def _rows(loaded: Any, image: SarImage, rows: np.ndarray, mid: np.ndarray, t: np.ndarray, top: float,
          offset: np.ndarray, max_crossings: int, oversample: int) -> np.ndarray:
    """The crossings of a batch of rows, float64 [len(rows), n_rg, max_crossings]."""
    base = _aims(image, mid, t, top, oversample, 0)                            # row 0's aim points
    along = image.azimuth[rows, None, None] * image.azimuth_direction          # [R, 1, 3]
    aims = base[None] + along                                                  # [R, M, 3]
    antennas = mid + (((aims[:, :1] - mid) @ t)[..., None] * t)                # [R, 1, 3] zero Doppler
    directions = aims - antennas
    directions /= _length(directions)[..., None]
    lift = (top - antennas[..., 2]) / directions[..., 2]                       # start just above the scene
    origins = antennas + lift[..., None] * directions
    distance, shape = _cast(loaded.scene, (origins - offset).reshape(-1, 3), directions.reshape(-1, 3))
    distance, shape = distance.reshape(aims.shape[:2]), shape.reshape(aims.shape[:2])
    valid = np.isfinite(distance)
    hits = origins + np.where(valid, distance, 0.0)[..., None] * directions    # a miss: its origin (not used)
    z0 = float(image.origin[2])
    slant = _length(hits - antennas)
    height = hits[..., 2] - z0
    pixels = image.origin + along + image.range[None, :, None] * image.range_direction
    pixel_range = _length(pixels - antennas)                                   # [R, n_rg]
    spacing = abs(float(image.range[1] - image.range[0])) / oversample
    joined = (valid[:, :-1] & valid[:, 1:] & (shape[:, :-1] == shape[:, 1:])
              & (_length(hits[:, 1:] - hits[:, :-1]) < _JUMP * spacing))
    out = np.full((rows.size, image.range.size, max_crossings), np.nan)
    for i in range(rows.size):
        out[i] = _crossings(slant[i], height[i], joined[i], pixel_range[i], max_crossings)
    return out


def _crossings(slant: np.ndarray, height: np.ndarray, joined: np.ndarray, pixel_range: np.ndarray,
               max_crossings: int) -> np.ndarray:
    """One row: the heights [n_rg, K] where the pixels' slant ranges fall between joined hits.

    A pixel takes from each chain of joined hits (one surface) every crossing of its slant range;
    a chain that comes within half a pixel's slant spacing of it without crossing (its range
    extremum lies in the pixel's cell: a trihedral's apex, a roof's far edge) gives its nearest
    point instead."""
    seg = np.flatnonzero(joined)
    chain = np.cumsum(~np.r_[joined, False])[seg]                   # one id per run of joined segments
    r0, r1, h0, h1 = slant[seg], slant[seg + 1], height[seg], height[seg + 1]
    lo, hi = np.minimum(r0, r1), np.maximum(r0, r1)
    order = np.argsort(pixel_range)
    sorted_range = pixel_range[order]
    half_cell = 0.5 * float(np.mean(np.diff(sorted_range))) if sorted_range.size > 1 else 0.0
    first = np.searchsorted(sorted_range, lo - half_cell, side="left")
    last = np.searchsorted(sorted_range, hi + half_cell, side="right")
    counts = last - first
    which = np.repeat(np.arange(seg.size), counts)
    pix = order[first[which] + np.arange(which.size) - np.repeat(np.cumsum(counts) - counts, counts)]
    r = pixel_range[pix]
    span = r1[which] - r0[which]
    frac = np.clip(np.where(span != 0, (r - r0[which]) / np.where(span != 0, span, 1.0), 0.5), 0.0, 1.0)
    h = h0[which] + frac * (h1[which] - h0[which])
    miss = np.maximum(np.maximum(lo[which] - r, r - hi[which]), 0.0)
    keys = np.lexsort((seg[which], miss, chain[which], pix))
    pix, h, miss, at, ch = pix[keys], h[keys], miss[keys], seg[which][keys], chain[which][keys]
    new = np.ones(pix.size, bool)
    new[1:] = (pix[1:] != pix[:-1]) | (ch[1:] != ch[:-1])
    groups = np.flatnonzero(new)
    crossed = np.zeros(pix.size, bool)
    if pix.size:
        crossed = np.repeat(np.minimum.reduceat(miss, groups) == 0, np.diff(np.r_[groups, pix.size]))
    repeat = np.zeros(pix.size, bool)                               # a crossing at a joint, counted twice
    repeat[1:] = ~new[1:] & (miss[1:] == 0) & (miss[:-1] == 0) & (np.abs(h[1:] - h[:-1]) < 1e-3)
    keep = np.where(crossed, (miss == 0) & ~repeat, new)
    pix, h = pix[keep], h[keep]
    out = np.full((pixel_range.size, max_crossings), np.nan)
    keys = np.lexsort((h, pix))
    pix, h = pix[keys], h[keys]
    start = np.r_[0, np.flatnonzero(np.diff(pix)) + 1] if pix.size else np.zeros(0, int)
    rank = np.arange(pix.size) - np.repeat(start, np.diff(np.r_[start, pix.size]))
    keep = rank < max_crossings
    out[pix[keep], rank[keep]] = h[keep]
    return out


def nearest_truth(heights_at_pixels: np.ndarray, estimates: np.ndarray) -> np.ndarray:
    """For detected scatterers: the crossing height nearest each estimate.

    ``heights_at_pixels`` float [M, K] (rows of :func:`iso_range_heights` at the scatterers'
    pixels, NaN-padded), ``estimates`` float [M] m. Returns float64 [M] m, NaN where the pixel
    has no crossing.
    """
    h = np.asarray(heights_at_pixels, np.float64).reshape(len(estimates), -1)
    e = np.asarray(estimates, np.float64)
    if h.shape[1] == 0:
        return np.full(e.shape, np.nan)
    gap = np.where(np.isfinite(h), np.abs(h - e[:, None]), np.inf)
    best = np.argmin(gap, axis=1)
    out = h[np.arange(h.shape[0]), best]
    return np.where(np.isfinite(gap[np.arange(h.shape[0]), best]), out, np.nan)
