"""The fused geometry kernels against their NumPy references (docs/design.md section 10.1);
the lit-boundary kernel's own cases are in tests/test_fused_boundary.py.

Truth: the references, which share none of the kernels' helpers: scipy's k-d tree for the
matching of rows that cancel (:func:`sarmitsuba.tracing.integration.term_lanes.kd_tree_pairs`),
and the pairs planted by construction; at render level the NumPy stages
(``geometry = reference``) on headings other than 0, faces oblique to the track, mirrors not at
right angles, a moving car and a bistatic receiver.

Deliberate bugs these tests were run against (each fails one):
  * the group ignored in the scan (rows of two sub-apertures or faces paired): the planted
    cross-group twins, and the render counts;
  * the "no third row" rule dropped for a row's partner (a row paired with one that has two
    matches): the chains of three;
  * the window ``tolerance`` wide instead of ``tolerance sqrt(1 + PHI^2)``: the pairs along the
    sort key's gradient;
  * only forward matches counted (the atomic count of earlier rows left out): the triples;
  * the sort key ``f_0`` alone (no projection): the rows of a patch line overflow the scan;
  * the earlier rows counted by ``scatter_add`` in Dr.Jit's default (Expand) mode: a kernel
    compiled per array length (the compile-once test);
  * the overflow groups' pairs dropped instead of matched by the reference: the overflow render
    differs from the reference render.
"""
from __future__ import annotations

import importlib.util

import numpy as np
import pytest
import trimesh

import sarmitsuba
import drjit as dr  # noqa: E402  (after sarmitsuba, which picks the libLLVM)
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.trace_inputs import TraceSettings
from sarmitsuba.tracing.fused import boundary, clipping, matching, moments, pieces, segments, shadows
from sarmitsuba.tracing.driver import mesh_trace
from sarmitsuba.tracing.fused.matching import PHI, SCAN_LIMIT, lone_pairs
from sarmitsuba.tracing.integration.term_lanes import MATCH_TOLERANCE, kd_tree_pairs
from sarmitsuba.tracing.visibility.occlusion import replace_pieces

from sarmitsuba.derivatives import AmplitudeLoss, ShapeParameter
from test_bistatic import RECEIVERS, block_scene
from test_geometry_gradients import SIZE, brick_box
from test_patches import rectangle

TOL = MATCH_TOLERANCE


def _sorted(pairs: np.ndarray) -> np.ndarray:
    pairs = np.sort(np.asarray(pairs, np.int64).reshape(-1, 2), axis=1)
    return pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]


def _planted(seed: int):
    """Rows of segment-like features (midpoint [m], then ``e_x^2, e_y^2, e_x e_y``) in 12 groups,
    with the lone pairs known by construction: returns ``(features, group, expected pairs)``."""
    rng = np.random.default_rng(seed)
    rows, groups, expected = [], [], []

    def add(feature, group):
        rows.append(np.asarray(feature, float))
        groups.append(group)
        return len(rows) - 1

    def base(scale=80.0):
        return np.concatenate([rng.uniform(-scale, scale, 2), rng.uniform(0.0, 4.0, 3)])

    for _ in range(150):                                   # lone pairs: off by up to 0.4 tol, any direction
        g = int(rng.integers(12))
        f = base()
        d = rng.normal(size=5)
        a = add(f, g)
        b = add(f + 0.4 * TOL * d / np.linalg.norm(d), g)
        expected.append((a, b))
    slope = np.array([1.0, PHI, 0.0, 0.0, 0.0]) / np.hypot(1.0, PHI)
    for _ in range(40):                                    # along the sort key's gradient: keys 1.12 tol apart
        g = int(rng.integers(12))
        f = base()
        a = add(f, g)
        b = add(f + 0.95 * TOL * slope, g)
        expected.append((a, b))
    for _ in range(30):                                    # chains a - b - c: b near two rows, no pair
        g = int(rng.integers(12))
        f = base()
        d = rng.normal(size=5)
        d /= np.linalg.norm(d)
        for step in (0.0, 0.8, 1.6):
            add(f + step * TOL * d, g)
    for _ in range(40):                                    # near misses: 1.5 tol apart, no pair
        g = int(rng.integers(12))
        f = base()
        d = rng.normal(size=5)
        add(f, g)
        add(f + 1.5 * TOL * d / np.linalg.norm(d), g)
    for _ in range(30):                                    # triples: three rows within tol, none lone
        g = int(rng.integers(12))
        f = base()
        for _ in range(3):
            d = rng.normal(size=5)
            add(f + 0.3 * TOL * d / np.linalg.norm(d), g)
    for _ in range(30):                                    # twins in two groups: no pair
        f = base()
        add(f, 0)
        add(f, 1)
    for x in (-10.0, 0.0, 10.0):                           # rows along patch lines x = const and y = const
        for k in range(2 * SCAN_LIMIT):
            add([x, -60.0 + k, 0.0, 1.0, 0.0], 5)
            add([-60.0 + k, x, 1.0, 0.0, 0.0], 6)
        a = add([x, 0.5, 0.0, 1.0, 0.0], 5)                # one lone pair on each line
        b = add([x, 0.5 + 0.5 * TOL, 0.0, 1.0, 0.0], 5)
        expected.append((a, b))
    order = rng.permutation(len(rows))                     # rows in no particular order
    back = np.argsort(order)
    features, group = np.array(rows)[order], np.array(groups, np.int64)[order]
    return features, group, _sorted(back[np.array(expected)])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_lone_pairs_are_the_planted_ones_and_the_k_d_trees(seed):
    """Planted lone pairs (distances up to 0.95 tolerance, some along the sort key's gradient,
    whose keys lie 1.12 tolerances apart), near misses at 1.5 tolerances, triples, chains of three
    (the middle row near both ends), twins in two groups and rows along patch lines (more on one
    line than ``SCAN_LIMIT``): the kernel finds exactly the planted pairs, as the k-d tree does,
    with no row overflowing."""
    features, group, expected = _planted(seed)
    pairs, overflow = lone_pairs(features, group, TOL)
    assert overflow == 0
    assert np.array_equal(_sorted(pairs), expected)
    assert np.array_equal(_sorted(kd_tree_pairs(features, group, TOL)), expected)


def test_a_crowded_window_goes_to_the_reference():
    """More rows than ``SCAN_LIMIT`` on one key (one midpoint, edges of every direction) and one
    lone pair among them: their group is left to the reference and counted, the pairs are still
    the k-d tree's, and a second group beside it is matched on the device."""
    rng = np.random.default_rng(4)
    crowd = np.column_stack([np.zeros((3 * SCAN_LIMIT, 2)), rng.uniform(0.0, 4.0, (3 * SCAN_LIMIT, 3))])
    twin = crowd[7] + [0.0, 0.0, 0.3 * TOL, 0.0, 0.0]
    other = np.array([[5.0, 5.0, 1.0, 0.0, 0.0], [5.0, 5.0 + 0.2 * TOL, 1.0, 0.0, 0.0]])
    features = np.vstack([crowd, twin, other])
    group = np.array([3] * (len(crowd) + 1) + [8, 8], np.int64)
    pairs, overflow = lone_pairs(features, group, TOL)
    assert overflow == len(crowd) + 1
    assert np.array_equal(_sorted(pairs), [[7, len(crowd)], [len(crowd) + 1, len(crowd) + 2]])
    assert np.array_equal(_sorted(pairs), _sorted(kd_tree_pairs(features, group, TOL)))


def test_overflowing_groups_give_each_of_their_pairs_once(monkeypatch):
    """A scan window of one row: most groups of the planted rows overflow and go to the k-d tree
    reference, which must replace (not join) what the device found in them: exactly the planted
    pairs, each once. (Caught: the device's pairs in an overflowing group kept beside the
    reference's, every such pair twice.)"""
    features, group, expected = _planted(0)
    monkeypatch.setattr(matching, "SCAN_LIMIT", 1)
    pairs, overflow = lone_pairs(features, group, TOL)
    assert overflow > len(features) // 2
    assert len(pairs) == len(expected) and np.array_equal(_sorted(pairs), expected)


def _growing_calls_peak(kernel, inputs) -> tuple[int, int]:
    """Dr.Jit's peak LLVM memory [bytes] over one call on the largest of ``inputs``, and over
    calls on each of them in turn (sizes doubling, so that no freed array fits the next call)."""
    kernel(*inputs[-1])
    peaks = []
    for calls in (inputs[-1:], inputs):
        dr.flush_malloc_cache()
        dr.detail.malloc_clear_statistics()
        for args in calls:
            kernel(*args)
        peaks.append(dr.detail.malloc_watermark(dr.JitBackend.LLVM))
    return peaks[0], peaks[1]


@pytest.mark.parametrize("kernel", ["moments", "lone_pairs"])
def test_a_kernel_hands_back_the_memory_it_freed(kernel):
    """Calls of growing sizes, as a render's batches are: Dr.Jit caches each freed array for a
    later one of its size, so unless a kernel hands its temporaries back
    (``device.releasing``) they pile up, and the peak over the calls is the sum of their
    temporaries (about twice the largest call's for doubling sizes), not the largest call's.
    (Caught: the kernel without ``releasing``: 1.97 times the largest call's peak.)"""
    rng = np.random.default_rng(9)
    if kernel == "moments":
        inputs = [(rng.uniform(-1.0, 1.0, (1 << k, 8, 2)), np.full(1 << k, 8)) for k in range(12, 18)]
        one, many = _growing_calls_peak(moments.moments, inputs)
    else:
        inputs = [(rng.uniform(0.0, 100.0, (1 << k, 5)), rng.integers(0, 64, 1 << k), TOL) for k in range(12, 18)]
        one, many = _growing_calls_peak(lone_pairs, inputs)
    assert one > 0 and many < 1.3 * one, (one, many)


def test_lone_pairs_compile_once_for_every_length():
    """The planted rows of two seeds (different lengths) after a first call: the second call
    launches only kernels the first compiled (the array length is a launch parameter, not part of
    a kernel's code), and still finds the planted pairs. Dr.Jit's Expand-mode scatter_add puts the
    length in the code: it fails this."""
    import drjit as dr
    kernels = []
    for seed in (0, 1):
        features, group, expected = _planted(seed)
        dr.set_flag(dr.JitFlag.KernelHistory, True)
        dr.kernel_history()                                # (clears it)
        pairs, _ = lone_pairs(features[: len(features) - 7 * seed], group[: len(group) - 7 * seed], TOL)
        kernels.append({k["hash"] for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT})
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        if seed == 0:
            assert np.array_equal(_sorted(pairs), expected)
    assert kernels[0] and kernels[1] <= kernels[0], len(kernels[1] - kernels[0])


def _tilted_wall() -> list:
    """A wall leaning 15 deg back from vertical and turned 30 deg from the track, on a ground of
    irregular triangles: a dihedral whose mirrors are not at right angles, faces oblique to the
    track, and faces of many triangles whose shared edges cancel."""
    normal = np.array([np.sin(np.radians(30.0)), -np.cos(np.radians(30.0)), 0.0])
    along = np.array([np.cos(np.radians(30.0)), np.sin(np.radians(30.0)), 0.0])
    up = np.cos(np.radians(15.0)) * np.array([0.0, 0.0, 1.0]) + np.sin(np.radians(15.0)) * -normal
    wall = rectangle(4.0 * up + np.array([0.0, 2.0, 0.0]), 6.0 * along, 4.0 * up, cuts=2, jitter=0.2, seed=1)
    ground = rectangle((0.0, 0.0, 0.0), (14.0, 0.0, 0.0), (0.0, 14.0, 0.0), cuts=3, jitter=0.25, seed=2)
    return [(wall, "metal", "wall"), (ground, "concrete", "ground")]


def _car() -> list:
    ground = rectangle((0.0, 0.0, 0.0), (20.0, 0.0, 0.0), (0.0, 20.0, 0.0), cuts=2, jitter=0.2, seed=3)
    car = trimesh.creation.box((4.4, 1.8, 1.4))
    car.apply_translation((0.0, 0.0, 0.7))
    return [(ground, "concrete", "ground"), (car, "pec", "car")]


BASE = {"frequency": 9.6e9, "bandwidth": 150e6, "incidence_angle": 45.0, "scene_center": (0.0, 0.0, 0.0),
        "n_pulses": 48, "prf": 200.0}
SCENES = {
    "block, heading 20 deg": lambda: sarmitsuba.Scene(block_scene(), sensor={**BASE, "heading": 20.0},
                                                      integrator={"max_depth": 2}),
    "tilted wall, heading -35 deg": lambda: sarmitsuba.Scene(_tilted_wall(), sensor={**BASE, "heading": -35.0},
                                                             integrator={"max_depth": 3}),
    "moving car": lambda: sarmitsuba.Scene(_car(), sensor={**BASE, "altitude": 500.0}, integrator={"max_depth": 2},
                                           velocities={"car": (6.0, 3.0, 0.0)}),
    "bistatic block": lambda: sarmitsuba.Scene(block_scene(), sensor={**BASE, **RECEIVERS["beside"]},
                                               integrator={"max_depth": 2}),
}


#: Every kernel of the fused path: (module, function), each with the reference's signature.
KERNELS = ((matching, "lone_pairs"), (boundary, "lit_boundary"), (clipping, "cut_outs"), (moments, "moments"), (pieces, "pieces_of"),
           (shadows, "shared_shadow_lines"),
           (segments.SegmentKinds, "never_specular"), (segments.SegmentKinds, "split_kinds"))


def _rows(out) -> int:
    """The rows a kernel gave: the length of its first output."""
    return len(out[0]) if isinstance(out, (tuple, list)) else len(out)


def _every_kernel(monkeypatch) -> dict:
    """Every kernel counted (kernel name -> rows it gave) and run however small its batch."""
    rows = {}

    def counted(module, name):
        real = getattr(module, name)

        def kernel(*args, **kwargs):
            out = real(*args, **kwargs)
            rows[name] = rows.get(name, 0) + _rows(out)
            return out
        return kernel

    for module, function in KERNELS:
        monkeypatch.setattr(module, function, counted(module, function))
    monkeypatch.setattr(moments, "DEVICE_ROWS", 0)          # the kernels even for these small scenes
    monkeypatch.setattr(mesh_trace, "SEGMENT_ROWS", 0)
    monkeypatch.setattr(pieces, "KERNEL_REGIONS", 0)
    monkeypatch.setattr(shadows, "DEVICE_ROWS", 0)
    monkeypatch.setattr(clipping, "DEVICE_PAIRS", 0)
    return rows


@pytest.mark.parametrize("name", list(SCENES))
def test_a_fused_render_is_the_reference_render(name, monkeypatch):
    """Each scene rendered with the fused kernels and with the NumPy reference: the same pairs
    cancel, the same boundaries are cut, so the raw data are bit for bit the same and so is the
    count of returns evaluated (a pair missed or made up, a segment lost, changes the lanes);
    every kernel had rows to work on, and no row overflowed."""
    rows = _every_kernel(monkeypatch)
    reference = simulate(SCENES[name](), integrator_overrides={"geometry": "reference"})
    assert rows == {}
    fused = simulate(SCENES[name](), integrator_overrides={"geometry": "fused"})
    assert sorted(rows) == sorted(f for _, f in KERNELS) and min(rows.values()) > 0, rows
    assert fused.trace.overflow_rows == 0 and reference.trace.overflow_rows == 0
    assert fused.trace.pulse_paths == reference.trace.pulse_paths
    assert np.array_equal(fused.raw.data, reference.raw.data)


def test_an_unknown_geometry_pipeline_is_refused_with_the_valid_values():
    with pytest.raises(ParameterError, match=r"geometry = 'gpu'; valid values: 'reference', 'fused'"):
        TraceSettings(geometry="gpu")


def test_overflow_rows_are_finished_by_the_reference_alone(monkeypatch):
    """A scan window of one row (``SCAN_LIMIT`` 1): the tilted wall's many shared segments crowd
    every window, so most groups overflow. Their rows go to the k-d tree reference, group by
    group, and the render is still the reference render bit for bit; the trace counts exactly
    the rows the reference matched. (A launch handed whole to the reference counts other rows;
    an overflow group dropped instead of matched changes the raw data.)"""
    spilled = []
    real = matching.lone_pairs_reference

    def reference_rows(features, group, tolerance):
        spilled.append(len(features))
        return real(features, group, tolerance)

    monkeypatch.setattr(matching, "SCAN_LIMIT", 1)
    monkeypatch.setattr(matching, "lone_pairs_reference", reference_rows)
    reference = simulate(SCENES["tilted wall, heading -35 deg"](), integrator_overrides={"geometry": "reference"})
    fused = simulate(SCENES["tilted wall, heading -35 deg"](), integrator_overrides={"geometry": "fused"})
    assert fused.trace.overflow_rows == sum(spilled) > 0
    assert fused.trace.pulse_paths == reference.trace.pulse_paths
    assert np.array_equal(fused.raw.data, reference.raw.data)


def test_geometric_gradients_through_the_kernels_are_the_references(tmp_path, monkeypatch):
    """A brick box's height, one of its vertices and its rotation (two bounces, its shadow on the
    ground cut by the box): the loss, the image and the three gradients (each from renders of the
    geometry moved by +-h, whose outlines the kernels cut) are the reference geometry's bit for
    bit, with the kernels doing the work. (Caught: the gradients' set-up dropping
    ``integrator_overrides``, so that no kernel runs; the cut-outs' cover test at half the
    piece's area.)"""
    box = brick_box(tmp_path)
    height = ShapeParameter("box", "height")
    parameters = [height, ShapeParameter("box", "vertices", (1, 0, 0), vertices=(7,)),
                  ShapeParameter("box", "rotation", (0, 0, 1))]
    target = sarmitsuba.gradients(box, AmplitudeLoss(np.zeros(SIZE["image_size"])), [], at={height: 1.5}, **SIZE)
    loss = AmplitudeLoss(np.abs(target.image))
    rows = _every_kernel(monkeypatch)
    reference = sarmitsuba.gradients(box, loss, parameters, integrator_overrides={"geometry": "reference"}, **SIZE)
    assert rows == {}
    fused = sarmitsuba.gradients(box, loss, parameters, integrator_overrides={"geometry": "fused"}, **SIZE)
    assert sorted(rows) == sorted(f for _, f in KERNELS) and min(rows.values()) > 0, rows
    assert fused.loss == reference.loss and np.array_equal(fused.image, reference.image)
    assert all(fused.gradient[p] == reference.gradient[p] != 0.0 for p in parameters)



def test_a_recheck_of_the_pieces_cut_again_finds_what_a_recheck_of_all_finds(monkeypatch):
    """The second recheck samples only the pieces the first cut again (the others' samples,
    regions and hits are the first pass's, their occluders all known): on Munich (one
    sub-aperture of Sionna RT's scene), every second
    pass gives the blockers and the changed pieces that the same pass over every cut piece gives,
    and some second passes find new occluders. (Caught: the second pass given no pieces, or the
    pieces as they were before they were cut again.)"""
    groups, real, spread = [], mesh_trace.recheck, mesh_trace.spread_occluders

    def new_group(*args):
        groups.append([])
        return spread(*args)

    def spy(s, lit, clipped, *args):
        out = real(s, lit, clipped, *args)
        groups[-1].append((s, lit, clipped, args, out))
        return out

    monkeypatch.setattr(mesh_trace, "spread_occluders", new_group)
    monkeypatch.setattr(mesh_trace, "recheck", spy)
    if importlib.util.find_spec("sionna") is None:           # (found, not imported: it sets its own variant)
        pytest.skip("Sionna RT's scenes are not installed")
    monkeypatch.setenv("SARMITSUBA_HOST_THREADS", "1")
    simulate("sionna:munich", sensor_overrides={"n_pulses": 19})
    seconds = [g[:2] for g in groups if len(g) > 1]
    assert seconds and sum(len(second[4][1]) for _, second in seconds) > 0
    for first, (s, lit, again, args, (blockers, changed)) in seconds:
        every = replace_pieces(first[2], again, first[4][1])
        assert len(every) > len(again)
        want_blockers, want_changed = real(s, lit, every, *args)
        assert np.array_equal(changed, want_changed)
        assert np.array_equal(blockers.codes(), want_blockers.codes())
