"""The tracer's fast kernels against their readable references (issue 56): the hashed row grouping,
the cached unfolding maps, the flag-table unique, the wedges' per-part caches, the packed ray
upload and the arriving directions of several views at once. Each pair must agree exactly (the
fast forms reorder no floating-point sum), on inputs with degenerate rows."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sarmitsuba.tracing.integration import edges
from sarmitsuba.tracing.integration import term_lanes
from sarmitsuba.tracing.discovery.chains import Chains
from sarmitsuba.core.arrays import row_norm
from sarmitsuba.tracing.discovery.specular import arriving, arriving_views
from sarmitsuba.tracing.driver.mesh_trace import _unique_keys
from sarmitsuba.tracing.integration.term_lanes import _equal_rows, _equal_rows_reference

from test_edges import _classify, _surfaces
from test_patches import rectangle


def _groups(order, group, n):
    """Each row's group number, renumbered by first appearance (a partition's canonical form)."""
    label = np.empty(n, np.int64)
    label[order] = group
    _, first, inverse = np.unique(label, return_index=True, return_inverse=True)
    rank = np.empty(len(first), np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    return rank[inverse]


@pytest.mark.parametrize("n", [1, 2, 7, 5000])
def test_equal_rows_groups_rows_as_the_lexicographic_sort(n):
    rng = np.random.default_rng(n)
    columns = [rng.integers(-3, 3, n), rng.integers(0, 2, n) * 10**12, np.full(n, -1, np.int64), rng.integers(-2, 2, n)]
    order, group = _equal_rows(columns)
    ref_order, ref_group = _equal_rows_reference(columns)
    assert np.array_equal(np.sort(order), np.arange(n))
    assert np.array_equal(_groups(order, group, n), _groups(ref_order, ref_group, n))
    # equal rows share a group, different rows do not
    rows = np.stack(columns, axis=1)
    label = _groups(order, group, n)
    for i in range(min(n, 40)):
        same = np.all(rows == rows[i], axis=1)
        assert np.array_equal(same, label == label[i])


def test_equal_rows_after_a_hash_collision_is_the_reference(monkeypatch):
    """Every row hashed alike (a forced collision): the reference's grouping."""
    columns = [np.array([3, 1, 3, 2, 1]), np.array([0, 0, 0, 5, 0])]
    monkeypatch.setattr(term_lanes, "_row_hash", lambda columns: np.zeros(len(columns[0]), np.uint64))
    order, group = _equal_rows(columns)
    assert np.array_equal(_groups(order, group, 5), _groups(*_equal_rows_reference(columns), 5))


def test_junctions_and_shared_edges_cancel_by_tolerance_not_by_rounding():
    """Two split ends of one straight boundary meet at a point each piece computed on its own,
    here 2e-13 m apart across a micrometre grid line (x = 0.5 um): they cancel; a third end at
    that point, another region, or two ends of one sign do not. Two segments of one face that
    run along each other the other way (their ends 2e-13 m apart across that line) cancel; the
    same way round, they do not. Catches the pairing by coordinates rounded to a grid, which a
    geometric derivative's moved geometry decides differently (docs/physics.md (AD4)): the
    pair is kept there."""
    from types import SimpleNamespace
    from sarmitsuba.tracing.integration.patch_terms import SPLIT_END, SPLIT_START
    x, d = 0.5e-6, 1e-13
    point = np.array([[x - d, 2.0], [x + d, 2.0], [x, 2.0]])
    edge = np.array([[1.0, 0.0], [3.0, 0.0], [2.0, 0.0]])
    kind = np.array([SPLIT_END, SPLIT_START, SPLIT_START])
    stable = np.ones(3, bool)

    def junctions(n, region, kinds=kind):
        return term_lanes.cancel_junctions(kinds[:n], np.arange(n), point[:n], edge[:n], np.asarray(region), stable[:n])
    assert junctions(2, [7, 7]).tolist() == [True, True]
    assert junctions(3, [7, 7, 7]).tolist() == [False, False, False]
    assert junctions(2, [7, 8]).tolist() == [False, False]
    assert junctions(2, [7, 7], np.array([SPLIT_START, SPLIT_START])).tolist() == [False, False]
    surfaces = SimpleNamespace(face=np.array([0]))
    chains = SimpleNamespace(parts=np.array([[0, -1]]), sub=np.array([0]))
    start = np.array([[0.0, 0.0], [1.0, x - d]])
    end = np.array([[1.0, x + d], [0.0, 0.0]])
    shared = term_lanes.cancel_shared(surfaces, chains, np.zeros(2, np.int64), start, end, np.ones(2, bool))
    assert shared.tolist() == [True, True]
    same_way = term_lanes.cancel_shared(surfaces, chains, np.zeros(2, np.int64), np.zeros((2, 2)),
                                        np.array([[1.0, x + d], [1.0, x - d]]), np.ones(2, bool))
    assert same_way.tolist() == [False, False]


def _chains(n, depth=3, seed=0):
    rng = np.random.default_rng(seed)
    order = rng.integers(0, depth, n)
    lin = rng.normal(size=(n, depth, 3, 3))
    shift = rng.normal(size=(n, depth, 3)) * 100
    parts = rng.integers(0, 50, (n, depth))
    return Chains(sub=rng.integers(0, 4, n), parts=parts, order=order, lin=lin, shift=shift)


@pytest.mark.parametrize("m", [0, 1, 999])
def test_unfolded_is_the_einsum_of_each_chains_last_map(m):
    chains = _chains(40)
    rng = np.random.default_rng(m)
    chain = rng.integers(0, 40, m)
    points = rng.normal(size=(m, 3)) * 300
    k = chains.order[chain]
    reference = np.einsum("mij,mj->mi", chains.lin[chain, k], points) + chains.shift[chain, k]
    assert np.allclose(chains.unfolded(points, chain), reference, rtol=1e-15, atol=1e-12)
    assert np.array_equal(chains.last, chains.parts[np.arange(40), chains.order])
    with pytest.raises(ValueError):                 # the cached maps are shared: read-only
        chains.lin_last[0, 0, 0] = 1.0


def test_arriving_from_several_views_is_each_view_alone():
    chains = _chains(30, seed=1)
    rng = np.random.default_rng(2)
    chain = rng.integers(0, 30, 500)
    points = rng.normal(size=(500, 3)) * 50
    views = rng.normal(size=(500, 3, 3)) * 5000
    together = arriving_views(chains, chain, points, views)
    for v in range(3):
        first = chains.unfolded(points, chain) - views[:, v]
        first /= np.linalg.norm(first, axis=1, keepdims=True)
        lin = chains.lin[chain, chains.order[chain]]
        reference = np.einsum("mji,mj->mi", lin, first)
        assert np.array_equal(together[v], arriving(chains, chain, points, views[:, v]))
        assert np.allclose(together[v], reference, rtol=1e-14, atol=1e-15)
    x = rng.normal(size=(100, 3))
    x[0] = 0.0
    assert np.array_equal(row_norm(x), np.linalg.norm(x, axis=1))


@pytest.mark.parametrize("n,size", [(0, 10), (1, 1), (3000, 20000), (50, 10**13)])
def test_unique_keys_is_numpys_unique(n, size):
    keys = np.random.default_rng(n).integers(0, size, n)
    expected = np.unique(keys, return_inverse=True)
    got = _unique_keys(keys, size)
    assert all(np.array_equal(a, b) and a.dtype == b.dtype for a, b in zip(expected, got))


def test_wedges_per_part_caches_give_the_direct_computation():
    """A box on a ground plate and a lone plate: the cached corner means and edge frames give
    ``_into`` and ``segment_wedges`` what the per-segment computation gives, bit for bit."""
    box = trimesh.creation.box((2.0, 3.0, 4.0))
    ground = rectangle((0, 0, 0), (10.0, 0, 0), (0, 10.0, 0))
    s = _surfaces([trimesh.Trimesh(box.vertices + [0, 0, 2.0], box.faces), ground])
    w, seg = _classify(s)
    rng = np.random.default_rng(3)
    part = rng.integers(0, s.n_parts, 200)
    tangent = rng.normal(size=(200, 3))
    point = rng.normal(size=(200, 3))
    assert np.array_equal(edges._into(s, part, tangent, point), edges._into(s, part, tangent, point,
                                                                          edges._part_centres(s)))
    length, unit = edges._part_edges(s)
    poly = s.polygon[part]
    edge = np.roll(poly, -1, axis=1) - poly
    assert np.array_equal(length[part], np.linalg.norm(edge, axis=2))
    assert np.array_equal(unit[part], edge / np.maximum(np.linalg.norm(edge, axis=2), 1e-30)[..., None])
    again = _classify(s)[1]                         # a second pass, through the filled caches
    assert all(np.array_equal(seg[k], again[k]) for k in seg)
    order, start = edges._group_order(w)
    assert np.array_equal(order, np.argsort(w.group, kind="stable"))
    assert np.array_equal(w.group[order], np.repeat(np.arange(len(start) - 1), np.diff(start)))


def test_packed_rays_are_the_reference_upload():
    """Bounded rays (one of zero length), unbounded rays: the packed float32 upload gives the
    reference's origins, directions and ``maxt`` exactly."""
    import mitsuba as mi
    from sarmitsuba.tracing.visibility.rays import CastCounter, Rays
    rays = Rays.__new__(Rays)
    rays.counter = CastCounter()
    rng = np.random.default_rng(4)
    start = rng.normal(size=(257, 3)) * 1000
    end = start + rng.normal(size=(257, 3)) * 10
    end[0] = start[0]
    for args in ((start, end, None), (start, None, rng.normal(size=(257, 3)))):
        fast, reference = rays._ray(*args), rays._ray_reference(*args)
        for field in ("o", "d", "maxt"):
            assert np.array_equal(np.asarray(getattr(fast, field)), np.asarray(getattr(reference, field)))
    assert rays.casts == 2 * 257
    assert isinstance(fast, mi.Ray3f)


def _region_lines_reference(surfaces, chains, antenna):
    """:func:`sarmitsuba.tracing.discovery.chains.region_lines` one window edge at a time (its form before
    the edges were batched)."""
    import sarmitsuba.tracing.discovery.chains as chains_mod
    EVERYTHING = chains_mod.EVERYTHING
    n, depth = chains.parts.shape
    last = chains.last
    source = chains_mod.image_source(chains, antenna)
    arriving = chains_mod.facing_sign(surfaces, last, source)
    valid = (arriving != 0) & (surfaces.seen_side[last] * arriving >= 0)
    returns = valid & (arriving == chains_mod.facing_sign(surfaces, last, antenna))
    width = max(depth - 1, 0) * (2 + surfaces.polygon.shape[1]) + max(depth - 2, 0)
    lines = np.tile(np.asarray(EVERYTHING), (n, max(width, 1), 1))
    k = chains.order
    frame_o, frame_u, frame_v = chains_mod.unfolded_frame(surfaces, chains)
    slot = 0
    previous = None
    for i in range(depth - 1):
        rows = np.flatnonzero(k > i)
        normal, offset, corners, n_corners = chains_mod._windows(surfaces, chains, i, rows)
        a = offset - np.einsum("mi,mi->m", normal, antenna[rows])              # n . (p - A)
        valid[rows] &= a != 0
        window_side = chains_mod.facing_sign(surfaces, chains.parts[rows, i], chains_mod._source_of(chains, rows, i, antenna[rows]))
        valid[rows] &= (window_side != 0) & (surfaces.seen_side[chains.parts[rows, i]] * window_side >= 0)
        # A and y on opposite sides of the window's plane: sign(a) n . (y - A) > 0
        g = np.sign(a)[:, None] * normal
        lines[rows, slot] = chains_mod.to_face_lines(g, -np.einsum("mi,mi->m", g, antenna[rows]), frame_o[rows], frame_u[rows], frame_v[rows])
        slot += 1
        # the last window crossed before y itself (t < 1): sign(a) n . (y - A) > |a|
        last_window = k[rows] == i + 1
        before = chains_mod.to_face_lines(g, -np.einsum("mi,mi->m", g, antenna[rows]) - np.abs(a), frame_o[rows], frame_u[rows],
                               frame_v[rows])
        lines[rows, slot] = np.where(last_window[:, None], before, EVERYTHING)
        slot += 1
        slots = np.arange(corners.shape[1])[None, :] < n_corners[:, None]
        centre = (corners * slots[..., None]).sum(axis=1) / n_corners[:, None]
        for e in range(corners.shape[1]):
            nxt = np.where(e + 1 < n_corners, e + 1, 0)
            p, q = corners[:, e] - antenna[rows], corners[np.arange(len(rows)), nxt] - antenna[rows]
            g = np.cross(p, q)
            g *= np.sign(np.einsum("mi,mi->m", g, centre - antenna[rows]))[:, None]
            live = e < n_corners
            line = chains_mod.to_face_lines(g, -np.einsum("mi,mi->m", g, antenna[rows]), frame_o[rows], frame_u[rows], frame_v[rows])
            lines[rows, slot] = np.where(live[:, None], line, EVERYTHING)
            slot += 1
        if previous is not None:           # t_{i-1} < t_i: (n_{i-1} / a_{i-1} - n_i / a_i) . (y - A) > 0
            prev_rows, prev_normal, prev_a = previous
            g = prev_normal[np.searchsorted(prev_rows, rows)] / prev_a[np.searchsorted(prev_rows, rows), None] \
                - normal / np.where(a != 0, a, 1.0)[:, None]
            lines[rows, slot] = chains_mod.to_face_lines(g, -np.einsum("mi,mi->m", g, antenna[rows]), frame_o[rows], frame_u[rows],
                                         frame_v[rows])
            slot += 1
        previous = (rows, normal, np.where(a != 0, a, 1.0))
    return lines, valid, returns & valid


def test_region_lines_batched_edges_are_the_edge_at_a_time_reference():
    """Chains of orders 1 to 3 through a box's faces and a ground plate (quads and triangles,
    padded corner slots), seen from antennas all around: the same half-planes, bit for bit."""
    from sarmitsuba.tracing.discovery.chains import region_lines, unfold
    box = trimesh.creation.box((2.0, 3.0, 4.0))
    ground = rectangle((0, 0, 0), (10.0, 0, 0), (0, 10.0, 0))
    tri = trimesh.Trimesh([[0, 0, 1.0], [1.0, 0, 1.5], [0, 1.0, 2.0]], [[0, 1, 2]])
    s = _surfaces([trimesh.Trimesh(box.vertices + [0, 0, 2.0], box.faces), ground, tri])
    rng = np.random.default_rng(5)
    n, depth = 300, 4
    order = rng.integers(0, depth, n)
    parts = np.where(np.arange(depth)[None, :] <= order[:, None], rng.integers(0, s.n_parts, (n, depth)), -1)
    chains = unfold(s, parts, order, np.zeros(n, np.int64))
    antenna = rng.normal(size=(n, 3)) * 1000
    antenna[:5] = s.plane_point(parts[:5, 0])              # on a window's plane: an invalid chain
    got, expected = region_lines(s, chains, antenna), _region_lines_reference(s, chains, antenna)
    for a, b in zip(got, expected):
        assert np.array_equal(a, b)
