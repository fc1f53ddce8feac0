"""Tomographic focusing of a stack held in memory: profiles, scatterers and the point cloud.

:func:`focus_elevation` is the Python entry point of the ``tomography`` command: it checks the
stack (:func:`sarmitsuba.stacks.tomography.check_stack`), derives the baselines from the
passes' own tracks, calibrates (TS6), chooses the pixels to invert
(:func:`sarmitsuba.stacks.tomo_pixels.select_pixels`, (TS7)), inverts each by beamforming (TS3), Capon (TS4)
or SL1MMER (TS5), detects the scatterers and places them in the scene (the reference pass's
iso-range circle, docs/physics.md (TS2)) and, when the scene has a ``geo_origin``, on the WGS84
ellipsoid (docs/physics.md (GEO1)).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..core.image import SarImage
from .interferometry import pair_baseline
from .tomo_pixels import check_region, select_pixels  # noqa: F401  (select_pixels: its former home)
from .tomography import (TomographyError, beamforming, calibration_phases, capon, check_stack, detect_peaks,
                         elevation_points, phase_model, stack_samples, steering, window_covariance)

__all__ = ["METHODS", "TomographyResult", "stack_geometry", "focus_elevation"]

#: Inversions of :func:`focus_elevation`.
METHODS = ("beamforming", "capon", "sparse")
#: Elevation samples per resolution cell ``rho_s`` of the profiles.
OVERSAMPLING = 8
_CHUNK = 512


@dataclass(frozen=True)
class TomographyResult:
    """A stack focused in elevation.

    Attributes
    ----------
    method : str
        One of :data:`METHODS`.
    elevation : float64 [S], m
        The profiles' elevation axis (arc length up the reference pass's iso-range circle).
    rows, cols : int64 [P]
        The inverted pixels.
    profiles : float32 [P, S]
        Reflectivity power over elevation [m^2, normalised radiometry]: beamforming, Capon, or the
        L1 step's ``|x|^2`` (sparse).
    scatterers : dict of arrays [M]
        ``row``, ``col`` (int64); ``elevation``, ``height`` (above the grid plane), ``x``, ``y``,
        ``z`` (world frame) [m]; ``power`` [m^2]; with a ``geo_origin``, ``latitude``,
        ``longitude`` [deg] and ``ellipsoid_height`` [m]; ``truth_height`` [m] when given truth.
    perpendicular : float64 [N], m
        Each pass's perpendicular baseline against the reference pass.
    reference : int
    calibration : float64 [N], rad
        The phase removed from each pass.
    elevation_resolution, elevation_ambiguity : float, m
        ``lambda R / (2 Delta b)`` and ``lambda R / (2 d_b)`` of the passes (TS1).
    """

    method: str
    elevation: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    profiles: np.ndarray
    scatterers: dict
    perpendicular: np.ndarray
    reference: int
    calibration: np.ndarray
    elevation_resolution: float
    elevation_ambiguity: float


def stack_geometry(images: Sequence[SarImage], raws: Sequence[Any], reference: int | None = None
                   ) -> tuple[int, np.ndarray, float, float]:
    """``(reference, perpendicular baselines float64 [N] m, rho_s, ambiguity)`` of the passes'
    own tracks (TS1), against the pass nearest the middle of the span when ``reference`` is None."""
    base = [pair_baseline(images[0], raws[0], raw) for raw in raws]
    perp = np.array([b.perpendicular for b in base])
    if reference is None:
        reference = int(np.argmin(np.abs(perp - 0.5 * (perp.min() + perp.max()))))
    perp = perp - perp[reference]
    wavelength_range = base[0].slant_range * 299_792_458.0 / float(raws[0].fc)
    span = float(np.ptp(perp))
    if span <= 0:
        raise TomographyError("the passes have no perpendicular baseline span: tomography needs passes at "
                              "different perpendicular baselines (tracks offset across the line of sight, as "
                              "`stack` flies them)")
    return reference, perp, wavelength_range / (2 * span), wavelength_range * (len(perp) - 1) / (2 * span)


def focus_elevation(images: Sequence[SarImage], raws: Sequence[Any], interval: tuple[float, float], *,
                    method: str = "beamforming", reference: int | None = None,
                    region: tuple[slice, slice] = (slice(None), slice(None)), min_power_db: float | None = None,
                    calibration_point: Sequence[float] | None = None, looks: tuple[int, int] = (3, 3),
                    threshold_db: float = -10.0, max_scatterers: int = 3, regularization: float = 0.05,
                    progress: bool = False) -> TomographyResult:
    """Focus a stack in elevation (module docstring).

    Parameters
    ----------
    images, raws : sequences of SarImage and RawData, one per pass
        On one ground grid (:func:`~sarmitsuba.stacks.tomography.check_stack`).
    interval : (float, float), m
        Elevations to invert; its length must stay below the ambiguity ``lambda R / (2 d_b)``.
    method : {"beamforming", "capon", "sparse"}
    reference : int, optional
        The pass whose iso-range circles carry the elevation axis (default: mid-span).
    region, min_power_db
        Pixels to invert (:func:`sarmitsuba.stacks.tomo_pixels.select_pixels`): a window of
        azimuth rows and range columns inside the image, and by default those at most 15 dB below
        its clutter level (TS7); ``min_power_db`` (< 0, dB): those within it of its brightest.
    calibration_point : 3 floats, m, optional
        A surveyed point scatterer (TS6); default the flat earth.
    looks : (int, int)
        Capon's covariance window.
    threshold_db, max_scatterers
        Scatterer detection in the beamforming and Capon profiles
        (:func:`~sarmitsuba.stacks.tomography.detect_peaks`); ``max_scatterers`` is also the
        sparse inversion's largest model order.
    regularization : float
        Of the sparse inversion (:func:`sarmitsuba.stacks.tomo_sparse.sl1mmer`).

    Returns
    -------
    TomographyResult

    Raises
    ------
    TomographyError
        Fewer than 3 passes, different grids or carriers, an unknown method, an interval that
        aliases, a window outside the image or without a pixel to invert, a reference point
        outside the image or not standing over its surroundings, bad detection parameters.
    """
    check_stack(images, raws)
    if method not in METHODS:
        raise TomographyError(f"method = {method!r}; valid: {', '.join(METHODS)}")
    reference, perp, rho, ambiguity = stack_geometry(images, raws, reference)
    lo, hi = (float(v) for v in interval)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise TomographyError(f"interval = {interval!r}: give two finite elevations lo < hi in metres")
    if hi - lo >= ambiguity:
        raise TomographyError(f"the baselines alias the elevations to invert: {hi - lo:.2f} m of elevation, but the "
                              f"passes' mean spacing repeats elevation every {ambiguity:.2f} m (lambda R / (2 d_b)): "
                              "render the stack with more passes or a smaller span, or invert a shorter interval")
    if not (math.isfinite(threshold_db) and threshold_db < 0):
        raise TomographyError(f"threshold_db = {threshold_db!r}: give a finite number of dB < 0 (a scatterer is a "
                              "profile peak within it of the pixel's strongest; default -10)")
    if isinstance(max_scatterers, bool) or int(max_scatterers) != max_scatterers or max_scatterers < 1:
        raise TomographyError(f"max_scatterers = {max_scatterers!r}: give a whole number >= 1 (default 3)")
    check_region(images[0].data.shape, region)
    calibration, _ = calibration_phases(images, raws, reference, calibration_point)
    rows, cols = select_pixels(images, region, min_power_db)
    s = np.arange(lo, hi + 0.5 * rho / OVERSAMPLING, rho / OVERSAMPLING)
    model = phase_model(images, raws, reference, rows, cols, (lo, hi))
    profiles = np.zeros((rows.size, s.size), np.float32)
    elevations = np.full((rows.size, max_scatterers), np.nan)
    powers = np.full((rows.size, max_scatterers), np.nan)
    if method == "sparse":
        from .tomo_sparse import sl1mmer
        found = sl1mmer(stack_samples(images, rows, cols, calibration), model, s, regularization=regularization,
                        max_scatterers=max_scatterers, progress=progress)
        profiles[:] = found.profiles
        elevations, powers = found.elevations, np.abs(found.amplitudes) ** 2
    else:
        for c0 in range(0, rows.size, _CHUNK):
            part = slice(c0, c0 + _CHUNK)
            a = steering(_rows_of(model, part), s)
            if method == "beamforming":
                profiles[part] = beamforming(stack_samples(images, rows[part], cols[part], calibration), a)
            else:
                cov = window_covariance(images, rows[part], cols[part], looks, calibration)
                profiles[part] = capon(cov, a)
            elevations[part], powers[part] = detect_peaks(profiles[part], s, threshold_db, max_scatterers)
    scatterers = _scatterers(images[reference], raws[reference], model, rows, cols, elevations, powers)
    return TomographyResult(method=method, elevation=s, rows=rows, cols=cols, profiles=profiles,
                            scatterers=scatterers, perpendicular=perp, reference=reference, calibration=calibration,
                            elevation_resolution=rho, elevation_ambiguity=ambiguity)


def _rows_of(model: Any, part: slice) -> Any:
    """The phase model of a slice of its pixels."""
    import dataclasses
    return dataclasses.replace(model, phase=model.phase[:, :, part], height=model.height[:, part])


def _scatterers(image: SarImage, raw: Any, model: Any, rows: np.ndarray, cols: np.ndarray,
                elevations: np.ndarray, powers: np.ndarray) -> dict:
    """The detected scatterers as flat arrays (:class:`TomographyResult`)."""
    from ..core import georef
    p, k = np.nonzero(np.isfinite(elevations))
    s = elevations[p, k]
    heights = _rows_of(model, slice(None)).heights(elevations)[p, k] if p.size else np.zeros(0)
    pixels = image.positions()[rows[p], cols[p]]
    points = elevation_points(image, raw, pixels, s[:, None])[:, 0] if p.size else np.zeros((0, 3))
    out = {"row": rows[p].astype(np.int64), "col": cols[p].astype(np.int64), "elevation": s, "height": heights,
           "x": points[:, 0], "y": points[:, 1], "z": points[:, 2], "power": powers[p, k]}
    radar = image.metadata.get("radar") if isinstance(image.metadata, dict) else None
    if isinstance(radar, dict) and radar.get("geo_origin") is not None and p.size:
        llh = georef.enu_to_geodetic(points, georef.of(radar))
        out.update(latitude=llh[:, 0], longitude=llh[:, 1], ellipsoid_height=llh[:, 2])
    return out
