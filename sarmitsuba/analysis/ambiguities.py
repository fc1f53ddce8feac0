"""Azimuth and range ambiguity-to-signal ratios (AASR, RASR) of the traced beam at the PRF.

:func:`ambiguity_ratio` is the azimuth ratio of any two-way power pattern and processing
weight (docs/physics.md (AMB1)); :func:`azimuth_ambiguity_ratio` applies it to a scene's traced
beam (the two-way pattern (A) between the first nulls) and the focuser's azimuth window over
that beam (K); :func:`range_ambiguity_ratio` sums the echoes of the ground at the
range-ambiguous slant ranges (AMB2); :func:`ambiguities` gathers both, the PRFs at which each
reaches :data:`LIMIT_DB`, and a warning when one exceeds it.

References
----------
.. [1] J. C. Curlander and R. N. McDonough, *Synthetic Aperture Radar: Systems and Signal
   Processing*, Wiley, 1991, sec. 6.5 (azimuth and range ambiguity-to-signal ratios).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.radar import RadarParameters
from ..focus.windows import spectral_window

__all__ = ["LIMIT_DB", "EARTH_RADIUS_M", "Ambiguities", "ambiguity_ratio", "azimuth_ambiguity_ratio",
           "range_ambiguity_ratio", "ambiguities"]

#: The ratio above which :func:`ambiguities` warns [dB].
LIMIT_DB = -20.0
#: Mean Earth radius [m], for the radar horizon that ends the ambiguous ranges (AMB2).
EARTH_RADIUS_M = 6_371_000.0


@dataclass(frozen=True)
class Ambiguities:
    """Ambiguity-to-signal ratios of one acquisition (docs/physics.md (AMB1), (AMB2)).

    ``aasr_db`` / ``rasr_db`` are None where the ratio is exactly 0 (the PRF exceeds the traced
    Doppler bandwidth; no ground at any ambiguous range); ``prf_min_aasr_hz`` is the lowest PRF
    with AASR <= :data:`LIMIT_DB`, ``prf_max_rasr_hz`` the highest with RASR <= it (None: no
    limit below 10 MHz); ``warning`` one line when either ratio exceeds it, else None.
    """

    aasr: float
    aasr_db: float | None
    rasr: float
    rasr_db: float | None
    processed_doppler_bandwidth_hz: float
    azimuth_window: str
    prf_min_aasr_hz: float
    prf_max_rasr_hz: float | None
    warning: str | None

    def line(self) -> str:
        """One line for ``sarmitsuba info``."""
        def db(x: float | None) -> str:
            return "none" if x is None else f"{x:.1f} dB"
        high = "none below 10 MHz" if self.prf_max_rasr_hz is None else f"{self.prf_max_rasr_hz:.4g} Hz"
        return (f"AASR {db(self.aasr_db)} (traced beam over {self.processed_doppler_bandwidth_hz:.1f} Hz of Doppler, "
                f"{self.azimuth_window} window; -20 dB from prf {self.prf_min_aasr_hz:.0f} Hz up), RASR "
                f"{db(self.rasr_db)} (flat ground, constant gamma; -20 dB up to prf {high}); "
                "docs/physics.md (AMB1), (AMB2)")


def ambiguity_ratio(power: Callable[[np.ndarray], np.ndarray], weight: Callable[[np.ndarray], np.ndarray],
                    band: tuple[float, float], prf: float, max_order: int | None = None,
                    samples: int = 8193) -> float:
    """AASR of a two-way power pattern ``P(f)`` processed with weight ``w(f)`` over ``band``, (AMB1):
    ``sum_{m != 0} int_band w^2(f) P(f + m prf) df / int_band w^2(f) P(f) df``.

    ``power`` and ``weight`` map float64 arrays of Doppler frequencies [Hz] to float64 arrays of the
    same shape; ``band = (f_lo, f_hi)`` [Hz] the processed band; ``prf`` [Hz]. ``max_order``: the
    largest ``|m|``; None = ``ceil((f_hi - f_lo) / prf)``, every alias of a pattern that is zero
    outside the band. Trapezoidal rule on ``samples`` points. Returns the linear ratio (float).
    """
    f = np.linspace(band[0], band[1], samples)
    w2 = weight(f) ** 2
    signal = np.trapezoid(w2 * power(f), f)
    orders = max_order if max_order is not None else math.ceil((band[1] - band[0]) / prf)
    alias = sum(np.trapezoid(w2 * (power(f + m * prf) + power(f - m * prf)), f) for m in range(1, orders + 1))
    return float(alias / signal)


def azimuth_ambiguity_ratio(p: RadarParameters, window: tuple[str, dict] = ("taylor", {}),
                            prf: float | None = None) -> float:
    """AASR (AMB1) of the traced stripmap beam of ``p`` at ``prf`` (default ``p.prf``): two-way power
    pattern ``g^4``, ``g`` the one-way field (A) along the beam's sines, zero beyond the traced beam;
    processed band the traced beam's Doppler band ``2 v [sin_lo, sin_hi] / lambda`` weighted by the
    azimuth ``window`` (``(name, params)`` of :mod:`sarmitsuba.focus.windows`). Linear ratio."""
    sin_lo, sin_hi = p.beam_sines
    scale = 2.0 * p.velocity / p.wavelength                  # Doppler [Hz] per unit along-track sine
    squint, length = math.radians(p.squint), p.pattern_length / p.wavelength

    def power(f: np.ndarray) -> np.ndarray:
        s = f / scale
        inside = (s >= sin_lo) & (s <= sin_hi)
        if length == 0:                                      # uniform beam: unit gain inside
            return inside.astype(np.float64)
        off = s * math.cos(squint) - np.sqrt(np.clip(1.0 - s * s, 0.0, None)) * math.sin(squint)
        return np.sinc(length * off) ** 4 * inside

    def weight(f: np.ndarray) -> np.ndarray:
        return spectral_window(window[0], (f / scale - sin_lo) / (sin_hi - sin_lo) - 0.5, 1.0, **window[1])

    return ambiguity_ratio(power, weight, (scale * sin_lo, scale * sin_hi), p.prf if prf is None else prf)


def range_ambiguity_ratio(p: RadarParameters, prf: float | None = None) -> float:
    """RASR (AMB2) at the scene centre: ``sum_{j != 0} S_j / S_0``, ``S_j = G_el^2(theta_j)
    sigma0(theta_j) / (R_j^3 sin(theta_j))`` at ``R_j = R + j c / (2 prf)``, flat ground at the
    altitude below the track (``cos(theta_j) = h / R_j``), up to the radar horizon; ``G_el^2`` the
    two-way elevation pattern (A) (1 without ``antenna_height``) and ``sigma0 = gamma cos(theta)``
    (constant gamma). Linear ratio."""
    prf = p.prf if prf is None else prf
    h, r0 = p.altitude, p.slant_range
    horizon = math.sqrt(2.0 * EARTH_RADIUS_M * h + h * h)
    step = SPEED_OF_LIGHT / (2.0 * prf)
    orders = min(math.ceil(max(horizon, r0) / step), 10**6)
    r = r0 + np.arange(-orders, orders + 1) * step
    r = r[(r > h) & (r <= max(horizon, r0))]
    theta = np.arccos(h / r)
    gain = np.ones_like(r)
    if p.antenna_height > 0:
        gain = np.sinc(p.antenna_height / p.wavelength * np.sin(theta - math.radians(p.incidence_angle))) ** 4
    s = gain * np.cos(theta) / (r ** 3 * np.sin(theta))
    centre = np.isclose(r, r0, rtol=0.0, atol=1e-6 * r0)
    return float(s[~centre].sum() / s[centre].sum())


def ambiguities(p: RadarParameters, window: tuple[str, dict] = ("taylor", {})) -> Ambiguities | None:
    """:class:`Ambiguities` of a straight stripmap acquisition ``p`` with the azimuth ``window``
    (the render's default: Taylor); None for spotlight and curved tracks (not modelled)."""
    if p.mode != "stripmap" or not p.straight_track:
        return None
    sin_lo, sin_hi = p.beam_sines
    traced = 2.0 * p.velocity * (sin_hi - sin_lo) / p.wavelength
    limit = 10.0 ** (LIMIT_DB / 10.0)
    aasr, rasr = azimuth_ambiguity_ratio(p, window), range_ambiguity_ratio(p)
    # AASR falls as the PRF rises (0 from the traced bandwidth on); RASR rises with it
    low = _bisect(lambda f: azimuth_ambiguity_ratio(p, window, f) <= limit, 0.05 * traced, traced)
    high = None if range_ambiguity_ratio(p, 1e7) <= limit else \
        _bisect(lambda f: range_ambiguity_ratio(p, f) > limit, 1.0, 1e7)
    warning = []
    if aasr > limit:
        warning.append(f"AASR {_db(aasr):.1f} dB > {LIMIT_DB:g} dB: azimuth ghosts at +-m prf lambda R / (2 v); raise "
                       f"the PRF above {low:.0f} Hz (or narrow the Doppler band: a longer antenna_length)")
    if rasr > limit:
        warning.append(f"RASR {_db(rasr):.1f} dB > {LIMIT_DB:g} dB: lower the PRF below {high:.0f} Hz "
                       "(or narrow the elevation beam: antenna_height)")
    return Ambiguities(aasr=aasr, aasr_db=_db(aasr), rasr=rasr, rasr_db=_db(rasr),
                       processed_doppler_bandwidth_hz=traced, azimuth_window=window[0], prf_min_aasr_hz=low,
                       prf_max_rasr_hz=high, warning="; ".join(warning) or None)


def _bisect(ok: Callable[[float], bool], lo: float, hi: float, steps: int = 30) -> float:
    """The boundary in ``[lo, hi]`` between ``ok`` False (at ``lo``) and True (at ``hi``), geometric bisection."""
    for _ in range(steps):
        mid = math.sqrt(lo * hi)
        lo, hi = (lo, mid) if ok(mid) else (mid, hi)
    return hi


def _db(x: float) -> float | None:
    return 10.0 * math.log10(x) if x > 0 else None

