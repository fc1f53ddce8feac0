"""What one pulse's returns need besides its transmit position: the beam's steering, the antenna's
axes on a curved track and its motion during the echo (docs/physics.md (A), (J3)).

:class:`PulseView` holds them for the pulse of a lane as Dr.Jit values, None where the effect is
off, so that nothing of it is compiled (docs/design.md section 7). :func:`receive_leg` is the
tracer's receive leg (J3); :func:`antenna_axes` the per-pulse axes of a curved track (NumPy,
once per acquisition).
"""
from __future__ import annotations

import math

import drjit as dr
import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ...core.trajectory import RECEIVE_ITERATIONS

__all__ = ["PulseView", "receive_leg", "antenna_axes", "receiver_axes"]


class PulseView:
    """One pulse's view of the scene beyond its transmit position (per lane, Dr.Jit values).

    Attributes
    ----------
    steer : mi.Float or None
        Spotlight: the along-track sine of the scene centre, which the beam is steered at.
    axis : mi.Array3f64 or None
        Curved track: the antenna's along-track axis (the direction of the nominal velocity,
        docs/physics.md (J7)); None: the track direction of the footprint.
    aperture, elevation : mi.Vector3f or None
        Curved track: the axes of the antenna pattern (A) for this pulse.
    velocity, acceleration : mi.Array3f64 or None
        No stop-and-hop: the receiving antenna's motion at transmission, for the receive leg (J3).
    receiver : mi.Array3f64 or None
        Bistatic: the receiver's platform at transmission (docs/physics.md (B1)); None: the
        transmitter receives.
    rx_steer : mi.Float or None
        Bistatic with a receive pattern: the along-track sine of the scene centre seen from the
        receiver, which its beam stares at (B3).
    rx_axes : (mi.Vector3f, mi.Vector3f) or None
        The receive pattern's along-track and elevation axes for this pulse (B3).
    """

    __slots__ = ("steer", "axis", "aperture", "elevation", "velocity", "acceleration", "receiver", "rx_steer", "rx_axes")

    def __init__(self, steer=None, axis=None, aperture=None, elevation=None, velocity=None, acceleration=None,
                 receiver=None, rx_steer=None):
        self.steer, self.axis, self.aperture, self.elevation = steer, axis, aperture, elevation
        self.velocity, self.acceleration = velocity, acceleration
        self.receiver, self.rx_steer, self.rx_axes = receiver, rx_steer, None


def receive_leg(view: PulseView, antenna, point, s):
    """The receive leg of a return at ``point`` (float64) whose first part (the transmit leg and
    the bounces, unfolded) is ``s`` [m] long: the vector from the point to the receiving antenna
    when the echo arrives, and its length (float64), eq. (J3). The receiving antenna (the
    transmitter ``antenna``, or bistatic the receiver's platform ``view.receiver``, (B1)) moves
    ``v tau + a tau^2 / 2`` during the echo, ``c tau = s + |R(tau) - point|``, solved by
    :data:`~sarmitsuba.core.trajectory.RECEIVE_ITERATIONS` fixed-point steps (each multiplies the
    error by ``v / c``); with stop-and-hop (no velocity in ``view``) where it is at transmission."""
    origin = antenna if view.receiver is None else view.receiver
    outgoing = origin - point
    dist = dr.norm(outgoing)
    if view.velocity is None:
        return outgoing, dist
    for _ in range(RECEIVE_ITERATIONS):
        tau = (s + dist) * (1.0 / SPEED_OF_LIGHT)
        outgoing = origin + view.velocity * tau + view.acceleration * (0.5 * tau * tau) - point
        dist = dr.norm(outgoing)
    return outgoing, dist


def antenna_axes(params, geometry) -> np.ndarray | None:
    """Per pulse, the antenna's along-track axis, aperture axis and elevation axis of a curved
    track, float64 [n_pulses, 3, 3] (rows: axes), or None for a straight track, whose axes are
    constant (docs/physics.md (A)).

    The along-track axis is :attr:`~sarmitsuba.core.geometry.AcquisitionGeometry.beam_axes`; the
    boresight is the direction to the scene centre with its along-track part removed (on a
    straight track the constant ``ground_range look - altitude z``); the aperture axis is the
    along-track axis turned by the squint toward it (stripmap), the elevation axis their cross
    product."""
    if geometry.beam_axes is None:
        return None
    axis = geometry.beam_axes
    to_c = np.asarray(geometry.scene_center, float) - geometry.positions
    bore = to_c - np.sum(to_c * axis, axis=1, keepdims=True) * axis
    bore /= np.linalg.norm(bore, axis=1, keepdims=True)
    squint = math.radians(params.squint) if params.mode == "stripmap" else 0.0
    aperture = math.cos(squint) * axis - math.sin(squint) * bore
    return np.stack([axis, aperture, np.cross(axis, bore)], axis=1)



def receiver_axes(receiver: np.ndarray, axis: np.ndarray, centre) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A bistatic receiver's pattern axes per pulse (docs/physics.md (B3)): from its positions
    ``receiver`` and along-track unit ``axis`` (float64 [n, 3] each) and the scene ``centre`` [3],
    ``(axis, elevation, steer)``: the along-track axis, the elevation axis ``axis x boresight``
    (boresight the unit direction to the centre, its along-track part removed), float64 [n, 3],
    and the along-track sine of the centre, float64 [n], which the staring beam is steered at."""
    to_c = np.asarray(centre, np.float64) - np.asarray(receiver, np.float64)
    to_c /= np.linalg.norm(to_c, axis=1, keepdims=True)
    steer = np.sum(to_c * axis, axis=1)
    bore = to_c - steer[:, None] * axis
    elevation = np.cross(axis, bore)
    elevation /= np.linalg.norm(elevation, axis=1, keepdims=True)
    return np.asarray(axis, np.float64), elevation, steer
