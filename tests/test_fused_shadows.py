"""The occluders' shadow half-planes on the Dr.Jit device
(:func:`sarmitsuba.tracing.fused.shadows.shared_shadow_lines`) against their NumPy reference
(:func:`sarmitsuba.tracing.visibility.occlusion.shared_shadow_lines`): the same half-planes, bit
for bit, and, independently of the reference, the points they hide are those whose path the
occluder blocks (docs/physics.md (M3), (M4), (B2)).

Cases: every call of ``simulate("urban")`` (legs 1 and the return leg, windows), with the kernel on
every batch and with the default threshold; every call of the render scenes of tests/test_fused.py
(a block at heading 20 deg, a tilted wall at depth 3, a moving car, a bistatic block); every
(chain, part, leg) of those scenes' chains (orders 0 to 2, every leg and the return leg, the
chain's own parts as occluders), from one antenna, two, and two with receivers; polygons whose
padding slots hold far corners; the kernel's ``hypot`` against NumPy's; and a ray-polygon test of
sampled points of the chains' last parts (orders 0 and 1, every leg, monostatic and bistatic). The
kernel runs on every row count (``DEVICE_ROWS`` 0) except in ``test_urban_calls[64]``.

Deliberate bugs these tests were run against, one at a time (each failed the tests named;
``test_urban_calls`` is ``[0]``, the kernel on every batch; the bit comparison of ``_same``
includes the signs of zeros):
  * the edge planes facing away from the occluder's centre (``s`` of the wrong sign), or every
    edge plane from corner 0 (the loop's corner not carried): every test but ``test_hypot``;
  * the next and the previous window swapped in the crossing conditions: ``test_urban_calls``,
    ``test_every_row_of_the_scenes`` (all three), ``test_padding_slots``,
    ``test_hidden_points[urban]``;
  * the return leg in the chain's unfolded frame (the face frame, or the leg's ``lin`` and
    ``shift``, not the real ones where ``back``): ``test_urban_calls``,
    ``test_render_scene_calls`` (tilted wall, bistatic block), ``test_every_row_of_the_scenes``
    (all three), ``test_padding_slots``, ``test_hidden_points[urban]``;
  * the receiver ignored on the return leg: ``test_render_scene_calls[bistatic block]``,
    ``test_every_row_of_the_scenes[receivers]``, ``test_hidden_points[bistatic block]``;
  * row 2 (after the previous window) kept on the first leg: ``test_urban_calls``,
    ``test_render_scene_calls[bistatic block]``, ``test_every_row_of_the_scenes`` (all three),
    ``test_padding_slots``, ``test_hidden_points[bistatic block]``;
  * row 1 never the point's own crossing (``t_O < 1``) on the last way-out leg:
    ``test_urban_calls``, ``test_render_scene_calls[bistatic block]``,
    ``test_every_row_of_the_scenes`` (all three), ``test_padding_slots``;
  * the padding rows initialised to ``(0, 0, 0)`` instead of :data:`EVERYTHING`; ``hypot`` as
    ``sqrt(a a + b b)``; the einsum's final ``+ 0`` dropped (a -0 left as it is): all of
    ``test_urban_calls`` (both), ``test_render_scene_calls``, ``test_every_row_of_the_scenes``
    and ``test_padding_slots`` (the zero: all but the tilted wall's render);
  * ``np.einsum``'s order taken as ``(x0 y0 + x1 y1) + x2 y2``: ``test_urban_calls`` (both),
    ``test_render_scene_calls[tilted wall]``, ``test_every_row_of_the_scenes`` (all three),
    ``test_padding_slots``.
Not caught, and no bugs: the first-bounce rule dropped (an order-0 chain's unfolded frame is the
identity, bit for bit: ``unfold`` starts from ``np.eye``, so the rule changes no bit; kept as the
reference has it), and the row loop run over every slot instead of stopping after the corners
(the carried corner is then corner 0 twice: ``g = 0``, whose face line is :data:`EVERYTHING`
exactly).
"""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (the variant first)
from sarmitsuba.tracing.fused import shadows
from sarmitsuba.tracing.visibility import occlusion

from test_fused import SCENES


@pytest.fixture(autouse=True)
def _kernel_always(monkeypatch):
    monkeypatch.setattr(shadows, "DEVICE_ROWS", 0)      # the kernel even for a few rows


def _same(surfaces, chains, chain, occluder, leg, antennas, receivers=None) -> int:
    """Assert the device's half-planes are the reference's, bit for bit; the rows compared."""
    want = occlusion.shared_shadow_lines(surfaces, chains, chain, occluder, leg, *antennas, receivers=receivers)
    got = shadows.shared_shadow_lines(surfaces, chains, chain, occluder, leg, *antennas, receivers=receivers)
    assert len(got) == len(want)
    for g, w in zip(got, want):
        assert g.dtype == w.dtype and g.shape == w.shape
        assert np.array_equal(g, w)
        assert np.array_equal(g.view(np.uint64), w.view(np.uint64))      # signed zeros too
    return len(chain)


def _recorded(monkeypatch, run) -> list:
    """The calls of ``shared_shadow_lines`` (from ``clip_mixed`` and the mesh tracer's rates, both through
    ``GeometryKernels``, which looks the reference up when a tracer is made) during ``run()``."""
    calls, reference = [], occlusion.shared_shadow_lines

    def record(surfaces, chains, chain, occluder, leg, *antennas, receivers=None):
        calls.append((surfaces, chains, chain.copy(), occluder.copy(), leg.copy(), tuple(a.copy() for a in antennas),
                      None if receivers is None else tuple(r.copy() for r in receivers)))
        return reference(surfaces, chains, chain, occluder, leg, *antennas, receivers=receivers)

    monkeypatch.setattr(occlusion, "shared_shadow_lines", record)
    run()
    monkeypatch.setattr(occlusion, "shared_shadow_lines", reference)
    return calls


_SCENE_CALLS: dict = {}


def _scene_calls(name: str) -> list:
    """The recorded calls of the render scene ``name`` (rendered once per session)."""
    if name not in _SCENE_CALLS:
        from sarmitsuba.pipeline import simulate
        with pytest.MonkeyPatch.context() as mp:
            _SCENE_CALLS[name] = _recorded(mp, lambda: simulate(SCENES[name](), integrator_overrides={"geometry": "reference"}))
    return _SCENE_CALLS[name]


def _urban_calls() -> list:
    """The recorded calls of ``simulate("urban")`` (run once per session)."""
    if "urban" not in _SCENE_CALLS:
        from sarmitsuba.pipeline import simulate
        with pytest.MonkeyPatch.context() as mp:
            _SCENE_CALLS["urban"] = _recorded(mp, lambda: simulate("urban", integrator_overrides={"geometry": "reference"}))
    return _SCENE_CALLS["urban"]


@pytest.mark.parametrize("device_rows", [0, shadows.DEVICE_ROWS])
def test_urban_calls(device_rows, monkeypatch):
    """Every call of ``simulate("urban")``: the inputs recorded, the device compared; with the
    threshold too (small batches by the reference, whole or after the kernel's unique rows)."""
    monkeypatch.setattr(shadows, "DEVICE_ROWS", device_rows)
    calls = _urban_calls()
    if device_rows:
        sizes = [(len(c[2]), len(np.unique(np.stack(c[2:5]), axis=1).T)) for c in calls]
        assert {n < device_rows for n, _ in sizes} == {True, False}
        assert any(n >= device_rows > k for n, k in sizes) and any(k >= device_rows for _, k in sizes)
    assert len(calls) > 10 and any(len(c[5]) == 2 for c in calls)
    legs = np.concatenate([c[4] for c in calls])
    assert np.any(legs == 1) and np.any(legs == calls[0][1].parts.shape[1])       # windows, the return leg
    assert sum(_same(c[0], c[1], c[2], c[3], c[4], c[5], c[6]) for c in calls) > 20000


@pytest.mark.parametrize("name", list(SCENES))
def test_render_scene_calls(name):
    calls = _scene_calls(name)
    assert calls and sum(_same(c[0], c[1], c[2], c[3], c[4], c[5], c[6]) for c in calls) > 300
    if name.startswith("bistatic"):
        assert all(c[6] is not None for c in calls)
    if name.startswith("tilted"):
        assert np.any(np.concatenate([c[4] for c in calls]) == 3)


def _all_rows(chains, n_parts):
    """Every (chain, part, leg) of ``chains``: legs ``0 .. order`` and the return leg ``D``."""
    depth = chains.parts.shape[1]
    rows = [(c, p, leg) for c in range(len(chains)) for p in range(n_parts)
            for leg in list(range(int(chains.order[c]) + 1)) + [depth]]
    return (np.array(rows, np.int64).T if rows else np.zeros((3, 0), np.int64))


@pytest.mark.parametrize("how", ["one antenna", "two antennas", "receivers"])
def test_every_row_of_the_scenes(how):
    """Each distinct chains object of the render scenes, every row of it (occluders that are the
    chain's own parts too), in a shuffled order with repeats."""
    rng = np.random.default_rng(3)
    total = 0
    for name in ("tilted wall, heading -35 deg", "bistatic block"):
        calls = _scene_calls(name)
        for chains_id in {id(c[1]) for c in calls}:
            s, chains, _, _, _, antennas, _ = next(c for c in calls if id(c[1]) == chains_id)
            chain, occluder, leg = _all_rows(chains, s.n_parts)
            pick = rng.permutation(np.concatenate([np.arange(len(chain)), rng.integers(0, len(chain), 50)]))
            a = antennas[0]
            b = a + rng.normal(0.0, 5.0, a.shape)
            ants = (a,) if how == "one antenna" else (a, b)
            receivers = None if how != "receivers" else (a + [40.0, -30.0, 5.0], b + [-20.0, 50.0, 0.0])
            total += _same(s, chains, chain[pick], occluder[pick], leg[pick], ants, receivers)
    assert total > 2000


def test_padding_slots():
    """Polygons whose padding slots hold far corners (not the first corner again, as
    :func:`~sarmitsuba.tracing.mesh.polygons.pad` leaves them): the rows past an occluder's
    corners are :data:`EVERYTHING` all the same."""
    import dataclasses
    rng = np.random.default_rng(8)
    calls = _scene_calls("tilted wall, heading -35 deg")
    total = 0
    for chains_id in {id(c[1]) for c in calls}:
        s, chains, _, _, _, antennas, _ = next(c for c in calls if id(c[1]) == chains_id)
        padding = np.arange(s.polygon.shape[1])[None, :] >= s.n_corners[:, None]
        polygon = s.polygon.copy()
        polygon[padding] = rng.uniform(-500.0, 500.0, (int(padding.sum()), 2))
        far = dataclasses.replace(s, polygon=polygon)
        chain, occluder, leg = _all_rows(chains, s.n_parts)
        total += _same(far, chains, chain, occluder, leg, antennas[:1])
    assert total > 1000


def test_hypot():
    """The kernel's ``hypot`` is NumPy's (the C library's), bit for bit, over many magnitudes,
    zeros, ties and the scaled ranges (below 2^-511 and above 2^511)."""
    import mitsuba as mi
    rng = np.random.default_rng(2)
    n = 200_000
    x = rng.normal(size=n) * 10.0 ** rng.uniform(-12, 12, n)
    y = rng.normal(size=n) * 10.0 ** rng.uniform(-12, 12, n)
    x[:1000], y[1000:2000], y[2000:3000] = 0.0, 0.0, x[2000:3000]
    x[3000:4000] *= 1e-160
    y[4000:5000] *= 1e160
    y[5000:6000] = x[5000:6000] * 1e-17
    got = shadows._hypot(mi.Float64(x), mi.Float64(y)).numpy()
    assert np.array_equal(got.view(np.uint64), np.hypot(x, y).view(np.uint64))


def test_hypot_where_its_two_corrections_meet():
    """``ax`` within 64 ulps of ``sqrt(3) ay``, where ``sqrt(ax^2 + ay^2)`` is ``2 ay`` and glibc
    switches between its two corrections (``h <= 2 ay``): bit for bit NumPy's there too.
    (Caught: the switch taken at ``h < 2 ay``, which random inputs almost never meet.)"""
    import mitsuba as mi
    rng = np.random.default_rng(5)
    ay = 10.0 ** rng.uniform(-8, 8, 4000)
    ax = np.sqrt(3.0) * ay
    steps = np.arange(-64, 65)
    ax = (ax[:, None] * (1.0 + steps * 2.0 ** -52)).ravel()
    ay = np.repeat(ay, len(steps))
    tie = np.sqrt(ax * ax + ay * ay) == 2.0 * ay
    assert tie.sum() > 1000
    got = shadows._hypot(mi.Float64(ax), mi.Float64(ay)).numpy()
    assert np.array_equal(got.view(np.uint64), np.hypot(ax, ay).view(np.uint64))


def _crosses(s, part, start, end, margin=1e-6):
    """+1 where the segments ``start`` -> ``end`` [m, 3] cross ``part``'s polygon (clear of its
    edges and ends by ``margin``), -1 where they clearly miss it, 0 where it is too close to tell."""
    normal, offset = s.normal[part], s.offset[part]
    corners = s.world_polygon[part][:s.n_corners[part]]
    d = end - start
    den = d @ normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (offset - start @ normal) / den
    hit = start + t[:, None] * d
    centre = corners.mean(axis=0)
    # signed distances of the crossing point to the edges' lines, inside positive
    dist = []
    for e in range(len(corners)):
        a, b = corners[e], corners[(e + 1) % len(corners)]
        inward = np.cross(normal, b - a)
        inward /= np.linalg.norm(inward)
        inward *= np.sign(inward @ (centre - a))
        dist.append((hit - a) @ inward)
    dist = np.min(dist, axis=0)
    length = np.linalg.norm(d, axis=1)
    inside_t = (t * length > margin) & ((1 - t) * length > margin)
    outside_t = (t * length < -margin) | ((1 - t) * length < -margin) | (np.abs(den) < 1e-12)
    out = np.zeros(len(start), np.int64)
    out[inside_t & (dist > margin)] = 1
    out[outside_t | (np.isfinite(dist) & (dist < -margin))] = -1
    return out


def _reflect(s, part, x):
    n, off = s.normal[part], s.offset[part]
    return x - 2.0 * (x @ n - off)[:, None] * n


def _path(s, chains, c, x, antenna, receiver):
    """The real path's legs (start, end) [m, 3] of points ``x`` through chain ``c`` of order 0 or 1
    (the image method, written here), the return leg last, and whether the path exists."""
    if chains.order[c] == 0:
        return [(np.repeat(antenna[None], len(x), 0), x)], [(x, np.repeat(receiver[None], len(x), 0))], \
            np.ones(len(x), bool)
    w = chains.parts[c, 0]
    y = _reflect(s, w, x)
    n, off = s.normal[w], s.offset[w]
    t = (off - antenna @ n) / ((y - antenna) @ n)
    p = antenna + t[:, None] * (y - antenna)
    # the reflection point inside the window (clear of its edges) and between A and y
    ok = (_crosses(s, w, np.repeat(antenna[None], len(x), 0), y, margin=1e-3) == 1)
    return [(np.repeat(antenna[None], len(x), 0), p), (p, x)], [(x, np.repeat(receiver[None], len(x), 0))], ok


@pytest.mark.parametrize("name", ["urban", "bistatic block", "tilted wall, heading -35 deg"])
def test_hidden_points(name):
    """Points of the chains' last parts (orders 0 and 1), sampled on their faces, for each
    recorded (chain, occluder, leg) row: where the path's leg (the image method, and a ray-polygon
    test, written here) clearly crosses the occluder, the point satisfies every half-plane of the
    row; where it clearly misses it, at least one fails. No reference involved."""
    rng = np.random.default_rng(5)
    calls = _urban_calls() if name == "urban" else _scene_calls(name)
    counts = {}
    for s, chains, chain, occluder, leg, antennas, receivers in calls:
        rows = np.unique(np.stack([chain, occluder, leg], axis=1), axis=0)
        rows = rows[chains.order[rows[:, 0]] <= 1]
        if len(rows) == 0:
            continue
        chain, occluder, leg = rows.T
        depth = chains.parts.shape[1]
        lines, = shadows.shared_shadow_lines(s, chains, chain, occluder, leg, antennas[0],
                                             receivers=None if receivers is None else receivers[:1])
        end = antennas[0] if receivers is None else receivers[0]
        for r in range(len(chain)):
            c, o, l = chain[r], occluder[r], leg[r]
            last = chains.last[c]
            face = s.polygon[last][:s.n_corners[last]]
            uv = rng.dirichlet(np.ones(len(face)), 40 if chains.order[c] == 0 else 1500) @ face
            x = s.plane_point(np.array([last]))[0] + uv[:, :1] * s.axis_u[last] + uv[:, 1:] * s.axis_v[last]
            out, ret, ok = _path(s, chains, c, x, antennas[0][c], end[c])
            first_bounce = chains.order[c] == 0 and receivers is None
            seg = ret[0] if l == depth else out[0] if first_bounce else out[l]
            crossing = np.where(ok, _crosses(s, o, *seg), 0)
            value = (uv @ lines[r, :, :2].T + lines[r, :, 2]).min(axis=1)
            assert np.all(value[crossing == 1] >= -1e-9)
            assert np.all(value[crossing == -1] < 0)
            kind = (int(chains.order[c]), "return" if l == depth else int(l))
            counts[kind] = counts.get(kind, np.zeros(2, np.int64)) + [np.sum(crossing == 1), np.sum(crossing == -1)]
    total = sum(counts.values())
    assert total[0] > 30 and total[1] > 300, counts                 # (hidden, visible) points tried
    if name == "urban":                                             # on the legs after a window, and back
        assert counts[(1, 1)][0] > 50 and counts[(1, "return")][0] > 50, counts
    if name == "bistatic block":                                    # the receiver's leg
        assert counts[(0, "return")][0] > 20, counts
