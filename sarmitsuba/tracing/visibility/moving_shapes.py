"""Moving shapes within a sub-aperture: the target's motion added to the lanes' rates
(docs/physics.md (V2)).

A sub-aperture traces the moving shapes where they stand at its reference time
(:mod:`sarmitsuba.tracing.driver.moving`); its pulses then see every point of a shape that moves
at ``v`` displaced by ``v (t_p - t_ref)``. A rigid translation keeps every mirror's normal, so a
chain's unfolding map ``U_d(x) = lin_d x + shift_d`` (eq. (M3)) keeps its linear part and its
shift moves at a constant rate: with each mirror plane's offset moving at ``n_i . v_i``,

    d shift_{i+1} / dt = lin_i (2 (n_i . v_i) n_i) + d shift_i / dt,

and the unfolded point ``U_d(x)`` moves at ``lin_d v_d + d shift_d / dt``. Both are linear in
time, as the (M8) rates are linear in the antenna's travel ``t``; a pulse ``t`` metres along
the lane's axis is ``t / V_a`` seconds from the reference (``V_a`` the antenna's speed along that
axis), so the target's rates per metre of travel are these divided by ``V_a`` and add to the
lanes' own (exact on a straight track at constant speed).

:func:`target_rates` is the readable reference: one lane at a time, unfolding the moved points
through the moved mirrors of its chain.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from ..discovery.chains import Chains
from ..integration.patch_terms import TermLanes
from ..loops import lane_float

__all__ = ["TargetMotion", "target_rates"]


@dataclasses.dataclass(frozen=True)
class TargetMotion:
    """What a sub-aperture's tracer needs to move its lanes with the shapes.

    Attributes
    ----------
    part_velocity : float64 [n_parts, 3], m/s
        Each part's velocity (zero for the still ones).
    antenna_velocity : float64 [n_s, 3], m/s
        The antenna's mean velocity over each sub-aperture of the launch (first to last pulse).
    """

    part_velocity: np.ndarray
    antenna_velocity: np.ndarray

    def rates(self, surfaces, chains: Chains) -> tuple[np.ndarray, np.ndarray]:
        """Per chain, float64 [n, 3] each: the last part's velocity and the unfolded point's
        (``lin_d v_d + d shift_d / dt``), m/s."""
        n, depth = chains.parts.shape
        parts = np.where(chains.parts >= 0, chains.parts, 0)
        velocity = self.part_velocity[parts] * (chains.parts >= 0)[..., None]
        d_shift = np.zeros((n, depth, 3))
        for i in range(depth - 1):
            normal = surfaces.normal[parts[:, i]]
            rate = 2.0 * np.einsum("ni,ni->n", normal, velocity[:, i])[:, None] * normal
            new = np.einsum("nij,nj->ni", chains.lin[:, i], rate) + d_shift[:, i]
            d_shift[:, i + 1] = np.where((chains.order > i)[:, None], new, d_shift[:, i])
        rows = np.arange(n)
        last = velocity[rows, chains.order]
        return last, np.einsum("nij,nj->ni", chains.lin_last, last) + d_shift[rows, chains.order]

    def moved(self, lanes: TermLanes, surfaces, chains: Chains, chain: np.ndarray,
              reference: np.ndarray) -> TermLanes:
        """``lanes`` (of chains ``chain`` [m]) with the rigid rates of their shapes' motion added
        (V3): the last part's velocity at the point, ``lin_d v_d + d shift_d / dt`` at its unfolded
        image, the edge unchanged."""
        if len(lanes) == 0 or not np.any(self.part_velocity):
            return lanes
        point_rate, unfolded_rate = (r[chain] for r in self.rates(surfaces, chains))
        if not np.any(point_rate) and not np.any(unfolded_rate):
            return lanes
        added = np.stack([point_rate, unfolded_rate, point_rate, unfolded_rate, np.zeros_like(point_rate)], axis=1)
        return self._added(lanes, added, reference)

    def with_rates(self, lanes: TermLanes, pieces, d_lanes: TermLanes, d_pieces, reference: np.ndarray,
                   shift: float = 0.0):
        """``(lanes, pieces)`` with the rates ``d_lanes``, ``d_pieces`` (their fields' derivatives in
        time, m/s: the lit geometry differenced, (V2)) added to their own per metre of travel;
        lanes of the geometry ``shift`` seconds after the reference time are carried back to it
        (``x - shift dx/dt``)."""
        added = np.stack([d_lanes.point, d_lanes.unfolded, d_lanes.middle, d_lanes.middle_unfolded,
                          d_lanes.edge.astype(np.float64)], axis=1)
        # an end where a moving line meets a still one at a grazing angle slides along it: frozen,
        # as (M8) freezes the antenna's (its first-order motion spans changes of the piece's shape)
        limit = SLIDE_LIMIT * float(np.linalg.norm(self.part_velocity, axis=1).max(initial=0.0))
        sliding = np.linalg.norm(added, axis=2).max(axis=1) > limit
        added[sliding] = 0.0
        if not np.any(added):
            return lanes, pieces
        if shift:
            lanes, pieces = _carried(lanes, d_lanes, shift), _carried(pieces, d_pieces, shift)
        lanes = self._added(lanes, added, reference)
        speed = float(np.linalg.norm(self.antenna_velocity[0]))
        if speed > 0 and len(pieces.segment_mid):
            mid, edge = (np.zeros(pieces.segment_mid.shape) if r is None else r.astype(np.float64)
                         for r in (pieces.segment_mid_rate, pieces.segment_edge_rate))
            pieces = dataclasses.replace(
                pieces, segment_mid_rate=(mid + d_pieces.segment_mid / speed).astype(lane_float()),
                segment_edge_rate=(edge + d_pieces.segment_edge / speed).astype(lane_float()))
        return lanes, pieces

    def _added(self, lanes: TermLanes, added: np.ndarray, reference: np.ndarray) -> TermLanes:
        """``lanes`` with ``added`` [m, 5, 3] (m/s: point, unfolded, middle, middle_unfolded,
        edge) added to their rates per metre of travel; lanes without rates of their own get the
        sub-aperture's reference position as origin and the antenna's direction as axis."""
        sub = lanes.sub.astype(np.int64)
        velocity = self.antenna_velocity[sub]
        if lanes.motion is None:
            speed = np.linalg.norm(velocity, axis=1, keepdims=True)
            origin = reference[sub]
            axis = (velocity / np.where(speed > 0, speed, 1.0)).astype(lane_float())
            motion = np.zeros((len(lanes), 5, 3))
        else:
            origin, axis, motion = lanes.origin, lanes.axis, lanes.motion.astype(np.float64)
        along = np.einsum("mi,mi->m", velocity, axis.astype(np.float64))[:, None]
        per_metre = np.where(np.abs(along) > 0, 1.0 / np.where(along != 0, along, 1.0), 0.0)
        motion = motion + added * per_metre[:, :, None]
        return dataclasses.replace(lanes, origin=origin, axis=axis, motion=motion.astype(lane_float()))


#: A lane whose point, image or edge moves faster than this many times the fastest shape (an end
#: sliding along a line that a moving line meets at a grazing angle) keeps still (V2).
SLIDE_LIMIT = 8.0

#: The positional fields a lane or piece moves by (:func:`_carried`).
_POSITIONS = ("point", "unfolded", "middle", "middle_unfolded", "edge", "centroid", "centroid_unfolded",
              "segment_mid", "segment_edge")


def _carried(table, rates, shift: float):
    """``table`` (term lanes or piece table) with its positional fields moved by ``-shift`` times
    their ``rates`` (the same dataclass, m/s), in their own dtypes."""
    moved = {}
    for name in _POSITIONS:
        value = getattr(table, name, None)
        if isinstance(value, np.ndarray) and value.dtype.kind == "f":
            moved[name] = (value.astype(np.float64) - shift * getattr(rates, name).astype(np.float64)).astype(value.dtype)
    return dataclasses.replace(table, **moved)


def target_rates(surfaces, parts: list[int], point: np.ndarray, velocity: np.ndarray,
                 dt: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Reference for :meth:`TargetMotion.rates`, one chain: the point ``point`` [3] on the last of
    ``parts`` (the chain ``X_0 .. X_d``) and its unfolded image, both moved ``dt`` seconds
    (every part at its own ``velocity[part]`` [3], m/s), each mirror reflected afresh:
    ``(point rate, unfolded rate)`` in m/s, float64 [3] each (differences over ``dt``, exact for
    a translation)."""
    def unfolded(x, shift_time):
        y = np.asarray(x, float)
        for part in reversed(parts[:-1]):
            n = surfaces.normal[part]
            offset = surfaces.offset[part] + shift_time * float(n @ velocity[part])
            y = y - 2.0 * (float(n @ y) - offset) * n
        return y

    moved = np.asarray(point, float) + dt * velocity[parts[-1]]
    return (moved - point) / dt, (unfolded(moved, dt) - unfolded(point, 0.0)) / dt
