"""The valid values of the SAR sensor's named parameters, and the checks a new
:class:`~sarmitsuba.core.radar.RadarParameters` runs on construction (docs/design.md section 4).

:func:`check_sensor` runs first the unit and range checks of :mod:`.valid_ranges`, then the
checks between fields (a beamwidth against an antenna length, a sampling rate against the
bandwidth, a trajectory's own parameters, a receiver's), and fills the defaults that follow from
other fields (the sampling rate, the beamwidth of an antenna, a circular track's spotlight mode).
Every failure is a :class:`~.valid_ranges.ParameterError` that names the parameter, its valid
range and the likely fix.
"""
from __future__ import annotations

import math
from typing import Any, Callable

from . import georef
from .constants import SPEED_OF_LIGHT
from .receiver import check_receiver
from .trajectory import MotionError, StateVectors
from .valid_ranges import ParameterError, check_ranges

__all__ = ["CHANNELS", "POLARIZATIONS", "TRAJECTORIES", "ORBIT_DIRECTIONS", "HALF_POWER_SINC", "check_sensor",
           "check_trajectory", "utc_time"]

#: ``x`` where ``sinc^2(x) = 1/2`` (``sinc(x) = sin(pi x) / (pi x)``): a uniform aperture of length
#: ``L`` has its one-way 3 dB points at ``sin(phi) = HALF_POWER_SINC lambda / L``.
HALF_POWER_SINC = 0.44294647


#: The channels of a quad-pol acquisition, receive then transmit letter (Lee and Pottier's
#: ``S_rx,tx``): ``HV`` is received on H and transmitted on V (docs/physics.md (P4)).
CHANNELS = ("HH", "HV", "VH", "VV")
#: Valid values of the sensor parameter ``polarization``.
POLARIZATIONS = ("VV", "HH", "HV", "VH", "quad")
#: Named values of the sensor parameter ``trajectory`` (anything else names a CSV of state vectors).
TRAJECTORIES = ("straight", "circular", "orbit")
#: Valid values of the sensor parameter ``orbit_direction`` (``trajectory = "orbit"``).
ORBIT_DIRECTIONS = ("descending", "ascending")


def check_sensor(params: Any, coerce: Callable) -> None:
    """Check the RadarParameters ``params`` as constructed, and fill its derived defaults in place.

    ``coerce`` is :func:`~sarmitsuba.core.radar.coerce_parameters`, handed on to the receiver's
    checks (a receiver's values are coerced as the sensor's own). Raises ParameterError naming the
    first parameter out of its range or at odds with another.
    """
    if params.sampling_rate == 0 and isinstance(params.bandwidth, (int, float)):
        object.__setattr__(params, "sampling_rate", 1.2 * params.bandwidth)
    check_ranges(params)                   # units and ranges first: the checks below divide by them
    if params.collection_start is not None:
        object.__setattr__(params, "collection_start", utc_time(params.collection_start))
    if params.orbit_pass_time is not None:
        from .state_vectors import utc_instant
        object.__setattr__(params, "orbit_pass_time", utc_instant(
            params.orbit_pass_time, "orbit_pass_time", "give the UTC time of the wanted pass's closest approach as "
            "ISO 8601 with an offset, e.g. --set orbit_pass_time=2026-06-15T12:00:00Z").isoformat())
    try:
        georef.parse(params.geo_origin)
    except georef.GeoReferenceError as exc:
        raise ParameterError(str(exc)) from None
    for name in ("antenna_length", "antenna_height"):
        value = getattr(params, name)
        if 0 < value <= SPEED_OF_LIGHT / params.frequency:
            raise ParameterError(f"{name} = {value} m must exceed the wavelength "
                                 f"{SPEED_OF_LIGHT / params.frequency:.4g} m (or be 0 for no pattern)")
    if params.beam not in ("tapered", "uniform"):
        raise ParameterError(f"beam = {params.beam!r}; valid values are 'tapered' and 'uniform'")
    if params.beam == "uniform" and params.antenna_length > 0:
        raise ParameterError(f"beam = 'uniform' ignores the pattern of antenna_length = {params.antenna_length} m: "
                             "remove antenna_length, or use beam = 'tapered'")
    if params.azimuth_beamwidth == 0:
        beam = (math.degrees(2.0 * math.asin(HALF_POWER_SINC * SPEED_OF_LIGHT / params.frequency
                                             / params.antenna_length))
                if params.antenna_length > 0 else 1.0)
        object.__setattr__(params, "azimuth_beamwidth", beam)
    elif params.antenna_length > 0:
        own = math.degrees(2.0 * math.asin(HALF_POWER_SINC * SPEED_OF_LIGHT / params.frequency / params.antenna_length))
        if not math.isclose(params.azimuth_beamwidth, own, rel_tol=1e-3):
            raise ParameterError(
                f"azimuth_beamwidth = {params.azimuth_beamwidth:g} deg disagrees with antenna_length = "
                f"{params.antenna_length:g} m, whose 3 dB beamwidth is {own:.4g} deg: give only one of them "
                "(e.g. --set azimuth_beamwidth=0 when the scene file sets a beamwidth)")
    _positive(params, "azimuth_beamwidth")
    if not 0.0 < params.incidence_angle < 90.0:
        raise ParameterError(
            f"incidence_angle = {params.incidence_angle} deg is outside the valid range (0, 90) deg")
    if params.sampling_rate < params.bandwidth:
        raise ParameterError(
            f"sampling_rate = {params.sampling_rate:g} Hz is below bandwidth = {params.bandwidth:g} Hz: "
            "complex sampling needs sampling_rate >= bandwidth")
    if params.look_side not in ("right", "left"):
        raise ParameterError(f"look_side = {params.look_side!r}; valid values are 'right' and 'left'")
    if params.mode not in ("stripmap", "spotlight"):
        raise ParameterError(f"mode = {params.mode!r}; valid values are 'stripmap' and 'spotlight'")
    if params.output not in ("compressed", "raw"):
        raise ParameterError(f"output = {params.output!r}; valid values are 'compressed' and 'raw'")
    if params.polarization not in POLARIZATIONS:
        raise ParameterError(f"polarization = {params.polarization!r}; valid values are "
                             f"{', '.join(repr(p) for p in POLARIZATIONS)} (case matters: 'quad' "
                             "for all four channels)")
    if int(params.n_pulses) != params.n_pulses or params.n_pulses < 0:
        raise ParameterError(f"n_pulses = {params.n_pulses} must be a whole number >= 0 (0 = automatic)")
    if not 0.0 < params.azimuth_beamwidth < 90.0:
        raise ParameterError(f"azimuth_beamwidth = {params.azimuth_beamwidth} deg is outside (0, 90) deg")
    if params.beam == "tapered" and params.antenna_length == 0 and \
            math.sin(math.radians(params.azimuth_beamwidth) / 2.0) / HALF_POWER_SINC >= 1.0:
        raise ParameterError(f"azimuth_beamwidth = {params.azimuth_beamwidth} deg is too wide for a tapered beam "
                             f"(its first nulls would pass 90 deg): use at most "
                             f"{math.degrees(2 * math.asin(HALF_POWER_SINC * 0.99)):.1f} deg, or beam = 'uniform'")
    if not (isinstance(params.squint, (int, float)) and -60.0 < params.squint < 60.0):
        raise ParameterError(f"squint = {params.squint!r} deg is outside the valid range (-60, 60) deg")
    check_trajectory(params, coerce)


def check_trajectory(params: Any, coerce: Callable) -> None:
    """``trajectory``, ``arc_deg``, ``orbit_*``, ``motion_error``, ``stop_and_hop``, ``ati_baseline``
    and the receiver of the RadarParameters ``params`` (no file is read here); ParameterError
    naming the parameter otherwise."""
    if not (isinstance(params.trajectory, StateVectors) or (isinstance(params.trajectory, str) and params.trajectory)):
        raise ParameterError(f"trajectory = {params.trajectory!r}: give 'straight', 'circular', 'orbit' or the path of a CSV "
                             "file of state vectors (time_s,x_m,y_m,z_m[,vx_mps,vy_mps,vz_mps])")
    if not (isinstance(params.arc_deg, (int, float)) and 0.0 < params.arc_deg <= 360.0):
        raise ParameterError(f"arc_deg = {params.arc_deg!r} deg is outside the valid range (0, 360] deg (the arc "
                             "of a circular trajectory; 360 = a full circle)")
    if params.arc_deg != 360.0 and params.trajectory != "circular":
        kind = params.trajectory.source if isinstance(params.trajectory, StateVectors) else repr(params.trajectory)
        raise ParameterError(f"arc_deg = {params.arc_deg:g} deg is used only by trajectory = 'circular' (the arc it "
                             f"flies), but trajectory = {kind}: add trajectory=circular, or remove arc_deg")
    if params.trajectory == "circular":
        if params.squint != 0:
            raise ParameterError(f"squint = {params.squint:g} deg with trajectory = 'circular': the beam follows the "
                                 "scene centre around the circle; remove squint")
        if params.mode != "spotlight":           # the beam follows the scene centre
            object.__setattr__(params, "mode", "spotlight")
    if not (isinstance(params.orbit_inclination, (int, float)) and 0.0 < params.orbit_inclination < 180.0):
        raise ParameterError(f"orbit_inclination = {params.orbit_inclination!r} deg is outside the valid range "
                             "(0, 180) deg (98.18 for Sentinel-1's sun-synchronous orbit)")
    if params.orbit_direction not in ORBIT_DIRECTIONS:
        raise ParameterError(f"orbit_direction = {params.orbit_direction!r}; valid values are 'descending' and "
                             "'ascending'")
    if isinstance(params.trajectory, StateVectors) and params.trajectory.epoch is not None and \
            params.collection_start is not None:
        raise ParameterError(f"collection_start = {params.collection_start!r} and the absolute times of trajectory "
                             f"{params.trajectory.source} both set the first pulse's UTC time: remove "
                             "collection_start (it follows from the trajectory's clock)")
    error = MotionError.parse(params.motion_error)        # TrajectoryError: a ParameterError
    object.__setattr__(params, "motion_error", None if error is None else str(error))
    if not isinstance(params.stop_and_hop, bool):
        raise ParameterError(f"stop_and_hop = {params.stop_and_hop!r}: give true or false")
    if not (isinstance(params.ati_baseline, (int, float)) and 0.0 <= params.ati_baseline <= 1e3):
        raise ParameterError(f"ati_baseline = {params.ati_baseline!r} m is outside the valid range [0, 1000] m (the "
                             "along-track separation of the second channel's phase centre; 0 = one channel)")
    if params.receiver:
        check_receiver(params, coerce)
    if params.ati_baseline > 0 and params.polarization == "quad":
        raise ParameterError("ati_baseline > 0 with polarization = 'quad': along-track interferometry renders one "
                             "polarisation; choose HH, VV, HV or VH")

def _positive(obj: Any, *names: str) -> None:
    for name in names:
        value = getattr(obj, name)
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} = {value!r} must be a finite number > 0")

def utc_time(text: Any) -> str:
    """``collection_start`` as an ISO 8601 UTC string (``"2026-11-24T10:00:00+00:00"``) from an
    ISO 8601 time with an offset (``Z`` or ``+hh:mm``; ``datetime.fromisoformat``). Raises
    ParameterError naming ``collection_start`` for anything else, a time without an offset
    included (it would be read in the machine's own zone)."""
    from .state_vectors import utc_instant
    return utc_instant(text, "collection_start", "give the UTC time of the first pulse as ISO 8601 with an offset, "
                       "e.g. --set collection_start=2026-11-24T10:00:00Z (or leave it out for the moment of the "
                       "render)").isoformat()
