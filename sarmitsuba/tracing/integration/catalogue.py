"""What the scatterer catalogue needs from the trace: every term lane's phase centre and its
returns summed coherently there (docs/physics.md (SC1)-(SC4)).

With ``sbr`` ``scatterers = true`` (``render --scatterers``) the mesh tracer
(:mod:`sarmitsuba.tracing.driver.mesh_trace`) hands each bounce order's term lanes to a
:class:`LaneCatalogue` before their pulses run:

1. :func:`phase_centres`, in NumPy, places each lane's phase centre ``P`` (SC1): the middle of its
   last point and that point unfolded (image theory), moved along the gradient of the range sum
   (the look direction, or the bistatic bisector) to the path's two-way length ``L``; a moving
   shape's lane is put back where its shape stands at mid-aperture, and images shifted along track
   by ``-R v_r / V`` (SC3);
2. every pulse's terms of the lane, as deposited, are multiplied by the conjugate carrier phase
   of that image point and summed, in fixed point (D7), one complex sum per lane and channel
   (:meth:`LaneSums.add`, called by :class:`~sarmitsuba.tracing.integration.patch_terms.PatchTerms`):
   what a focuser matched to the point adds up, without its window (SC2);
3. :meth:`LaneCatalogue.rows` merges the lanes of one chain of parts whose image points fall in
   one quantisation cube of ``step`` metres into
   :class:`CatalogueRows`; :func:`merge_rows` merges the rows of every launch alike.

The products stage (:func:`sarmitsuba.analysis.scatterers.build_catalogue`) divides the sums by
the image's point-target gain, merges rows into resolution cells and keeps the strongest.
Distributed clutter is not summed here: the catalogue summarises it per surface from the image.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ..deposit.fixed_point import AMPLITUDE
from ..device import device_array
from .pulse_view import receive_leg

__all__ = ["CatalogueRows", "LaneCatalogue", "LaneSums", "catalogued", "lane_catalogue", "response_offset", "merge_rows", "group_sums", "rows_of", "phase_centres",
           "NEWTON_STEPS"]

#: Newton steps of (SC1) along the range sum's gradient: each squares the relative error, which
#: starts below ``(|U - B| / R)^2``; three leave it far below float64 rounding for any chain
#: shorter than its range.
NEWTON_STEPS = 3


@dataclass(frozen=True)
class CatalogueRows:
    """Lanes merged by chain of parts and quantisation cell (NumPy; one row per merge).

    Attributes
    ----------
    parts : int64 [k, D]
        The chain's parts ``X_0 .. X_d`` (rows of :class:`~sarmitsuba.tracing.mesh.patches.Surfaces`),
        -1 beyond; ``D`` the traced depth.
    shapes : int64 [k, D]
        Their shapes' indices in ``mitsuba.Scene.shapes()``, -1 beyond.
    order : int64 [k]
        Bounce order ``d + 1``.
    cell : int64 [k, 3]
        Quantisation cell of the image point: ``floor(point / step)``, a cube of ``step`` metres.
    amplitude : complex128 [k, n_channels]
        ``sum`` over lanes and pulses of each term times ``exp(+j k L_P)`` (SC2), sqrt(m^2) x pulses.
    side : complex128 [k, 2]
        The first channel's same sums at the image point moved ``+side`` and ``-side`` along track
        (:attr:`LaneCatalogue.side`): the azimuth response's samples there (SC4).
    weight : float64 [k]
        ``sum |lane sum|^2`` over the merged lanes (the weights of the centres below).
    centre : float64 [k, 3]
        ``sum`` weight x phase centre at mid-aperture (SC1), m (local frame).
    shift : float64 [k]
        ``sum`` weight x along-track image shift ``-R v_r / V`` (SC3), m.
    radial : float64 [k]
        ``sum`` weight x radial velocity ``v_r`` (half the path's rate of length), m/s.
    face : float64 [k]
        ``sum`` weight of the lanes that are area terms (the face near its specular direction);
        the rest are edge and corner terms (Gordon's boundary form, edge currents).
    lanes : int64 [k]
        Lanes merged.
    """

    parts: np.ndarray
    shapes: np.ndarray
    order: np.ndarray
    cell: np.ndarray
    amplitude: np.ndarray
    side: np.ndarray
    weight: np.ndarray
    centre: np.ndarray
    shift: np.ndarray
    radial: np.ndarray
    face: np.ndarray
    lanes: np.ndarray

    def __len__(self) -> int:
        return len(self.order)

    @staticmethod
    def empty(depth: int, n_channels: int) -> "CatalogueRows":
        """No rows, of traced depth ``depth`` and ``n_channels`` channels."""
        i2, f = np.zeros((0, depth), np.int64), np.zeros(0)
        return CatalogueRows(parts=i2, shapes=i2.copy(), order=np.zeros(0, np.int64), cell=np.zeros((0, 3), np.int64),
                             amplitude=np.zeros((0, n_channels), np.complex128),
                             side=np.zeros((0, 2), np.complex128), weight=f, centre=np.zeros((0, 3)),
                             shift=f.copy(), radial=f.copy(), face=f.copy(), lanes=np.zeros(0, np.int64))


def merge_rows(parts: list[CatalogueRows]) -> CatalogueRows | None:
    """One :class:`CatalogueRows` of ``parts`` (launches, batches), rows of one chain and cell summed;
    None when ``parts`` is empty. Rows come out sorted by chain and cell, so the result does not
    depend on the order of ``parts`` (every sum is over the same rows, in one order)."""
    parts = [p for p in parts if p is not None]
    if not parts:
        return None
    cat = {f.name: np.concatenate([getattr(p, f.name) for p in parts]) for f in dataclasses.fields(CatalogueRows)}
    key = np.concatenate([cat["parts"], cat["cell"]], axis=1)
    if len(key) == 0:
        return CatalogueRows(**cat)
    # a stable sort of the rows first, so that every row's sum adds its members in one order
    order = np.lexsort(key.T[::-1])
    cat = {name: value[order] for name, value in cat.items()}
    key = key[order]
    _, first, group = np.unique(key, axis=0, return_index=True, return_inverse=True)
    group = group.reshape(-1)
    n = len(first)
    out = {name: cat[name][first] for name in ("parts", "shapes", "order", "cell")}
    for name in ("weight", "shift", "radial", "face", "lanes", "centre", "amplitude", "side"):
        out[name] = group_sums(cat[name], group, n).astype(cat[name].dtype)
    return CatalogueRows(**out)


def group_sums(values: np.ndarray, group: np.ndarray, n: int) -> np.ndarray:
    """Sums of ``values`` [k] or [k, c] (float or complex) over the rows of each of ``n`` groups,
    ``group`` int [k] each row's: [n] or [n, c], in the rows' order within a group."""
    if values.ndim == 2:
        return np.stack([group_sums(values[:, c], group, n) for c in range(values.shape[1])], axis=1).reshape(n, values.shape[1])
    if np.iscomplexobj(values):
        return np.bincount(group, values.real, n) + 1j * np.bincount(group, values.imag, n)
    return np.bincount(group, values, n)


def phase_centres(transmit: np.ndarray, receive: np.ndarray, unfolded: np.ndarray, last: np.ndarray,
                  length: np.ndarray) -> np.ndarray:
    """Phase centres float64 [m, 3] (m) of paths from ``transmit`` [m, 3] that last meet the scene
    at ``last`` [m, 3], unfolded to ``unfolded`` (``U_d`` of it, docs/physics.md (M3)), and reach
    ``receive`` [m, 3] after ``length`` [m] metres, eq. (SC1): from the middle ``M = (U_d(B) + B) / 2``,
    whose range history the path's follows to first order for any motion of the antennas
    (``|U - T| + |B - R| = 2 |M - T| + O(|U - B|^2 / R)`` monostatic), Newton steps along the
    gradient ``g = (P - T) / |P - T| + (P - R) / |P - R|`` of the range sum make its length exact
    (:data:`NEWTON_STEPS`). One bounce: ``B`` itself; a trihedral: its apex (``U`` reflects
    ``B`` through it); a dihedral: the foot of ``B`` on its fold."""
    p = 0.5 * (unfolded + last)
    for _ in range(NEWTON_STEPS):
        a, b = p - transmit, p - receive
        ra, rb = np.linalg.norm(a, axis=1), np.linalg.norm(b, axis=1)
        g = a / ra[:, None] + b / rb[:, None]
        step = (ra + rb - length) / np.einsum("ij,ij->i", g, g)
        p = p - step[:, None] * g
    return p


class LaneSums:
    """One order's coherent lane sums on the device, in fixed point (D7): ``n_lanes x n_channels``
    complex slots at each lane's image point (SC2), and two more, of the first channel, at the
    points ``side`` [m] along track on either side (the lane's own azimuth response there, (SC4))."""

    def __init__(self, points: np.ndarray, n_channels: int, side: np.ndarray):
        self.n_channels = n_channels
        self.points = device_array(mi.Array3f64, np.ascontiguousarray(points.T))
        self.side = [float(v) for v in side]
        self.words = AMPLITUDE.zeros(2 * len(points) * n_channels)
        self.side_words = AMPLITUDE.zeros(4 * len(points))

    def _back(self, returns, point, antenna, view, lref):
        """``exp(+j k (|P - A| + |P - R| - L_ref))`` at ``point``."""
        leg = point - antenna
        s = dr.norm(leg)
        _, dist = receive_leg(view, antenna, point, s)
        phase = returns.carrier_phase(s + dist - lref)
        return mi.Complex2f(phase.real, -phase.imag)

    def phases(self, returns, point, antenna, view, lref) -> tuple:
        """One pulse's compensations of lanes at their image points ``point`` (mi.Array3f64), eq.
        (SC2): ``exp(+j k (|c - A| + |c - R| - L_ref))`` at ``c = point``, ``point + side`` and
        ``point - side``; computed once per pulse, for every term :meth:`add` adds."""
        side = mi.Array3f64(*self.side)
        return tuple(self._back(returns, c, antenna, view, lref) for c in (point, point + side, point - side))

    def add(self, ctx: dict, phases: tuple, lane, values, active) -> None:
        """Add one pulse's terms ``values`` (one mi.Complex2f per channel) of lanes ``lane`` where
        ``active``, each times its compensation at the image point, the first channel's also at
        ``point +- side`` (``phases``: :meth:`phases`), eq. (SC2)."""
        for c, value in enumerate(values):
            z = value * phases[0]
            slot = (lane * self.n_channels + c) * 2
            AMPLITUDE.add(self.words, z.real, slot, active, mode=ctx["tally"])
            AMPLITUDE.add(self.words, z.imag, slot + 1, active, mode=ctx["tally"])
        for k in range(2):
            z = values[0] * phases[1 + k]
            slot = (lane * 2 + k) * 2
            AMPLITUDE.add(self.side_words, z.real, slot, active, mode=ctx["tally"])
            AMPLITUDE.add(self.side_words, z.imag, slot + 1, active, mode=ctx["tally"])

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """``(complex128 [n_lanes, n_channels], complex128 [n_lanes, 2])``: the sums at the image
        points and, of the first channel, at ``point + side`` and ``point - side`` (after the kernel ran)."""
        pairs = AMPLITUDE.read(self.words).reshape(-1, self.n_channels, 2)
        side = AMPLITUDE.read(self.side_words).reshape(-1, 2, 2)
        return pairs[..., 0] + 1j * pairs[..., 1], side[..., 0] + 1j * side[..., 1]


@dataclass(frozen=True)
class LaneCatalogue:
    """The acquisition's configuration of the catalogue's lane sums (host side).

    Parameters
    ----------
    shape_index : int64 [max registry id + 1]
        Each Mitsuba shape registry id's index in ``mitsuba.Scene.shapes()`` (-1: none), as
        :attr:`~sarmitsuba.tracing.mesh.patches.Surfaces.shape_id` holds them.
    velocity : float64 [n_shapes, 3]
        Each shape's velocity, m/s (zero for shapes that hold still).
    track : float64 [3]
        The track's unit direction (along which moving shapes' images shift).
    speed : float
        The platform's speed ``V``, m/s.
    step : float
        Quantisation cell of the image points (a cube), m.
    n_channels : int
    side : float
        How far along track, each side of its image point, a lane's azimuth response is sampled,
        m: half the azimuth resolution ``lambda / (2 (sin_hi - sin_lo))`` of the traced beam.
    """

    shape_index: np.ndarray
    velocity: np.ndarray
    track: np.ndarray
    speed: float
    step: float
    n_channels: int
    side: float = 0.0

    def lanes(self, surfaces, lanes, lane_chain: np.ndarray, chains, transmit: np.ndarray, receive: np.ndarray,
              times: np.ndarray | None, area: np.ndarray) -> dict:
        """What the catalogue keeps of each lane: a dict of NumPy arrays, one row per lane, for
        :class:`~sarmitsuba.tracing.integration.patch_terms.TermLanes` ``catalogue``: ``parts``,
        ``shapes`` int64 [m, D]; ``order`` [m]; ``centre`` (SC1) at mid-aperture and ``point``, the
        still point that images where the lane does (SC3), float64 [m, 3]; ``shift``, ``radial``
        [m]; ``cell`` int64 [m, 3]; ``area`` bool [m]; ``side`` float64 [3]: where the azimuth
        response is sampled, from the image point (:attr:`side` along the track).

        ``lanes``: the order's :class:`TermLanes` on ``surfaces``; ``lane_chain`` [m]: each lane's
        row of ``chains``; ``transmit``, ``receive`` float64 [m, 3]: its sub-aperture's reference
        positions; ``times`` float64 [m] s: its sub-aperture's reference time from mid-aperture
        (moving shapes stand there), or None; ``area`` bool [m]: the lane is an area term."""
        chain = np.asarray(lane_chain, np.int64)
        parts = chains.parts[chain]
        depth = chains.order[chain]
        shapes = np.where(parts >= 0, self.shape_index[surfaces.shape_id[np.maximum(parts, 0)].astype(np.int64)], -1)
        unfolded, last = np.asarray(lanes.unfolded, float), np.asarray(lanes.point, float)
        leg_in, leg_out = unfolded - transmit, last - receive
        length = np.linalg.norm(leg_in, axis=1) + np.linalg.norm(leg_out, axis=1)
        centre = phase_centres(transmit, receive, unfolded, last, length)
        w_first = self.velocity[np.maximum(shapes[:, 0], 0)] * (shapes[:, :1] >= 0)
        w_last = self.velocity[np.maximum(shapes[np.arange(len(chain)), depth], 0)]
        radial = 0.5 * (np.einsum("ij,ij->i", w_first, leg_in / np.linalg.norm(leg_in, axis=1)[:, None])
                        + np.einsum("ij,ij->i", w_last, leg_out / np.linalg.norm(leg_out, axis=1)[:, None]))
        if times is not None:           # the shapes stood here at the sub-aperture's time: back to mid-aperture
            centre = centre - 0.5 * (w_first + w_last) * times[:, None]
        shift = -np.linalg.norm(centre - transmit, axis=1) * radial / self.speed        # (SC3)
        point = centre + shift[:, None] * self.track
        cell = np.floor(point / self.step).astype(np.int64)
        return dict(parts=parts, shapes=shapes, order=depth + 1, centre=centre, point=point, shift=shift,
                    radial=radial, cell=cell, area=np.asarray(area, bool), side=self.side * self.track)


def rows_of(pending: list) -> CatalogueRows | None:
    """The :class:`CatalogueRows` of a launch's ``(LaneSums, lanes' catalogue dict)`` pairs, read
    after its kernels ran: lanes merged by chain of parts and quantisation cell; None when empty."""
    out = []
    for sums, meta in pending:
        amplitude, side = sums.read()
        weight = np.sum(np.abs(amplitude) ** 2, axis=1)
        keep = np.flatnonzero(weight > 0)
        w = weight[keep]
        out.append(CatalogueRows(parts=meta["parts"][keep], shapes=meta["shapes"][keep], order=meta["order"][keep],
                                 cell=meta["cell"][keep], amplitude=amplitude[keep], side=side[keep], weight=w,
                                 centre=meta["centre"][keep] * w[:, None], shift=meta["shift"][keep] * w,
                                 radial=meta["radial"][keep] * w, face=np.where(meta["area"][keep], w, 0.0),
                                 lanes=np.ones(len(keep), np.int64)))
    return merge_rows(out)


def catalogued(catalogue: LaneCatalogue, surfaces, lanes, lane_chain: np.ndarray, chains, launch, rx,
               area: np.ndarray):
    """``lanes`` (:class:`~sarmitsuba.tracing.integration.patch_terms.TermLanes`) with what the
    catalogue keeps of each (:meth:`LaneCatalogue.lanes`): phase centres from each sub-aperture's
    reference positions (``rx``: bistatic, the receiver's reference positions first), moving shapes
    carried back to mid-aperture (SC1)-(SC3)."""
    sub = np.asarray(lanes.sub, np.int64)
    transmit = launch.reference[sub]
    receive = transmit if rx is None else rx[0][sub]
    times = None
    if launch.pulse_time is not None and np.any(catalogue.velocity):
        first, last = launch.first, launch.first + launch.count - 1
        times = (0.5 * (launch.pulse_time[first] + launch.pulse_time[last]))[sub]
    meta = catalogue.lanes(surfaces, lanes, lane_chain, chains, transmit, receive, times, area)
    return dataclasses.replace(lanes, catalogue=meta)


def lane_catalogue(scene, params, footprint, effects) -> LaneCatalogue:
    """The :class:`LaneCatalogue` of an acquisition: the scene's shapes and their velocities
    (``effects.moving_shapes``), the track (``footprint``), the platform's speed, and a
    quantisation cell of a quarter of the slant-range resolution ``c / (2 B)``."""
    from ..mesh.patches import shape_indices
    ids = shape_indices(list(scene.shapes()))
    index = np.full(int(ids.max(initial=-1)) + 1, -1, np.int64)
    index[ids] = np.arange(len(ids))
    velocity = np.zeros((len(ids), 3))
    motion = effects.moving_shapes
    if motion is not None:
        velocity[list(motion.shapes)] = motion.velocities()
    return LaneCatalogue(shape_index=index, velocity=velocity, track=np.asarray(footprint.track, float),
                         speed=float(params.velocity), step=SPEED_OF_LIGHT / (8.0 * params.bandwidth),
                         n_channels=len(effects.channels), side=response_offset(params))


def response_offset(params) -> float:
    """Where along track a lane's azimuth response is sampled, each side of its image point [m]:
    half the azimuth resolution of the traced beam, ``lambda / (4 (sin_hi - sin_lo))``."""
    lo, hi = params.beam_sines
    return 0.25 * params.wavelength / max(hi - lo, 1e-6)
