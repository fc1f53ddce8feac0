"""The per-segment step on the Dr.Jit device (:class:`sarmitsuba.tracing.fused.segments.SegmentKinds`):
the stable flags and split kinds against the tracer's NumPy reference (``MeshTracer._never_specular``,
``MeshTracer._split_kinds``, every row of ``simulate("urban")`` and of a tilted-wall scene at
heading -35 deg with chains of three bounces), and against a second method written here with
plain linear algebra on scenes at headings 20 and -35 deg with a bistatic receiver.

Deliberate bugs these tests were run against (each fails the tests named):
  * ``np.einsum("mji,mj->mi")`` taken as ``mij`` (the map not transposed when folding back):
    ``test_reference_rows`` and ``test_second_method`` on the tilted wall (mirrors);
  * the receiver's views replaced by the transmitter's: both tests on the bistatic block;
  * the tangential projection left out of ``u_t``: ``test_reference_rows`` (urban, tilted wall),
    ``test_second_method`` (block, tilted wall);
  * the distance to the segment from the first view only (``t`` fixed at 0):
    ``test_reference_rows`` (urban), ``test_second_method`` (block);
  * split and sinc kinds swapped: every test.
"""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (the variant first)
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.driver import mesh_trace
from sarmitsuba.tracing.fused import segments

from test_fused import SCENES


def _record(monkeypatch, scene, integrator=None):
    """Render ``scene`` with the fused tracer; every call of the kernels compared with the
    reference on the same rows. Returns the rows compared and the rows that differ."""
    monkeypatch.setattr(mesh_trace, "SEGMENT_ROWS", 0)
    tracer, counts = [], {"rows": 0, "differ": 0, "stable": 0, "kinds": set()}
    real_init = mesh_trace.MeshTracer.__init__
    never, kinds = segments.SegmentKinds.never_specular, segments.SegmentKinds.split_kinds

    def init(self, *args, **kwargs):
        real_init(self, *args, **kwargs)
        tracer.append(self)

    def checked_never(self, chains, chain, points, diagonal, views, rx_views):
        got = never(self, chains, chain, points, diagonal, views, rx_views)
        at = chains.sub[chain]
        want = tracer[-1]._never_specular(chains, chain, points, diagonal, views[at], rx_views[at])
        counts["rows"] += len(got)
        counts["differ"] += int(np.sum(got != want))
        counts["stable"] += int(np.sum(want))
        return got

    def checked_kinds(self, chains, chain, part, p2, q2, views, rx_views):
        got = kinds(self, chains, chain, part, p2, q2, views, rx_views)
        at = chains.sub[chain]
        want = tracer[-1]._split_kinds(chains, chain, part, p2, q2, views[at], rx_views[at])
        counts["rows"] += len(got)
        counts["differ"] += int(np.sum(got != want))
        counts["kinds"] |= set(np.unique(want).tolist())
        return got

    monkeypatch.setattr(mesh_trace.MeshTracer, "__init__", init)
    monkeypatch.setattr(segments.SegmentKinds, "never_specular", checked_never)
    monkeypatch.setattr(segments.SegmentKinds, "split_kinds", checked_kinds)
    simulate(scene, integrator_overrides={"geometry": "fused", **(integrator or {})})
    return counts


@pytest.mark.parametrize("scene", ["urban", "tilted wall, heading -35 deg", "bistatic block"])
def test_reference_rows(scene, monkeypatch):
    counts = _record(monkeypatch, scene if scene == "urban" else SCENES[scene]())
    assert counts["rows"] > 1000 and counts["differ"] == 0, counts
    assert 0 < counts["stable"] < counts["rows"] and len(counts["kinds"]) >= 2


def _plain(k, normals, chains, chain, points, edges, views, rx_views):
    """A second method, row by row with matrices: the arriving direction ``L^T (L x + s - A) /
    |...|`` and the return ``(R - x) / |R - x|`` at each view; ``u_t`` and the distance from 0 to
    its path; ``alpha = k/2 (d - b) . e``."""
    stable, alpha = [], []
    for r, c in enumerate(chain):
        lin, shift = chains.lin_last[c], chains.shift_last[c]
        normal = normals[chains.last[c]]
        y = lin @ points[r] + shift
        u_t, a = [], []
        for v in range(3):
            d = lin.T @ ((y - views[chains.sub[c], v]) / np.linalg.norm(y - views[chains.sub[c], v]))
            b = (rx_views[chains.sub[c], v] - points[r]) / np.linalg.norm(rx_views[chains.sub[c], v] - points[r])
            u = d - b
            u_t.append(u - normal * (u @ normal))
            a.append(0.5 * k * ((d - b) @ edges[r]))
        dist = []
        for p, q in ((u_t[0], u_t[1]), (u_t[1], u_t[2])):
            t = np.clip(-(p @ (q - p)) / max((q - p) @ (q - p), 1e-300), 0.0, 1.0)
            dist.append(np.linalg.norm(p + t * (q - p)))
        stable.append(k * min(dist))
        alpha.append(a)
    return np.array(stable), np.array(alpha)


@pytest.mark.parametrize("scene", ["block, heading 20 deg", "tilted wall, heading -35 deg", "bistatic block"])
def test_second_method(scene, monkeypatch):
    """The kernels' flags and kinds against :func:`_plain` on a sample of the scene's rows, away
    from the thresholds (rows within 1e-9 of one are left out: rounding decides them)."""
    monkeypatch.setattr(mesh_trace, "SEGMENT_ROWS", 0)
    seen = {"stable": 0, "kinds": 0}
    never, kinds = segments.SegmentKinds.never_specular, segments.SegmentKinds.split_kinds

    def check_never(self, chains, chain, points, diagonal, views, rx_views):
        got = never(self, chains, chain, points, diagonal, views, rx_views)
        rows = np.arange(0, len(chain), max(1, len(chain) // 200))
        score, _ = _plain(self.k, self.surfaces.normal, chains, chain[rows], points[rows],
                          np.zeros((len(rows), 3)), views, rx_views)
        score = score * diagonal[rows]
        clear = np.abs(score - self.margin) > 1e-9 * self.margin
        assert np.array_equal(got[rows][clear], (score >= self.margin)[clear])
        seen["stable"] += int(clear.sum())
        return got

    def check_kinds(self, chains, chain, part, p2, q2, views, rx_views):
        got = kinds(self, chains, chain, part, p2, q2, views, rx_views)
        rows = np.arange(0, len(chain), max(1, len(chain) // 200))
        s = self.surfaces
        mid = s.to_world(part[rows], 0.5 * (p2[rows] + q2[rows]))
        edge = s.to_world(part[rows], q2[rows]) - s.to_world(part[rows], p2[rows])
        _, alpha = _plain(self.k, s.normal, chains, chain[rows], mid, edge, views, rx_views)
        size = np.abs(alpha)
        same = np.all(np.sign(alpha) == np.sign(alpha[:, :1]), axis=1)
        split = same & (size.min(axis=1) >= self.sinc_regime) & (size.max(axis=1) >= self.alpha_s)
        want = np.where(split, self.kinds[0], np.where(size.max(axis=1) < self.alpha_s, self.kinds[1], self.kinds[2]))
        near = np.any(np.abs(size - self.sinc_regime) <= 1e-9 * self.sinc_regime, axis=1) | \
            np.any(np.abs(size - self.alpha_s) <= 1e-9 * self.alpha_s, axis=1)
        assert np.array_equal(got[rows][~near], want[~near])
        seen["kinds"] += int((~near).sum())
        return got

    monkeypatch.setattr(segments.SegmentKinds, "never_specular", check_never)
    monkeypatch.setattr(segments.SegmentKinds, "split_kinds", check_kinds)
    simulate(SCENES[scene](), integrator_overrides={"geometry": "fused"})
    assert seen["stable"] > 100 and seen["kinds"] > 100, seen


def test_the_kernels_dot_and_norm_sum_in_numpys_order():
    """The kernel's row products are NumPy's bit for bit: ``_dot`` as ``np.einsum("mi,mi->m")``
    and ``_norm`` as ``row_norm``, over magnitudes from 1e-6 to 1e6 (a sum taken in another order
    changes the last bit of many rows, and a row whose score lies within that bit of a threshold
    changes its kind). (Caught: ``_dot`` summed ``(a0 b0 + a1 b1) + a2 b2``.)"""
    import mitsuba as mi
    from sarmitsuba.core.arrays import row_norm
    rng = np.random.default_rng(7)
    a = rng.normal(size=(50_000, 3)) * 10.0 ** rng.uniform(-6, 6, (50_000, 1))
    b = rng.normal(size=(50_000, 3)) * 10.0 ** rng.uniform(-6, 6, (50_000, 1))
    da, db = [mi.Float64(a[:, i]) for i in range(3)], [mi.Float64(b[:, i]) for i in range(3)]
    dot = segments._dot(da, db).numpy()
    norm = segments._norm(da).numpy()
    assert np.array_equal(dot.view(np.uint64), np.einsum("mi,mi->m", a, b).view(np.uint64))
    assert np.array_equal(norm.view(np.uint64), row_norm(a).view(np.uint64))
