"""The same render twice gives the same bits (docs/physics.md (D7)).

Every sum the tracer forms is of integers (128-bit fixed point in two int64 words), so neither
the threads' timing nor their number changes a bit. The oracles here are independent of the
code under test: Python's exact rationals for the fixed-point rounding and sums, and, for whole
renders, the fact that a float sum split over one Dr.Jit thread and over two adds in another
order: a float32 atomic add put back into any accumulator makes the two renders differ in their
last bits, which the exact comparisons below see (each was tried: see each test).
"""
from __future__ import annotations

import re
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (sets the variant before Dr.Jit loads)
import drjit as dr
import mitsuba as mi
from sarmitsuba.derivatives import AmplitudeLoss, MaterialParameter, raw_derivative
from sarmitsuba.tracing.deposit.accumulate import Accumulator
from sarmitsuba.tracing.deposit.fixed_point import (AMPLITUDE, GRADIENT, POWER, SOLID_ANGLE, UnrepresentableSum, decode,
                                                    encode)

REPO = Path(__file__).resolve().parents[1]
SCALES = (AMPLITUDE, POWER, SOLID_ANGLE, GRADIENT)


def _exact(value: float, scale) -> int:
    """``round(v 2^F)`` in exact rational arithmetic, ties to even (Python's ``round``)."""
    return round(Fraction(value) * 2 ** scale.fraction_bits)


def _values(scale, n: int = 400, seed: int = 3) -> np.ndarray:
    """Signed values from a few quanta up to a sixteenth of the scale's largest, both signs,
    log-uniform in magnitude, with exact ties and powers of two among them."""
    rng = np.random.default_rng(seed)
    exponent = rng.uniform(-scale.fraction_bits + 2, np.log2(scale.largest) - 4, n)
    values = np.sign(rng.standard_normal(n)) * 2.0 ** exponent
    ties = np.array([0.5, 1.5, 2.5, -0.5, -2.5, 3.0, 2.0 ** 33 + 0.5]) * scale.quantum
    return np.concatenate([values, ties, [0.0, scale.quantum, -scale.quantum, 1.0, -1.0]])


@pytest.mark.parametrize("scale", SCALES, ids=lambda s: s.unit.split()[0])
def test_words_are_the_exactly_rounded_integer(scale):
    """A value's words, on the device and in the NumPy reference, hold ``round(v 2^F)`` (ties to
    even) exactly: ``hi 2^K + lo`` against Python's rationals. Catches ``hi`` floored on one
    side and truncated on the other, ``lo`` truncated instead of rounded, a split by ``2^F``
    instead of ``2^(F - K)``, and the float32 value rounded before the scaling."""
    values = _values(scale)
    device = np.stack([np.asarray(w.numpy(), np.int64) for w in scale.words(mi.Float64(values))[:2]], axis=1)
    reference = encode(values, scale)
    np.testing.assert_array_equal(device, reference)
    for v, (hi, lo) in zip(values, reference):
        assert int(hi) * 2 ** scale.split_bits + int(lo) == _exact(float(v), scale), v
    # float32 inputs (the kernels' values) reach the words unrounded
    single = values[np.abs(values) < 1e30].astype(np.float32)
    words = np.stack([np.asarray(w.numpy(), np.int64) for w in scale.words(mi.Float(single))[:2]], axis=1)
    np.testing.assert_array_equal(words, encode(single.astype(np.float64), scale))


def test_sums_are_exact_and_the_same_in_any_order():
    """20,000 terms of magnitudes across 70 octaves, scatter-added into 7 slots in three orders
    (one a reversal): the words are the same bits every time, and each slot reads the exact sum
    of its terms' rounded integers (Python's rationals), within ``N 2^-(F+1)`` of the exact sum of
    the terms. The float32 scatter-add of the same terms is not order-free (checked here too, so
    the test can tell). Catches a carry between the words (``lo`` overflowing into ``hi``) done
    per term, a decode that reads ``hi 2^-F``, and partial sums kept in float."""
    rng = np.random.default_rng(7)
    n, slots = 20_000, 7
    values = np.sign(rng.standard_normal(n)) * 2.0 ** rng.uniform(-40, 30, n)
    index = rng.integers(0, slots, n)
    results, floats = [], []
    for order in (np.arange(n), np.arange(n)[::-1], rng.permutation(n)):
        words = AMPLITUDE.zeros(slots)
        AMPLITUDE.add(words, mi.Float64(values[order]), mi.UInt32(index[order].astype(np.uint32)), True)
        results.append(np.asarray(words.numpy(), np.int64)[:-2])           # the refusal slot aside
        assert AMPLITUDE.read(words).shape == (slots,)
        total = dr.zeros(mi.Float, slots)
        dr.scatter_add(total, mi.Float(values[order].astype(np.float32)), mi.UInt32(index[order].astype(np.uint32)))
        floats.append(total.numpy().copy())
    assert all(np.array_equal(results[0], r) for r in results[1:])
    assert not all(np.array_equal(floats[0], f) for f in floats[1:])
    read = decode(results[0].reshape(-1, 2), AMPLITUDE)
    for s in range(slots):
        mine = values[index == s]
        integers = sum(_exact(float(v), AMPLITUDE) for v in mine)
        assert read[s] == pytest.approx(float(Fraction(integers, 2 ** AMPLITUDE.fraction_bits)), rel=1e-15, abs=0)
        exact = sum(Fraction(float(v)) for v in mine)
        assert abs(Fraction(read[s]) - exact) <= len(mine) * Fraction(1, 2 ** (AMPLITUDE.fraction_bits + 1)) \
            + abs(exact) * Fraction(1, 2 ** 52)


def test_words_wrap_around_and_still_sum_exactly():
    """Sums whose words overflow on the way (2^14 terms of +- 0.9 of the largest term into one
    slot, alternating so the total stays small) read the exact total: integer addition modulo
    2^64 associates. Catches saturating instead of wrapping adds."""
    big = 0.9 * AMPLITUDE.largest
    values = np.array([big, big, -big, -big] * 4096 + [3.25], np.float64)
    words = AMPLITUDE.zeros(1)
    AMPLITUDE.add(words, mi.Float64(values), dr.zeros(mi.UInt32, len(values)), True)
    assert AMPLITUDE.read(words)[0] == 3.25


def test_values_the_words_cannot_hold_are_refused_not_clamped():
    """Not finite, or beyond the largest: not added (the slot keeps the other terms' sum) but
    counted, and reading the sums raises, for a tally and for a launch's histogram, instead of
    returning clamped values. Catches a ``select`` that clamps to the largest value, NaN
    converted to an integer, and a refusal counted into the slot itself."""
    values = [1.0, np.nan, np.inf, -np.inf, 2.0 * AMPLITUDE.largest, 2.0]
    words = AMPLITUDE.zeros(1)
    AMPLITUDE.add(words, mi.Float64(values), dr.zeros(mi.UInt32, len(values)), True)
    pairs = np.asarray(words.numpy(), np.int64).reshape(-1, 2)
    assert decode(pairs[:1], AMPLITUDE)[0] == 3.0 and pairs[1, 0] == 4
    with pytest.raises(UnrepresentableSum, match="4 value"):
        AMPLITUDE.read(words)
    with pytest.raises(ValueError, match="finite"):
        encode([np.nan], AMPLITUDE)
    from sarmitsuba.scene.trace_inputs import FastTimeWindow, TraceSettings
    window = FastTimeWindow(t0=0.0, n_samples=16, fs=1e8, oversample=2)
    sums, ctx = Accumulator(TraceSettings(), window, 1, 1), {"n_b": 2}
    sums.open(ctx)
    sums.add(ctx, mi.Float([1.0, np.nan, 0.5]), mi.Float([0.0, 1.0, 0.25]), mi.UInt32([3, 4, 3]), True)
    with pytest.raises(UnrepresentableSum, match="1 return"):
        sums.read_histogram(ctx)


@pytest.fixture
def threads():
    """Sets Dr.Jit's thread count for the test, then restores it."""
    before = dr.thread_count()
    yield dr.set_thread_count
    dr.set_thread_count(before)


def _render(scene, **kwargs):
    sim = sarmitsuba.simulate(scene, **kwargs)
    t = sim.trace
    paths = None if t.paths is None else np.stack([t.paths.pulse, t.paths.position, t.paths.value.real,
                                                   t.paths.value.imag, t.paths.order])
    return dict(raw=sim.raw.data, image=sim.image.data, energy=t.energy_per_order, outside=t.energy_outside_window,
                carried=t.carried_power_per_order, raw_energy=t.raw_energy_per_order, paths=paths)


@pytest.mark.parametrize("kernel, regions", [("linear", "patches"), ("exact", "patches"), ("exact", "tiles")])
def test_renders_on_one_and_two_threads_are_bit_identical(threads, kernel, regions):
    """The dihedral with rough ground and walls (clutter, double bounces, edge currents), on one
    Dr.Jit thread and on two: the raw data, the image and every energy tally bit for bit, with
    the gridded deposit and with the exact kernel's path list, traced by the mesh tracer and by
    ray tubes. On two threads a float sum splits between the threads' copies and adds in another
    order than on one: each of these put back was tried and fails here: a float32 scatter-add in
    the histogram, in the energy tally, in the tubes' carried-power tally, and the exact
    kernel's path list left in the order the threads filled it (its float64 sums, cast to
    complex64, rarely show that order; the list itself does)."""
    # tiles: tubes 10 cm apart, so that a launch spans several of Dr.Jit's blocks of lanes; 64 of
    # the 219 pulses (a million paths for the exact kernel)
    tiles = {"ray_spacing": 0.1} if regions == "tiles" else {}
    pulses = {"sensor_overrides": {"n_pulses": 64}} if regions == "tiles" else {}
    scene = dict(material_overrides={"gamma_db": -10},
                 integrator_overrides={"range_kernel": kernel, "lit_regions": regions, **tiles}, **pulses)
    out = []
    for n in (1, 2):
        threads(n)
        out.append(_render("dihedral", **scene))
    one, two = out
    assert np.abs(one["raw"]).max() > 0 and one["energy"].sum() > 0 and one["carried"].sum() > 0
    for name in one:
        if one[name] is not None:
            assert np.array_equal(np.asarray(one[name]), np.asarray(two[name])), name


def _rough_dihedral(folder: Path) -> str:
    """The built-in dihedral with a rough concrete floor (gamma -10 dB) and a brick wall."""
    xml = (REPO / "scenes" / "dihedral.xml").read_text()
    materials = ('<bsdf type="radar" id="soil"><string name="material" value="concrete"/>'
                 '<float name="gamma_db" value="-10"/></bsdf>'
                 '<bsdf type="radar" id="brick"><string name="material" value="brick"/></bsdf>')
    xml = re.sub(r'<bsdf type="radar" id="metal">.*?</bsdf>', materials, xml, flags=re.S)
    xml = xml.replace('<ref id="metal"/>', '<ref id="soil"/>', 1).replace('<ref id="metal"/>', '<ref id="brick"/>', 1)
    path = folder / "rough_dihedral.xml"
    path.write_text(xml)
    return str(path)


def test_derivatives_on_one_and_two_threads_are_bit_identical(threads, tmp_path):
    """Forward mode (``raw_derivative`` of urban, 16 pulses, with respect to its soil's clutter
    gamma: deposits of more lanes than one of Dr.Jit's blocks) and reverse mode (``gradients`` of
    an image loss on a rough dihedral with respect to its floor's gamma and its wall's
    permittivity), on one Dr.Jit thread and on two: the same bits. Catches the forward tangents
    deposited by a float scatter-add, and, in reverse mode, a table read by a plain gather (its
    adjoint then races in float atomics between the lanes that share a material); both tried."""
    path = _rough_dihedral(tmp_path)
    gamma, eps_r = MaterialParameter("soil", "gamma"), MaterialParameter("brick", "relative_permittivity")
    size = {"image_size": (32, 32), "image_spacing": 0.5, "sensor_overrides": {"n_pulses": 32}}
    loss = AmplitudeLoss(np.zeros((32, 32)))
    out = []
    for n in (1, 2):
        threads(n)
        forward = raw_derivative("urban", gamma, sensor_overrides={"n_pulses": 16}).data
        reverse = sarmitsuba.gradients(path, loss, [gamma, eps_r], **size)
        out.append((forward, reverse.loss, reverse.gradient[gamma], reverse.gradient[eps_r]))
    assert np.abs(out[0][0]).max() > 0 and out[0][2] != 0 and out[0][3] != 0
    assert np.array_equal(out[0][0], out[1][0])
    assert out[0][1:] == out[1][1:]


def test_shared_reads_add_their_adjoints_in_any_order(threads):
    """200,000 lanes read 8 entries of a differentiable array for 1 to 4 pulses each in a
    replay-like loop (``dr.backward_from`` inside a symbolic loop's body): through
    :func:`~sarmitsuba.tracing.deposit.adjoint.read` the entries' gradients are the same bits on
    one thread and on two with the lanes shuffled, and within 1e-6 of the float64 sum of the
    lanes' adjoints (NumPy); through a plain gather (the float atomics the sinks replace) the
    shuffle changes them, so the test can tell. Catches ``read`` falling back to a gather, and a
    sink's adjoint added with the wrong index or sign."""
    from sarmitsuba.tracing.deposit.adjoint import AdjointSink, read
    rng = np.random.default_rng(5)
    n = 200_000
    index = rng.integers(0, 8, n).astype(np.uint32)
    weight = rng.standard_normal(n).astype(np.float32)
    count = rng.integers(1, 5, n).astype(np.uint32)

    def gradient(sinked: bool, order: np.ndarray) -> np.ndarray:
        source = dr.detach(mi.Float(np.linspace(1.0, 2.0, 8).astype(np.float32)))
        dr.enable_grad(source)
        sink = AdjointSink(source) if sinked else None
        idx, w, c = mi.UInt32(index[order]), mi.Float(weight[order]), mi.UInt32(count[order])

        def body(q):
            with dr.resume_grad():
                value = read(source, (idx + q) % 8, True, sink)
                dr.backward_from(value * w * mi.Float(q + 1))
            return (q + 1,)
        with dr.suspend_grad():
            dr.while_loop((mi.UInt32(0),), lambda q: q < c, body, label="test reads")
        return (sink.gradient() if sinked else dr.grad(source)).numpy().astype(np.float64)
    reference = np.zeros(8)
    for q in range(4):
        live = count > q
        np.add.at(reference, (index[live] + q) % 8, weight[live].astype(np.float64) * (q + 1))
    results = {}
    for n_threads, order in ((1, np.arange(n)), (2, rng.permutation(n))):
        threads(n_threads)
        results[n_threads] = (gradient(True, order), gradient(False, order))
    assert np.array_equal(results[1][0], results[2][0])
    np.testing.assert_allclose(results[1][0], reference, rtol=1e-6)
    assert not np.array_equal(results[1][1], results[2][1])


def test_pieces_whose_boundary_moves_are_told_apart():
    """``piece_moves`` against a loop over each piece's segments: a piece moves where any of its
    own segments has a rate, never for its neighbour's (the launch-wide flag it replaces made a
    still piece's area term depend on its launch-mates). Catches the cumulative count read one
    row off, and the edge rates left out."""
    from sarmitsuba.tracing.integration.patch_terms import PieceTable, piece_moves
    rng = np.random.default_rng(2)
    count = np.array([3, 0, 2, 4, 1, 2], np.uint32)
    start = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.uint32)
    n = int(count.sum())
    mid_rate, edge_rate = np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32)
    mid_rate[[2, 5], 1] = rng.standard_normal(2)             # the first piece's last segment, the fourth's first
    edge_rate[11, 2] = 1e-9                                   # the last piece's last segment, only its edge
    zero = np.zeros((6, 3))
    table = PieceTable(zero, zero, np.ones(6, np.float32), np.ones(6), zero, zero, zero, start, count,
                       np.zeros((n, 3), np.float32), np.zeros((n, 3), np.float32), mid_rate, edge_rate)
    expected = [bool(np.any(mid_rate[s:s + c]) or np.any(edge_rate[s:s + c])) for s, c in zip(start, count)]
    assert piece_moves(table).tolist() == expected == [True, False, False, True, False, True]
