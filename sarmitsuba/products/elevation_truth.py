"""The heights a tomographic inversion should find: where each pixel's iso-range circle meets the
scene's geometry that the antenna sees (docs/physics.md (G2), (TS2)).

A ground-plane image (plane ``z = z0``, ``z0 = image.origin[2]``) focused from a straight track
shows at pixel ``G`` every point ``P`` of the circle about the track line through ``G``: in the
plane through ``G`` normal to the track, ``|A - P| = |A - G|`` with ``A`` the zero-Doppler
antenna of ``G``'s row (the point of the track line closest to the row). That is layover (G2):
the ground at ``G`` itself, a facade where the circle meets it, a roof at height ``h`` from
``h / tan(theta)`` farther out. Of those points, the ones ``A`` sees are the scatterers of the
cell, and their heights the truth of the cell's elevation profile (TS2).

:func:`iso_range_heights` casts, for every requested row, a fan of rays from ``A`` in that
plane, aimed at the image line ``oversample`` rays per ground-range pixel spacing, from the
farther of the image's and the scene's near edges to the nearer of the points where a ray
through the scene's top lands beyond the image's far edge and beyond the scene's. Each ray's
first hit ``P`` has a slant range ``|A - P|`` (float64, from ``A``) and a height ``P_z - z0``.
Neighbouring rays whose hits lie on the same shape, less than :data:`_JUMP` hit spacings apart
(no jump across a depth edge), form one surface:

* where its slant range passes a pixel's ``|A - G|`` between two such hits, the pixel gets the
  height interpolated linearly in slant range: one crossing of the circle with the surface
  (each hit belongs to the segment it starts, so a circle through a hit counts once);
* where its nearest or farthest hit images into a pixel's cell without the surface's ranges
  reaching the pixel's (a roof's far edge, the top of a facade, a trihedral's apex), the pixel
  gets that hit's height: the edge lays over into the cell.

Per pixel the heights are sorted; one less than a hit spacing above the previous is the same
scatterer (a wall's foot on the ground, coplanar faces) and dropped; the lowest
``max_crossings`` are kept (the ground and the low facades, which a tomogram of a building
resolves first; the built-in urban scene has no pixel with more than 4).
Heights on plane surfaces are exact; edges and corners are good to a hit spacing.
:func:`nearest_truth` matches detected scatterers to them.

Cost: ``oversample`` rays per pixel spacing of each requested row's scene extent, cast in
batches of :data:`_BATCH_RAYS`, and vectorised NumPy per batch: about 1 s for the built-in
urban scene's full image (0.97 M pixels, 2.9 M rays) on 2 cores.

The scene is traced in its local frame (world minus ``loaded.offset``); rays are cast in
float32 from just above the scene's top, their origins and the ranges kept in float64, so the
heights are good to millimetres for scenes within some kilometres of the local origin.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.geometry import acquisition_geometry
from ..core.image import SarImage
from .groundtruth import intersect

__all__ = ["MAX_CROSSINGS", "iso_range_heights", "nearest_truth"]

#: Crossings kept per pixel (the lowest, when a pixel has more).
MAX_CROSSINGS = 4
#: Two neighbouring hits belong to one surface when closer than this many hit spacings (a hit
#: spacing: the rays' on the ground, or on a wall at the fan's steepest incidence when wider).
_JUMP = 6.0
#: Rays in flight per batch (about 150 B each).
_BATCH_RAYS = 2_000_000


@dataclass(frozen=True)
class _Fan:
    """The fan of rays of azimuth coordinate 0, world frame, float64; every row's is the same
    moved along the track (a straight, level track)."""

    antenna: np.ndarray       # [3] m, zero-Doppler antenna of azimuth coordinate 0
    step: np.ndarray          # [3] the antenna's move per metre of azimuth coordinate
    directions: np.ndarray    # [M, 3] unit
    start: np.ndarray         # [M] m, from the antenna to each ray's origin (just above the scene)
    across: np.ndarray        # [M] directions . range_direction
    down: np.ndarray          # [M] -directions_z
    height: float             # m, H = A_z - z0
    nadir: float              # m, the antenna's coordinate on the range axis
    pixel_range: np.ndarray   # [n_rg] m, |A - G| of each column (every row alike)
    spacing: float            # m, neighbouring hits' spacing on the ground or on a wall, the wider
    gap: float                # m, neighbouring hits farther apart lie on different surfaces


def iso_range_heights(loaded: Any, image: SarImage, rows: np.ndarray | None = None, *,
                      max_crossings: int = MAX_CROSSINGS, oversample: int = 4) -> np.ndarray:
    """Heights above the image plane where each pixel's iso-range circle meets visible geometry.

    Layover (docs/physics.md (G2)): every point of the circle about the straight track through
    a pixel focuses into it; the points of it the antenna sees (ground, facade, a roof laid over)
    are the scatterers a tomographic inversion of the pixel should find (TS2). See the module
    docstring for the ray fan, the interpolation and which crossings are kept.

    Parameters
    ----------
    loaded : LoadedScene
        The scene as loaded for the pass whose track defines the circles
        (:func:`sarmitsuba.scene.loader.load_scene`; its Mitsuba scene is in the local frame,
        ``loaded.offset`` float64 [3] the world-minus-local offset, m).
    image : SarImage
        A ground-plane image of that pass (world frame, only its grid is used): azimuth axis
        along the track, range axis horizontal and beyond the antenna's nadir.
    rows : int array [n_rows], optional
        The azimuth rows to compute, in ``[0, n_az)`` (default all, in order).
    max_crossings : int, default :data:`MAX_CROSSINGS`
        Crossings kept per pixel, the lowest (>= 1).
    oversample : int, default 4
        Rays per ground-range pixel spacing (>= 1). Heights on plane surfaces are exact at any
        value; edges and corners (a roof's front edge laid over) are good to about the rays'
        spacing on the surface (a pixel spacing over ``oversample``, over ``tan(theta)`` on a
        wall).

    Returns
    -------
    float64 ndarray [n_rows, n_rg, max_crossings], m
        Heights above ``z0 = image.origin[2]``, ascending along the last axis, NaN-padded
        (all NaN where the circle meets nothing the antenna sees, e.g. outside the scene).

    Raises
    ------
    ValueError
        The image is not a ground-plane :class:`~sarmitsuba.core.image.SarImage`, its axes do not
        run along and across the (straight, level) track, it reaches the antenna's nadir, the
        antenna is not above the scene's top, or ``rows``, ``max_crossings`` or ``oversample``
        are out of range.
    """
    fan = _fan(loaded, image, _whole(oversample, "oversample"))
    count = _whole(max_crossings, "max_crossings")
    n_az, n_rg = image.data.shape
    rows = _checked_rows(rows, n_az)
    out = np.full((rows.size, n_rg, count), np.nan)
    step = max(1, _BATCH_RAYS // fan.start.size)
    offset = np.asarray(loaded.offset, np.float64)
    for first in range(0, rows.size, step):
        batch = rows[first:first + step]
        slant, shape = _cast(loaded.scene, fan, image.azimuth[batch], offset)
        out[first:first + batch.size] = _crossings(fan, image.range, slant, shape, count)
    return out


def nearest_truth(heights_at_pixels: np.ndarray, estimates: np.ndarray) -> np.ndarray:
    """For detected scatterers: the crossing height nearest each estimate.

    Parameters
    ----------
    heights_at_pixels : float array [M, K], m
        The rows of :func:`iso_range_heights` at the scatterers' pixels (NaN-padded; float32
        as stored in a stack's ``truth.npz`` is accepted).
    estimates : float array [M], m
        The estimated heights above the same plane ``z0``.

    Returns
    -------
    float64 ndarray [M], m
        The finite entry of each row nearest its estimate (the lower on a tie); NaN where the
        row has none.

    Raises
    ------
    ValueError
        The two do not have the same number of rows.
    """
    e = np.asarray(estimates, np.float64).ravel()
    h = np.asarray(heights_at_pixels, np.float64)
    if h.ndim != 2 or h.shape[0] != e.size:
        raise ValueError(f"heights_at_pixels must be [M, K] with M = {e.size} estimates, got {list(h.shape)}")
    if h.shape[1] == 0:
        return np.full(e.shape, np.nan)
    gap = np.where(np.isfinite(h), np.abs(h - e[:, None]), np.inf)
    best = np.argmin(gap, axis=1)
    pick = np.arange(h.shape[0])
    return np.where(np.isfinite(gap[pick, best]), h[pick, best], np.nan)


def _whole(value: Any, name: str) -> int:
    if isinstance(value, bool) or not float(value).is_integer() or value < 1:
        raise ValueError(f"{name} must be a whole number >= 1, got {value!r}")
    return int(value)


def _checked_rows(rows: Any, n_az: int) -> np.ndarray:
    if rows is None:
        return np.arange(n_az)
    out = np.asarray(rows)
    if out.ndim != 1 or (out.size and (out.dtype.kind not in "iu" or out.min() < 0 or out.max() >= n_az)):
        raise ValueError(f"rows must be a 1-D array of integer rows in [0, {n_az}), got {rows!r}")
    return out.astype(np.int64)


def _fan(loaded: Any, image: SarImage, oversample: int) -> _Fan:
    """The checked geometry and the ray fan of azimuth coordinate 0 (module docstring)."""
    if not isinstance(image, SarImage):
        raise ValueError(f"image must be a sarmitsuba.core.image.SarImage, got {type(image).__name__}")
    if image.plane != "ground":
        raise ValueError(f"iso-range heights need a ground-plane image, got plane = {image.plane!r}")
    if image.range.size < 2:
        raise ValueError(f"iso-range heights need at least 2 range columns, got {image.range.size}")
    geometry = acquisition_geometry(loaded.params)
    t, look = np.asarray(geometry.track_direction, np.float64), np.asarray(image.range_direction, np.float64)
    if (geometry.curved or abs(t[2]) > 1e-6 or abs(float(image.azimuth_direction @ t)) < 1.0 - 1e-6
            or abs(look[2]) > 1e-6 or abs(float(look @ t)) > 1e-6):
        raise ValueError("iso-range heights need a straight, level track, the image's azimuth axis along it and "
                         f"its range axis horizontal: track {t.tolist()}, azimuth_direction "
                         f"{image.azimuth_direction.tolist()}, range_direction {look.tolist()}")
    offset = np.asarray(loaded.offset, np.float64)
    mid = np.asarray(geometry.positions, np.float64).mean(axis=0) + offset       # world frame
    antenna = mid + float((image.origin - mid) @ t) * t
    z0 = float(image.origin[2])
    height, nadir = float(antenna[2] - z0), float((antenna - image.origin) @ look)
    top = max(float(loaded.bbox_hi[2] + offset[2]) - z0, 0.0) + 1.0              # above z0, m
    if height <= top:
        raise ValueError(f"the antenna ({height:.3f} m above z0 = {z0:.3f} m) must be above the scene's top "
                         f"({top - 1.0:.3f} m above z0)")
    rg = np.asarray(image.range, np.float64)
    if rg.min() <= nadir:
        raise ValueError(f"the image must lie beyond the antenna's nadir (range {nadir:.3f} m); its range axis "
                         f"starts at {rg.min():.3f} m")
    aims = _aims(loaded, image, offset, height, nadir, top, oversample)
    spread = np.hypot(aims - nadir, height)
    across, down = (aims - nadir) / spread, height / spread
    spacing = _spacing(rg) / oversample * max(1.0, float(down[0] / across[0]))     # / tan(theta), steepest
    return _Fan(antenna=antenna, step=float(image.azimuth_direction @ t) * t,
                directions=across[:, None] * look + down[:, None] * np.array([0.0, 0.0, -1.0]),
                start=np.maximum(0.0, (height - top) / down), across=across, down=down, height=height,
                nadir=nadir, pixel_range=np.hypot(rg - nadir, height), spacing=spacing, gap=_JUMP * spacing)


def _spacing(rg: np.ndarray) -> float:
    return float(np.median(np.abs(np.diff(rg))))


def _aims(loaded: Any, image: SarImage, offset: np.ndarray, height: float, nadir: float, top: float,
          oversample: int) -> np.ndarray:
    """Range coordinates [M] m on the image line the fan aims at, ``oversample`` per pixel
    spacing: from the farther of the image's and the scene's near edges (a ray aimed nearer hits
    nothing that images into the image) to the nearer of where a ray through the scene's top
    above its far edge lands and where one through the top of the image's far-edge circle does."""
    rg, look = np.asarray(image.range, np.float64), image.range_direction
    lo, hi = np.asarray(loaded.bbox_lo, np.float64), np.asarray(loaded.bbox_hi, np.float64)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    across = (corners + offset - image.origin) @ look
    lift = height / (height - top)                       # a ray through the top at d from the nadir lands at d lift
    scene_far = nadir + (float(across.max()) - nadir) * lift
    circle = math.hypot(float(rg.max()) - nadir, height)         # the far edge's circle, at the top
    image_far = nadir + math.sqrt(circle ** 2 - (height - top) ** 2) * lift
    spacing = _spacing(rg) / oversample
    near = max(float(rg.min()), float(across.min())) - 2 * spacing
    far = max(min(scene_far, image_far), near) + 2 * spacing
    aims = np.arange(near, far + spacing, spacing)
    return aims[aims > nadir + 1e-3 * height]


def _cast(scene: Any, fan: _Fan, azimuth: np.ndarray, offset: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The fans of the rows at ``azimuth`` [R] m: slant range ``|A - P|`` of each first hit,
    float64 [R, M] m (inf on a miss), and its shape id, uint32 [R, M]."""
    antennas = fan.antenna - offset + azimuth[:, None] * fan.step            # [R, 3] local frame
    origins = (antennas[:, None, :] + fan.start[None, :, None] * fan.directions[None]).reshape(-1, 3)
    directions = np.broadcast_to(fan.directions.astype(np.float32)[None], (azimuth.size,) + fan.directions.shape)
    hit = intersect(scene, origins.astype(np.float32), directions.reshape(-1, 3), normals=False)
    shape = (azimuth.size, fan.start.size)
    return fan.start + hit["t"].reshape(shape), hit["shape"].reshape(shape)


def _crossings(fan: _Fan, rg: np.ndarray, slant: np.ndarray, shape: np.ndarray, count: int) -> np.ndarray:
    """The table of a batch of rows, float64 [R, n_rg, count] (module docstring)."""
    n_rows, n_rays = slant.shape
    valid = np.isfinite(slant)
    s = np.where(valid, slant, 0.0)
    step = np.hypot(np.diff(s * fan.across, axis=1), np.diff(s * fan.down, axis=1))
    link = np.zeros((n_rows, n_rays), bool)             # link[v]: hit v and hit v + 1 lie on one surface
    link[:, :-1] = valid[:, :-1] & valid[:, 1:] & (shape[:, :-1] == shape[:, 1:]) & (step < fan.gap)
    link = link.ravel()                                  # (each row ends unlinked)
    s, height = s.ravel(), (fan.height - s * fan.down).ravel()
    hit, column, h = _segment_crossings(fan.pixel_range, s, height, link)
    extreme_hit, extreme_column, extreme_h = _extremes(fan, rg, s, height, link, valid.ravel())
    pix = (np.r_[hit, extreme_hit] // n_rays) * rg.size + np.r_[column, extreme_column]
    return _table(pix, np.r_[h, extreme_h], n_rows, rg.size, count, fan.spacing)


def _segment_crossings(pixel_range: np.ndarray, s: np.ndarray, height: np.ndarray,
                       link: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (segment, column) whose pixel range lies on the segment ``v, v + 1`` of linked hits:
    (v [n], column [n], height interpolated in slant range [n] m). A segment holds the range of
    its first hit, not of its second (the next segment's first), except a surface's last, which
    holds both."""
    order = np.argsort(pixel_range, kind="stable")
    ranges = pixel_range[order]
    left = np.searchsorted(ranges, s, "left")           # per hit: columns (sorted) below its range
    right = left + (ranges[np.minimum(left, ranges.size - 1)] == s)      # ... and at or below it
    at = right != left
    seg = np.flatnonzero(link[:-1] & ((left[:-1] != left[1:]) | (right[:-1] != right[1:]) | at[:-1] | at[1:]))
    a, b = seg, seg + 1                                  # the segments that hold a column's range
    last = ~link[b]
    rising = s[b] > s[a]
    first = np.where(rising, left[a], np.where(last, left[b], right[b]))
    end = np.where(rising, np.where(last, right[b], left[b]), right[a])
    n = np.maximum(end - first, 0)
    which = np.repeat(np.arange(seg.size), n)
    column = order[first[which] + np.arange(which.size) - np.repeat(np.cumsum(n) - n, n)]
    a, b = a[which], b[which]
    span = s[b] - s[a]
    frac = np.where(span != 0, (pixel_range[column] - s[a]) / np.where(span != 0, span, 1.0), 0.0)
    return a, column, height[a] + frac * (height[b] - height[a])


def _extremes(fan: _Fan, rg: np.ndarray, s: np.ndarray, height: np.ndarray, link: np.ndarray,
              valid: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each surface's nearest and farthest hit, for the column whose cell shows it when the
    surface's ranges do not reach that column's: (hit [n], column [n], height [n] m). A hit
    linked to neither neighbour is a surface of its own (a small object, a fragment of faces
    that overlap)."""
    before = np.r_[False, link[:-1]]
    alone = valid & ~link & ~before
    begin = np.flatnonzero((link & ~before) | alone)     # a surface's hits: begin..end
    end = np.flatnonzero((~link & before) | alone)
    if begin.size == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    n = end - begin + 1
    hits = np.repeat(begin, n) + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    owner = np.repeat(np.arange(begin.size), n)
    bounds = np.ravel(np.column_stack([begin, end + 1]))
    padded = np.r_[s, 0.0]
    order = np.argsort(rg, kind="stable")
    axis = rg[order]
    edges = 0.5 * (axis[1:] + axis[:-1])                 # between the columns' cells
    out = []
    for reduce, beyond in ((np.minimum, -1.0), (np.maximum, 1.0)):
        value = reduce.reduceat(padded, bounds)[::2]
        at = np.flatnonzero(s[hits] == value[owner])
        at = hits[at[np.r_[True, owner[at][1:] != owner[at][:-1]]]]     # the first such hit of each surface
        ground = fan.nadir + np.sqrt(np.maximum(value ** 2 - fan.height ** 2, 0.0))    # where it images
        column = order[np.searchsorted(edges, ground)]
        inside = (ground >= 1.5 * axis[0] - 0.5 * axis[1]) & (ground <= 1.5 * axis[-1] - 0.5 * axis[-2])
        keep = inside & (beyond * (fan.pixel_range[column] - value) > 0)
        out.append((at[keep], column[keep], height[at[keep]]))
    return tuple(np.concatenate(parts) for parts in zip(*out))


def _table(pix: np.ndarray, h: np.ndarray, n_rows: int, n_rg: int, count: int, merge: float) -> np.ndarray:
    """Heights per pixel, ascending, the lowest ``count``: float64 [n_rows, n_rg, count], NaN-padded.
    A height less than ``merge`` [m] above the pixel's previous one is the same scatterer (a wall's
    foot on the ground, coplanar faces) and dropped."""
    out = np.full((n_rows * n_rg, count), np.nan)
    keys = np.lexsort((h, pix))
    pix, h = pix[keys], h[keys]
    same = np.r_[False, (pix[1:] == pix[:-1]) & (np.diff(h) < merge)] if pix.size else np.zeros(0, bool)
    pix, h = pix[~same], h[~same]
    new = np.r_[True, pix[1:] != pix[:-1]] if pix.size else np.zeros(0, bool)
    start = np.flatnonzero(new)
    rank = np.arange(pix.size) - np.repeat(start, np.diff(np.r_[start, pix.size]))
    keep = rank < count
    out[pix[keep], rank[keep]] = h[keep]
    return out.reshape(n_rows, n_rg, count)
