"""Absolute radiometry: the radar equation, thermal noise and image calibration (docs/physics.md (R1)-(R4)).

Switched on by the sensor's ``transmit_power`` (absolute units) and ``noise_figure_db`` /
``noise_temperature`` (thermal noise). Without them data are normalised (sqrt(m^2)) and
noiseless, and none of this runs.

Units in absolute mode: raw samples in sqrt(W) at the receiver, range compressed by a
unit-energy matched filter so that thermal noise keeps its power ``k T B F`` per sample
while a point target's peak power is ``P_r B T_p`` (the time-bandwidth gain).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import fft as sp_fft

from ..core.constants import BOLTZMANN
from ..scene.effects import EffectSet
from ..core.radar import ParameterError, RadarParameters

__all__ = ["RadarEquation", "radar_equation", "thermal_noise", "calibrate_image", "effective_pulses"]


@dataclass(frozen=True)
class RadarEquation:
    """Constants of the single-pulse radar equation for one sensor.

    Attributes
    ----------
    transmit_power : float, W
    gain : float
        Antenna gain (linear), transmit = receive.
    losses : float
        System losses (linear, >= 1).
    wavelength : float, m
    bandwidth : float, Hz
    pulse_length : float, s
    noise_power : float, W
        ``k T B F`` (0 when noise is off).
    """

    transmit_power: float
    gain: float
    losses: float
    wavelength: float
    bandwidth: float
    pulse_length: float
    noise_power: float

    @property
    def constant(self) -> float:
        """``P_t G^2 lambda^2 / ((4 pi)^3 L)`` [W m^2]: received power = constant sigma / R^4, eq. (R1)."""
        return self.transmit_power * self.gain**2 * self.wavelength**2 / ((4 * math.pi) ** 3 * self.losses)

    @property
    def time_bandwidth(self) -> float:
        """Range-compression gain ``B T_p``."""
        return self.bandwidth * self.pulse_length

    def received_power(self, rcs: float, slant_range: float) -> float:
        """Single-pulse received power [W] of a target of RCS [m^2] at slant range [m], eq. (R1)."""
        return self.constant * rcs / slant_range**4

    def snr(self, rcs: float, slant_range: float) -> float:
        """Single-pulse SNR ``P_t G^2 lambda^2 sigma / ((4 pi)^3 R^4 k T B F L)``, eq. (R2)."""
        return self.received_power(rcs, slant_range) / self.noise_power

    def image_snr(self, rcs: float, slant_range: float, n_pulses: float) -> float:
        """Point-target SNR in the focused image: single-pulse SNR x ``B T_p`` x pulses, eq. (R3)."""
        return self.snr(rcs, slant_range) * self.time_bandwidth * n_pulses

    def amplitude_scale(self, slant_range: float | np.ndarray) -> float | np.ndarray:
        """Factor from normalised amplitude (sqrt(m^2)) to compressed absolute amplitude (sqrt(W)):
        ``sqrt(constant B T_p) / R^2``."""
        return np.sqrt(self.constant * self.time_bandwidth) / np.asarray(slant_range) ** 2


def radar_equation(params: RadarParameters, effects: EffectSet | None = None) -> RadarEquation | None:
    """The radar equation of a sensor, or None when absolute radiometry is off.

    ``effects`` (:class:`~sarmitsuba.effects.EffectSet`, default ``EffectSet.of(params)``) says
    whether absolute radiometry and thermal noise are on.

    Gain: ``antenna_gain_db``, else ``4 pi L_a H_a / lambda^2`` (uniform aperture, efficiency 1;
    Skolnik, *Radar Handbook*, 3rd ed., eq. 9.3). Noise power ``k T B F`` with T = noise
    temperature (290 K default) and F = noise figure.

    Raises
    ------
    ParameterError
        Noise without transmit power, or transmit power without any way to get the gain.
    """
    effects = EffectSet.of(params) if effects is None else effects
    if not effects.radiometry:
        if effects.noise:
            raise ParameterError("noise_figure_db / noise_temperature need transmit_power (absolute radiometry); "
                                 "give transmit_power [W] too")
        return None
    if params.antenna_gain_db is not None:
        gain = 10.0 ** (params.antenna_gain_db / 10.0)
    elif params.antenna_length > 0 and params.antenna_height > 0:
        gain = 4.0 * math.pi * params.antenna_length * params.antenna_height / params.wavelength**2
    else:
        raise ParameterError("transmit_power needs the antenna gain: give antenna_gain_db [dBi], or "
                             "antenna_length and antenna_height [m]")
    temperature = params.noise_temperature if params.noise_temperature is not None else 290.0
    figure = 10.0 ** ((params.noise_figure_db or 0.0) / 10.0)
    noise = BOLTZMANN * temperature * params.bandwidth * figure if effects.noise else 0.0
    return RadarEquation(params.transmit_power, gain, 10.0 ** (params.losses_db / 10.0), params.wavelength,
                         params.bandwidth, params.pulse_length, noise)


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
    mean of sinc^2 between its first nulls).
    """
    if params.pattern_length <= 0 or pulses <= 0:
        return float(pulses)
    lo, hi = params.beam_sines
    squint = math.radians(params.squint) if params.mode == "stripmap" else 0.0
    sines = np.linspace(lo, hi, max(int(pulses), 2))
    g2 = np.sinc(params.pattern_length / params.wavelength * np.sin(np.arcsin(sines) - squint)) ** 2
    return float(g2.sum() ** 2 / g2.size) * pulses / g2.size
