"""Focusing by name: an algorithm name (``bp``, ``ffbp``, ``omegak``, ``rda``) to its focuser call.

:func:`focus` is what ``sarmitsuba.focus.focus``, ``sarmitsuba.refocus`` and the ``focus``
command run: any :class:`~sarmitsuba.core.raw.RawData` honouring the contract (docs/design.md
section 3), focused with the options a sarmitsuba render records in its metadata (ground
grid, traced beam, Doppler bandwidth, squint, antenna pattern; :func:`render_focusing`).
:func:`backprojector` and :func:`azimuth_pattern` are the pieces ``simulate`` shares.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Callable, NamedTuple

import numpy as np

from ..core.image import SarImage
from ..core.radar import ParameterError, RadarParameters
from ..core.geometry import AcquisitionGeometry, acquisition_geometry
from ..core.raw import RawData
from .backprojection import backproject
from .ffbp import GeometryNotSupported, ffbp
from .grid import ImageGrid
from .omegak import omega_k
from .range_compression import apply_range_window, range_compress
from .rda import range_doppler
from .scene_grid import ground_grid
from .stripmap import slant_output_grid, stripmap_geometry
from .windows import window_spec

__all__ = ["compressed_for_focus", "focus_window", "focus_windows", "ALGORITHMS", "focus", "autofocus_image", "backprojector", "azimuth_pattern", "RenderFocusing", "render_focusing",
           "recorded_geometry"]

#: Algorithm names of :func:`focus`: direct and fast factorised backprojection, omega-K, range-Doppler.
ALGORITHMS = ("bp", "ffbp", "omegak", "rda")


class RenderFocusing(NamedTuple):
    """Focusing options a sarmitsuba render records (:func:`render_focusing`)."""

    grid: ImageGrid | None                 # ground grid of the scene, None for other data
    azimuth_beamwidth: float | None        # deg, traced stripmap beam (None: spotlight or unknown)
    doppler_bandwidth: float | None        # Hz
    squint: float                          # deg
    azimuth_pattern: float | None          # L / lambda of the two-way azimuth pattern


def azimuth_pattern(params: RadarParameters) -> float | None:
    """``L / lambda`` of the two-way azimuth pattern the tracer applied (stripmap with a tapered
    beam or antenna of length ``L`` [m]), or None."""
    if params.mode != "stripmap" or params.pattern_length <= 0:
        return None
    return params.pattern_length / params.wavelength


def backprojector(name: str) -> Callable[..., SarImage]:
    """The backprojection focuser ``name``: ``"bp"`` is :func:`~sarmitsuba.focus.backproject`;
    ``"ffbp"`` is :func:`~sarmitsuba.focus.ffbp` (bistatic data included, on polar images of the
    range sum, docs/physics.md (F10)), which hands the acquisitions it does not factorise (a grid
    straddling the track or its baseline, a velocity normal to the image plane) to direct
    backprojection and says so in ``metadata["focus"]["fallback"]``. Both take ``(raw, grid, **options)``.

    Raises ValueError for any other name."""
    if name == "bp":
        return backproject
    if name != "ffbp":
        raise ValueError(f"backprojection focuser = {name!r}; valid: bp, ffbp")

    def fast(raw: RawData, grid: ImageGrid, **kwargs: Any) -> SarImage:
        try:
            return ffbp(raw, grid, **kwargs)
        except GeometryNotSupported as exc:
            image = backproject(raw, grid, **kwargs)
            image.metadata["focus"]["fallback"] = f"direct backprojection: {exc}"
            return image
    return fast


def render_focusing(raw: RawData) -> RenderFocusing:
    """Ground grid, azimuth beamwidth [deg], Doppler bandwidth [Hz], squint [deg] and azimuth
    pattern ``L / lambda`` of a sarmitsuba render, from the RawData metadata (radar parameters,
    scene box, frame offset); ``(None, None, None, 0.0, None)`` for other data."""
    meta = raw.metadata
    try:
        params = RadarParameters.from_mapping({k: v for k, v in meta["radar"].items() if v is not None})
        offset = np.asarray(meta.get("frame_offset", [0.0, 0.0, 0.0]), float)
        lo = np.asarray(meta["scene_info"]["bbox_min"], float) + offset
        hi = np.asarray(meta["scene_info"]["bbox_max"], float) + offset
    except (KeyError, TypeError, ValueError):
        return RenderFocusing(None, None, None, 0.0, None)
    if params.straight_track:
        geometry = acquisition_geometry(dataclasses.replace(params, n_pulses=max(params.n_pulses, 1)))
    else:                                  # circular or state vectors: the track the data record
        geometry = recorded_geometry(raw, params)
    beam = params.traced_beamwidth if params.mode == "stripmap" else None
    return RenderFocusing(ground_grid(params, lo, hi, geometry), beam, params.doppler_bandwidth, params.squint,
                          azimuth_pattern(params))


def recorded_geometry(raw: RawData, params: RadarParameters) -> AcquisitionGeometry:
    """The :class:`~sarmitsuba.core.geometry.AcquisitionGeometry` of a curved track as the data
    record it (transmit positions and velocities; the along-track axes their horizontal
    directions, the track and look directions at mid-aperture), about ``params.scene_center``."""
    velocity = raw.velocity * np.array([1.0, 1.0, 0.0])
    axes = velocity / np.maximum(np.linalg.norm(velocity, axis=1, keepdims=True), 1e-300)
    track = axes[raw.n_pulses // 2]
    look = (1.0 if params.look_side == "right" else -1.0) * np.array([track[1], -track[0], 0.0])
    return AcquisitionGeometry(raw.tx_position, raw.velocity, raw.pulse_time, np.asarray(params.scene_center, float),
                               track, look, beam_axes=axes)


def focus(raw: RawData, algorithm: str = "bp", *, window: Any = "taylor", window_range: Any = None,
          window_azimuth: Any = None, progress: bool = False) -> SarImage:
    """Focus any RawData honouring the contract (docs/design.md section 3) with ``algorithm``.

    ``bp``: direct backprojection, ``ffbp``: fast factorised backprojection; onto the scene's
    ground grid when the metadata carry sarmitsuba's radar parameters and scene box (with their
    beam gating), else onto the slant-plane grid of the straight-track geometry. ``omegak`` /
    ``rda`` (with SRC): the FFT focusers (straight track), on their slant-plane grid. Every image
    measures azimuth from the scene centre's closest approach (frames: docs/design.md section 8).
    Chirped input is range-compressed first. Windows: names of :mod:`sarmitsuba.focus.windows`
    (rect, taylor, hamming, kaiser, hann) or ``(name, {params})``: ``window`` in range and
    azimuth (default Taylor, nbar 4, -35 dB: the same as :func:`sarmitsuba.pipeline.render`),
    ``window_range`` / ``window_azimuth`` for one axis (default: ``window``). Backprojection
    applies the azimuth window over the beam (or, without a beam, over the aperture) and
    divides out the recorded antenna pattern.

    Returns
    -------
    SarImage
        complex64; ``metadata["focus"]`` records the algorithm and its options.

    Raises
    ------
    ValueError
        Unknown algorithm or window, or a track the FFT focusers cannot handle (they name
        backprojection).
    """
    if algorithm not in ALGORITHMS:
        raise ValueError(f"algorithm = {algorithm!r}; valid: {', '.join(ALGORITHMS)}")
    window_range = window if window_range is None else window_range
    window_azimuth = window if window_azimuth is None else window_azimuth
    grid, beam, doppler, squint, pattern = render_focusing(raw)
    if algorithm == "omegak":
        return omega_k(raw, window_range=window_range, window_azimuth=window_azimuth, doppler_bandwidth=doppler,
                       azimuth_pattern=pattern)
    if algorithm == "rda":
        return range_doppler(raw, window_range=window_range, window_azimuth=window_azimuth, src=True,
                             doppler_bandwidth=doppler, azimuth_pattern=pattern)
    compressed, grid = _backprojection_input(raw, window_range, grid)
    return backprojector(algorithm)(compressed, grid, azimuth_beamwidth=beam, squint=squint, azimuth_pattern=pattern,
                                    window_azimuth=window_azimuth, progress=progress)


def autofocus_image(raw: RawData, algorithm: str, *, window_range: Any, azimuth_margin: float,
                    progress: bool = False) -> SarImage:
    """The backprojection phase gradient autofocus estimates from (docs/physics.md (PGA6)):
    ``algorithm`` (``bp`` or ``ffbp``) on :func:`focus`'s grid widened by ``azimuth_margin`` [m]
    at either end of its azimuth axis (at its own spacing), a rectangular azimuth window over the
    beam, and the antenna pattern left in (dividing it out lifts the sidelobes of pixels near the
    ends of the illuminated strip by tens of dB). Raises ValueError as :func:`focus`."""
    grid, beam, _, squint, _ = render_focusing(raw)
    compressed, grid = _backprojection_input(raw, window_range, grid)
    if azimuth_margin > 0 and grid.azimuth.size > 1:
        step = float(np.median(np.diff(grid.azimuth)))
        extra = step * np.arange(1, int(np.ceil(azimuth_margin / step)) + 1)
        grid = dataclasses.replace(grid, azimuth=np.r_[grid.azimuth[0] - extra[::-1], grid.azimuth,
                                                       grid.azimuth[-1] + extra])
    return backprojector(algorithm)(compressed, grid, azimuth_beamwidth=beam, squint=squint, azimuth_pattern=None,
                                    window_azimuth="rect", progress=progress)


def _backprojection_input(raw: RawData, window_range: Any, grid: ImageGrid | None) -> tuple[RawData, ImageGrid]:
    """Range-compressed (and range-windowed) data and the grid a backprojection of ``raw`` runs on."""
    range_name, range_params = window_spec(window_range)      # a name, or (name, {params})
    compressed = range_compress(raw, range_name, **range_params) if not raw.range_compressed else (
        apply_range_window(raw, range_name, **range_params) if range_name != "rect" else raw)
    if grid is None:
        grid = slant_output_grid(stripmap_geometry(raw), raw)
    return compressed, grid


def focus_windows(window: Any, window_range: Any = None, window_azimuth: Any = None) -> tuple[tuple, tuple]:
    """The range and azimuth windows ``(name, params)`` of :func:`sarmitsuba.pipeline.simulate` / :func:`~sarmitsuba.pipeline.render`:
    ``window_range`` and ``window_azimuth``, each defaulting to ``window``; every one checked by
    :func:`focus_window`. Raises ParameterError naming the window."""
    return (focus_window(window if window_range is None else window_range),
            focus_window(window if window_azimuth is None else window_azimuth))


def focus_window(window: Any) -> tuple[str, dict]:
    """Check the focusing window of :func:`sarmitsuba.pipeline.simulate` / :func:`~sarmitsuba.pipeline.render`: a name of
    :mod:`sarmitsuba.focus.windows` (``"rect"`` for none) or ``(name, {params})``; returns
    ``(name, params)`` with the defaults filled in. Raises ParameterError naming ``window``."""
    try:
        return window_spec(window)
    except ValueError as exc:
        raise ParameterError(f"window: {exc}") from None


def compressed_for_focus(raw: RawData, window: tuple[str, dict] = ("rect", {})) -> RawData:
    """Range-compressed data for focusing, weighted by the range ``window`` (name, params):
    chirped raw output is compressed with it (matched filter); compressed output, whose pulse
    has a rect spectrum, is windowed over the band (:func:`~sarmitsuba.focus.apply_range_window`)."""
    name, params = window
    if not raw.range_compressed:
        return range_compress(raw, name, **params)
    return apply_range_window(raw, name, **params) if name != "rect" else raw
