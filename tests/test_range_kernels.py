"""The range-kernel accuracy knob (docs/physics.md (D1)-(D4)): nearest, linear, sinc, exact.

The ``exact`` kernel is checked against a direct NumPy sum of compressed pulses, and the
gridded kernels against ``exact`` on a traced trihedral (paths of all three orders).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

import sarmitsuba  # noqa: F401
from sarmitsuba import binning, deposit
from sarmitsuba.deposit import LANCZOS_A
from sarmitsuba.pipeline import simulate
from sarmitsuba.radar import ParameterError
from sarmitsuba.scene import load_scene
from sarmitsuba.trace import PathList
from sarmitsuba.trace_inputs import FastTimeWindow


def _nrmse_db(a: np.ndarray, ref: np.ndarray) -> float:
    return 20.0 * math.log10(np.linalg.norm(a - ref) / np.linalg.norm(ref))


@pytest.mark.parametrize("nu", [0.0, 0.02, 0.05, 0.2, 0.4])
def test_sinc_kernel_droop_matches_independent_quadrature(nu):
    """(D2)/(D3): the Lanczos kernel's response D(nu) = int h(x) cos(2 pi nu x) dx (adaptive quad)."""
    h = lambda x: np.sinc(x) * np.sinc(x / LANCZOS_A) * math.cos(2 * math.pi * nu * x)  # noqa: E731
    expected = quad(h, -LANCZOS_A, LANCZOS_A, limit=200)[0]
    assert deposit.droop(np.array([nu]), "sinc")[0] == pytest.approx(expected, abs=1e-8)
    assert deposit.droop(np.array([nu]), "linear")[0] == pytest.approx(np.sinc(nu) ** 2)


def test_exact_kernel_is_the_direct_sum_of_compressed_pulses():
    """(D4) against NumPy: s_p[n] = exp(-j k L_ref) sum_i v_i sinc(B (n - x_i) / fs), tails included
    (one path lies outside the window and still reaches its samples)."""
    rng = np.random.default_rng(3)
    window = FastTimeWindow(t0=1e-5, fs=120e6, n_samples=96, oversample=8)
    n_pulses, n_paths = 3, 40
    paths = PathList(pulse=rng.integers(0, n_pulses, n_paths).astype(np.int32),
                     order=np.ones(n_paths, np.uint8),
                     position=np.concatenate([rng.uniform(0, 95, n_paths - 1), [101.3]]),
                     value=(rng.normal(size=n_paths) + 1j * rng.normal(size=n_paths)).astype(np.complex64),
                     spectral=np.zeros(n_paths, np.int8))
    lref = np.array([3000.1, 3000.2, 3000.3])
    fc, bw = 9.6e9, 100e6
    got = binning.exact_compress(paths, n_pulses, lref, window, fc, bw, block_lanes=100)   # several launches
    n = np.arange(window.n_samples)
    expected = np.zeros((n_pulses, window.n_samples), complex)
    for p, x, v in zip(paths.pulse, paths.position, paths.value):
        expected[p] += v * np.sinc(bw / window.fs * (n - x))
    expected *= np.exp(-1j * 2 * math.pi * fc / 299_792_458.0 * lref)[:, None]
    assert _nrmse_db(got, expected) < -100


@pytest.fixture(scope="module")
def traced():
    """The built-in PEC trihedral traced with every kernel at oversample 2 and 8 (3 bounce orders)."""
    out = {}
    for oversample in (2, 8):
        for kernel in ("nearest", "linear", "sinc", "exact"):
            out[kernel, oversample] = simulate("trihedral", sensor_overrides={"n_pulses": 64},
                                               integrator_overrides={"range_kernel": kernel,
                                                                     "oversample": oversample})
    return out


def test_gridded_kernels_converge_to_exact(traced):
    """Raw-data error against ``exact``: sinc at oversample 2 is as good as linear at 8
    (both below -45 dB); linear at 2 is limited by its alias (D2), nearest by its shift (D1)."""
    err = {key: _nrmse_db(sim.raw.data, traced["exact", key[1]].raw.data) for key, sim in traced.items()
           if key[0] != "exact"}
    assert err["sinc", 2] < -45 and err["linear", 8] < -45 and err["sinc", 8] < -45, err
    assert -40 < err["linear", 2] < err["nearest", 2], err
    assert err["nearest", 8] < err["nearest", 2] - 6, err
    assert err["nearest", 8] > err["linear", 8] + 15, err


def test_exact_kernel_traces_the_same_paths(traced):
    """Kernel choice changes how paths are binned, not which are traced: same casts, same energy."""
    ref = traced["exact", 8].trace
    for kernel in ("nearest", "linear", "sinc"):
        sim = traced[kernel, 8].trace
        np.testing.assert_array_equal(sim.rays_per_order, ref.rays_per_order)
        np.testing.assert_allclose(sim.energy_per_order, ref.energy_per_order, rtol=1e-4)
    assert len(traced["exact", 8].trace.paths.pulse) > 0
    assert traced["exact", 8].trace.spectrum.size == 0


def test_exact_kernel_splits_bounce_orders():
    sim = simulate("trihedral", sensor_overrides={"n_pulses": 16},
                   integrator_overrides={"range_kernel": "exact", "split_bounces": True})
    assert len(sim.raw_per_order) == 3
    total = sum(r.data.astype(np.complex128) for r in sim.raw_per_order)
    assert _nrmse_db(total, sim.raw.data) < -100
    assert np.abs(sim.raw_per_order[2].data).max() > np.abs(sim.raw_per_order[0].data).max()   # trihedral: order 3


def test_exact_kernel_refuses_chirped_output_before_tracing():
    with pytest.raises(ParameterError, match="exact.*output"):
        load_scene("trihedral", {"output": "raw"}, {"range_kernel": "exact"})


def test_unknown_range_kernel_names_the_valid_ones():
    with pytest.raises(ParameterError, match="nearest, linear, sinc, exact"):
        load_scene("trihedral", None, {"range_kernel": "cubic"})
