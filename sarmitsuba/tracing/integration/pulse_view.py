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

__all__ = ["PulseView", "receive_leg", "antenna_axes"]


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
        No stop-and-hop: the antenna's motion at transmission, for the receive leg (J3).
    """

    __slots__ = ("steer", "axis", "aperture", "elevation", "velocity", "acceleration")

    def __init__(self, steer=None, axis=None, aperture=None, elevation=None, velocity=None, acceleration=None):
        self.steer, self.axis, self.aperture, self.elevation = steer, axis, aperture, elevation
        self.velocity, self.acceleration = velocity, acceleration


def receive_leg(view: PulseView, antenna, point, s):
    """The receive leg of a return at ``point`` (float64) whose first part (the transmit leg and
    the bounces, unfolded) is ``s`` [m] long: the vector from the point to the antenna when the
    echo arrives, and its length (float64), eq. (J3). The antenna moves ``v tau + a tau^2 / 2``
    during the echo, ``c tau = s + |A(tau) - point|``, solved by
    :data:`~sarmitsuba.core.trajectory.RECEIVE_ITERATIONS` fixed-point steps (each multiplies the
    error by ``v / c``); with stop-and-hop (no velocity in ``view``) the transmit position."""
    outgoing = antenna - point
    dist = dr.norm(outgoing)
    if view.velocity is None:
        return outgoing, dist
    for _ in range(RECEIVE_ITERATIONS):
        tau = (s + dist) * (1.0 / SPEED_OF_LIGHT)
        outgoing = antenna + view.velocity * tau + view.acceleration * (0.5 * tau * tau) - point
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

