"""Geometric ground truth of a SAR image: layover, shadow, building footprints, double-bounce lines.

Every mask here is computed from the scene's geometry by Mitsuba ray casting (closest-hit
and shadow rays, vectorised over pixels or over ray fans), never from the image, so it
can label an image or check it. Masks are bool ``[n_az, n_rg]`` on a ground-plane
:class:`~sarmitsuba.core.image.SarImage`'s own grid.

Geometry (docs/physics.md (G1)-(G3)). The image is focused on the horizontal plane
``z = z0`` of its grid (``z0 = image.origin[2]``, the scene centre). A straight track
images a point ``P`` at *zero Doppler*: in the plane through ``P`` perpendicular to the
track, at the ground point ``G`` (``z = z0``) with the same distance to the track line.
With ``A`` the antenna at zero Doppler, ``H = A_z - z0`` and ``r_A`` the antenna's ground
range on the image axis,

.. math::

    r_{img} = r_A + \\sqrt{|A - P|^2 - H^2}
    \\;\\approx\\; g - h / \\tan\\theta_{loc},

where ``g`` is ``P``'s own ground range, ``h = P_z - z0`` its height and
``theta_loc`` the local incidence angle: **layover**, a point at height ``h`` appears
``h / tan(theta)`` closer to the sensor (G2). The exact form is used; it is the
iso-range circle on which backprojection focuses ``P``. The ground behind a wall of
height ``h`` is hidden from the antenna over ``h tan(theta)`` of ground range:
**shadow** (G3). A wall facing the sensor returns the wall-ground double bounce at the
ground position of its foot (G1): the **double-bounce line**.

=============================  ==============================================================
:func:`ground_truth`           All masks at once (:class:`GroundTruth`), sharing the work.
:func:`layover_mask`           Pixels onto which elevated surfaces seen by the antenna map.
:func:`shadow_mask`            Ground pixels the antenna cannot see (not under a building).
:func:`footprint_mask`         Ground pixels covered by geometry above ``z0 + threshold``.
:func:`double_bounce_mask`     Pixels of the visible wall-ground contact lines.
:func:`facade_foot_points`     World points of those contact lines, float64 ``[n, 3]``.
:func:`agreement`              How well an image shows them (bright layover, dark shadow).
=============================  ==============================================================

The antenna positions come from the scene's resolved radar parameters
(:func:`sarmitsuba.core.radar.acquisition_geometry`): the zero-Doppler antenna of a pixel is the
point of the straight track line closest to it (the line is extended beyond the first and
last pulse when needed). The plane ``z0`` counts as ground everywhere, also where the
scene has no ground geometry (the dihedral's shadow falls behind its plate). The image's grid
is in the world frame, the loaded scene in its local one (world minus ``loaded.offset``: a
scene far from the origin is traced about its own centre); the grid is moved into the scene's
frame, rays start near the scene and are cast in float32 there, so masks are exact to well
under a pixel for scenes within some kilometres of their local origin, wherever they lie.

Cost: about one ray per pixel for each of shadow, footprint and double bounce, and
``oversample`` rays per pixel spacing along each row's fan for layover: about 1 s for the
built-in urban scene (0.7 M pixels) and 15-20 s for Sionna's munich (11 M pixels) on 2 cores.
"""
from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.image import SarImage
from ..core.outputs import atomic_savez
from ..core.geometry import acquisition_geometry

__all__ = ["GroundTruth", "ground_truth", "layover_mask", "shadow_mask", "footprint_mask",
           "double_bounce_mask", "facade_foot_points", "agreement", "intersect"]

#: Default height above the image plane ``z0`` [m] above which a surface counts as elevated.
HEIGHT_THRESHOLD = 0.1
#: Rays in flight per batch (memory: about 100 B per ray).
_BATCH_RAYS = 2_000_000


@dataclass(frozen=True)
class GroundTruth:
    """Geometric masks of one image (see the module docstring for the definitions).

    Attributes
    ----------
    layover : bool [n_az, n_rg]
        Pixels onto which elevated surfaces (``h > height_threshold``) visible from the
        antenna are mapped.
    shadow : bool [n_az, n_rg]
        Ground pixels (at ``z0``) not visible from the zero-Doppler antenna, excluding
        building footprints.
    footprint : bool [n_az, n_rg]
        Ground pixels covered by geometry higher than ``z0 + height_threshold``.
    double_bounce : bool [n_az, n_rg]
        Pixels containing the foot of a wall that faces the sensor, with lit ground in front.
    scene_area : bool [n_az, n_rg]
        Pixels whose ground point lies inside the horizontal extent of the scene's bounding
        box (the image grid also covers margins around it).
    height_threshold : float, m
        Height above ``z0`` above which a surface counts as elevated.
    z0 : float, m
        Height of the image plane.
    """

    layover: np.ndarray
    shadow: np.ndarray
    footprint: np.ndarray
    double_bounce: np.ndarray
    scene_area: np.ndarray
    height_threshold: float
    z0: float

    def fractions(self) -> dict[str, float]:
        """Fraction of the image's pixels in each mask."""
        return {name: float(getattr(self, name).mean())
                for name in ("layover", "shadow", "footprint", "double_bounce", "scene_area")}

    def save(self, path: str | os.PathLike) -> Path:
        """Write the masks as ``.npz`` (bool arrays plus the two scalars), atomically."""
        return atomic_savez(Path(path), layover=self.layover, shadow=self.shadow, footprint=self.footprint,
                             double_bounce=self.double_bounce, scene_area=self.scene_area,
                             height_threshold=np.float64(self.height_threshold), z0=np.float64(self.z0))


# ============================================================================ geometry
@dataclass(frozen=True)
class _Frame:
    """Image grid and zero-Doppler track geometry, float64 throughout, in the scene's local frame
    (world minus ``offset``, the frame the scene is traced in: ``LoadedScene.offset``)."""

    image: SarImage          # the image's grid moved into the local frame
    scene: Any
    mid: np.ndarray          # [3] mid-aperture antenna, m
    track: np.ndarray        # [3] unit track direction
    z0: float                # image plane height, m
    top: float               # a height above all geometry, m
    spacing: float           # ground-range pixel spacing, m
    offset: np.ndarray       # [3] world position of the local frame's origin, m

    def row_antennas(self, rows: np.ndarray) -> np.ndarray:
        """Zero-Doppler antenna of each image row, float64 [len(rows), 3]."""
        im = self.image
        centres = im.origin + im.azimuth[rows, None] * im.azimuth_direction
        s = (centres - self.mid) @ self.track
        return self.mid + s[:, None] * self.track

    def pixels(self, rows: np.ndarray) -> np.ndarray:
        """World positions of the pixels of ``rows`` (at ``z0``), float64 [len(rows), n_rg, 3]."""
        im = self.image
        return (im.origin + im.azimuth[rows, None, None] * im.azimuth_direction
                + im.range[None, :, None] * im.range_direction)


def _frame(loaded: Any, image: SarImage) -> _Frame:
    if not isinstance(image, SarImage):
        raise ValueError(f"image must be a sarmitsuba.core.image.SarImage, got {type(image).__name__}")
    if image.plane != "ground":
        raise ValueError(f"ground-truth masks need a ground-plane image, got plane = {image.plane!r}")
    if image.range.size < 2 or image.azimuth.size < 1:
        raise ValueError(f"image grid too small for masks: {image.data.shape}")
    geometry = acquisition_geometry(loaded.params)
    track = geometry.track_direction
    if abs(float(image.azimuth_direction @ track)) < 1.0 - 1e-6 or abs(float(image.range_direction[2])) > 1e-6:
        raise ValueError("the image's azimuth axis must run along the track and its range axis must be "
                         f"horizontal; got azimuth_direction {image.azimuth_direction.tolist()}, track "
                         f"{track.tolist()}, range_direction {image.range_direction.tolist()}")
    mid = geometry.positions.mean(axis=0)                  # a point of the (straight) track line
    # the image is in the world frame, the scene (its geometry, track and box) in its local one
    offset = np.asarray(getattr(loaded, "offset", np.zeros(3)), np.float64)
    if np.any(offset):
        image = dataclasses.replace(image, origin=np.asarray(image.origin, np.float64) - offset)
    z0 = float(image.origin[2])
    top = max(float(loaded.bbox_hi[2]), z0) + 1.0
    spacing = float(abs(image.range[1] - image.range[0]))
    return _Frame(image=image, scene=loaded.scene, mid=np.asarray(mid, np.float64), track=track, z0=z0, top=top,
                  spacing=spacing, offset=offset)


def _row_batches(n_rows: int, rays_per_row: int) -> list[np.ndarray]:
    step = max(1, _BATCH_RAYS // max(1, rays_per_row))
    return [np.arange(i, min(n_rows, i + step)) for i in range(0, n_rows, step)]


# ============================================================================ Mitsuba casts
def _rays(origins: np.ndarray, directions: np.ndarray, maxt: np.ndarray | None) -> Any:
    import mitsuba as mi
    o = origins.astype(np.float32)
    d = directions.astype(np.float32)
    ray = mi.Ray3f(mi.Point3f(o[:, 0], o[:, 1], o[:, 2]), mi.Vector3f(d[:, 0], d[:, 1], d[:, 2]))
    return ray if maxt is None else mi.Ray3f(ray, mi.Float(maxt.astype(np.float32)))


def intersect(scene: Any, origins: np.ndarray, directions: np.ndarray, maxt: np.ndarray | None = None,
              normals: bool = True) -> dict[str, np.ndarray]:
    """Closest hits of a batch of rays (one Mitsuba ``ray_intersect``, cast in float32).

    Parameters
    ----------
    scene : mitsuba.Scene
        The scene, in the frame the rays are given in (a loaded scene's local frame).
    origins, directions : float [n, 3], m and unit vectors
        Ray origins and directions (cast to float32).
    maxt : float [n], m, optional
        Farthest distance along each ray (default unbounded).
    normals : bool, default True
        Also return the geometric normals.

    Returns
    -------
    dict
        ``t`` float64 [n], m (inf on a miss); ``shape`` uint32 [n], a per-shape id (0 on a
        miss); with ``normals``, ``n`` float64 [n, 3], the geometric normal at the hit.
    """
    import drjit as dr
    import mitsuba as mi
    si = scene.ray_intersect(_rays(origins, directions, maxt), ray_flags=mi.RayFlags.Minimal, coherent=False)
    fields = [si.t, dr.reinterpret_array(mi.UInt32, si.shape)]      # t = inf, shape = 0 on a miss
    if normals:
        fields += [si.n.x, si.n.y, si.n.z]
    dr.eval(*fields)                                       # one kernel: trace once, not once per field
    out = {"t": np.asarray(fields[0]).astype(np.float64),  # zero-copy views, copied here
           "shape": np.asarray(fields[1]).copy()}
    if normals:
        out["n"] = np.stack([np.asarray(f) for f in fields[2:]], axis=1).astype(np.float64)
    return out


def _blocked(scene: Any, origins: np.ndarray, directions: np.ndarray, maxt: np.ndarray) -> np.ndarray:
    """Shadow rays: bool [n], True when something lies within ``maxt`` along the ray."""
    import drjit as dr
    import mitsuba as mi
    hit = dr.select(scene.ray_test(_rays(origins, directions, maxt)), mi.UInt32(1), mi.UInt32(0))
    dr.eval(hit)
    return np.asarray(hit) != 0


# ============================================================================ masks
def footprint_mask(loaded: Any, image: SarImage, *, height_threshold: float = HEIGHT_THRESHOLD) -> np.ndarray:
    """Building footprints: ground pixels covered by geometry above ``z0 + height_threshold``.

    A vertical ray from above the scene down to each pixel's ground point; the pixel is in
    the footprint when it first hits a surface higher than ``z0 + height_threshold``.

    Parameters
    ----------
    loaded : LoadedScene
        The scene the image was simulated from (``sarmitsuba.scene.loader.load_scene``).
    image : SarImage
        Ground-plane image; only its grid is used.
    height_threshold : float, default 0.1, m
        Height above the image plane above which a surface counts as elevated.

    Returns
    -------
    bool ndarray [n_az, n_rg]
    """
    return _footprint(_frame(loaded, image), _threshold(height_threshold))


def shadow_mask(loaded: Any, image: SarImage, *, height_threshold: float = HEIGHT_THRESHOLD) -> np.ndarray:
    """Radar shadow: ground pixels whose ground point the zero-Doppler antenna cannot see.

    A shadow ray from each pixel's ground point (1 cm above ``z0``) toward its zero-Doppler
    antenna; the pixel is in shadow when the ray is blocked and the point is not inside a
    building footprint (:func:`footprint_mask`). Behind a wall of height ``h`` on flat
    ground the shadow is ``h tan(theta_inc)`` long in ground range (docs/physics.md (G3)).

    Parameters and returns as :func:`footprint_mask`.
    """
    frame = _frame(loaded, image)
    threshold = _threshold(height_threshold)
    return _shadow(frame) & ~_footprint(frame, threshold)


def layover_mask(loaded: Any, image: SarImage, *, height_threshold: float = HEIGHT_THRESHOLD,
                 oversample: int = 2, shapes: Any = None) -> np.ndarray:
    """Layover: pixels onto which elevated surfaces visible from the antenna are mapped.

    For every image row, a fan of rays leaves the row's zero-Doppler antenna in the plane
    perpendicular to the track, dense enough that neighbouring rays land ``spacing /
    oversample`` apart at the far edge of the scene. Each first hit ``P`` at height
    ``h = P_z - z0 > height_threshold`` is mapped to the ground range of equal slant range,
    ``r_A + sqrt(|A - P|^2 - H^2)`` (``~ g - h / tan(theta)``, docs/physics.md (G2)), and
    its pixel is marked. Two neighbouring rays that hit the same shape less than eight ray
    spacings apart lie on one continuous surface, so every pixel between their image
    positions is marked too: steep incidence cannot leave holes in the band.

    Parameters
    ----------
    loaded, image, height_threshold
        As :func:`footprint_mask`.
    oversample : int, default 2
        Rays per pixel spacing at the far edge (>= 1); the interval filling makes more
        unnecessary.
    shapes : collection of int, optional
        Only the elevated surfaces of these shapes count (their indices in ``scene.shapes()``:
        the roofs of :func:`sarmitsuba.scene.roles.shape_roles`, say); default all.

    Returns
    -------
    bool ndarray [n_az, n_rg]
    """
    if int(oversample) != oversample or oversample < 1:
        raise ValueError(f"oversample must be a whole number >= 1, got {oversample!r}")
    frame = _frame(loaded, image)
    ids = None
    if shapes is not None:
        import drjit as dr
        import mitsuba as mi
        every = list(frame.scene.shapes())
        ids = np.array([int(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(every[int(k)]))[0]) for k in shapes],
                       np.uint32)
    return _layover(frame, _threshold(height_threshold), int(oversample), ids)


def double_bounce_mask(loaded: Any, image: SarImage, *,
                       height_threshold: float = HEIGHT_THRESHOLD) -> np.ndarray:
    """Double-bounce lines: pixels holding the foot of a wall that faces the sensor.

    See :func:`facade_foot_points`; this is the same set rasterised on the image grid
    (nearest pixel). The wall-ground double bounce focuses there (docs/physics.md (G1)).
    """
    frame = _frame(loaded, image)
    mask, _ = _double_bounce(frame, _threshold(height_threshold))
    return mask


def facade_foot_points(loaded: Any, image: SarImage, *,
                       height_threshold: float = HEIGHT_THRESHOLD) -> np.ndarray:
    """World points of the visible wall-ground contact lines (where double bounces focus).

    From each lit ground pixel (not in shadow, not under a building) a horizontal ray
    ``height_threshold / 2`` above ``z0`` runs one pixel spacing away from the sensor. A hit
    on a steep surface (``|n_z| < 0.7``) whose normal faces the sensor
    (``n . range_direction < -0.05``) is a wall foot: the ground in front of it is lit and the
    ground-wall (or wall-ground) path returns to the antenna with the two-way length of the
    foot (docs/physics.md (G1)).

    Returns
    -------
    float64 ndarray [n_points, 3], m
        One point per pixel of :func:`double_bounce_mask` (the hit nearest the sensor).
    """
    frame = _frame(loaded, image)
    _, points = _double_bounce(frame, _threshold(height_threshold))
    return points + frame.offset


def ground_truth(loaded: Any, image: SarImage, *, height_threshold: float = HEIGHT_THRESHOLD,
                 oversample: int = 2) -> GroundTruth:
    """All masks of :class:`GroundTruth` for ``image``, computed once each (no SAR tracing).

    Parameters
    ----------
    loaded : LoadedScene
        The scene the image was simulated from. Its resolved radar parameters give the
        track; load it with the parameters the image was made with, e.g.
        ``load_scene(image.metadata["scene_path"], sensor_overrides=...)``.
    image : SarImage
        Ground-plane image; only its grid is used.
    height_threshold : float, default 0.1, m
    oversample : int, default 2
        As :func:`layover_mask`.

    Raises
    ------
    ValueError
        Slant-plane image, image axes not along / across the track, or bad arguments.
    """
    frame = _frame(loaded, image)
    threshold = _threshold(height_threshold)
    if int(oversample) != oversample or oversample < 1:
        raise ValueError(f"oversample must be a whole number >= 1, got {oversample!r}")
    footprint = _footprint(frame, threshold)
    shadow = _shadow(frame) & ~footprint
    double, _ = _double_bounce(frame, threshold, footprint=footprint, shadow=shadow)
    xy = frame.image.positions()[..., :2]                    # local, as the scene's box
    scene_area = np.all((xy >= loaded.bbox_lo[:2]) & (xy <= loaded.bbox_hi[:2]), axis=-1)
    return GroundTruth(layover=_layover(frame, threshold, int(oversample)), shadow=shadow, footprint=footprint,
                       double_bounce=double, scene_area=scene_area, height_threshold=threshold,
                       z0=frame.z0 + float(frame.offset[2]))


def agreement(image: SarImage, truth: GroundTruth, threshold_db: float = 6.0) -> dict[str, Any]:
    """How well an image shows its ground truth: bright layover and double bounce, dark shadow.

    Parameters
    ----------
    image : SarImage
        The image the masks were computed for (same grid).
    truth : GroundTruth
    threshold_db : float, default 6
        "Bright" is an intensity ``|I|^2`` more than ``threshold_db`` above the image median,
        "dark" more than ``threshold_db`` below it. Single pixels, no speckle filtering.

    Returns
    -------
    dict
        ``layover_overlap``: fraction of layover pixels that are bright;
        ``double_bounce_bright``: the same for double-bounce pixels; ``shadow_dark``:
        fraction of the shadow pixels inside the scene area that are dark (each None for an
        empty mask); ``median_db``: ``10 log10`` of the image median; ``<mask>_mean_db``:
        mean intensity of each mask over the median, dB; ``<mask>_pixels``: pixel counts;
        ``threshold_db``.

    Notes
    -----
    The median is taken over the pixels of ``truth.scene_area`` (all pixels when it is
    empty): the image grid adds empty margins around the scene, whose near-zero pixels
    would otherwise pull the median down by an amount that depends on the margin.
    """
    if truth.layover.shape != image.data.shape:
        raise ValueError(f"masks {truth.layover.shape} and image {image.data.shape} have different grids")
    threshold_db = float(threshold_db)
    power = np.abs(image.data.astype(np.complex128)) ** 2
    area = truth.scene_area if truth.scene_area.any() else np.ones(power.shape, bool)
    median = float(np.median(power[area]))
    bright, dark = median * 10 ** (threshold_db / 10), median * 10 ** (-threshold_db / 10)
    out: dict[str, Any] = {"threshold_db": threshold_db,
                           "median_db": 10 * math.log10(median) if median > 0 else None}
    for name in ("layover", "shadow", "footprint", "double_bounce"):
        mask = getattr(truth, name)
        out[f"{name}_pixels"] = int(mask.sum())
        mean = float(power[mask].mean()) if mask.any() else float("nan")
        out[f"{name}_mean_db"] = 10 * math.log10(mean / median) if mask.any() and mean > 0 and median > 0 else None

    def fraction(mask: np.ndarray, test: np.ndarray) -> float | None:
        return float(test[mask].mean()) if mask.any() else None

    out["layover_overlap"] = fraction(truth.layover, power > bright)
    out["double_bounce_bright"] = fraction(truth.double_bounce, power > bright)
    out["shadow_dark"] = fraction(truth.shadow & area, power < dark)
    return out


def _threshold(value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ValueError(f"height_threshold must be a finite number > 0 (m), got {value!r}")
    return v


# ============================================================================ implementations
def _footprint(frame: _Frame, threshold: float) -> np.ndarray:
    n_az, n_rg = frame.image.data.shape
    out = np.zeros((n_az, n_rg), bool)
    down = np.array([0.0, 0.0, -1.0])
    for rows in _row_batches(n_az, n_rg):
        ground = frame.pixels(rows).reshape(-1, 3)
        start = ground.copy()
        start[:, 2] = frame.top
        hit = intersect(frame.scene, start, np.broadcast_to(down, start.shape),
                        np.full(len(start), frame.top - frame.z0 + 1.0), normals=False)
        height = frame.top - hit["t"] - frame.z0          # -inf for misses
        out[rows] = (height > threshold).reshape(len(rows), n_rg)
    return out


def _shadow(frame: _Frame) -> np.ndarray:
    """Blocked line of sight from each ground point to its zero-Doppler antenna (footprints included)."""
    n_az, n_rg = frame.image.data.shape
    out = np.zeros((n_az, n_rg), bool)
    lift = 0.01                                            # m above z0: the ground itself does not block
    for rows in _row_batches(n_az, n_rg):
        ground = frame.pixels(rows)
        ground[..., 2] += lift
        antenna = np.broadcast_to(frame.row_antennas(rows)[:, None, :], ground.shape)
        d = (antenna - ground).reshape(-1, 3)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        maxt = (frame.top - (frame.z0 + lift)) / d[:, 2]   # only geometry below `top` can block
        out[rows] = _blocked(frame.scene, ground.reshape(-1, 3), d, maxt).reshape(len(rows), n_rg)
    return out


def _double_bounce(frame: _Frame, threshold: float, footprint: np.ndarray | None = None,
                   shadow: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    im = frame.image
    n_az, n_rg = im.data.shape
    if footprint is None:
        footprint = _footprint(frame, threshold)
    if shadow is None:
        shadow = _shadow(frame) & ~footprint
    lit = ~(footprint | shadow)
    mask = np.zeros((n_az, n_rg), bool)
    points = []
    ahead = im.range_direction
    for rows in _row_batches(n_az, n_rg):
        start = frame.pixels(rows)
        start[..., 2] += 0.5 * threshold
        start = start.reshape(-1, 3)
        hit = intersect(frame.scene, start, np.broadcast_to(ahead, start.shape),
                        np.full(len(start), frame.spacing))
        ok = (np.isfinite(hit["t"]) & lit[rows].ravel() & (np.abs(hit["n"][:, 2]) < 0.7)
              & (hit["n"] @ ahead < -0.05))
        foot = start[ok] + hit["t"][ok, None] * ahead
        foot[:, 2] = frame.z0
        row = np.repeat(rows, n_rg)[ok]
        col = np.rint(((foot - im.origin) @ ahead - im.range[0]) / (im.range[1] - im.range[0])).astype(np.int64)
        keep = (col >= 0) & (col < n_rg)
        first = ~mask[row[keep], col[keep]]
        mask[row[keep], col[keep]] = True
        points.append(foot[keep][first])
    return mask, (np.concatenate(points) if points else np.zeros((0, 3)))


def _layover(frame: _Frame, threshold: float, oversample: int, shapes: np.ndarray | None = None) -> np.ndarray:
    im = frame.image
    n_az, n_rg = im.data.shape
    look = im.range_direction
    d_rg = float(im.range[1] - im.range[0])
    antenna0 = frame.row_antennas(np.array([0]))[0]
    height = antenna0[2] - frame.z0                        # H, m (same for every row: level track)
    r_antenna = float((antenna0 - im.origin) @ look)       # r_A, m (same for every row)
    if height <= 0:
        raise ValueError(f"the antenna ({antenna0[2]:.3f} m) must be above the image plane z0 = {frame.z0:.3f} m")
    # ray fan: aim points on z0 from the nearer of image / scene edges to beyond the far edge,
    # far enough that rays grazing the tallest geometry at the far edge are included
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    box = frame.scene.bbox()
    lo, hi = np.array(box.min, np.float64), np.array(box.max, np.float64)
    across = (lo + corners * (hi - lo) - im.origin) @ look
    near = min(float(im.range[0]), float(across.min())) - frame.spacing
    far_ground = max(float(im.range[-1]), float(across.max()))
    far = far_ground + max(0.0, hi[2] - frame.z0) * (far_ground - r_antenna) / height + frame.spacing
    near = max(near, r_antenna + 1e-3 * height)            # never aim behind the nadir
    psi_hi, psi_lo = math.atan2(height, near - r_antenna), math.atan2(height, far - r_antenna)
    r_far = math.hypot(height, far - r_antenna)
    n_rays = max(2, int(math.ceil((psi_hi - psi_lo) * r_far / (frame.spacing / oversample))) + 1)
    psi = np.linspace(psi_hi, psi_lo, n_rays)
    dirs = np.cos(psi)[:, None] * look + np.sin(psi)[:, None] * np.array([0.0, 0.0, -1.0])
    t_start = np.maximum(0.0, (antenna0[2] - frame.top) / np.sin(psi))   # start just above the scene
    gap = 8.0 * r_far * (psi_hi - psi_lo) / (n_rays - 1)              # continuity test, m

    out = np.zeros((n_az, n_rg), bool)
    for rows in _row_batches(n_az, n_rays):
        antenna = frame.row_antennas(rows)
        origins = (antenna[:, None, :] + t_start[None, :, None] * dirs[None, :, :]).reshape(-1, 3)
        hit = intersect(frame.scene, origins, np.broadcast_to(dirs[None], (len(rows), n_rays, 3)).reshape(-1, 3),
                        normals=False)
        slant = (t_start[None, :] + hit["t"].reshape(len(rows), n_rays))            # |A - P|, m (float64)
        z = antenna[:, None, 2] - slant * np.sin(psi)[None, :]
        elevated = np.isfinite(slant) & (z - frame.z0 > threshold)
        if shapes is not None:
            elevated &= np.isin(hit["shape"], shapes).reshape(len(rows), n_rays)
        with np.errstate(invalid="ignore"):
            r_img = r_antenna + np.sqrt(np.maximum(slant**2 - height**2, 0.0))
        col = (r_img - im.range[0]) / d_rg                                          # fractional column
        row = np.broadcast_to(np.arange(len(rows))[:, None], col.shape)              # row within the batch
        diff = np.zeros((len(rows), n_rg + 1), np.int64)
        # single samples: nearest pixel
        _mark(diff, row[elevated], np.rint(col[elevated]), np.rint(col[elevated]), n_rg)
        # connected neighbours on one surface: every pixel between their image positions
        shape = hit["shape"].reshape(len(rows), n_rays)
        with np.errstate(invalid="ignore"):
            pos_step = np.hypot(np.diff(slant * np.cos(psi)[None, :], axis=1),
                                np.diff(slant * np.sin(psi)[None, :], axis=1))
        pair = (elevated[:, 1:] & elevated[:, :-1] & (shape[:, 1:] == shape[:, :-1])
                & np.isfinite(pos_step) & (pos_step < gap))
        lo_c = np.minimum(col[:, 1:], col[:, :-1])[pair]
        hi_c = np.maximum(col[:, 1:], col[:, :-1])[pair]
        _mark(diff, row[:, 1:][pair], np.ceil(lo_c), np.floor(hi_c), n_rg)
        out[rows] = np.cumsum(diff, axis=1)[:, :n_rg] > 0
    return out


def _mark(diff: np.ndarray, rows: np.ndarray, first: np.ndarray, last: np.ndarray, n_rg: int) -> None:
    """Add the column intervals ``[first, last]`` (float, rounded) of ``rows`` to the difference array."""
    first = np.maximum(first, 0)
    last = np.minimum(last, n_rg - 1)
    keep = (first <= last) & np.isfinite(first) & np.isfinite(last)
    width = diff.shape[1]
    base = rows[keep].astype(np.int64) * width
    size = diff.size
    diff += (np.bincount(base + first[keep].astype(np.int64), minlength=size)
             - np.bincount(base + last[keep].astype(np.int64) + 1, minlength=size)).reshape(diff.shape)
