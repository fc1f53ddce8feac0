"""What one kernel launch traces: a few sub-apertures of consecutive pulses (their antenna
positions, reference lengths, reference positions and along-track aim limits) and the
rectangular blocks of the aim lattice whose ray tubes each of them casts (docs/physics.md (T1),
(T2), (T3)). :mod:`sarmitsuba.tracing.driver.trace` builds them; :class:`sarmitsuba.tracing.driver.kernel.Kernel`
traces them.
"""
from __future__ import annotations

from dataclasses import dataclass

import mitsuba as mi
import numpy as np

from ..device import device_array

__all__ = ["Blocks", "Launch", "receiver_launch"]


@dataclass(frozen=True)
class Blocks:
    """Rectangular pieces of the aim lattice that one launch traces (docs/physics.md (T1), (T2)).

    Block ``b`` holds ``n_a[b] x n_j[b]`` tubes of sub-aperture ``sub[b]``, lanes ``start[b]`` on
    (``i`` along track, ``j`` in range, ``j`` fastest): tube ``(i, j)`` aims at the centre of the
    cell ``(i0 + (i + 1/2) / m, j0 + (j + 1/2) / m)`` of the coarse lattice, ``m`` tubes per coarse
    cell edge (1 for the coarse lattice, the refinement factor around small objects). Tubes are
    lattice neighbours only within a block.

    Attributes
    ----------
    start, sub, n_a, n_j, m : uint32 [n_blocks]
    i0, j0 : int32 [n_blocks]
        Coarse-lattice cell of the block's first tube.
    """

    start: np.ndarray
    sub: np.ndarray
    i0: np.ndarray
    j0: np.ndarray
    n_a: np.ndarray
    n_j: np.ndarray
    m: np.ndarray

    @staticmethod
    def of(rows: list) -> "Blocks":
        """Blocks from ``(sub, i0, j0, n_a, n_j, m)`` rows, lanes in that order."""
        table = np.asarray(rows, np.int64).reshape(-1, 6)
        sizes = table[:, 3] * table[:, 4]
        start = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.uint32)
        u32 = lambda c: table[:, c].astype(np.uint32)   # noqa: E731
        return Blocks(start=start, sub=u32(0), i0=table[:, 1].astype(np.int32), j0=table[:, 2].astype(np.int32),
                      n_a=u32(3), n_j=u32(4), m=u32(5))

    @property
    def n_lanes(self) -> int:
        """Tubes (lanes) of all blocks, ``sum n_a n_j``."""
        return int((self.n_a.astype(np.int64) * self.n_j).sum())


@dataclass(frozen=True)
class Launch:
    """One kernel launch: sub-apertures of consecutive pulses and the tubes each of them casts.

    Attributes
    ----------
    antenna : float64 [n_b, 3], m
        Antenna positions of the batch's pulses (a sub-aperture's pulses are consecutive rows).
    lref : float64 [n_b], m
        Reference two-way lengths ``L_ref`` of those pulses.
    first, count : int64 [n_s]
        First pulse (row of ``antenna``) and number of pulses of each sub-aperture.
    reference : float64 [n_s, 3], m
        Each sub-aperture's reference position: the tubes' common source (docs/physics.md (T3)).
    r_near : float64 [n_s], m
        Distance from the reference position at which the rays start (float32 origins near the scene).
    along_limits : float64 [n_s, 2], m
        Along-track aim limits of each sub-aperture (the union of its pulses').
    blocks : Blocks
        The lattice pieces traced, each for one sub-aperture.
    velocity, acceleration : float64 [n_b, 3] or None
        The antenna's motion at each pulse's transmission, for the receive leg (docs/physics.md
        (J3)); None with stop-and-hop.
    axes : float64 [n_b, 3, 3] or None
        Curved tracks: each pulse's along-track, aperture and elevation axes
        (:func:`sarmitsuba.tracing.integration.pulse_view.antenna_axes`); None on a straight track.
    pulse_time : float64 [n_b] or None, s
        The pulses' transmit times from mid-aperture, for moving shapes
        (:mod:`sarmitsuba.tracing.driver.moving`); None when the scene holds still.
    receiver, received : float64 [n_b, 3] or None, m
        Bistatic (docs/physics.md (B1)): the receiver's platform at each pulse's transmission
        (the kernels' receive leg starts there and moves with ``velocity``, ``acceleration``,
        which are then the receiver's), and where it is when the scene centre's echo arrives
        (what the host's visibility and rates see). None: the transmitter receives.
    receiver_reference : float64 [n_s, 3] or None, m
        Bistatic: each sub-aperture's receiver reference position, the midpoint of ``received``
        at its first and last pulse (the return legs' end for visibility, (B2)).
    receiver_axis : float64 [n_b, 3] or None
        Bistatic: the receiver's along-track unit axis at each pulse (its pattern, (B3)).
    """

    antenna: np.ndarray
    lref: np.ndarray
    first: np.ndarray
    count: np.ndarray
    reference: np.ndarray
    r_near: np.ndarray
    along_limits: np.ndarray
    blocks: Blocks
    velocity: np.ndarray | None = None
    acceleration: np.ndarray | None = None
    axes: np.ndarray | None = None
    pulse_time: np.ndarray | None = None
    receiver: np.ndarray | None = None
    received: np.ndarray | None = None
    receiver_reference: np.ndarray | None = None
    receiver_axis: np.ndarray | None = None

    @property
    def n_pulses(self) -> int:
        """Pulses of the launch."""
        return self.antenna.shape[0]

    @property
    def n_subapertures(self) -> int:
        """Sub-apertures of the launch (one reference position each)."""
        return self.reference.shape[0]

    @property
    def n_lanes(self) -> int:
        """Tubes (lanes) of the launch: its blocks' lanes."""
        return self.blocks.n_lanes

    def lane_block(self) -> mi.UInt32:
        """[n_lanes]: the block of every lane, on the device."""
        return device_array(mi.UInt32, np.repeat(np.arange(self.blocks.n_a.size), self.blocks.n_a.astype(np.int64) * self.blocks.n_j))


def receiver_launch(geometry, p0: int, p1: int, subs, g: slice, continuous: bool) -> dict:
    """The :class:`Launch` fields of a bistatic receiver (docs/physics.md (B1), (B2)) for pulses
    ``[p0, p1)`` and sub-apertures ``subs`` rows ``g``: ``receiver``, ``received``,
    ``receiver_reference``, ``receiver_axis`` and, without stop-and-hop (``continuous``), the
    receiver's ``velocity`` and ``acceleration``; ``{}`` for a monostatic ``geometry``."""
    if not geometry.bistatic:
        return {}
    received = geometry.rx_positions
    first, last = subs.first[g], subs.first[g] + subs.count[g] - 1
    velocity = geometry.receiver_velocity[p0:p1]
    horizontal = velocity * np.array([1.0, 1.0, 0.0])
    norm = np.linalg.norm(horizontal, axis=1, keepdims=True)
    axis = np.where(norm > 0, horizontal / np.where(norm > 0, norm, 1.0), geometry.track_direction)
    out = dict(receiver=geometry.receiver_positions[p0:p1], received=received[p0:p1],
               receiver_reference=0.5 * (received[first] + received[last]), receiver_axis=axis)
    if continuous:
        out.update(velocity=velocity, acceleration=geometry.receiver_acceleration[p0:p1])
    return out
