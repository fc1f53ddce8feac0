"""The contract shared by the straight-track FFT focusers (omega-K and range-Doppler).

:func:`~sarmitsuba.focus.omega_k` and :func:`~sarmitsuba.focus.range_doppler` accept the same
options and return the same slant-plane :class:`~sarmitsuba.core.image.SarImage`
(:func:`~sarmitsuba.focus.stripmap.slant_output_grid`). What they share lives here:

* input handling: :func:`range_compressed` (chirped data are matched-filtered first) and
  :func:`focus_setup` (geometry, window specs, worker threads, processed Doppler band);
* the Doppler-domain numerics: :func:`doppler_axis` (true, unwrapped Doppler frequency of
  each azimuth FFT bin) and :func:`doppler_rows` (with the migration offset ``alpha``),
  :func:`unit_mean_window` (a band window scaled to unit mean),
  :func:`azimuth_weights` (the azimuth window normalised so a point target keeps its peak,
  antenna pattern included) and :func:`cis` (float64 phase in cycles to complex64);
* the output: :func:`windows_label` and :func:`slant_image`.

References
----------
.. [1] I. G. Cumming and F. H. Wong, *Digital Processing of Synthetic Aperture Radar
   Data*, Artech House, 2005, ch. 6 (range-Doppler) and ch. 8 (omega-K).
"""
from __future__ import annotations

import copy
from typing import Any, NamedTuple

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData
from .bp_contract import available_cpus
from .grid import ImageGrid
from .stripmap import StripmapGeometry, stripmap_geometry
from .windows import spectral_window, window_label, window_mean, window_spec

__all__ = ["FocusSetup", "focus_setup", "range_compressed", "doppler_axis", "doppler_rows", "unit_mean_window", "azimuth_weights",
           "cis", "windows_label", "slant_image"]

#: A window as :func:`~sarmitsuba.focus.windows.window_spec` returns it: ``(name, params)``.
WindowSpec = tuple[str, dict[str, float]]


# ============================================================================ inputs
class FocusSetup(NamedTuple):
    """Checked options of an FFT focuser (:func:`focus_setup`)."""

    geometry: StripmapGeometry
    window_range: WindowSpec
    window_azimuth: WindowSpec
    workers: int
    doppler_bandwidth: float


def range_compressed(raw: RawData) -> RawData:
    """``raw`` itself when range compressed, else its matched-filter output (unweighted).

    Raises TypeError when ``raw`` is not a :class:`~sarmitsuba.core.raw.RawData`."""
    if not isinstance(raw, RawData):
        raise TypeError(f"raw must be a sarmitsuba.core.raw.RawData, got {type(raw).__name__}")
    if raw.range_compressed:
        return raw
    from .range_compression import range_compress  # imported only when needed
    return range_compress(raw)


def focus_setup(raw: RawData, geometry: Any, scene_centre: Any, squint: Any, reference_range: Any,
                window_range: Any, window_azimuth: Any, doppler_bandwidth: Any, workers: Any) -> FocusSetup:
    """Check the options the FFT focusers share and find the geometry.

    ``geometry`` (a :class:`StripmapGeometry`) wins; else :func:`stripmap_geometry` of ``raw``
    with ``scene_centre`` (3 floats, m), ``squint`` (deg) and ``reference_range`` (m). Windows
    are :func:`~sarmitsuba.focus.windows.window_spec` options; ``workers`` an integer >= 1 or
    None (all CPUs); ``doppler_bandwidth`` [Hz] in ``(0, prf]``, None for the whole PRF.

    Raises TypeError for a geometry of another type, ValueError for a bad geometry, window,
    worker count or band, or for spotlight data (the metadata's ``radar.mode``): the FFT focusers
    assume a beam fixed to the platform, so they name ``bp`` and ``ffbp`` instead.
    """
    radar = raw.metadata.get("radar") if isinstance(raw.metadata, dict) else None
    if isinstance(radar, dict) and radar.get("trajectory") == "circular":
        raise ValueError("omega-K and range-Doppler focus stripmap data from a straight track (a beam fixed to the "
                         "platform); these raw data are from a circular track (trajectory = circular: the antenna "
                         "flies a circle about the scene centre, its beam on it). Focus them with backprojection: "
                         "--algorithm bp or ffbp")
    if isinstance(radar, dict) and radar.get("mode") == "spotlight":
        raise ValueError("omega-K and range-Doppler focus stripmap data (a beam fixed to the platform); these raw "
                         "data are spotlight (mode = spotlight: the beam steered at the scene centre). Focus them "
                         "with backprojection: --algorithm bp or ffbp")
    geo = geometry if geometry is not None else stripmap_geometry(
        raw, scene_centre=scene_centre, squint=squint, reference_range=reference_range)
    if not isinstance(geo, StripmapGeometry):
        raise TypeError(f"geometry must be a StripmapGeometry, got {type(geo).__name__}")
    band = raw.prf if doppler_bandwidth is None else float(doppler_bandwidth)
    if not (np.isfinite(band) and 0 < band <= raw.prf * (1 + 1e-9)):
        raise ValueError(f"doppler_bandwidth must be in (0, prf = {raw.prf:g}] Hz, got {doppler_bandwidth!r}")
    return FocusSetup(geo, window_spec(window_range), window_spec(window_azimuth), _workers(workers), band)


def _workers(workers: int | None) -> int:
    if workers is None:
        return available_cpus()
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    return int(workers)


# ============================================================================ Doppler domain
def doppler_axis(n: int, prf: float, centroid: float) -> np.ndarray:
    """True Doppler frequency [Hz] of each of the ``n`` azimuth FFT bins (float64 [n]):
    ``fftfreq`` unwrapped into ``[centroid - prf/2, centroid + prf/2)`` (the PRF ambiguity resolved)."""
    f = np.fft.fftfreq(n, 1.0 / prf)
    return f + prf * np.floor((centroid + prf / 2.0 - f) / prf)


def doppler_rows(raw: RawData, geometry: StripmapGeometry) -> tuple[np.ndarray, np.ndarray]:
    """True Doppler frequency ``f_eta`` [Hz] of each azimuth FFT row (:func:`doppler_axis` about the
    centroid) and ``alpha = c f_eta / (2 Vr)`` [Hz], the range-frequency offset of the migration
    (``D(f_eta) = sqrt(1 - (alpha / f0)^2)``, C&W eq. 6.23); float64 ``[n_pulses]`` each.

    Raises ValueError when the Doppler band reaches the evanescent region ``|alpha| >= fc - B/2``."""
    f_eta = doppler_axis(raw.data.shape[0], raw.prf, geometry.doppler_centroid)
    alpha = SPEED_OF_LIGHT * f_eta / (2.0 * geometry.velocity)
    if np.any(np.abs(alpha) >= raw.fc - raw.bandwidth / 2):
        raise ValueError("the Doppler band reaches the evanescent region (c f_eta / 2Vr >= fc - B/2)")
    return f_eta, alpha


def unit_mean_window(spec: WindowSpec, freqs: np.ndarray, bandwidth: float) -> np.ndarray:
    """The window ``spec`` over the band ``|f| <= bandwidth / 2`` scaled to unit mean over it
    (so a point target keeps its peak amplitude), 0 outside; float64, shape of ``freqs`` [Hz]."""
    name, params = spec
    if name == "rect":  # fast path: the indicator of the band
        return (np.abs(freqs) <= bandwidth / 2.0).astype(np.float64)
    return spectral_window(name, freqs, bandwidth, **params) / window_mean(name, **params)


def azimuth_weights(spec: WindowSpec, f_eta: np.ndarray, centroid: float, bandwidth: float,
                    pattern: float | None, wavelength: float, velocity: float, squint: float) -> np.ndarray:
    """Azimuth window over the processed Doppler band, normalised so that a point target keeps
    its peak amplitude; float64 like ``f_eta`` [Hz] (the rows' true Doppler frequencies).

    Without a pattern, the window at unit mean (:func:`unit_mean_window`). With one (``pattern`` =
    ``L / lambda`` of the two-way field pattern ``g^2 = sinc^2(L sin(phi - squint) / lambda)``
    that weights the data, ``sin(phi) = lambda f_eta / (2 v)``, ``squint`` in rad), the window divided by the mean
    of ``w g^2`` over the band's rows: the target's peak is ``a mean(w g^2) / mean(w g^2)``,
    its amplitude, as in backprojection (docs/physics.md (K))."""
    w = unit_mean_window(spec, f_eta - centroid, bandwidth)
    if not pattern:
        return w
    sine = np.clip(wavelength * f_eta / (2.0 * velocity), -1.0, 1.0)
    g2 = np.sinc(pattern * (sine * np.cos(squint) - np.sqrt(1.0 - sine**2) * np.sin(squint))) ** 2
    inside = np.abs(f_eta - centroid) <= bandwidth / 2.0
    gain = float(np.mean((w * g2)[inside])) if np.any(inside) else 1.0
    return w / gain if gain > 0 else w


def cis(cycles: np.ndarray) -> np.ndarray:
    """``exp(j 2 pi cycles)`` as complex64; ``cycles`` float64, reduced modulo 1 in float64
    first, so arguments of 1e8 rad (800 km) keep their sub-milliradian phase."""
    frac = cycles - np.round(cycles)
    ang = (2.0 * np.pi * frac).astype(np.float32)
    out = np.empty(ang.shape, np.complex64)
    out.real = np.cos(ang)
    out.imag = np.sin(ang)
    return out


# ============================================================================ output
def windows_label(window_range: WindowSpec, window_azimuth: WindowSpec) -> str:
    """``SarImage.window`` of an FFT focuser: ``"range=taylor(nbar=4, sll=-35), azimuth=rect"``."""
    return f"range={window_label(*window_range)}, azimuth={window_label(*window_azimuth)}"


def slant_image(raw: RawData, grid: ImageGrid, data: np.ndarray, algorithm: str, window: str,
                focus: dict[str, Any]) -> SarImage:
    """The focused image on the slant-plane ``grid``: ``data`` as complex64 ``[n_azimuth, n_range]``,
    a deep copy of ``raw.metadata`` with ``metadata["focus"] = focus``."""
    metadata = copy.deepcopy(raw.metadata)
    metadata["focus"] = focus
    return SarImage(data=np.ascontiguousarray(data, dtype=np.complex64), azimuth=np.array(grid.azimuth),
                    range=np.array(grid.range), origin=np.array(grid.origin),
                    azimuth_direction=np.array(grid.azimuth_direction),
                    range_direction=np.array(grid.range_direction), plane="slant", algorithm=algorithm,
                    window=window, metadata=metadata)
