"""The spatial-frequency support of a backprojected image, for SICD's ``Grid`` (NGA.STND.0024-1, SICD
Volume 1, section "Grid": ``KCtr``, ``ImpRespBW``, ``ImpRespWid``, ``WgtType``, ``WgtFunct``,
``TimeCOAPoly``; docs/physics.md (K), (K2)).

The aperture that formed the pixel at ``q`` is modelled on the straight track (the line through
the antenna positions' mean along their mean velocity ``t``): the antenna positions ``p`` between
the first and the last pulse, kept where the along-track sine ``s = (q - p) . t / |q - p|`` lies in
the processed beam ``[b0, b1]`` (``metadata["focus"]["beam_sines"]``; every position without a
beam). The sines ``s1 <= s2`` that bound it give the support of the two-way phase
``exp(j 4 pi f / c |q - p|)`` over the band ``f = fc +- B / 2``: with ``s_m = (s1 + s2) / 2``,
``r`` the unit vector from the track to ``q`` and ``e_rg``, ``e_az`` the image axes,

- range (SICD Row): ``KCtr = 2 fc / c sqrt(1 - s_m^2) (r . e_rg)``, ``ImpRespBW = 2 B / c
  sqrt(1 - s_m^2) |r . e_rg|`` (``r . e_rg`` is ``sin(theta_inc)`` on flat ground, 1 in the slant plane);
- azimuth (SICD Col): ``KCtr = (s1 + s2) / lambda``, ``ImpRespBW = 2 (s2 - s1) / lambda``;
- the weighting over the azimuth support (``WgtFunct``) is what the image's impulse response is
  made of (docs/physics.md (K2)): the azimuth window ``w(u)`` (``u`` the sine's place in the beam,
  or the pulse's place in the aperture without a beam) times the two-way antenna pattern
  ``sinc^2(L / lambda sin(phi - squint))`` when the focusing recorded one, times the pulses'
  density ``1 / |ds / dp|``; in range, the range window.

``ImpRespWid`` is the -3 dB width of the weighting's impulse response (the window's own
:func:`sarmitsuba.focus.windows.impulse_response_width` when the weighting is the bare window).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData

__all__ = ["Track", "track_of", "Aperture", "Weighting", "grid_direction", "weighting_irw", "WINDOW_NAMES",
           "WEIGHT_SAMPLES", "SupportError", "FLOOR", "uniform_weighting", "kept_fraction", "flattening_gain",
           "flattened", "uniform_metadata"]

#: sarmitsuba window name -> SICD WgtType/WindowName.
WINDOW_NAMES = {"rect": "UNIFORM", "taylor": "TAYLOR", "hamming": "HAMMING", "hann": "HANNING", "kaiser": "KAISER"}
#: Samples of ``WgtFunct`` over the support (the SICD volume 1 recommendation).
WEIGHT_SAMPLES = 512
#: Antenna positions sampled along the aperture when its weighting is evaluated.
_FINE = 8193
#: Weighting (amplitude, relative to its peak) below which a uniform SICD drops the support
#: rather than divide by it: -20 dB, so no part of the spectrum gains more than 20 dB.
FLOOR = 0.1


class SupportError(ValueError):
    """The image's metadata do not describe a track and an aperture a SICD grid can be built from."""


@dataclass(frozen=True)
class Track:
    """The collection a SICD describes: per-pulse times [s] (float64 [n]), antenna positions and
    velocities (float64 [n, 3], local frame, m and m/s), carrier ``fc`` [Hz], ``bandwidth`` [Hz], ``prf`` [Hz]."""

    pulse_time: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    fc: float
    bandwidth: float
    prf: float


def track_of(image: SarImage, raw: RawData | None) -> Track:
    """The :class:`Track` of ``raw`` (its transmit positions), else the one the radar parameters in
    ``image.metadata["radar"]`` synthesise (:func:`sarmitsuba.core.radar.acquisition_geometry`, world frame).

    Raises SupportError when neither is available.
    """
    if raw is not None:
        return Track(raw.pulse_time, raw.tx_position, raw.velocity, raw.fc, raw.bandwidth, raw.prf)
    from ..core.radar import ParameterError, RadarParameters
    from ..core.geometry import acquisition_geometry
    radar = image.metadata.get("radar") if isinstance(image.metadata, dict) else None
    try:
        params = RadarParameters.from_mapping({k: v for k, v in radar.items() if v is not None})
        geometry = acquisition_geometry(params)
    except (AttributeError, TypeError, ValueError, KeyError, ParameterError):
        raise SupportError("writing SICD needs the raw data that were focused, or an image whose metadata "
                           "record the resolved radar parameters (metadata['radar'] of a sarmitsuba render): "
                           "pass raw=") from None
    return Track(geometry.pulse_time, geometry.positions, geometry.velocity, params.frequency, params.bandwidth,
                 params.prf)


def _focus(image: SarImage) -> dict:
    focus = image.metadata.get("focus") if isinstance(image.metadata, dict) else None
    return focus if isinstance(focus, dict) else {}


def window_of(image: SarImage, key: str) -> tuple[str, dict]:
    """(name, parameters) of the focusing window ``metadata["focus"][key]`` (``"window_range"`` or
    ``"window_azimuth"``); ``("rect", {})`` when the metadata hold none."""
    spec = _focus(image).get(key)
    if not isinstance(spec, dict) or "name" not in spec:
        return "rect", {}
    return str(spec["name"]), {k: v for k, v in spec.items() if k != "name"}


@dataclass(frozen=True)
class Weighting:
    """A direction's weighting over its support: ``name`` (SICD ``WindowName``), ``parameters``
    (``[(name, value)]``), ``samples`` (float64 [WEIGHT_SAMPLES] over the support, peak 1; None
    for a bare uniform window) and ``irw`` (-3 dB width of its impulse response in units of
    1 / ImpRespBW)."""

    name: str
    parameters: list
    samples: np.ndarray | None
    irw: float


def weighting_irw(samples: np.ndarray, fft: int = 1 << 18) -> float:
    """-3 dB width of ``|p|^2``, in units of ``1 / B``, of the impulse response ``p`` of ``samples``
    (float [n], uniformly spread over a support ``B``): 0.8859 for a uniform weighting."""
    samples = np.asarray(samples, dtype=np.float64)
    power = np.abs(np.fft.rfft(samples, fft)) ** 2
    power /= power[0]
    k = int(np.argmax(power < 0.5))
    half = k - 1 + (power[k - 1] - 0.5) / (power[k - 1] - power[k])
    return 2.0 * half * samples.size / fft


def window_weighting(window: tuple[str, dict]) -> Weighting:
    """The :class:`Weighting` of a bare focusing window (``WgtFunct`` its samples at the support's
    cell centres; none for ``rect``, whose width is SICD's 0.8859)."""
    from ..focus.windows import impulse_response_width, spectral_window
    name, params = window
    u = (np.arange(WEIGHT_SAMPLES) + 0.5) / WEIGHT_SAMPLES
    samples = None if name == "rect" else spectral_window(name, u - 0.5, 1.0, **params)
    return Weighting(WINDOW_NAMES.get(name, name.upper()), [(k.upper(), str(v)) for k, v in params.items()],
                     samples, impulse_response_width(name, **params))


def uniform_weighting() -> Weighting:
    """The :class:`Weighting` of a uniform support (``WgtType`` ``UNIFORM``, no ``WgtFunct``, SICD's
    0.8859 / ImpRespBW impulse-response width)."""
    return window_weighting(("rect", {}))


def kept_fraction(weighting: Weighting) -> float:
    """The share (0, 1] of the support a uniform SICD keeps of an image of this weighting: the
    central, symmetric run of ``WgtFunct`` cells at or above :data:`FLOOR` times its peak (1 when
    every cell is: sarmitsuba's Taylor windows, whose edges are 0.17). Raises SupportError when
    the central cells lie below it."""
    if weighting.samples is None:
        return 1.0
    s = np.asarray(weighting.samples, dtype=np.float64)
    s = s / s.max()
    n = s.size
    inner = s[(n - 1) // 2::-1] >= FLOOR                    # centre outward, each half
    outer = s[n // 2:] >= FLOOR
    both = inner[:min(inner.size, outer.size)] & outer[:min(inner.size, outer.size)]
    pairs = both.size if both.all() else int(np.argmin(both))
    if pairs == 0:
        raise SupportError(f"the {weighting.name} weighting lies below {FLOOR} of its peak at the support's "
                           "centre: no uniform SICD; write the image's own weighting (weighting='image')")
    return 1.0 if pairs == both.size else 2.0 * pairs / n


def flattening_gain(weighting: Weighting, bandwidth: float, kept: float):
    """The spectral gain that makes an image of ``weighting`` over a support of ``bandwidth``
    [cycles/m] uniform over the central ``kept`` of it (docs/physics.md (K3)): a function of the
    baseband frequency ``f`` [cycles/m] (float array; the support centred on 0, ``WgtFunct``'s
    first cell at ``-bandwidth / 2``), ``mean(w) / (kept w(f / bandwidth))`` (unit peak gain
    kept), ``w`` the cells linearly interpolated and held beyond the outer cells; 0 beyond
    ``+-kept bandwidth / 2`` when ``kept < 1``. None for a uniform weighting (nothing to do)."""
    if weighting.samples is None:
        return None
    samples = np.asarray(weighting.samples, dtype=np.float64)
    cells = (np.arange(samples.size) + 0.5) / samples.size - 0.5
    scale = float(samples.mean()) / kept

    def gain(f: np.ndarray) -> np.ndarray:
        u = np.asarray(f, dtype=np.float64) / bandwidth
        out = scale / np.interp(u, cells, samples)
        if kept < 1.0:
            out[np.abs(u) > 0.5 * kept * (1.0 + 1e-9)] = 0.0
        return out
    return gain


def flattened(image: SarImage) -> tuple[float, float] | None:
    """(row, col) shares of the aperture's support that a uniform SICD kept, when ``image`` was read
    from one (``metadata["focus"]["spectral_weighting"]``, written by
    :func:`~sarmitsuba.formats.sicd.write_sicd`); None else."""
    focus = image.metadata.get("focus") if isinstance(image.metadata, dict) else None
    flat = focus.get("spectral_weighting") if isinstance(focus, dict) else None
    if not isinstance(flat, dict) or flat.get("name") != "uniform":
        return None
    kept = flat.get("kept", (1.0, 1.0))
    return float(kept[0]), float(kept[1])


def uniform_metadata(metadata: Any, kept: tuple[float, float], sines: tuple[float, float] | None = None) -> Any:
    """The image metadata a uniform SICD carries: ``metadata["focus"]`` with rect windows, no
    antenna pattern, the processed beam's sines (``beam_sines``; replaced by ``sines``, the
    along-track sines that bound the aperture seen from the SCP, when given: a track shorter than
    the beam bounds it) narrowed to the share ``kept[1]`` of the azimuth support (else the track's
    length), the band to ``kept[0]`` of the range support (so the point-target analysis of the
    file models its uniform response; ``sine_scale`` then 1, those sines being the ones seen), and
    ``spectral_weighting`` (what :func:`flattened` reads back; the azimuth share left in it is 1
    where the beam's sines say it)."""
    if not isinstance(metadata, dict) or not isinstance(metadata.get("focus"), dict):
        return metadata
    focus = dict(metadata["focus"], window_range={"name": "rect"}, window_azimuth={"name": "rect"},
                 azimuth_pattern=None)
    left = [kept[0], kept[1]]
    if kept[0] < 1.0 and focus.get("bandwidth"):
        focus["bandwidth"] = float(focus["bandwidth"]) * kept[0]
    if focus.get("beam_sines") is not None:
        lo, hi = (float(v) for v in (focus["beam_sines"] if sines is None else sines))
        centre, half = 0.5 * (lo + hi), 0.5 * (hi - lo) * kept[1]
        focus["beam_sines"], left[1] = [centre - half, centre + half], 1.0
        if sines is not None:        # the sines seen from the SCP already hold the orbit's sweep kappa
            focus["sine_scale"] = 1.0
    elif kept[1] < 1.0 and isinstance(focus.get("track"), dict) and focus["track"].get("length"):
        focus["track"] = dict(focus["track"], length=float(focus["track"]["length"]) * kept[1])
    focus["spectral_weighting"] = {"name": "uniform", "kept": left,
                                   "note": "the focusing weighting was taken out by write_sicd (docs/physics.md (K3))"}
    return {**metadata, "focus": focus}


def grid_direction(unit_ecef: np.ndarray, spacing: float, bandwidth: float, kctr: float, weighting: Weighting,
                   deltak: tuple[float, float], deltakcoa: np.ndarray) -> dict[str, Any]:
    """One ``Grid/Row`` or ``Grid/Col`` element (sarkit's dictionary form; SICD volume 1, Grid):
    unit vector (ECEF), sample spacing ``SS`` [m], ``ImpRespBW`` and ``KCtr`` [cycles/m], the
    weighting, ``DeltaK1``/``DeltaK2`` [cycles/m] and ``DeltaKCOAPoly`` (Poly2D [cycles/m] of the
    row and column coordinates [m])."""
    element = {"UVectECF": unit_ecef, "SS": float(spacing), "ImpRespWid": weighting.irw / bandwidth, "Sgn": -1,
               "ImpRespBW": float(bandwidth), "KCtr": float(kctr), "DeltaK1": float(deltak[0]),
               "DeltaK2": float(deltak[1]), "DeltaKCOAPoly": np.asarray(deltakcoa, dtype=np.float64),
               "WgtType": {"WindowName": weighting.name}}
    if weighting.parameters:
        element["WgtType"]["Parameter"] = list(weighting.parameters)
    if weighting.samples is not None:
        element["WgtFunct"] = np.asarray(weighting.samples, dtype=np.float64)
    return element


class Aperture:
    """The aperture of a backprojected ``image`` focused from ``track`` (module docstring), evaluated
    at points of the local frame.

    Raises SupportError when the track does not move or a point lies on it.
    """

    def __init__(self, image: SarImage, track: Track):
        focus = _focus(image)
        velocity = np.asarray(track.velocity, dtype=np.float64).mean(axis=0)
        self.speed = float(np.linalg.norm(velocity))
        if not self.speed > 0:
            raise SupportError("writing SICD needs a moving platform: the track's velocity is zero")
        self.heading = velocity / self.speed
        positions = np.asarray(track.position, dtype=np.float64)
        self.anchor = positions.mean(axis=0)
        along = (positions - self.anchor) @ self.heading
        self.span = (float(along.min()), float(along.max()))
        times = np.asarray(track.pulse_time, dtype=np.float64) - float(track.pulse_time[0])
        self.time_fit = np.polyfit(along, times, 1) if np.ptp(along) > 0 else np.array([0.0, 0.0])
        beam = focus.get("beam_sines")
        # the sines the points see sweep kappa times the beam's on a curved (orbit) track: 1 on a
        # straight one (focus.beam.sine_scale, docs/physics.md (J7)); the beam in seen sines
        self.kappa = float(focus.get("sine_scale") or 1.0)
        self.beam = (self.kappa * float(beam[0]), self.kappa * float(beam[1])) if beam is not None else None
        pattern, squint = focus.get("azimuth_pattern"), focus.get("squint")
        self.pattern = float(pattern) if pattern else None
        self.squint = float(np.radians(float(squint or 0.0)))
        self.fc, self.bandwidth = float(track.fc), float(track.bandwidth)
        self.wavelength = SPEED_OF_LIGHT / self.fc
        self.window = window_of(image, "window_azimuth")
        self.e_rg = np.asarray(image.range_direction, dtype=np.float64)
        self.e_az = np.asarray(image.azimuth_direction, dtype=np.float64)

    def geometry(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(along-track coordinate [n] m, distance to the track [n] m, unit vector from the track [n, 3])."""
        rel = np.atleast_2d(np.asarray(points, dtype=np.float64)) - self.anchor
        along = rel @ self.heading
        across = rel - along[:, None] * self.heading
        r0 = np.linalg.norm(across, axis=1)
        if np.any(r0 <= 0):
            raise SupportError("a point of the image lies on the track: no SICD grid")
        return along, r0, across / r0[:, None]

    def interval(self, along: np.ndarray, r0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(first, last) along-track antenna positions [n] m that formed the points: the track, cut to the beam."""
        lo, hi = np.full_like(along, self.span[0]), np.full_like(along, self.span[1])
        if self.beam is not None:
            tan = np.tan(np.arcsin(np.clip(self.beam, -0.999999, 0.999999)))
            lo, hi = np.maximum(lo, along - r0 * tan[1]), np.minimum(hi, along - r0 * tan[0])
        return lo, np.maximum(hi, lo)

    def sines(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The along-track sines ``s1 <= s2`` [n] bounding the aperture seen from the points."""
        along, r0, _ = self.geometry(points)
        lo, hi = self.interval(along, r0)
        return (along - hi) / np.hypot(along - hi, r0), (along - lo) / np.hypot(along - lo, r0)

    def support(self, points: np.ndarray) -> dict[str, np.ndarray]:
        """Support of the two-way phase at the points (module docstring), each [n], cycles/m:
        ``kctr_row``, ``kctr_col`` (its centre along the image's range and azimuth axes),
        ``bw_row``, ``bw_col`` (its extents), and ``n_range`` (``r . e_rg``)."""
        _, _, unit = self.geometry(points)
        s1, s2 = self.sines(points)
        mid = 0.5 * (s1 + s2)
        cosine = np.sqrt(1.0 - mid ** 2)
        n_range = unit @ self.e_rg
        k = 2.0 * self.fc / SPEED_OF_LIGHT
        return {"kctr_row": k * cosine * n_range,
                "kctr_col": k * (mid * (self.heading @ self.e_az) + cosine * (unit @ self.e_az)),
                "bw_row": 2.0 * self.bandwidth / SPEED_OF_LIGHT * cosine * np.abs(n_range),
                "bw_col": k * (s2 - s1) * abs(float(self.heading @ self.e_az)), "n_range": n_range}

    def coa_time(self, points: np.ndarray, spotlight: bool) -> np.ndarray:
        """Centre-of-aperture time [n] s after the first pulse: when the antenna sees the point at the
        middle of the processed beam (the beam's centre crossing; broadside without a beam), or, in
        spotlight, at the middle of the aperture that formed it."""
        along, r0, _ = self.geometry(points)
        if spotlight:
            lo, hi = self.interval(along, r0)
            position = 0.5 * (lo + hi)
        else:
            centre = 0.5 * (self.beam[0] + self.beam[1]) if self.beam is not None else 0.0
            position = along - r0 * np.tan(np.arcsin(centre))
        return np.polyval(self.time_fit, position)

    def azimuth_weighting(self, point: np.ndarray) -> Weighting:
        """The :class:`Weighting` over the azimuth support seen from one point (module docstring):
        the bare window's when the aperture is the whole beam (or track) without a pattern."""
        from ..focus.windows import spectral_window
        along, r0, _ = self.geometry(point)
        lo, hi = self.interval(along, r0)
        p = np.linspace(float(lo[0]), float(hi[0]), _FINE)
        delta = along[0] - p
        s = delta / np.hypot(delta, r0[0])
        if self.beam is not None:
            u = (s - self.beam[0]) / (self.beam[1] - self.beam[0])
        else:
            u = (p - self.span[0]) / max(self.span[1] - self.span[0], 1e-300)
        name, params = self.window
        weight = spectral_window(name, np.clip(u, 0.0, 1.0) - 0.5, 1.0, **params)
        if self.pattern is not None:
            weight = weight * np.sinc(self.pattern * np.sin(np.arcsin(s / self.kappa) - self.squint)) ** 2
        weight = weight * (delta ** 2 + r0[0] ** 2) ** 1.5 / r0[0] ** 2            # 1 / |ds / dp|
        cells = s.min() + (np.arange(WEIGHT_SAMPLES) + 0.5) / WEIGHT_SAMPLES * np.ptp(s)
        samples = np.interp(cells, s[::-1], weight[::-1])
        samples = samples / samples.max()
        if float(self.heading @ self.e_az) < 0:      # cells along the column frequency (k_col ~ s heading . e_az)
            samples = samples[::-1]
        bare = window_weighting(self.window)
        reference = np.ones(WEIGHT_SAMPLES) if bare.samples is None else bare.samples
        if np.max(np.abs(samples - reference)) < 1e-3:
            return bare
        note = "aperture: the window over the processed beam or track" + (
            f", times the two-way antenna pattern sinc^2({self.pattern:.6g} sin(phi - squint))"
            if self.pattern is not None else "") + ", times the pulses' density"
        return Weighting(bare.name + "_AND_APERTURE", [*bare.parameters, ("APERTURE", note)], samples,
                         weighting_irw(samples))
