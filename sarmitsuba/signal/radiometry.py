"""Absolute radiometry: thermal noise and image calibration by the radar equation (docs/physics.md (R1)-(R4)).

The radar equation itself (:class:`~sarmitsuba.scene.radar_equation.RadarEquation`) is the
scene stage's: it depends on the sensor alone.

Switched on by the sensor's ``transmit_power`` (absolute units) and ``noise_figure_db`` /
``noise_temperature`` (thermal noise). Without them data are normalised (sqrt(m^2)) and
noiseless, and none of this runs.

Units in absolute mode: raw samples in sqrt(W) at the receiver, range compressed by a
unit-energy matched filter so that thermal noise keeps its power ``k T B F`` per sample
while a point target's peak power is ``P_r B T_p`` (the time-bandwidth gain).
"""
from __future__ import annotations

import math

import numpy as np
from scipy import fft as sp_fft

from ..core.radar import RadarParameters
from ..scene.radar_equation import RadarEquation

__all__ = ["thermal_noise", "calibrate_image", "effective_pulses"]


def thermal_noise(shape: tuple[int, int], power: float, fs: float, bandwidth: float, seed: int) -> np.ndarray:
    """Complex Gaussian receiver noise band-limited to ``|f| <= B / 2``, complex64 ``shape``.

    White noise of density ``N0 = power / B`` over the sampling band ``fs`` is filtered to the
    signal band, so each sample has power ``power`` (= k T B F), eq. (R4). Deterministic for
    a seed (NumPy PCG64).
    """
    rng = np.random.default_rng([seed, 0x5A12])
    n = shape[1]
    white = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * math.sqrt(power / bandwidth * fs / 2.0)
    f = sp_fft.fftfreq(n, d=1.0 / fs)
    band = np.abs(f) <= 0.5 * bandwidth
    return sp_fft.ifft(sp_fft.fft(white, axis=1) * band, axis=1).astype(np.complex64)


def calibrate_image(data: np.ndarray, positions: np.ndarray, track_point: np.ndarray, track_direction: np.ndarray,
                    equation: RadarEquation) -> np.ndarray:
    """Calibrated image (sqrt(m^2)) from an absolute one: divide each pixel by ``amplitude_scale(R)``.

    ``R`` is the pixel's zero-Doppler slant range to the straight track through ``track_point``
    along ``track_direction``; a point target's peak is then sqrt(RCS) and clutter's mean
    intensity ``sigma0 rho_az rho_gr``.
    """
    rel = positions - track_point
    perp = rel - (rel @ track_direction)[..., None] * track_direction
    slant = np.linalg.norm(perp, axis=-1)
    return (data / equation.amplitude_scale(slant)).astype(np.complex64)


def effective_pulses(params: RadarParameters, pulses: int) -> float:
    """Coherent integration gain of ``pulses`` pulses spread evenly over the traced beam, eq. (R3).

    Each pulse's echo carries the two-way field pattern ``g^2 = sinc^2(L sin(phi) / lambda)``
    (docs/physics.md (A)); summed unweighted, the signal grows as ``sum g^2`` and the noise as
    ``sqrt(N)``, so the image SNR gains ``N_eff = (sum g^2)^2 / N`` (``N`` for a uniform beam,
    0.2038 N = (0.45141)^2 N for the tapered beam traced to its nulls, 0.45141 being the
    mean of sinc^2 between its first nulls). A bistatic echo (``params.bistatic``) carries the
    two-way pattern ``g_t g_r``: the transmitter's one-way ``g_t`` and the receiver's ``g_r``, which
    is 1 at the scene centre its beam stares at (docs/physics.md (B3)), so ``(sum g_t)^2 / N``,
    0.3475 N = (Si(pi) / pi)^2 N for the tapered beam.
    """
    if params.pattern_length <= 0 or pulses <= 0:
        return float(pulses)
    power = 1 if params.bistatic else 2
    lo, hi = params.beam_sines
    squint = math.radians(params.squint) if params.mode == "stripmap" else 0.0
    sines = np.linspace(lo, hi, max(int(pulses), 2))
    g2 = np.abs(np.sinc(params.pattern_length / params.wavelength * np.sin(np.arcsin(sines) - squint))) ** power
    return float(g2.sum() ** 2 / g2.size) * pulses / g2.size
