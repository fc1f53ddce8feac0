"""Derivatives of a trace with respect to a shape's geometry: its pose or its vertices (docs/physics.md
(AD4)).

The mesh tracer (M1)-(M8) turns the geometry into lanes on the host (NumPy, float64: lit pieces,
their boundary segments, chains, rates) and the kernels evaluate every lane's terms for every
pulse in Dr.Jit. With the lit regions' topology held (the same pieces, cut by the same lines,
the same visibility), every lane input is a smooth function of the vertices, and every deposited
term a smooth function of the lane inputs. :class:`MovedTracer` takes the two factors apart:

* the lane inputs' tangent ``d data / dp``: the host geometry run again with the shape's vertices
  moved by ``h`` (1 um) along the parameter's displacement field, in float64 (the Mitsuba
  scene stays: its visibility rays decide nothing differently at a micrometre), each moved
  lane paired with its own (:mod:`.lane_pairs`) and differenced, ``(x(p + h) - x(p)) / h``, in
  float64 before the upload rounds it. The lanes are piecewise rational in the vertices, so the
  difference is exact to ``O(h)`` relative to the faces' size. Every discrete entry (lane
  kinds, pieces, rows) must agree between the two runs; otherwise the parameter moves a
  boundary of visibility, the step is taken to ``-h``, and :class:`GeometryChange` says so
  where that changes it too;
* the terms' dependence on the lane inputs: Dr.Jit's automatic differentiation through the
  kernels, exactly, forward (:class:`~sarmitsuba.tracing.derivatives.tangents.TangentSums`) or reverse
  (:class:`~sarmitsuba.tracing.derivatives.tangents.AdjointSums`).

So the phase, ``k`` times the path length's change, which a finite difference of whole renders
resolves only with steps far below a wavelength, is differentiated exactly; only the geometry,
whose scale is metres, is differenced. The moved runs move the shadow edges and mirrored windows
too, so the boundaries' motion is in the tangent; what this leaves out is a change of the
topology, which :class:`GeometryChange` reports (AD4).
"""
from __future__ import annotations

import dataclasses

import drjit as dr
import mitsuba as mi
import numpy as np

from ...core.radar import ParameterError
from ..mesh.facets import mesh_parts, scene_meshes, set_vertices
from .lane_pairs import GeometryChange, align_scatterers, align_terms, tangent_lanes, topology_change
from ..deposit.replay import carry
from ..loops import RECORDING, float64_lanes
from ..mesh.patches import moved_surfaces

#: How far a moved lane may lie from the lane it is paired with, in steps ``h`` times the largest
#: vertex displacement: a lane's point moves with the vertices' (a shadow's tip more, by the
#: ratio of the occluder's distances).
ALIGN_TOLERANCE = 50.0

#: The smooth shapes' patch grids are shifted by this many patches along their frame's axes while
#: geometric derivatives are taken: a mesh's own lines through its frame's origin (a trihedral's
#: mirrored edges through its apex) then miss the grid's corners, where the pieces' topology
#: would hang on rounding.
GRID_OFFSET = np.array([0.3819660, 0.2763932, 0.2360680])

__all__ = ["GeometryMove", "GeometryChange", "moved_surfaces", "move_scene", "exact_meshes", "MovedTracer"]


@dataclasses.dataclass(frozen=True)
class GeometryMove:
    """A geometric parameter as the tracer sees it: ``shape`` the shape's index in
    ``scene.shapes()``, ``field`` float64 [n_v, 3] each vertex's displacement per unit of the
    parameter (m per unit, in the loaded scene's frame), ``step`` the host's difference step
    ``h`` (units of the parameter)."""

    shape: int
    field: np.ndarray
    step: float


#: The float64 vertices :func:`move_scene` gave each scene (by ``id``): the host geometry of the
#: derivatives' tracers starts from them, not from the float32 buffer the rays see.
_EXACT: dict = {}


def move_scene(scene, vertices: dict) -> None:
    """Move the Mitsuba scene's meshes: shape ``k`` (its index in ``scene.shapes()``) to the
    vertices ``vertices[k]`` (float [n_v, 3], m; the buffer rewritten in float32 and the scene's
    acceleration structure rebuilt). The float64 vertices are kept for the geometric
    derivatives' host geometry (:func:`exact_meshes`): a move of a micro-radian would otherwise
    be rounded to the float32 buffer's metre-scale steps of 6e-8 m."""
    _EXACT[id(scene)] = {k: np.asarray(v, np.float64) for k, v in vertices.items()}
    set_vertices(scene, vertices)


def exact_meshes(scene) -> list:
    """:func:`~sarmitsuba.tracing.mesh.facets.scene_meshes` of ``scene`` with the float64 vertices
    of the shapes :func:`move_scene` moved."""
    meshes = scene_meshes(scene)
    for k, v in _EXACT.get(id(scene), {}).items():
        meshes[k] = (v, meshes[k][1])
    return meshes


def _bent(meshes: list, shape: int, field: np.ndarray) -> bool:
    """Whether the displacement ``field`` [n_v, 3] of ``shape``'s vertices bends a face (moves a
    vertex off its face's plane): tried with a move of a thousandth of the shape's size, far
    beyond the coplanarity tolerance of :func:`~sarmitsuba.tracing.mesh.facets.mesh_parts`."""
    v = meshes[shape][0]
    size = float(np.ptp(v, axis=0).max()) if len(v) else 0.0
    largest = float(np.abs(field).max(initial=0.0))
    if size == 0.0 or largest == 0.0:
        return False
    moved = v + (1e-3 * size / largest) * field
    a = mesh_parts(meshes)
    b = mesh_parts([(moved, m[1]) if k == shape else m for k, m in enumerate(meshes)])
    return not (np.array_equal(a.triangle_part, b.triangle_part) and np.array_equal(a.n_vertices, b.n_vertices))


class _Recording:
    """Stands in for a moved tracer's term and scatterer kernels: keeps the lanes they are given
    (and the piece table), in call order, without depositing."""

    def __init__(self):
        self.uploads, self.depths = [], []

    def terms(self, ctx, lanes, pieces, depth: int) -> None:
        self.uploads.append((lanes, pieces) if len(lanes) else None)
        self.depths.append(depth)

    def clutter(self, ctx, lanes, depth: int) -> None:
        self.uploads.append((lanes,) if len(lanes) else None)
        self.depths.append(depth)

    @classmethod
    def of(cls, tracer, ctx, launch):
        """A recording of ``tracer`` on ``launch`` and its counters."""
        record = cls()
        return record, record.run(tracer, ctx, launch)

    def run(self, tracer, ctx, launch):
        """Run ``tracer`` on ``launch`` with its term and scatterer kernels replaced by this
        recording's; its counters."""
        terms, clutter = tracer.terms, tracer.clutter
        tracer.terms = self.terms
        tracer.clutter = self.clutter if clutter is not None else None
        try:
            return tracer(ctx, launch)
        finally:
            tracer.terms, tracer.clutter = terms, clutter


def _components(x):
    """The flat Dr.Jit arrays of a (nested) Dr.Jit array."""
    if dr.depth_v(x) > 1:
        for i in range(len(x)):
            yield from _components(x[i])
    else:
        yield x


def _float_leaves(x, path=()):
    """``(path, array)`` of every floating-point Dr.Jit array in ``x`` (a dict, list, tuple,
    dataclass or Dr.Jit array): the entries an upload's kernels read that can carry a tangent."""
    if isinstance(x, dict):
        for key, value in x.items():
            yield from _float_leaves(value, path + (key,))
    elif isinstance(x, (list, tuple)):
        for i, value in enumerate(x):
            yield from _float_leaves(value, path + (i,))
    elif dataclasses.is_dataclass(x) and not isinstance(x, type):
        for field in dataclasses.fields(x):
            yield from _float_leaves(getattr(x, field.name), path + (field.name,))
    elif dr.is_array_v(x) and dr.is_float_v(x):
        yield path, x


def _at(x, path):
    """The entry of ``x`` at ``path`` (:func:`_float_leaves`), None where there is none."""
    for key in path:
        if isinstance(x, dict):
            x = x.get(key)
        elif isinstance(x, (list, tuple)):
            x = x[key] if key < len(x) else None
        else:
            x = getattr(x, key, None)
        if x is None:
            return None
    return x


def _put(x, path, value) -> None:
    """Set the entry of ``x`` at ``path`` (:func:`_float_leaves`) to ``value``."""
    for key in path[:-1]:
        x = x[key] if isinstance(x, (dict, list, tuple)) else getattr(x, key)
    if isinstance(x, (dict, list)):
        x[path[-1]] = value
    else:
        setattr(x, path[-1], value)


def _difference(up, here, step: float):
    """``(up - here) / step`` of a Dr.Jit array, or of every such array of a dataclass (the
    Jones matrix), detached; None stays None."""
    if up is None:
        return None
    if dataclasses.is_dataclass(up) and not isinstance(up, type):
        return dataclasses.replace(up, **{f.name: _difference(getattr(up, f.name), getattr(here, f.name), step)
                                          for f in dataclasses.fields(up)})
    return dr.detach(up - here) * (1.0 / step)


#: Stands for a tangent entry that is zero throughout (kept until the reverse pass without its array).
ZERO = "zero"


def _zeros_dropped(tangent: dict) -> dict:
    """``tangent`` with each entry that is a Dr.Jit array of zeros replaced by :data:`ZERO`: most
    of a height's tangents are (the normals, a ground's points), and they would be held, per
    launch and parameter, until the reverse pass. One evaluation for all entries."""
    keys = [key for key, value in tangent.items() if dr.is_array_v(value) and dr.is_float_v(value)]
    largest = [dr.max(dr.abs(mi.Float64(c)) if dr.width(c) else mi.Float64(0.0)) for key in keys
               for c in _components(tangent[key])]
    dr.eval(*largest)
    values = iter([float(x.numpy().ravel()[0]) for x in largest])
    for key in keys:
        if not any([next(values) for _ in _components(tangent[key])]):
            tangent[key] = ZERO
    return tangent


#: The key of a scatterer upload's tangent that holds which of its rows the move moves (bool [n], NumPy).
ROWS = "moved rows"


def _moving_rows(main, plus) -> np.ndarray:
    """bool [n]: the rows of a lanes dataclass (float64 NumPy fields) where any floating-point
    field of ``plus`` (its moved and paired copy) differs from ``main``'s: the rows whose tangent
    is not zero (their points, normals or earlier bounces' windows move)."""
    moving = np.zeros(len(main), bool)
    for field in dataclasses.fields(main):
        a, p = getattr(main, field.name), getattr(plus, field.name)
        if isinstance(a, np.ndarray) and a.dtype.kind == "f" and a.ndim and len(a) == len(main):
            moving |= np.any((p != a).reshape(len(a), -1), axis=1)
    return moving


def _rows_of(lanes, rows: np.ndarray):
    """The lanes dataclass with only ``rows`` (int [m]) of its per-lane fields."""
    n = len(lanes)
    return dataclasses.replace(lanes, **{f.name: np.take(getattr(lanes, f.name), rows, axis=0)
                                         for f in dataclasses.fields(lanes)
                                         if isinstance(getattr(lanes, f.name), np.ndarray)
                                         and getattr(lanes, f.name).ndim and len(getattr(lanes, f.name)) == n})


def _gathered(x, rows: np.ndarray, n: int):
    """A tangent (dict, list, dataclass or Dr.Jit array) with only ``rows`` of its per-lane
    (width ``n``) arrays; other entries (:data:`ZERO`, None, width 1) as they are."""
    if isinstance(x, dict):
        return {key: _gathered(value, rows, n) for key, value in x.items() if key != ROWS}
    if isinstance(x, list):
        return [_gathered(value, rows, n) for value in x]
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return dataclasses.replace(x, **{f.name: _gathered(getattr(x, f.name), rows, n) for f in dataclasses.fields(x)})
    if dr.is_array_v(x) and dr.width(x) == n and n > 1:
        return dr.gather(type(x), x, mi.UInt32(np.asarray(rows, np.uint32)))
    return x


def _launch_key(launch) -> tuple:
    """What tells a launch apart from the trace's others: its sub-apertures' pulses and references."""
    return launch.first.tobytes(), launch.count.tobytes(), np.asarray(launch.reference).tobytes()


class MovedTracer:
    """The kernel's mesh tracer with the lane inputs made differentiable leaves carrying their
    tangents along each of ``moves`` (a list of :class:`GeometryMove`).

    Per launch: the tracer itself runs the host geometry and records the lanes it would deposit;
    then, one move at a time, a moved tracer runs the geometry with the shape's vertices moved by
    ``h`` along the move, and each of its uploads is paired with the tracer's own
    (:func:`~.lane_pairs.align_terms`) and differenced, ``(x(p + h) - x(p)) / h``, the tangent
    (:meth:`_tangent`). The recorded uploads are then deposited: as leaves (``dr.enable_grad``)
    whose tangents are kept in :attr:`tangents` (leaf -> one tangent per move), or, while
    :attr:`kept` is a dict (the values pass of :func:`sarmitsuba.gradients`), as plain values,
    each launch's uploads and tangents kept there. :attr:`replay` set to those makes the next
    launches deposit the kept uploads as leaves without running any geometry: one trace of the
    geometry for the values and the gradient. Forward mode (:attr:`forward`) sets each leaf's
    tangent on it; reverse mode calls :meth:`accumulate` after the launch, which adds
    ``<dL/d leaf, tangent>`` to :attr:`totals`.
    """

    def __init__(self, kernel, moves):
        self.kernel, self.moves, self.main = kernel, list(moves), kernel.mesh
        base = exact_meshes(kernel.scene)
        for move in self.moves:
            if move.field.shape != base[move.shape][0].shape:
                raise ParameterError(f"displacement field shape {move.field.shape}: the shape has "
                                     f"{base[move.shape][0].shape[0]} vertices")
        # a move that bends a face splits its shape's faces into triangles, in both geometries
        separate = sorted({m.shape for m in self.moves if _bent(base, m.shape, m.field)})
        offset = GRID_OFFSET * kernel.fp.patch_size
        exact = dict(_EXACT.get(id(kernel.scene), {}))
        kernel.mesh = self.main = kernel.mesh_tracer(*moved_surfaces(kernel.scene, kernel.material_table, exact,
                                                                      separate, offset))
        self._geometry = base, separate, offset, exact
        # interior segments cancel as in a render (stable neighbours across a patch line, by
        # cells; shared edges and junctions, within a tolerance): the same decisions a step away
        self.main.simplify = True
        #: Each move's moved tracers by step (``+h``, and ``-h`` once a ``+h`` step has changed the topology).
        self.tracers = [{} for _ in self.moves]
        #: Per move: None, or what changed the topology within a step (:meth:`_differenced`).
        self.changes: list = [None] * len(self.moves)
        #: Per move: whether neither step kept the topology in some launch (its derivative undefined).
        self.undefined = np.zeros(len(self.moves), bool)
        self.tangents: list = []
        #: ``(leaf, entry)`` of the uploads' entries that carried derivatives of their own (:meth:`_leaves`).
        self.links: list = []
        self.totals = np.zeros(len(self.moves))
        #: Forward mode: each leaf's tangent (one move) is set on it when it is made.
        self.forward = False
        #: Whether material parameters are differentiated too: the reverse pass then replays every
        #: lane (each carries their gradient), not only the scatterers some move moves.
        self.materials = True
        #: A dict while the values are traced: each launch's ``(uploads, counters)``, by launch.
        self.kept: dict | None = None
        #: What :attr:`kept` held, to deposit as leaves launch by launch instead of tracing.
        self.replay: dict | None = None
        self.surfaces = self.main.surfaces

    def __call__(self, ctx: dict, launch) -> dict:
        if self.replay is not None:
            uploads, stats = self.replay.pop(_launch_key(launch))
            self._deposit(ctx, uploads, True, replayed=True)
            return stats
        with float64_lanes():
            uploads, stats = self._traced(ctx, launch)
        if self.kept is not None:
            self.kept[_launch_key(launch)] = (uploads, stats)
        self._deposit(ctx, uploads, self.kept is None)
        return stats

    def _traced(self, ctx: dict, launch):
        """The launch's geometry, the tracer's and then each move's at ``+h``, each move's paired
        and differenced before the next is run (one moved geometry held at a time): the tracer's
        uploads ``[(kernel, args, depth, [tangent per move])]`` and its counters. On one thread:
        run on two, the moved geometries made the gradient at urban's default pulse count 10 %
        faster and its peak memory 45 % larger (3.9 times the render's)."""
        uploads, stats = self._uploads(*_Recording.of(self.main, ctx, launch))
        for j, move in enumerate(self.moves):
            moved, _ = _Recording.of(self._moved_tracer(j, move.step), ctx, launch)
            for upload, tangent in zip(uploads, self._differenced(j, ctx, launch, uploads, moved)):
                upload[3].append(tangent)
        return uploads, stats

    def _uploads(self, own, stats):
        """The tracer's recorded uploads as ``(kernel, args, depth, [])`` and its counters."""
        kinds = {"terms": self.main.terms, "clutter": self.main.clutter}
        return [(kinds["terms" if x is None or len(x) == 2 else "clutter"], x, depth, [])
                for x, depth in zip(own.uploads, own.depths)], stats

    def _moved_tracer(self, j: int, step: float):
        """Move ``j``'s tracer with the shape's vertices moved by ``step`` along it (built once)."""
        if step not in self.tracers[j]:
            base, separate, offset, exact = self._geometry
            move, kernel = self.moves[j], self.kernel
            tracer = kernel.mesh_tracer(*moved_surfaces(kernel.scene, kernel.material_table,
                                                        {**exact, move.shape: base[move.shape][0] + step * move.field},
                                                        separate, offset))
            tracer.simplify = True
            self.tracers[j][step] = tracer
        return self.tracers[j][step]

    def _differenced(self, j: int, ctx: dict, launch, uploads: list, moved) -> list:
        """Move ``j``'s tangent of each upload (None for an empty one): the forward difference
        from ``moved`` (the recording at ``+h``), or, where the step ``+h`` changes the lit regions'
        topology, the backward one from ``-h`` (:attr:`changes` says so); where both do, zero
        tangents and :attr:`undefined` set."""
        move, problems = self.moves[j], []
        for step in (move.step, -move.step):
            if step < 0:
                moved, _ = _Recording.of(self._moved_tracer(j, step), ctx, launch)
            try:
                if len(moved.uploads) != len(uploads):
                    raise topology_change("bounce orders reached")
                out = []
                for (kernel, args, depth, _), other in zip(uploads, moved.uploads):
                    if (args is None) != (other is None):
                        raise topology_change("lit pieces")
                    out.append(None if args is None else self._tangent(kernel, args, other, move, depth, step))
            except GeometryChange as change:
                problems.append(str(change))
                continue
            if problems and self.changes[j] is None:
                self.changes[j] = (f"a step of +{move.step:g} changes the topology ({problems[0]}); the derivative "
                                   f"is the one-sided one from -{move.step:g}")
            return out
        self.undefined[j] = True
        self.changes[j] = f"steps of +-{move.step:g} both change the topology ({problems[0]}): no derivative"
        return [None if args is None else {} for _, args, _, _ in uploads]

    def _deposit(self, ctx: dict, uploads: list, leaves: bool, replayed: bool = False) -> None:
        """Deposit the recorded uploads, their entries made leaves with their tangents (or plain
        values). ``replayed`` (the reverse pass, whose values nobody reads) without
        :attr:`materials`: of the scatterer uploads only the rows some move moves."""
        for kernel, args, depth, tangents in uploads:
            if args is None:
                continue
            if replayed and not self.materials and len(args) == 1:
                masks = [t.get(ROWS) for t in tangents]
                if masks and all(m is not None for m in masks):
                    rows = np.flatnonzero(np.logical_or.reduce(masks))
                    if len(rows) == 0:
                        continue
                    args, tangents = (_rows_of(args[0], rows),), [_gathered(t, rows, len(args[0])) for t in tangents]
            data = kernel.upload(*args, depth)
            if leaves:
                self._leaves(data, tangents)
            with RECORDING:
                kernel.deposit(ctx, data, args[0], depth)
        dr.eval()
        dr.sync_thread()

    @staticmethod
    def _tangent(kernel, args, moved, move: GeometryMove, depth: int, step: float) -> dict:
        """The upload's tangent along ``move``: the paired lanes' difference over ``step`` (float64
        on the host, :func:`~.lane_pairs.tangent_lanes`) uploaded as the lanes are, and the
        earlier bounces' factors (``gamma``, the Jones matrices) differenced on the device."""
        tolerance = ALIGN_TOLERANCE * move.step * float(np.abs(move.field).max(initial=0.0)) + 1e-9
        if len(args) == 2:
            plus = align_terms(*args, *moved, tolerance)
        else:
            plus = (align_scatterers(args[0], moved[0], tolerance),)
        tangent = kernel.upload(*(tangent_lanes(a, p, step) for a, p in zip(args, plus)), depth)
        # kept until the reverse pass: its floating-point entries only (the lanes' kinds, rows and
        # flags are the tracer's own), and which scatterers the move moves
        tangent = {key: value for key, value in tangent.items() if any(True for _ in _float_leaves(value))}
        if len(args) == 1:
            tangent[ROWS] = _moving_rows(args[0], plus[0])
        if depth == 0:                       # no earlier bounce: its factors are constants
            for key in ("gamma", "jones", "edge_jones"):
                if tangent.get(key) is not None:
                    tangent[key] = None
            return _zeros_dropped(tangent)
        up, here = kernel.upload(*plus, depth), kernel.upload(*args, depth)
        for key in ("gamma", "jones", "edge_jones"):
            if key in tangent:
                tangent[key] = _difference(up[key], here[key], step)
        return _zeros_dropped(tangent)

    def _leaves(self, data: dict, tangents: list) -> None:
        """Every floating-point entry of ``data`` that has a tangent along some move is replaced by
        a leaf of its value (detached, ``dr.enable_grad``), kept with its tangents in
        :attr:`tangents`; an entry that carried derivatives of its own (an earlier bounce's
        reflection factor, read from the material tables) is kept beside its leaf in
        :attr:`links`, so that what the leaf receives reaches the tables too. Which entries are
        leaves is decided by the kind of upload, never by the tangents' values: a tangent that
        happens to be zero (a normal that a height change keeps, to rounding) would otherwise
        change the backward pass's graph, and Dr.Jit would compile its kernels again at every
        new geometry."""
        for path, entry in list(_float_leaves(data)):
            along = [_at(t, path) for t in tangents]
            if all(t is None for t in along):
                continue
            along = [None if isinstance(t, str) else t for t in along]       # ZERO: nothing to add
            leaf = dr.detach(entry)
            dr.enable_grad(leaf)
            _put(data, path, leaf)
            if dr.grad_enabled(entry) and not self.forward:
                self.links.append((leaf, entry))
            if self.forward:                     # forward mode (one move): the tangent, set once
                dr.set_grad(leaf, type(leaf)(0) if along[0] is None else along[0])
            self.tangents.append((leaf, along))

    def accumulate(self) -> None:
        """Reverse mode, after the launch's replay: what the linked leaves received is carried to
        the material tables (:func:`~sarmitsuba.tracing.deposit.replay.carry`), and
        ``dL/dp_j += <dL/d leaf, tangent_j>`` over the launch's leaves, summed on the device and
        read once; then forget them."""
        carry(self.links)
        sums = [None] * len(self.moves)
        for leaf, tangents in self.tangents:
            grads = list(_components(dr.grad(leaf)))
            for j, tangent in enumerate(tangents):
                if tangent is None:
                    continue
                for g, t in zip(grads, _components(tangent)):
                    term = mi.Float64(dr.sum(g * t))
                    sums[j] = term if sums[j] is None else sums[j] + term
        kept = [x for x in sums if x is not None]
        dr.eval(*kept)
        for j, total in enumerate(sums):
            if total is not None:
                self.totals[j] += float(total.numpy()[0])
        self.tangents, self.links = [], []
