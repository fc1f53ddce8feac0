"""``max_depth = auto``: the probe chooses the bounce orders a scene calls for (docs/physics.md
(DEP1)-(DEP3), ``sarmitsuba/tracing/driver/depth.py``).

The truths are geometric: a plate returns at one order, a dihedral at two, a trihedral at three,
and a street canyon of parallel mirrors at the order its unfolded ray path sets. Unfolded by the
walls' mirrors, a ray entering a canyon of width ``w`` and height ``h`` at incidence ``theta`` runs
``L = 2 h tan(theta)`` across the street before it leaves; it returns to the sensor when it
crossed an odd number of wall images (the street flips its vertical direction once, the walls
its horizontal one), and its order is those crossings plus one. With ``w = 4 m``, ``h = 10 m``:
at 35 deg ``L / w = 3.5`` (3 or 4 crossings: order 4 returns), at 40 deg ``L / w = 4.2`` (4 or 5
crossings: order 6 returns). Each test names the deliberate bug it exists for.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.info import scene_info
from sarmitsuba.pipeline import render, simulate
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.tracing.driver.depth import choose_depth, decide

SCENES = Path(__file__).parent / "scenes"
CANYON = str(SCENES / "street_canyon.xml")


def _choice(source, sensor=None, integrator=None):
    loaded = load_scene(source, sensor or {}, {"max_depth": "auto", **(integrator or {})}, {})
    return choose_depth(loaded)


# ---------------------------------------------------------------------------- the rule (DEP2)
def test_an_order_that_holds_little_does_not_stop_the_choice_when_a_later_one_holds_much():
    """Bug: stopping at the first order whose own share is under the tolerance ("the last order is
    small") would stop at 2 (0.4 %) although order 4 holds half the energy."""
    energy = np.array([50.0, 0.4, 0.0, 49.6, 0.0, 0.0, 0.0, 0.0])
    carried = np.array([1.0, 0.5, 0.4, 0.3, 0.1, 0.0, 0.0, 0.0])
    assert decide(energy, carried, -20.0) == (4, "tolerance")
    # nothing carried past order 4: the orders beyond are empty for a reason the rays saw
    assert decide(energy, np.where(np.arange(8) < 4, carried, 0.0), -20.0) == (4, "nothing beyond")


def test_the_tolerance_is_a_share_of_energy_in_decibels():
    """Shares 90, 9 and 1 %: -20 dB (1 %) keeps two orders, as the 1 % left out is exactly the
    tolerance; -25 dB (0.32 %) needs all three. Bug: reading the tolerance as an amplitude ratio
    (20 log10: 10 %) would keep one order; a strict inequality would keep three at -20 dB."""
    energy, carried = np.array([90.0, 9.0, 1.0]), np.ones(3)
    assert decide(energy, carried, -20.0) == (2, "tolerance")
    assert decide(energy, carried, -25.0) == (3, "cap")
    assert decide(energy, carried, -25.0, rays_beyond=0) == (3, "nothing beyond")
    assert decide(energy, carried, -9.0) == (1, "tolerance")        # -9 dB = 12.6 % >= the 10 % left out
    assert decide(energy, carried, -11.0) == (2, "tolerance")
    assert decide(np.zeros(5), np.zeros(5), -20.0) == (1, "no returns")


def test_the_probe_traces_every_eighth_pulse_of_the_same_track_to_the_cap():
    """The probe traces ray tubes with the scene's own spacing to ``depth_cap``, every order apart,
    on every 8th pulse at an eighth of the PRF: the same track (the first and last positions within
    8 pulses' travel of the full track's) and the same along-track speed. Bugs: probing only to the
    render's depth (it would never see the orders beyond); a PRF left as it was (an eighth of
    the track); probing with the render's fine fast-time grid (eight times the deposit)."""
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.tracing.driver.depth import PROBE_STRIDE, probe_scene
    loaded = load_scene("trihedral", {}, {"ray_spacing": 0.05}, {})
    probe = probe_scene(loaded)
    st, p = probe.settings, probe.params
    # the mesh render's ray_spacing is not the probe's: its tubes are one resolution cell
    assert st.max_depth == 8 and st.lit_regions == "tiles" and st.ray_spacing == 0 and st.oversample == 1
    tiles = probe_scene(load_scene("trihedral", {}, {"ray_spacing": 0.5, "lit_regions": "tiles"}, {}))
    assert tiles.settings.ray_spacing == 0.5
    assert p.n_pulses == loaded.params.n_pulses // PROBE_STRIDE and p.prf == loaded.params.prf / PROBE_STRIDE
    full, thin = acquisition_geometry(loaded.params).positions, acquisition_geometry(p).positions
    step = loaded.params.velocity / loaded.params.prf
    assert np.linalg.norm(thin[0] - full[0]) < PROBE_STRIDE * step
    assert np.linalg.norm(thin[-1] - full[-1]) < PROBE_STRIDE * step
    assert probe_scene(load_scene("trihedral", {}, {"depth_cap": 5}, {})).settings.max_depth == 5


# ---------------------------------------------------------------------------- scenes (DEP1)
@pytest.mark.parametrize("scene, order", [("trihedral", 3), ("dihedral", 2)])
def test_a_corner_reflector_chooses_its_own_order(scene, order):
    """The trihedral's third order and the dihedral's second hold all but 1e-4 of the energy, and
    nothing goes on past them (their last bounce leaves toward the sensor). Bug: the depth taken
    as an index (one less), or the orders' shares shifted by one."""
    loaded, choice = _choice(scene)
    assert choice.depth == order and loaded.settings.max_depth == order
    assert choice.reason == "nothing beyond"
    assert choice.share[order - 1] > 0.999
    assert not np.any(choice.carried[order:] > 0)


@pytest.mark.parametrize("incidence", [35.0, 52.0])
def test_a_dihedral_seen_off_its_symmetry_plane_still_needs_two(incidence):
    """The dihedral's fold runs along track: turned about it by 10 and 7 deg (off its 45 deg
    symmetry plane, one face nearer its normal), the double bounce stays a retro-reflection (the
    two mirrors' product reverses any direction normal to the fold), and it still holds all but
    1 % of the energy. Bug: a probe that takes the depth from the first order's share alone."""
    _, choice = _choice("dihedral", {"incidence_angle": incidence})
    assert choice.depth == 2
    assert choice.share[1] > 0.99


def test_a_plate_chooses_one():
    """A lone plate has one order: no specular ray of its lit face meets anything. Bug: a minimum
    depth of two, or an order 2 invented from rays that meet nothing."""
    _, choice = _choice(str(SCENES / "plane.xml"))
    assert choice.depth == 1 and choice.reason == "nothing beyond"
    assert choice.carried[1:].sum() == 0


@pytest.mark.parametrize("incidence, order", [(35.0, 4), (40.0, 6)])
def test_a_street_canyon_needs_the_order_its_unfolded_path_sets(incidence, order):
    """The canyon's orders below the returning one hold little (under 1 % each at 35 deg: the
    order 3 paths leave forward, the order 2 ones need a crossing the geometry does not allow),
    the returning one (module docstring) over 90 %. Bug: any rule that stops at a small order
    (2 or 3 here) before the one that returns."""
    _, choice = _choice(CANYON, {"incidence_angle": incidence})
    assert choice.depth == order
    assert choice.share[order - 1] > 0.9
    if order == 4:
        assert choice.share[1] < 0.01 and choice.share[2] < 0.01
    assert choice.beyond() <= 0.01


# ---------------------------------------------------------------------------- the render and info
def test_the_render_traces_the_chosen_depth_exactly_and_info_predicts_it():
    """``auto`` on the canyon: ``info`` predicts depth 4 from the same probe; the render traces four
    orders, and its raw data equal those of ``max_depth = 4`` bit for bit (the probe's cap
    settings do not leak into the render: a window sized for 8 orders would change the raw
    data's shape). Bugs: info planning the cap instead of the choice; the render tracing to
    the cap; the probe's settings kept."""
    predicted = scene_info(CANYON).depth
    auto = simulate(CANYON)
    fixed = simulate(CANYON, integrator_overrides={"max_depth": 4})
    assert predicted["mode"] == "auto" and predicted["depth"] == auto.depth.depth == 4
    assert len(auto.trace.raw_energy_per_order) == 4 and fixed.depth is None
    assert auto.raw.data.shape == fixed.raw.data.shape
    assert np.array_equal(auto.raw.data, fixed.raw.data)
    shares = auto.trace.raw_energy_per_order / auto.trace.raw_energy_per_order.sum()
    assert shares[3] > 0.9                          # the render measures what the probe found


def test_the_summary_says_the_cap_stopped_it(tmp_path):
    """``depth_cap = 2`` on the trihedral (which needs 3; its first two orders hold about as much
    as each other, so the first alone leaves half of the energy up to the cap out): the choice
    stops at the cap, says so with the reason ``cap``, and the render warns, naming the cap and
    how to raise it; a fixed depth writes ``mode: fixed``. Bug: a cap that stops the depth
    without a word."""
    summary = render("trihedral", tmp_path / "capped", integrator_overrides={"depth_cap": 2}, progress=False)
    assert summary.depth["mode"] == "auto" and summary.depth["depth"] == 2 and summary.depth["reason"] == "cap"
    assert "cap 2" in summary.depth_warning and "depth_cap" in summary.depth_warning
    assert set(summary.depth["seconds_by_order"]) == {"1", "2"}
    fixed = render("trihedral", tmp_path / "fixed", integrator_overrides={"max_depth": 3}, progress=False)
    assert fixed.depth["mode"] == "fixed" and fixed.depth["depth"] == 3 and fixed.depth_warning is None


def test_the_readme_example_renders_with_no_depth_warning(tmp_path):
    """The README's Python example (a house, a trihedral on rough ground, ``max_depth`` left to
    auto), on fewer pulses. Bug: auto warning of the orders it chose to leave out."""
    import trimesh

    import sarmitsuba
    ground = trimesh.Trimesh([[-60, -60, 0], [60, -60, 0], [60, 60, 0], [-60, 60, 0]], [[0, 1, 2], [0, 2, 3]])
    house = trimesh.creation.box((20, 20, 10)).apply_translation((0, 0, 5))
    reflector = trimesh.load(Path(__file__).parents[1] / "scenes/meshes/trihedral.obj").apply_translation((0, 30, 0))
    scene = sarmitsuba.Scene(
        meshes=[(ground, {"material": "medium_dry_ground", "gamma_db": -14}, "ground"),
                (house, "concrete", "house"), (reflector, "pec", "reflector")],
        sensor={"frequency": 9.6e9, "bandwidth": 150e6, "incidence_angle": 45, "scene_center": (0, 0, 0),
                "n_pulses": 96})
    summary = render(scene, tmp_path / "house", progress=False)
    assert summary.depth["mode"] == "auto" and summary.depth_warning is None
    assert summary.depth["reason"] in ("tolerance", "nothing beyond")


@pytest.mark.parametrize("flag, value", [("--max-depth", "0"), ("--max-depth", "deep"),
                                         ("--integrator-set", "depth_cap=0"),
                                         ("--integrator-set", "depth_tolerance_db=3"),
                                         ("--integrator-set", "depth_tolerance_db=nan")])
def test_bad_depth_settings_are_refused_with_one_message(capsys, flag, value):
    """Bug: a depth setting out of range accepted (a cap of 0 would trace nothing; a positive
    tolerance would stop before the first order)."""
    from sarmitsuba.cli import main
    with pytest.raises(SystemExit) as exit_info:
        code = main(["info", "trihedral", flag, value])
        raise SystemExit(code)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err and ("max_depth" in err[-1] or "max-depth" in err[-1] or "depth_" in err[-1])
    assert "Traceback" not in "\n".join(err)
