"""The interferometric baseline of a pass shifted by the sensor's ``track_offset`` (docs/physics.md (I1)-(I3)).

A render with ``track_offset = (dx, dy, dz)`` flies the nominal track shifted by that vector: the
secondary pass of a repeat-pass pair whose primary is the same scene without the offset. At the
scene centre ``C`` and the nominal mid-aperture antenna ``A``, with ``t`` the track direction,
``u = (A - C) / R`` the unit vector toward the sensor and ``R = |A - C|``:

* the baseline's part normal to the track, ``B_n = B - (B . t) t``, splits into the parallel
  baseline ``B_par = B_n . u`` (along the line of sight, positive away from the scene) and the
  perpendicular baseline ``B_perp = B_n . e``, ``e = u x t`` for a right-looking radar
  (``t x u`` looking left): the direction normal to the line of sight in which the look angle
  grows (outward and down);
* the critical perpendicular baseline ``B_crit = lambda R tan(theta) B_w / c`` (range bandwidth
  ``B_w``, incidence ``theta``): the two passes' ground-range spectra no longer overlap
  (Gatelli et al., IEEE TGRS 32(4), 1994; Bamler and Hartl, Inverse Problems 14, 1998, eq. 30);
* the height of ambiguity ``h_a = lambda R sin(theta) / (2 |B_perp|)``: the height that adds one
  2 pi cycle of interferometric phase (Hanssen, *Radar Interferometry*, 2001, eq. 2.5.13).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.radar import RadarParameters
from ..core.geometry import acquisition_geometry

__all__ = ["Baseline", "baseline", "perpendicular_direction", "StackBaselines", "stack_baselines", "STACK_SPACINGS"]

#: How :func:`stack_baselines` places ``count`` passes over a ``span``.
STACK_SPACINGS = ("uniform", "random")


@dataclass(frozen=True)
class Baseline:
    """The baseline of a pass shifted by ``track_offset`` against the nominal pass (module docstring).

    Attributes
    ----------
    vector : float64 [3], m
        The track offset ``B``.
    along_track, parallel, perpendicular : float, m
        ``B . t``, ``B_par`` and ``B_perp``.
    critical : float, m
        The critical perpendicular baseline ``lambda R tan(theta) B_w / c``.
    height_of_ambiguity : float, m
        ``lambda R sin(theta) / (2 |B_perp|)``; infinite for ``B_perp = 0``.
    slant_range : float, m
        ``R``, nominal mid-aperture antenna to scene centre.
    """

    vector: np.ndarray
    along_track: float
    parallel: float
    perpendicular: float
    critical: float
    height_of_ambiguity: float
    slant_range: float


def _frame(params: RadarParameters) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(e, u, t, R)`` of the nominal pass: perpendicular and line-of-sight unit vectors, track
    direction, slant range to the scene centre (module docstring)."""
    import dataclasses
    nominal = acquisition_geometry(dataclasses.replace(params, track_offset=(0.0, 0.0, 0.0)))
    t = nominal.track_direction
    to_sensor = nominal.positions[len(nominal.positions) // 2] - nominal.scene_center
    r = float(np.linalg.norm(to_sensor))
    u = to_sensor / r
    e = np.cross(u, t) if params.look_side == "right" else np.cross(t, u)
    return e, u, t, r


def perpendicular_direction(params: RadarParameters) -> np.ndarray:
    """The unit vector ``e`` (float64 [3], world frame) along which a ``track_offset`` is a pure
    perpendicular baseline: normal to the track and to the line of sight, pointing where the look
    angle grows (module docstring). ``track_offset = b e`` gives ``B_perp = b``, ``B_par = 0``."""
    return _frame(params)[0]


def baseline(params: RadarParameters) -> Baseline:
    """The baseline of ``params.track_offset`` (resolved parameters: ``scene_center`` and
    ``n_pulses`` set, as after :func:`sarmitsuba.scene.loader.load_scene`).

    Raises
    ------
    ParameterError
        Unresolved parameters (:func:`sarmitsuba.core.radar.acquisition_geometry`).
    """
    b = np.asarray(params.track_offset, dtype=np.float64)
    e, u, t, r = _frame(params)
    normal = b - (b @ t) * t
    perpendicular = float(normal @ e)
    theta = math.radians(params.incidence_angle)
    critical = params.wavelength * r * math.tan(theta) * params.bandwidth / SPEED_OF_LIGHT
    ambiguity = params.wavelength * r * math.sin(theta) / (2.0 * abs(perpendicular)) if perpendicular else math.inf
    return Baseline(vector=b, along_track=float(b @ t), parallel=float(normal @ u), perpendicular=perpendicular,
                    critical=critical, height_of_ambiguity=ambiguity, slant_range=r)


@dataclass(frozen=True)
class StackBaselines:
    """The passes of a tomographic stack and what their baselines give (docs/physics.md (TS1)).

    Attributes
    ----------
    track_offsets : float64 [N, 3], m
        Each pass's ``track_offset``.
    perpendicular : float64 [N], m
        Each pass's perpendicular baseline against the nominal track (:func:`baseline`).
    reference : int
        The pass nearest the middle of the span: the stack's elevation axis is its iso-range circle.
    span : float, m
        ``Delta b = max - min`` of ``perpendicular``.
    mean_spacing : float, m
        ``d_b = Delta b / (N - 1)``.
    elevation_resolution : float, m
        ``rho_s = lambda R / (2 Delta b)`` (Zhu and Bamler, IEEE TGRS 48(10), 2010, eq. 4).
    elevation_ambiguity : float, m
        ``lambda R / (2 d_b)``: the elevation interval the stack maps without aliasing.
    slant_range, wavelength, incidence : float
        ``R`` [m] of the nominal pass, ``lambda`` [m], incidence angle [deg] at the scene centre.
    """

    track_offsets: np.ndarray
    perpendicular: np.ndarray
    reference: int
    span: float
    mean_spacing: float
    elevation_resolution: float
    elevation_ambiguity: float
    slant_range: float
    wavelength: float
    incidence: float

    def height_range(self) -> float:
        """The height interval [m] that the stack maps without aliasing:
        ``elevation_ambiguity sin(theta)`` (a point ``h`` above the ground lies ``s = h / sin(theta)``
        up its iso-range circle, docs/physics.md (T1))."""
        return self.elevation_ambiguity * math.sin(math.radians(self.incidence))


def stack_baselines(params: RadarParameters, *, track_offsets: Any = None, baselines: Any = None,
                    span: float | None = None, count: int | None = None, spacing: str = "uniform",
                    seed: int = 0) -> StackBaselines:
    """The passes of a stack, from one of three descriptions.

    Parameters
    ----------
    params : RadarParameters
        Resolved (``scene_center`` and ``n_pulses`` set, as after
        :func:`sarmitsuba.scene.loader.load_scene`); its own ``track_offset`` is ignored.
    track_offsets : float [N, 3], m, optional
        Each pass's track shift, world frame.
    baselines : float [N], m, optional
        Perpendicular baselines: the passes fly ``b e`` (:func:`perpendicular_direction`).
    span, count : float [m] and int, optional
        ``count`` perpendicular baselines over ``[-span / 2, span / 2]``: evenly spaced
        (``spacing="uniform"``) or, with ``spacing="random"``, the two ends plus ``count - 2``
        drawn uniformly between them (``numpy.random.default_rng(seed)``), as real orbits scatter.

    Raises
    ------
    ParameterError
        Not exactly one description; fewer than 3 passes; a non-finite value; two passes with the
        same perpendicular baseline (the stack has no elevation aperture between them); an
        unknown ``spacing``; a ``seed`` that is not a whole number >= 0.
    """
    from ..core.radar import ParameterError
    given = [name for name, value in (("track_offsets", track_offsets), ("baselines", baselines),
                                      ("span", span)) if value is not None]
    if len(given) != 1:
        raise ParameterError(f"a stack needs exactly one of track_offsets, baselines or span (with count), got "
                             f"{', '.join(given) or 'none'}: e.g. --span 12 --passes 10")
    e, _, _, r = _frame(params)
    if span is not None:
        offsets = _spread(span, count, spacing, seed)[:, None] * e
    elif baselines is not None:
        offsets = _finite("baselines", baselines, 1)[:, None] * e
    else:
        offsets = _finite("track_offsets", track_offsets, 2)
    if offsets.shape[0] < 3:
        raise ParameterError(f"a stack needs at least 3 passes, got {offsets.shape[0]}: tomography resolves "
                             "elevation from 3 or more baselines (2 passes: use `interferogram`)")
    import dataclasses
    perp = np.array([baseline(dataclasses.replace(params, track_offset=tuple(o))).perpendicular for o in offsets])
    ordered = np.sort(perp)
    if np.min(np.diff(ordered)) <= 1e-6 * max(1.0, float(np.ptp(perp))):
        raise ParameterError(f"two passes share a perpendicular baseline ({np.round(perp, 4).tolist()} m): "
                             "every pass needs its own baseline for the elevation aperture")
    delta = float(ordered[-1] - ordered[0])
    spacing_mean = delta / (len(perp) - 1)
    wavelength = params.wavelength
    return StackBaselines(track_offsets=offsets, perpendicular=perp,
                          reference=int(np.argmin(np.abs(perp - 0.5 * (ordered[0] + ordered[-1])))),
                          span=delta, mean_spacing=spacing_mean,
                          elevation_resolution=wavelength * r / (2.0 * delta),
                          elevation_ambiguity=wavelength * r / (2.0 * spacing_mean),
                          slant_range=r, wavelength=wavelength, incidence=float(params.incidence_angle))


def _spread(span: Any, count: Any, spacing: str, seed: int) -> np.ndarray:
    """``count`` baselines over ``[-span / 2, span / 2]`` (:func:`stack_baselines`)."""
    from ..core.radar import ParameterError
    if spacing not in STACK_SPACINGS:
        raise ParameterError(f"spacing = {spacing!r}; valid: {', '.join(STACK_SPACINGS)}")
    try:
        width, n = float(span), int(count)
        ok = math.isfinite(width) and width > 0 and n == count
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ParameterError(f"span = {span!r} m and count = {count!r} passes: give a finite span > 0 m and a whole "
                             "number of passes >= 3, e.g. --span 12 --passes 10")
    if n < 3:
        raise ParameterError(f"a stack needs at least 3 passes, got count = {n}: tomography resolves elevation from "
                             "3 or more baselines (2 passes: use `interferogram`)")
    if spacing == "uniform":
        return np.linspace(-0.5 * width, 0.5 * width, n)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError(f"seed = {seed!r}: the random baselines' seed is a whole number >= 0 (any: the same "
                             "seed gives the same stack), e.g. 3")
    inner = np.random.default_rng(seed).uniform(-0.5 * width, 0.5 * width, n - 2)
    return np.sort(np.concatenate([[-0.5 * width, 0.5 * width], inner]))


def _finite(name: str, values: Any, ndim: int) -> np.ndarray:
    """``values`` as float64 with ``ndim`` axes (the last of 3 for offsets), all finite."""
    from ..core.radar import ParameterError
    try:
        array = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        array = np.zeros((0,))
    shape_ok = array.ndim == ndim and (ndim == 1 or array.shape[1] == 3)
    if not shape_ok or not np.all(np.isfinite(array)):
        what = "perpendicular baselines in metres, e.g. 0,1.5,3" if ndim == 1 else \
            "track offsets dx,dy,dz in metres, one per pass, e.g. 0,0,0;0,1,-1;0,2,-2"
        raise ParameterError(f"{name} = {values!r}: expected finite {what}")
    return array
