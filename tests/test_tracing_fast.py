"""The tracer's fast kernels against their readable references (issue 56): the hashed row grouping,
the cached unfolding maps, the flag-table unique, the wedges' per-part caches, the packed ray
upload and the arriving directions of several views at once. Each pair must agree exactly (the
fast forms reorder no floating-point sum), on inputs with degenerate rows."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from sarmitsuba.tracing import edges, term_lanes
from sarmitsuba.tracing.chains import Chains
from sarmitsuba.tracing.mesh_trace import _arriving, _arriving_views, _norm, _unique_keys
from sarmitsuba.tracing.term_lanes import _equal_rows, _equal_rows_reference

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
    together = _arriving_views(chains, chain, points, views)
    for v in range(3):
        first = chains.unfolded(points, chain) - views[:, v]
        first /= np.linalg.norm(first, axis=1, keepdims=True)
        lin = chains.lin[chain, chains.order[chain]]
        reference = np.einsum("mji,mj->mi", lin, first)
        assert np.array_equal(together[v], _arriving(chains, chain, points, views[:, v]))
        assert np.allclose(together[v], reference, rtol=1e-14, atol=1e-15)
    x = rng.normal(size=(100, 3))
    x[0] = 0.0
    assert np.array_equal(_norm(x), np.linalg.norm(x, axis=1))


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
    order, groups = edges._group_order(w)
    assert np.array_equal(groups, np.sort(w.group, kind="stable"))


def test_packed_rays_are_the_reference_upload():
    """Bounded rays (one of zero length), unbounded rays: the packed float32 upload gives the
    reference's origins, directions and ``maxt`` exactly."""
    import mitsuba as mi
    from sarmitsuba.tracing.visibility import Rays
    rays = Rays.__new__(Rays)
    rays.casts = 0
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
