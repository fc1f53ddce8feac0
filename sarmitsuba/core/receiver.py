"""A receiver on a platform of its own: bistatic acquisitions (docs/physics.md (B1)-(B4)).

The sensor's ``receiver_*`` parameters describe a second platform that receives what the first
transmits. Each is a platform or antenna parameter of :class:`~sarmitsuba.core.radar.RadarParameters`
with the prefix ``receiver_`` (:data:`RECEIVER_FIELDS`): ``receiver_trajectory``,
``receiver_altitude``, ``receiver_incidence_angle``, ``receiver_heading``, ``receiver_velocity``,
``receiver_look_side``, ``receiver_track_offset``, ... Any trajectory kind the transmitter takes
(straight, circular, orbit, state vectors) the receiver takes too, flown over the same pulse
times. Giving any of them makes the acquisition bistatic; giving none keeps it monostatic.

The receiver's antenna stares at the scene centre (it is steered there at every pulse, as a
spotlight beam is) and has a pattern only when ``receiver_antenna_length`` or
``receiver_antenna_height`` is given; it inherits nothing of the transmitter's antenna.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Any, Mapping

import numpy as np

from .valid_ranges import ParameterError

__all__ = ["RECEIVER_FIELDS", "RECEIVER_PREFIX", "MAX_BISTATIC_ANGLE", "receiver_values", "receiver_parameters",
           "check_receiver", "check_bistatic_angle", "horizon_check"]

#: The prefix of the receiver's parameters in the sensor (``receiver_altitude``).
RECEIVER_PREFIX = "receiver_"
#: The platform and antenna parameters a receiver may set.
RECEIVER_FIELDS = ("trajectory", "velocity", "altitude", "incidence_angle", "heading", "look_side", "track_offset",
                   "arc_deg", "orbit_inclination", "orbit_direction", "squint", "antenna_length", "antenna_height",
                   "antenna_gain_db")
#: The largest bistatic angle [deg] at the scene centre: beyond it the geometry nears forward
#: scatter, where range resolution ``c / (2 B cos(beta / 2))`` is lost (Willis, *Bistatic Radar*,
#: 2nd ed., 2005, sec. 5.3).
MAX_BISTATIC_ANGLE = 150.0


def receiver_values(values: Mapping[str, Any], coerce) -> tuple[tuple[str, Any], ...]:
    """The receiver's parameters ``{name: value}`` (names without the prefix, values coerced by
    ``coerce``, :func:`sarmitsuba.core.radar.coerce_parameters`, as the sensor's own are) as
    sorted ``(name, value)`` pairs. Raises ParameterError for a name that is not in
    :data:`RECEIVER_FIELDS`."""
    out = {}
    for name, value in dict(values).items():
        if name not in RECEIVER_FIELDS:
            raise ParameterError(f"sar sensor parameter {RECEIVER_PREFIX}{name}: a receiver sets only "
                                 f"{', '.join(RECEIVER_PREFIX + f for f in RECEIVER_FIELDS)}")
        out.update(coerce({name: value}))
    return tuple(sorted(out.items()))


def receiver_parameters(params) -> Any:
    """The receiver's platform as :class:`~sarmitsuba.core.radar.RadarParameters` (the
    transmitter's radar, pulses and scene centre with the receiver's own platform, a beam
    staring at the scene centre, and its own antenna), or None for a monostatic sensor. Raises
    ParameterError naming the ``receiver_*`` parameter at fault."""
    given = dict(params.receiver)
    if not given:
        return None
    own = dict(trajectory="straight", squint=0.0, antenna_length=0.0, antenna_height=0.0, azimuth_beamwidth=0.0,
               antenna_gain_db=None, arc_deg=360.0, track_offset=(0.0, 0.0, 0.0), motion_error=None,
               ati_baseline=0.0, receiver=(), mode="spotlight", beam="tapered")
    own.update(given)
    try:
        return replace(params, **own)
    except ParameterError as exc:
        text = str(exc)
        first = text.split(" ", 1)[0]
        raise ParameterError(f"{RECEIVER_PREFIX}{text}" if first in RECEIVER_FIELDS
                             else f"receiver: {text}") from None


def check_receiver(params, coerce) -> None:
    """Check ``params.receiver`` (sorted pairs after coercion; a mapping from Python is coerced
    here by ``coerce``) and what a bistatic acquisition refuses. Raises ParameterError."""
    if isinstance(params.receiver, Mapping):
        object.__setattr__(params, "receiver", receiver_values(params.receiver, coerce))
    receiver_parameters(params)
    if params.ati_baseline > 0:
        raise ParameterError("ati_baseline > 0 with a receiver_* platform: along-track interferometry is monostatic "
                             "here; remove ati_baseline or the receiver_* parameters")


def check_bistatic_angle(tx: np.ndarray, rx: np.ndarray, center: np.ndarray) -> None:
    """Raise ParameterError when the bistatic angle at ``center`` exceeds
    :data:`MAX_BISTATIC_ANGLE` at any pulse (``tx``, ``rx`` float64 [n, 3], m)."""
    a, b = np.asarray(tx, np.float64) - center, np.asarray(rx, np.float64) - center
    # the angle between the legs, atan2(|a x b|, a . b) (analysis.bistatic.bistatic_angle's, unchecked)
    beta = np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1)))
    if beta.size and float(beta.max()) > MAX_BISTATIC_ANGLE:
        i = int(np.argmax(beta))
        raise ParameterError(f"receiver_*: the bistatic angle at the scene centre reaches {beta[i]:.1f} deg (pulse {i}), "
                             f"beyond {MAX_BISTATIC_ANGLE:g} deg, near forward scatter, where a bistatic SAR has no "
                             "range resolution: move the receiver to the transmitter's side of the scene (its "
                             "receiver_heading, receiver_look_side or receiver_incidence_angle)")


def horizon_check(rx: np.ndarray, center: np.ndarray) -> None:
    """Raise ParameterError when the receiver ``rx`` (float64 [n, 3], m) is at or below the
    scene centre's horizon (its elevation seen from ``center`` <= 0) at some pulse: it never
    sees the scene there."""
    up = np.asarray(rx, np.float64) - np.asarray(center, np.float64)
    elevation = np.degrees(np.arctan2(up[:, 2], np.hypot(up[:, 0], up[:, 1])))
    if elevation.size and float(elevation.min()) <= 0.0:
        i = int(np.argmin(elevation))
        raise ParameterError(f"receiver_trajectory: the receiver is {elevation[i]:.2f} deg "
                             f"{'below' if elevation[i] < 0 else 'on'} the scene centre's horizon at pulse {i} and "
                             "never sees the scene there: give it a receiver_altitude above the scene, or a "
                             "trajectory that passes over the scene's side of the Earth")
