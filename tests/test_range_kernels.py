"""The range-kernel accuracy knob (docs/physics.md (D1)-(D4)): nearest, linear, sinc, exact.

The ``exact`` kernel is checked against a direct NumPy sum of compressed pulses, and the
gridded kernels against ``exact`` on a traced trihedral (paths of all three orders).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.signal import binning
from sarmitsuba.tracing.deposit import fast_time as deposit
from sarmitsuba.pipeline import simulate
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.tracing.driver.trace import PathList
from sarmitsuba.scene.trace_inputs import FastTimeWindow


def _nrmse_db(a: np.ndarray, ref: np.ndarray) -> float:
    return 20.0 * math.log10(np.linalg.norm(a - ref) / np.linalg.norm(ref))


def _deposited_response(nu: float, range_kernel: str, n_offsets: int = 2048) -> float:
    """The droop measured on what is deposited: unit terms at sub-bin offsets u = (k + 1/2) / K
    deposited with :func:`deposit.deposit_reference` (the oracle of the tracer's taps), each
    with value exp(+j 2 pi nu u) / K, so that the histogram's DFT at nu, sum_n hist[n]
    exp(-j 2 pi nu n), is the mean over u of sum_n h(n - u) exp(-j 2 pi nu (n - u)). That mean
    over a period of u is int h(x) exp(-j 2 pi nu x) dx (Poisson): the kernel's continuous
    spectrum, here without typing the kernel's formula (midpoint rule, error < 1e-7)."""
    u = (np.arange(n_offsets) + 0.5) / n_offsets
    position = 16.0 + u
    hist = deposit.deposit_reference(position, np.exp(2j * math.pi * nu * position) / n_offsets,
                                     np.zeros(n_offsets, int), 40, range_kernel)
    response = hist[deposit.SPECTRAL_ORDERS.index(0)] @ np.exp(-2j * math.pi * nu * np.arange(40))
    assert abs(response.imag) < 1e-9                   # a symmetric kernel: a real response
    return float(response.real)


@pytest.mark.parametrize("nu", [0.0, 0.02, 0.05, 0.2, 0.4])
def test_kernel_droop_matches_the_deposited_response(nu):
    """(D2)/(D3): ``droop`` is the spectrum of the taps the deposit actually lays down (second
    method: a DFT of deposited terms, not the kernel's closed form). Catches a droop whose
    Lanczos half-width differs from the deposit's (A = 3 against 4: 0.075 at nu = 0.4), a
    linear droop of sinc instead of sinc^2 (0.18 at nu = 0.4), a cosine of nu instead of
    2 pi nu, or a Simpson grid too coarse for the kernel's lobes."""
    for kernel in ("sinc", "linear"):
        assert deposit.droop(np.array([nu]), kernel)[0] == pytest.approx(_deposited_response(nu, kernel), abs=1e-6)


def test_droop_textbook_values():
    """A triangle of unit half-width has spectrum sinc^2: (2 / pi)^2 = 0.405285 at nu = 1/2
    (sinc instead: 2 / pi = 0.64). The Lanczos kernel is a near-ideal low-pass of the fine grid:
    1 at DC and 1/2 at its edge nu = 1/2 (the window's spectrum is symmetric about the edge),
    within the truncation of its window at +-A (1.3e-3 at DC)."""
    assert deposit.droop(np.array([0.5]), "linear")[0] == pytest.approx(0.405285, abs=1e-6)
    assert deposit.droop(np.array([0.0]), "sinc")[0] == pytest.approx(1.0, abs=2e-3)
    assert deposit.droop(np.array([0.5]), "sinc")[0] == pytest.approx(0.5, abs=1e-3)


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
