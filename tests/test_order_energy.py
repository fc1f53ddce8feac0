"""The energy each bounce order holds (docs/physics.md (D6); summary.json ``energy_by_order``,
``depth_warning``; ``sarmitsuba info`` of a render folder).

Truths: a second trace one order shallower (the deeper trace's extra order is the difference of
the two, sampled in the time domain by an inverse FFT: Parseval's other side), the raw data
themselves (equal up to the compressed pulse's tails beyond the window), a lone plate that
cannot return a second bounce, and the threshold's arithmetic.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scipy import fft as sp_fft

from sarmitsuba.analysis.orders import DEEPEST_SHARE, depth_warning, energy_by_order, format_render, render_summary
from sarmitsuba.cli import main
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.pipeline import render, simulate
from sarmitsuba.signal.binning import compressed_pulse_spectrum
from sarmitsuba.tracing.deposit import order_energy

PLATE = str(Path(__file__).parent / "scenes" / "plane.xml")
#: The raw data's window ends a few resolution cells past the scene: the compressed pulses' sinc
#: tails beyond it hold ~2 / (pi^2 K) of a return's energy K samples out (a few 1e-3 here).
TAILS = 1e-2


@pytest.fixture
def every_pulse(monkeypatch):
    """Each order's energy measured on every pulse (not the default subsample), for exact checks."""
    monkeypatch.setattr(order_energy, "ENERGY_STRIDE", 1)


def _time_domain_energy(spectrum: np.ndarray, fs: float, bandwidth: float) -> float:
    """Sum of |samples|^2 over the padded grid of the range-compressed spectrum (S2), by an
    inverse FFT: the time-domain side of Parseval's theorem."""
    filt = compressed_pulse_spectrum(spectrum.shape[1], fs, bandwidth)
    samples = sp_fft.ifft(spectrum.astype(np.complex128) * filt[None, :], axis=1)
    return float(np.sum(np.abs(samples) ** 2))


@pytest.mark.parametrize("incidence", [45.0, 35.0])
def test_second_order_is_what_a_second_bounce_adds(incidence, every_pulse):
    """Dihedral at depth 1 and 2: order 2's energy is that of (depth 2 - depth 1), from the
    spectra exactly and from the raw data up to the tails; order 1 agrees between the two."""
    sensor = {"n_pulses": 64, "incidence_angle": incidence}
    one = simulate("dihedral", sensor_overrides=sensor, integrator_overrides={"max_depth": 1}, progress=False)
    two = simulate("dihedral", sensor_overrides=sensor, integrator_overrides={"max_depth": 2}, progress=False)
    fs, bandwidth = two.raw.fs, two.raw.bandwidth
    e1, e2 = two.trace.raw_energy_per_order
    added = two.trace.spectrum.astype(np.complex128) - one.trace.spectrum
    assert e2 == pytest.approx(_time_domain_energy(added, fs, bandwidth), rel=1e-4)
    assert e1 == pytest.approx(_time_domain_energy(one.trace.spectrum, fs, bandwidth), rel=1e-4)
    assert one.trace.raw_energy_per_order[0] == pytest.approx(e1, rel=1e-4)
    raw_added = two.raw.data.astype(np.complex128) - one.raw.data
    assert e2 == pytest.approx(float(np.sum(np.abs(raw_added) ** 2)), rel=TAILS)
    assert e2 > 1e4 * e1            # the dihedral's double bounce dominates


@pytest.mark.parametrize("lit_regions", ["patches", "tiles"])
def test_orders_read_apart_agree_with_orders_deposited_apart(lit_regions, every_pulse):
    """One histogram read after each order (the default) against one histogram per order
    (``split_bounces``), for the mesh tracer and the ray tubes; and each kept order's energy
    against its own raw data."""
    overrides = {"max_depth": 2, "lit_regions": lit_regions}
    sensor = {"n_pulses": 48, "incidence_angle": 40.0}
    read = simulate("dihedral", sensor_overrides=sensor, integrator_overrides=overrides, progress=False)
    kept = simulate("dihedral", sensor_overrides=sensor, integrator_overrides={**overrides, "split_bounces": True},
                    progress=False)
    np.testing.assert_allclose(read.trace.raw_energy_per_order, kept.trace.raw_energy_per_order, rtol=1e-4)
    for energy, raw in zip(kept.trace.raw_energy_per_order, kept.raw_per_order):
        assert energy == pytest.approx(float(np.sum(np.abs(raw.data.astype(np.complex128)) ** 2)), rel=TAILS)


@pytest.mark.parametrize("scene, pulses, bound", [("urban", 256, 0.02), ("dihedral", 96, 0.10)])
def test_the_default_subsample_estimates_every_pulses_energy(scene, pulses, bound, monkeypatch):
    """The default measures the orders on every ENERGY_STRIDE-th pulse: against every pulse (the
    exact sums of the tests here), the dominant order's energy within ``bound`` (measured: urban
    1.1 %, the dihedral's one flash across a few pulses, the worst case, 5.8 %) and every share
    within 0.01; the raw data are the same. Relies on the bit-for-bit guarantee (docs/physics.md
    (D7)): the stride only picks the pulses whose orders are measured, the raw data are reduced from
    the orders' sum either way, so any difference is the bug."""
    assert order_energy.ENERGY_STRIDE > 1
    sampled = simulate(scene, sensor_overrides={"n_pulses": pulses}, progress=False)
    monkeypatch.setattr(order_energy, "ENERGY_STRIDE", 1)
    full = simulate(scene, sensor_overrides={"n_pulses": pulses}, progress=False)
    assert np.array_equal(sampled.raw.data, full.raw.data)
    e_s, e_f = sampled.trace.raw_energy_per_order, full.trace.raw_energy_per_order
    dominant = int(np.argmax(e_f))
    assert e_s[dominant] == pytest.approx(e_f[dominant], rel=bound)
    assert np.max(np.abs(e_s / e_s.sum() - e_f / e_f.sum())) < 0.01


@pytest.mark.parametrize("incidence", [30.0, 50.0])
def test_lone_plate_holds_everything_in_order_one(incidence, every_pulse):
    """A flat plate has no second bounce: order 2 holds nothing, order 1 the raw data's energy."""
    sim = simulate(PLATE, sensor_overrides={"n_pulses": 32, "incidence_angle": incidence},
                   integrator_overrides={"max_depth": 2}, progress=False)
    e1, e2 = sim.trace.raw_energy_per_order
    assert e2 == 0.0 and e1 > 0
    assert e1 == pytest.approx(float(np.sum(np.abs(sim.raw.data.astype(np.complex128)) ** 2)), rel=TAILS)
    assert energy_by_order(sim.trace.raw_energy_per_order)["share"] == {"1": 1.0, "2": 0.0}
    assert depth_warning(sim.trace.raw_energy_per_order) is None


def test_threshold_and_shares():
    """The warning starts at DEEPEST_SHARE of the orders' sum; shares are of that sum."""
    assert DEEPEST_SHARE == 0.10
    assert depth_warning(np.array([0.91, 0.09])) is None
    message = depth_warning(np.array([0.5, 0.4, 0.1]))           # exactly 10 %
    assert "bounce order 3" in message and "--max-depth 4" in message and "10.0 %" in message
    assert depth_warning(np.zeros(3)) is None and depth_warning(None) is None
    assert depth_warning(np.array([5.0])) is None          # one order: single bounce asked for
    shares = energy_by_order(np.array([3.0, 1.0]))
    assert shares["share"] == {"1": 0.75, "2": 0.25} and shares["unit"] == "m^2"
    assert energy_by_order(None) is None


def test_render_writes_and_info_reads_the_orders(tmp_path, capsys):
    """summary.json holds energy_by_order and the warning; ``info`` prints them from the folder
    or the file, and names both kinds of input for anything else. (The dihedral in the tube
    preview, which does not look past its deepest order, so that its second order's 99 % warns.)"""
    out = tmp_path / "dihedral"
    summary = render("dihedral", out, sensor_overrides={"n_pulses": 32},
                     integrator_overrides={"lit_regions": "tiles", "max_depth": 2}, progress=False)
    written = json.loads((out / "summary.json").read_text())
    assert written["energy_by_order"] == summary.energy_by_order
    assert written["energy_by_order"]["share"]["2"] > 0.99
    assert "--max-depth 3" in written["depth_warning"]
    for path in (out, out / "summary.json"):
        assert main(["info", str(path)]) == 0
        text = capsys.readouterr().out
        assert "order  2" in text and "--max-depth 3" in text
    assert render_summary("dihedral") is None and render_summary(PLATE) is None
    with pytest.raises(ParameterError, match="neither scene.xml .* nor summary.json"):
        render_summary(tmp_path / "empty" if (tmp_path / "empty").mkdir() is None else None)
    (tmp_path / "other.json").write_text('{"a": 1}')
    with pytest.raises(ParameterError, match="not a render's summary.json"):
        render_summary(tmp_path / "other.json")
    assert "not in this summary.json" in format_render({"scene": "x", "n_pulses": 1, "rays_per_order": [1]})


def test_exact_kernel_does_not_measure_the_orders():
    """The exact range kernel keeps terms, not spectra: no per-order energy, and none reported."""
    sim = simulate("dihedral", sensor_overrides={"n_pulses": 16}, integrator_overrides={"range_kernel": "exact"},
                   progress=False)
    assert sim.trace.raw_energy_per_order is None
    assert energy_by_order(sim.trace.raw_energy_per_order) is None and depth_warning(None) is None


@pytest.mark.parametrize("scene, depth", [("dihedral", 2), ("trihedral", 3)])
def test_a_corners_own_order_holds_everything_and_nothing_lies_beyond_it(scene, depth):
    """The dihedral's second order and the trihedral's third hold all the energy, and their rays
    leave toward the radar: the tracer finds no ray past them (``rays_beyond`` 0) and does not
    warn, and tracing one order deeper confirms it, the extra order holding nothing. (Caught:
    ``rays_beyond`` not looked for, as before: the README's trihedral warned on every render.)"""
    sensor = {"n_pulses": 48}
    sim = simulate(scene, sensor_overrides=sensor, integrator_overrides={"max_depth": depth})
    energy = sim.trace.raw_energy_per_order
    assert energy[-1] > 0.99 * energy.sum()
    assert sim.trace.rays_beyond == 0 and depth_warning(energy, sim.trace.rays_beyond) is None
    deeper = simulate(scene, sensor_overrides=sensor, integrator_overrides={"max_depth": depth + 1})
    assert deeper.trace.raw_energy_per_order[-1] <= 1e-9 * deeper.trace.raw_energy_per_order.sum()


#: urban's central 300 pulses: enough of its track for rays to meet a third bounce.
PULSES_300 = {"n_pulses": 300}


def test_urban_at_depth_two_has_rays_beyond_and_warns(monkeypatch):
    """urban at depth 2 (order 2 holds 99 %), every launch made to look past its deepest order:
    some rays meet more of the scene, the warning says how many, and a third order traced holds
    energy indeed. Without looking (a tube trace) the warning stays, with the corner caveat.
    Its central 300 pulses (of 779; 294 rays beyond, order 3 holds 3e-4 of the energy): at 128
    pulses no ray meets more of the scene."""
    from sarmitsuba.tracing.driver import mesh_trace
    assert mesh_trace.BEYOND_SHARE == DEEPEST_SHARE          # the tracer looks where the warning would fire
    monkeypatch.setattr(mesh_trace, "BEYOND_SHARE", 0.0)
    sim = simulate("urban", sensor_overrides=PULSES_300, integrator_overrides={"max_depth": 2})
    energy = sim.trace.raw_energy_per_order
    assert sim.trace.rays_beyond > 0
    message = depth_warning(energy, sim.trace.rays_beyond)
    assert message and f"{sim.trace.rays_beyond:,} of its specular rays meet more of the scene" in message
    deeper = simulate("urban", sensor_overrides=PULSES_300, integrator_overrides={"max_depth": 3})
    assert deeper.trace.raw_energy_per_order[-1] > 0
    assert "with nothing beyond it" in depth_warning(energy, None)
