"""The radar equation of a sensor: the link budget that absolute radiometry scales by (docs/physics.md (R1)-(R3)).

It belongs to the scene stage because it depends only on the sensor and the effects the scene
switches on: a scene is checked against it when it is loaded, before any tracing. Raw data are
scaled by it in :mod:`sarmitsuba.signal.binning`, images calibrated by it in
:mod:`sarmitsuba.signal.radiometry`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.constants import BOLTZMANN
from ..core.radar import ParameterError, RadarParameters
from .effects import EffectSet

__all__ = ["RadarEquation", "radar_equation", "receiver_gain"]


@dataclass(frozen=True)
class RadarEquation:
    """Constants of the single-pulse radar equation for one sensor.

    Attributes
    ----------
    transmit_power : float, W
    gain : float
        Antenna gain (linear), transmit = receive; bistatic ``sqrt(G_t G_r)``, so that ``gain^2``
        is the product of the two antennas' gains (docs/physics.md (B3)).
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

    ``effects`` (:class:`~sarmitsuba.scene.effects.EffectSet`, default ``EffectSet.of(params)``) says
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
    if params.bistatic:            # P_t G_t G_r lambda^2 / ((4 pi)^3 R_t^2 R_r^2 L), docs/physics.md (B3)
        gain = math.sqrt(gain * receiver_gain(params))
    temperature = params.noise_temperature if params.noise_temperature is not None else 290.0
    figure = 10.0 ** ((params.noise_figure_db or 0.0) / 10.0)
    noise = BOLTZMANN * temperature * params.bandwidth * figure if effects.noise else 0.0
    return RadarEquation(params.transmit_power, gain, 10.0 ** (params.losses_db / 10.0), params.wavelength,
                         params.bandwidth, params.pulse_length, noise)


def receiver_gain(params: RadarParameters) -> float:
    """A bistatic receiver's antenna gain (linear): ``receiver_antenna_gain_db``, else ``4 pi L_r H_r /
    lambda^2`` from ``receiver_antenna_length`` and ``receiver_antenna_height``, else 1 (isotropic,
    0 dBi, as its pattern is then; docs/physics.md (B3))."""
    from ..core.receiver import receiver_parameters
    rp = receiver_parameters(params)
    if rp.antenna_gain_db is not None:
        return 10.0 ** (rp.antenna_gain_db / 10.0)
    if rp.antenna_length > 0 and rp.antenna_height > 0:
        return 4.0 * math.pi * rp.antenna_length * rp.antenna_height / params.wavelength**2
    return 1.0
