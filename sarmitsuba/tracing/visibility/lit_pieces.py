"""What a bounce order's chains light: their regions cut into the patches' pieces, and which of
those the antenna sees, by rays aimed at the pieces' own points (docs/physics.md (M2)-(M4)).

For a batch of chains (:class:`sarmitsuba.tracing.discovery.chains.Chains`, each seen from its
sub-aperture's reference position ``A``), :func:`lit_pieces`:

1. clips each chain's last part to the half-planes of the points the antenna reaches through its
   mirrors (its *region*, exact: :func:`sarmitsuba.tracing.discovery.chains.region_lines`);
2. cuts the regions into pieces of the part's patches (:func:`sarmitsuba.tracing.mesh.piece_cuts.pieces_of`),
   within the reach of the beam;
3. aims rays at every piece's corners (pulled a hair inside the piece), along each leg of the path
   through the chain (the reflection points of :func:`sarmitsuba.tracing.discovery.chains.path_points`) and
   back to the antenna;
4. keeps a piece whose corners all see the antenna both ways (*lit*), or only on the way out
   (*transmit-lit*: where the next bounce order's chains start). A piece whose corners disagree is
   *mixed*: its exact lit part is cut by :mod:`sarmitsuba.tracing.visibility.occlusion`.
"""
from __future__ import annotations

import dataclasses

import math
from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

from ..discovery.chains import Chains, path_points, region_lines, unfolded_lines
from ..mesh.patches import UNIT_SQUARE, Pieces, Surfaces
from ..mesh.piece_cuts import cell_key, pieces_of
from ..mesh.polygons import clip, corner_slots, moments
from ..device import device_array, table_array
from ..loops import RECORDING, loop_mode
from .rays import NO_HIT, PathVisibility, Rays, lift

__all__ = ["in_leg_planes", "Blockers", "LitPieces", "lit_pieces", "SAMPLE_INSET", "corner_samples", "device_samples",
           "recheck", "RECHECKS"]

#: A piece's visibility samples sit this fraction of the patch size inside it, toward its
#: centroid: a corner on a part's edge (a wall's foot on the ground; a grid anchored at a shape's
#: vertex runs along that shape's edges) would otherwise start its ray on the neighbouring surface.
SAMPLE_INSET = 1e-3
#: Rounds of :func:`recheck`: a mixed piece's cut lit region is sampled again at its own corners
#: and centroid; occluders met there (that the piece's corners missed: another face of the same
#: building, whose shadow joins the first's) join its cut-outs and it is cut again.
RECHECKS = 2
#: An occluder whose corners all lie within this distance [m] of the plane a leg starts or ends on
#: hides nothing on that leg (:func:`in_leg_planes`): the legs start lifted by at least
#: ``visibility.SURFACE_LIFT`` (1e-4 m) off their planes.
IN_PLANE = 1e-4


#: Bits of a :class:`Blockers` pair code below its piece: ``piece << 31 | (key + 2)`` (keys
#: ``leg * n_parts + part`` stay far below 2^31; pieces may reach 2^32).
_KEY_BITS = 31


def _pair_codes(piece: np.ndarray, key: np.ndarray) -> np.ndarray:
    """int64 [k]: ``piece * 2^31 + key + 2`` of pairs (0 <= piece < 2^32, -2 <= key < 2^31 - 2): ordered as
    the pairs (by piece, then key)."""
    return (piece << _KEY_BITS) + (key + 2)


@dataclass(frozen=True)
class Blockers:
    """The occluders of a bounce order's mixed pieces, sparse: the distinct pairs
    ``(piece, key)`` sorted by piece, then key (as :func:`sarmitsuba.core.arrays.unique_pairs`
    sorts them). A key is ``leg * n_parts + part`` (``leg`` 0 .. d the transmit legs, d + 1 the
    return), or ``-2`` for an occluder that is not a mesh.

    Attributes
    ----------
    piece : int64 [m]
        Rows of the bounce order's pieces, ascending.
    key : int64 [m]
        Each pair's occluder key (ascending within a piece, unique per piece).
    """

    piece: np.ndarray
    key: np.ndarray

    @classmethod
    def empty(cls) -> "Blockers":
        """No occluders."""
        return cls(np.zeros(0, np.int64), np.zeros(0, np.int64))

    @classmethod
    def of(cls, piece: np.ndarray, key: np.ndarray) -> "Blockers":
        """The distinct pairs of ``piece`` [k] (0 .. 2^32 - 1) and ``key`` [k] (-2 .. 2^31 - 3;
        int64, any order, repeats allowed).

        Raises ValueError for a piece or key out of that range."""
        piece, key = np.asarray(piece, np.int64), np.asarray(key, np.int64)
        if len(piece) and (int(piece.min()) < 0 or int(piece.max()) >= 1 << 32 or int(key.min()) < -2
                           or int(key.max()) >= (1 << _KEY_BITS) - 2):
            raise ValueError("Blockers: pieces must lie in [0, 2^32) and keys in [-2, 2^31 - 2)")
        return cls._of_codes(np.sort(_pair_codes(piece, key)))

    @classmethod
    def _of_codes(cls, code: np.ndarray) -> "Blockers":
        """The distinct pairs of sorted pair codes int64 [k] (:func:`_pair_codes`)."""
        if len(code):
            code = code[np.concatenate([[True], code[1:] != code[:-1]])]
        return cls(code >> _KEY_BITS, (code & ((1 << _KEY_BITS) - 1)) - 2)

    def codes(self) -> np.ndarray:
        """One int64 per pair, ascending in the pairs' order (:func:`_pair_codes`)."""
        return _pair_codes(self.piece, self.key)

    def __len__(self) -> int:
        return len(self.piece)

    def union(self, other: "Blockers") -> "Blockers":
        """The pairs of both (two sorted runs: merged by one stable sort, linear)."""
        return Blockers._of_codes(np.sort(np.concatenate([self.codes(), other.codes()]), kind="stable"))

    def rows(self, ids: np.ndarray, mesh: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """The pairs of pieces ``ids`` [r] (any order): the position in ``ids`` int64 [k]
        (ascending) and the key int64 [k] of each (a piece's keys ascending); ``mesh``: only
        the mesh parts' keys (``>= 0``)."""
        ids = np.asarray(ids, np.int64)
        lo = np.searchsorted(self.piece, ids, side="left")
        size = np.searchsorted(self.piece, ids, side="right") - lo
        at = np.repeat(np.arange(len(ids)), size)
        index = np.arange(len(at)) + np.repeat(lo - (np.cumsum(size) - size), size)
        key = self.key[index]
        if mesh:
            real = key >= 0
            at, key = at[real], key[real]
        return at, key

    def mesh_only(self, n: int) -> np.ndarray:
        """bool [n]: which of ``n`` pieces have a mesh occluder and no other."""
        out = np.zeros(n, bool)
        out[self.piece[self.key >= 0]] = True
        out[self.piece[self.key == -2]] = False
        return out

    def dense(self, n: int) -> np.ndarray:
        """The pairs as a table int64 [n, c] (row ``p``: piece ``p``'s keys ascending, -1 beyond),
        the form they had before: for tests and inspection."""
        per = np.bincount(self.piece, minlength=n)
        table = np.full((n, int(per.max(initial=0))), -1, np.int64)
        slot = np.arange(len(self.piece)) - np.repeat(np.cumsum(per) - per, per)
        table[self.piece, slot] = self.key
        return table


@dataclass(frozen=True)
class LitPieces:
    """A bounce order's pieces and what the antenna sees of them.

    Attributes
    ----------
    chains : Chains
        The chains the regions belong to (row ``r`` of a region is chain ``r``).
    pieces : Pieces
        Every piece of every non-empty region (``pieces.region`` is a chain row).
    lit, transmit : bool [n]
        All corners see the antenna on every leg (lit), or on every leg but the return
        (transmit-lit: lit pieces are transmit-lit).
    mixed : bool [n]
        The corners disagree on some leg: the piece is partly shadowed.
    blockers : Blockers
        For mixed pieces, the parts that hid some corner on some leg, as ``leg * n_parts + part``
        (``leg`` 0 .. d the transmit legs, d + 1 the return; -2 an occluder that is not a mesh).
    samples : int
        The points the rays were aimed at (each along every leg of its path).
    sent : float64 [n]
        The fraction of each piece's samples the wave reaches (every leg but the return clear).
    """

    chains: Chains
    pieces: Pieces
    lit: np.ndarray
    transmit: np.ndarray
    mixed: np.ndarray
    blockers: Blockers
    samples: int = 0
    sent: np.ndarray | None = None


def corner_samples(pieces: Pieces) -> tuple[np.ndarray, np.ndarray]:
    """The visibility samples of pieces: each piece's corners pulled :data:`SAMPLE_INSET` patch
    sizes toward its centroid (off the parts' edges, which a mesh-aligned grid may follow, and
    off the neighbouring piece), piece by piece. Returns face coordinates float64 [s, 2] and the
    piece of each sample int64 [s] (ascending)."""
    p = pieces.patch
    whole = np.flatnonzero(pieces.whole)
    border = np.flatnonzero(~pieces.whole)
    rows = np.take(pieces.border, border)
    poly, count = np.take(pieces.polygon, rows, axis=0), np.take(pieces.count, rows)
    # each piece's samples in one run, pieces in order: a whole patch's 4, a border piece's corners
    size = np.full(len(pieces.whole), 4, np.int64)
    size[border] = count
    first = np.cumsum(size) - size
    out = np.empty((int(size.sum()), 2))
    points = out.view(np.complex128).reshape(-1)            # a point as one 16-byte item: faster scatters
    corners = (np.take(pieces.cell, whole, axis=0) + 0.5)[:, None, :] + (UNIT_SQUARE[None] - 0.5) * (1.0 - 2.0 * SAMPLE_INSET)
    corners *= p
    np.put(points, (np.take(first, whole)[:, None] + np.arange(4)).reshape(-1), corners.view(np.complex128).reshape(-1))
    k = poly.shape[1]
    slots = corner_slots(count, k)
    # the live corners summed in corner order (the masked sum over the middle axis, same bits)
    centroid = poly[:, 0] * slots[:, 0, None]
    for j in range(1, k):
        centroid += poly[:, j] * slots[:, j, None]
    centroid /= np.maximum(count, 1)[:, None]
    toward = centroid[:, None, :] - poly
    distance = np.sqrt(toward[..., 0] * toward[..., 0] + toward[..., 1] * toward[..., 1])
    step = np.minimum(SAMPLE_INSET * p, 0.5 * distance) / np.where(distance > 0, distance, 1.0)
    toward *= step[..., None]
    toward += poly                                          # poly + toward * step
    live = np.flatnonzero(slots)
    np.put(points, np.take(first, border)[live // k] + live % k, np.take(toward.view(np.complex128).reshape(-1), live))
    return out, np.repeat(np.arange(len(size)), size)


def device_samples(pieces: Pieces):
    """:func:`corner_samples` computed on the Dr.Jit device, one lane per sample (the same
    arithmetic in the same order: bit for bit). Returns the face coordinates as two Float64
    arrays [s] and the piece of each sample int64 [s] (ascending)."""
    f64, u32 = mi.Float64, mi.UInt32
    n = len(pieces.whole)
    size = np.full(n, 4, np.int64)
    border = np.flatnonzero(~pieces.whole)
    rows = np.take(pieces.border, border)
    size[border] = np.take(pieces.count, rows)
    owner = np.repeat(np.arange(n), size)
    if len(owner) == 0:
        return (f64(), f64()), owner
    first = np.cumsum(size) - size
    slot = device_array(u32, (np.arange(len(owner)) - np.repeat(first, size)).astype(np.uint32))
    lane = device_array(u32, owner.astype(np.uint32))
    p = pieces.patch
    # whole pieces: the patch's corners pulled in by SAMPLE_INSET (corner_samples' constant)
    square = (UNIT_SQUARE - 0.5) * (1.0 - 2.0 * SAMPLE_INSET)
    cell = np.ascontiguousarray(pieces.cell, np.float64).reshape(-1)
    cell = table_array(f64, cell)
    cx = dr.gather(f64, cell, lane * 2) + 0.5
    cy = dr.gather(f64, cell, lane * 2 + 1) + 0.5
    sx, sy = (dr.select(slot == 0, float(square[0, a]), dr.select(slot == 1, float(square[1, a]), dr.select(
        slot == 2, float(square[2, a]), f64(float(square[3, a]))))) for a in (0, 1))
    whole_x, whole_y = (cx + sx) * p, (cy + sy) * p
    is_whole = dr.gather(mi.Bool, table_array(mi.Bool, pieces.whole), lane)
    if len(rows) == 0:
        return (whole_x, whole_y), owner
    # border pieces: each corner pulled toward the mean of the live corners (the width a runtime
    # value and the corners a loop: one kernel whatever the batch's width)
    width = dr.opaque(u32, pieces.polygon.shape[1])
    poly = table_array(f64, np.ascontiguousarray(pieces.polygon, np.float64).reshape(-1))
    row = dr.gather(u32, table_array(u32, np.maximum(pieces.border, 0).astype(np.uint32)), lane)
    count = dr.gather(u32, table_array(u32, pieces.count.astype(np.uint32)), row)

    def add(j, mean_x, mean_y):
        return (j + 1, mean_x + dr.gather(f64, poly, (row * width + j) * 2),
                mean_y + dr.gather(f64, poly, (row * width + j) * 2 + 1))

    with RECORDING:                     # a symbolic loop: recorded one thread at a time
        _, mean_x, mean_y = dr.while_loop((u32(0), dr.zeros(f64, len(owner)), dr.zeros(f64, len(owner))),
                                          lambda j, *_: j < dr.select(is_whole, 0, count), add, mode=loop_mode(),
                                          label="sample centroids")
    mean_x /= dr.maximum(f64(count), 1.0)
    mean_y /= dr.maximum(f64(count), 1.0)
    px = dr.gather(f64, poly, (row * width + slot) * 2)
    py = dr.gather(f64, poly, (row * width + slot) * 2 + 1)
    tx, ty = mean_x - px, mean_y - py
    distance = dr.sqrt(tx * tx + ty * ty)
    step = dr.minimum(SAMPLE_INSET * p, 0.5 * distance) / dr.select(distance > 0, distance, 1.0)
    return (dr.select(is_whole, whole_x, tx * step + px), dr.select(is_whole, whole_y, ty * step + py)), owner


def legs(surfaces: Surfaces, chains: Chains, chain: np.ndarray, points: np.ndarray, antenna: np.ndarray,
         receiver: np.ndarray | None = None):
    """The legs of the paths to ``points`` [s, 3] through chains ``chain`` [s]: start and end
    float64 [s, D + 1, 3], lifted off their surfaces, and which legs exist bool [s, D + 1]
    (legs ``0 .. d`` on the way out, leg ``D`` the return: to ``antenna`` [s, 3], or bistatic to
    ``receiver`` [s, 3], docs/physics.md (B2), where it exists at the first bounce too)."""
    depth = chains.parts.shape[1]
    order = chains.order[chain]
    q = path_points(surfaces, chains, chain, points, antenna)
    start = np.zeros((len(chain), depth + 1, 3))
    end = np.zeros_like(start)
    exists = np.zeros((len(chain), depth + 1), bool)
    for leg in range(depth):
        live = order >= leg
        rows = np.flatnonzero(live)
        chain_rows = np.take(chain, rows)
        a = np.take(antenna if leg == 0 else q[:, leg - 1], rows, axis=0)
        b = np.take(q[:, leg], rows, axis=0)
        part_b = np.take(chains.parts[:, leg], chain_rows)
        b = lift(b, np.take(surfaces.normal, part_b, axis=0), a)
        if leg > 0:
            a = lift(a, np.take(surfaces.normal, np.take(chains.parts[:, leg - 1], chain_rows), axis=0), b)
        # every ray starts on the mesh (the first leg from its far end): its float32 origin sits
        # near the scene, where Embree's precision is the scene's, not the antenna's range's
        start[rows, leg], end[rows, leg], exists[rows, leg] = b if leg == 0 else a, a if leg == 0 else b, True
    last = chains.last[chain]
    first_bounce = order == 0
    back = antenna if receiver is None else receiver
    start[:, depth] = lift(points, np.take(surfaces.normal, last, axis=0), back)
    end[:, depth] = back
    # monostatic, at the first bounce the return is the way out
    exists[:, depth] = ~first_bounce if receiver is None else True
    return start, end, exists


def lit_pieces(surfaces: Surfaces, chains: Chains, antenna: np.ndarray, rays: Rays, visibility: PathVisibility,
               patch: float, span: tuple | None = None, receiver: np.ndarray | None = None,
               cut=pieces_of) -> LitPieces:
    """The pieces of ``chains`` [n] seen from ``antenna`` [n, 3] (each chain's reference position)
    and what the antenna sees of them, eqs. (M2)-(M4).

    Parameters
    ----------
    surfaces, chains : Surfaces, Chains
    antenna : float64 [n, 3]
    rays : Rays
        Casts for the occluders of mixed pieces.
    visibility : PathVisibility
        Casts for the legs.
    patch : float
        Patch size [m].
    span : (g float64 [n, 3], lo [n], hi [n]), optional
        The beam's reach: pieces are cut only where ``lo <= g . U_d(x) <= hi`` (the unfolded
        path's end along the track, for a straight stripmap track).
    receiver : float64 [n, 3], optional
        Bistatic: each chain's receiver reference position, the return legs' end (docs/physics.md
        (B2)); default the antenna.
    cut : callable, optional
        Cuts the regions into pieces: :func:`~sarmitsuba.tracing.mesh.piece_cuts.pieces_of` (the
        default) or a function with its signature and results.
    """
    lines, valid, returns = region_lines(surfaces, chains, antenna, receiver)
    last = chains.last
    region, count = clip(surfaces.polygon[last], np.where(valid, surfaces.n_corners[last], 0), lines)
    reach = None
    if span is not None:
        g, lo, hi = span
        reach = unfolded_lines(surfaces, chains, np.concatenate([g, -g]).reshape(2, -1, 3).transpose(1, 0, 2),
                               np.stack([-lo, hi], axis=1))
    pieces = cut(region, count, patch, reach)
    return classify(surfaces, chains, pieces, antenna, rays, visibility, returns, receiver)


def classify(surfaces: Surfaces, chains: Chains, pieces: Pieces, antenna: np.ndarray, rays: Rays,
             visibility: PathVisibility, returns: np.ndarray | None = None,
             receiver: np.ndarray | None = None) -> LitPieces:
    """What the antenna sees of ``pieces`` (their region ``r`` is chain ``r``): rays along every leg
    of the paths to their corners (:class:`sarmitsuba.tracing.visibility.rays.PathVisibility`), eq. (M4).
    ``returns`` bool [n_chains]: which chains can return at all (default all); ``receiver``
    [n_chains, 3]: bistatic, where the return legs end (B2)."""
    order = int(chains.order.max(initial=0))
    coords, owner = device_samples(pieces)
    chain = pieces.region[owner]
    bits = visibility.legs_clear(chains, chain, coords, antenna, order, receiver)
    out_mask = (1 << (order + 1)) - 1
    out_clear = (bits & out_mask) == out_mask
    both = out_clear if order == 0 and receiver is None else out_clear & ((bits >> (order + 1)) & 1).astype(bool)
    if returns is not None:
        both &= returns[chain]
    n = len(pieces)
    total = np.bincount(owner, minlength=n)
    lit_count = np.bincount(owner, weights=both, minlength=n)
    sent_count = np.bincount(owner, weights=out_clear, minlength=n)
    lit, transmit = (lit_count == total) & (total > 0), (sent_count == total) & (total > 0)
    mixed = ((lit_count > 0) & ~lit) | ((sent_count > 0) & ~transmit)
    # the mixed pieces' samples again on the host (the same points), for their occluders
    samples = len(owner)
    rows = np.flatnonzero(mixed)
    coords, local = corner_samples(pieces.select(rows))
    owner = np.take(rows, local)
    blockers = _blockers(rays, surfaces, chains, coords, owner, np.take(pieces.region, owner), antenna, mixed,
                         math.sqrt(2.0) * pieces.patch, receiver)
    return LitPieces(chains=chains, pieces=pieces, lit=lit, transmit=transmit, mixed=mixed, blockers=blockers,
                     samples=samples, sent=sent_count / np.maximum(total, 1))


def _blockers(rays: Rays, surfaces: Surfaces, chains: Chains, coords, owner, chain, antenna, mixed,
              reach: float, receiver=None) -> Blockers:
    """For each mixed piece, the parts that hid its samples (``leg * n_parts + part``, unique per
    piece; ``-2`` for an occluder that is not a mesh; :class:`Blockers`), by the NumPy
    legs of :func:`legs` cast again with :meth:`Rays.first_hit`. An occluder stands for its whole
    face and the parts of its shape it meets at a corner (:attr:`Rays.occluder_partners`): they
    join where their bounding spheres come within ``reach`` [m] (the piece's size) of the leg that
    met it."""
    n = len(mixed)
    rows = np.flatnonzero(mixed[owner])
    if len(rows) == 0:
        return Blockers.empty()
    chain_rows = np.take(chain, rows)
    points = surfaces.to_world(np.take(chains.last, chain_rows), np.take(coords, rows, axis=0))
    start, end, exists = legs(surfaces, chains, chain_rows, points, np.take(antenna, chain_rows, axis=0),
                              None if receiver is None else np.take(receiver, chain_rows, axis=0))
    # the legs that exist, as rows of the flat [s * (D + 1), 3] tables (row gathers by np.take)
    slot = np.flatnonzero(exists)
    sample, leg = np.divmod(slot, exists.shape[1])
    start, end = np.take(start.reshape(-1, 3), slot, axis=0), np.take(end.reshape(-1, 3), slot, axis=0)
    part, _ = rays.first_hit(start, end)
    found = np.flatnonzero(part != NO_HIT)
    key = np.where(part >= 0, leg * surfaces.n_parts + part, -2)[found]
    piece = np.take(owner, np.take(rows, np.take(sample, found)))
    # an occluder is the whole face it belongs to and the faces next to it: they cast the rest of
    # the shadow, whichever of them the samples met (a wall meshed as many triangles; a box's roof
    # and the wall that form the tip of its shadow)
    via = np.flatnonzero(key >= 0)
    hit_part = key[via] % surfaces.n_parts
    partner_start, partner_parts = rays.occluder_partners
    size = partner_start[hit_part + 1] - partner_start[hit_part]
    rep = np.repeat(via, size)
    local = np.arange(int(size.sum())) - np.repeat(np.cumsum(size) - size, size)
    extra = partner_parts[np.repeat(partner_start[hit_part], size) + local]
    met = np.take(found, rep)
    a, b = np.take(start, met, axis=0), np.take(end, met, axis=0)
    centre, radius = rays.part_sphere
    centre = np.take(centre, extra, axis=0)
    ab = b - a
    t = np.clip(np.einsum("mi,mi->m", centre - a, ab) / np.maximum(np.einsum("mi,mi->m", ab, ab), 1e-300), 0, 1)
    gap = a + t[:, None] * ab - centre
    near = np.sqrt(np.add.reduce(gap * gap, axis=1)) <= np.take(radius, extra) + reach    # as linalg.norm
    piece = np.concatenate([piece, piece[rep[near]]])
    key = np.concatenate([key, (key[rep[near]] // surfaces.n_parts) * surfaces.n_parts + extra[near]])
    piece_chain = np.zeros(n, np.int64)
    piece_chain[owner] = chain
    # whether an occluder lies in a leg's own planes depends on the pair alone: asked once a pair
    pairs = Blockers.of(piece, key)
    keep = ~in_leg_planes(surfaces, chains, piece_chain[pairs.piece], pairs.key)
    return Blockers(pairs.piece[keep], pairs.key[keep])


def in_leg_planes(surfaces: Surfaces, chains: Chains, chain: np.ndarray, key: np.ndarray) -> np.ndarray:
    """bool [k]: whether occluder ``key`` [k] (``leg * n_parts + part``, as in
    :attr:`LitPieces.blockers`; negative: never) of a path through chain ``chain`` [k] lies in the
    plane of a part its leg starts or ends on, to :data:`IN_PLANE` m: a leg leaves or meets that
    plane at its end and crosses it nowhere else, so such a part hides nothing on it, and its
    shadow there is degenerate (crossed at the point itself), which rounding turns into all or
    nothing. A partner of an occluder is often such a part: the face itself, or a window the leg
    starts from (docs/physics.md (M4))."""
    depth = chains.parts.shape[1]
    real = key >= 0
    leg = np.where(real, key // surfaces.n_parts, 0)
    part = np.where(real, key % surfaces.n_parts, 0)
    order = chains.order[chain]
    back = leg == depth
    end = np.where(back, -1, chains.parts[chain, np.minimum(leg, depth - 1)])
    start = np.where(back, chains.last[chain], np.where(leg >= 1, chains.parts[chain, np.maximum(leg - 1, 0)], -1))
    end = np.where(~back & (leg > order), -1, end)
    out = np.zeros(len(chain), bool)
    for plane in (start, end):
        # the answer depends on the (plane, part) pair alone: asked once a pair
        rows = np.flatnonzero(real & (plane >= 0))
        pairs, at = np.unique(plane[rows] * surfaces.n_parts + part[rows], return_inverse=True)
        out[rows] |= _part_in_plane(surfaces, pairs % surfaces.n_parts, pairs // surfaces.n_parts)[at.reshape(-1)]
    return out


def _part_in_plane(surfaces: Surfaces, part: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """bool [k]: every corner of part ``part`` [k] lies within :data:`IN_PLANE` of part ``plane``'s
    plane [k]."""
    corners = np.take(surfaces.world_polygon, part, axis=0)
    slots = np.arange(corners.shape[1])[None, :] < surfaces.n_corners[part][:, None]
    distance = np.abs(np.einsum("kvi,ki->kv", corners, surfaces.normal[plane]) - surfaces.offset[plane][:, None])
    return np.all(np.where(slots, distance, 0.0) <= IN_PLANE, axis=1)


def recheck(surfaces: Surfaces, lit: LitPieces, clipped, antenna: np.ndarray, rays: Rays,
            visibility: PathVisibility, receiver: np.ndarray | None = None) -> tuple[Blockers, np.ndarray]:
    """The mixed pieces' blockers with the occluders met from points of their cut lit regions
    (``clipped``, :class:`sarmitsuba.tracing.visibility.occlusion.ClippedPieces`): each region's corners and
    edge midpoints pulled :data:`SAMPLE_INSET` patch sizes toward its centroid, and the centroid
    (``antenna`` [n_chains, 3]; bistatic, ``receiver`` [n_chains, 3] where the return legs end). Returns the new blockers (:class:`Blockers`, as :attr:`LitPieces.blockers`) and the rows
    of ``lit.pieces`` that gained an occluder (int64, ascending)."""
    n = len(lit.mixed)
    if len(clipped) == 0:
        return lit.blockers, np.zeros(0, np.int64)
    centre = np.concatenate([clipped.centroid[clipped.owner]] * 2)
    points = np.concatenate([clipped.start, 0.5 * (clipped.start + clipped.end)])
    toward = centre - points
    distance = np.linalg.norm(toward, axis=1)
    step = np.minimum(SAMPLE_INSET * lit.pieces.patch, 0.5 * distance) / np.where(distance > 0, distance, 1.0)
    coords = np.concatenate([points + toward * step[:, None], clipped.centroid])
    piece = clipped.piece[np.concatenate([clipped.owner, clipped.owner, np.arange(len(clipped))])]
    order = np.argsort(piece, kind="stable")
    coords, piece = coords[order], piece[order]
    chain = lit.pieces.region[piece]
    # the Dr.Jit legs first: only the samples some leg hides are cast again for their occluders
    order = int(lit.chains.order.max(initial=0))
    bits = visibility.legs_clear(lit.chains, chain, coords, antenna, order, receiver)
    out_mask = (1 << (order + 1)) - 1
    clear = (bits & out_mask) == out_mask
    if order > 0 or receiver is not None:
        clear &= ((bits >> (order + 1)) & 1).astype(bool)
    hidden = ~clear
    if not np.any(hidden):
        return lit.blockers, np.zeros(0, np.int64)
    coords, piece, chain = coords[hidden], piece[hidden], chain[hidden]
    mixed = np.zeros(n, bool)
    mixed[clipped.piece] = True
    found = _blockers(rays, surfaces, lit.chains, coords, piece, chain, antenna, mixed, math.sqrt(2.0) * lit.pieces.patch,
                      receiver)
    old = lit.blockers
    real = found.key >= 0                   # a non-mesh occluder met here leaves the piece as it is
    new = Blockers(found.piece[real], found.key[real])
    code, old_code = new.codes(), old.codes()
    at = np.minimum(np.searchsorted(old_code, code), max(len(old_code) - 1, 0))
    known = (old_code[at] == code) if len(old_code) else np.zeros(len(code), bool)
    if np.all(known):
        return old, np.zeros(0, np.int64)
    return old.union(new), np.unique(new.piece[~known])


def spread_occluders(lit: LitPieces, clipped) -> tuple[LitPieces, np.ndarray]:
    """``lit`` with the wholly lit or wholly dark pieces that a cut piece's shadow edges run into
    made mixed, with that piece's occluders: a shadow's edge or tip that crosses a patch line (or
    corner) into the next piece between its samples is cut there too, eq. (M4).

    ``clipped`` (:class:`sarmitsuba.tracing.visibility.occlusion.ClippedPieces`) holds the cut pieces; a
    segment of a cut boundary that ends on its patch's side line without running along it crosses
    into the patch across that line (both, and the diagonal one, at a corner). Returns the new
    ``lit`` and the rows made mixed (int64): the caller returns those that no occluder cuts to
    what they were."""
    pieces = lit.pieces
    none = (lit, np.zeros(0, np.int64))
    if len(clipped) == 0:
        return none
    row = clipped.piece[clipped.owner]
    low = pieces.cell[row] * pieces.patch
    tol = 1e-9 * pieces.patch
    def sides(point):
        return [np.where(np.abs(point[:, axis] - low[:, axis]) < tol, -1,
                         np.where(np.abs(point[:, axis] - low[:, axis] - pieces.patch) < tol, 1, 0)) for axis in (0, 1)]

    start_side, end_side = sides(clipped.start), sides(clipped.end)
    # a segment along the patch's own side line is the piece's edge, not a shadow's
    inner = ~np.any([(a != 0) & (a == b) for a, b in zip(start_side, end_side)], axis=0)
    sources, steps = [], []
    for side in (start_side, end_side):
        side = [np.where(inner, v, 0) for v in side]
        for dx, dy in ((1, 0), (0, 1), (1, 1)):
            step = np.stack([side[0] * dx, side[1] * dy], axis=1)
            live = np.any(step != 0, axis=1) & ((dx == 0) | (side[0] != 0)) & ((dy == 0) | (side[1] != 0))
            sources.append(row[live])
            steps.append(step[live])
    source, step = np.concatenate(sources), np.concatenate(steps)
    if len(source) == 0:
        return none
    keys = cell_key(pieces.region, pieces.cell)
    order = np.argsort(keys, kind="stable")
    sorted_keys = keys[order]
    wanted = cell_key(pieces.region[source], pieces.cell[source] + step)
    at = np.minimum(np.searchsorted(sorted_keys, wanted), len(keys) - 1)
    found = sorted_keys[at] == wanted
    source, target = source[found], order[at[found]]
    keep = ~lit.mixed[target]
    source, target = source[keep], target[keep]
    if len(target) == 0:
        return lit, np.zeros(0, np.int64)
    at, key = lit.blockers.rows(source, mesh=True)
    new = Blockers.of(target[at], key)
    rows = np.unique(new.piece)
    if len(rows) == 0:
        return lit, np.zeros(0, np.int64)
    old = lit.blockers
    at = np.minimum(np.searchsorted(rows, old.piece), len(rows) - 1)
    stay = rows[at] != old.piece                    # the targets' occluders are their sources'
    blockers = Blockers(old.piece[stay], old.key[stay]).union(new)
    lit_now, mixed_now = lit.lit.copy(), lit.mixed.copy()
    lit_now[rows], mixed_now[rows] = False, True
    return dataclasses.replace(lit, lit=lit_now, mixed=mixed_now, blockers=blockers), rows
