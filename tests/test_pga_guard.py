"""PGA needs dominant scatterers (sarmitsuba.focus.autofocus, docs/physics.md (PGA3)).

On rendered clutter alone PGA used to fit a "phase error" to speckle (17 to 20 iterations, 6 to 7
rad rms) and smear an image that was already focused (its coherence with the input fell to 0.08 to
0.19). The truth here is the rendered image itself: with no dominant scatterer PGA must warn and
hand it back untouched; with a trihedral 30 dB above the same kind of clutter it must still run
and restore the peak that the true track gives.
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.focus import ImageGrid, ffbp
from sarmitsuba.focus.autofocus import AutofocusWarning, pga
from sarmitsuba.pipeline import simulate

MOTION = "0.02, 40"          # 2 cm sinusoidal sway of period 40 m (the issue-30 case)
GROUND = trimesh.Trimesh([[-40, -40, 0], [40, -40, 0], [40, 40, 0], [-40, 40, 0]], [[0, 1, 2], [0, 2, 3]])


def _render(gamma_db: float, trihedral: bool, ground: trimesh.Trimesh = GROUND, pixels=((256, 0.1), (64, 0.2))) -> tuple:
    """True-track and nominal-track ffbp images (``pixels``: count and spacing [m] along track and in
    range; default 0.1 m x 0.2 m, 256 x 64) of rough ``ground``, optionally with the built-in
    trihedral at the scene centre, and the raw data."""
    meshes = [(ground, {"material": "medium_dry_ground", "gamma_db": gamma_db}, "ground")]
    if trihedral:
        meshes.append((trimesh.load("scenes/meshes/trihedral.obj"), "pec", "trihedral"))
    scene = sarmitsuba.Scene(meshes=meshes, integrator={"max_depth": 3 if trihedral else 1},
                             sensor={"frequency": 9.6e9, "bandwidth": 150e6, "incidence_angle": 45,
                                     "scene_center": (0, 0, 0), "motion_error": MOTION})
    sim = simulate(scene, focuser="ffbp", image_size=(32, 32))
    frame = sim.image
    (n_az, d_az), (n_rg, d_rg) = pixels
    grid = ImageGrid(origin=frame.origin, azimuth_direction=frame.azimuth_direction,
                     range_direction=frame.range_direction, azimuth=(np.arange(n_az) - n_az // 2) * d_az,
                     range=(np.arange(n_rg) - n_rg // 2) * d_rg, plane="ground")
    return ffbp(sim.raw, grid), ffbp(sim.raw.on_track("nominal"), grid), sim.raw


@pytest.fixture(scope="module")
def clutter():
    return _render(-14.0, trihedral=False)


@pytest.mark.parametrize("track", ["true", "nominal"])
def test_pga_hands_clutter_back_unchanged(clutter, track):
    """Catches PGA running on speckle (no dominance check, or a threshold below clutter's 12 to 14
    dB): it changed every pixel of this image (coherence with the input 0.19 / 0.08)."""
    image = clutter[0 if track == "true" else 1]
    with pytest.warns(AutofocusWarning, match="no dominant scatterer"):
        out, report = pga(image)
    assert np.array_equal(out.data, image.data)
    assert not report.applied and report.iterations == 0 and report.rms_phase_error == 0.0
    assert report.dominance_db < 16.0            # speckle: about 10 log10((ln N + 0.58) / ln 2) = 11.7 dB, N = 16384
    assert out.metadata["autofocus"]["applied"] is False
    assert out.metadata["autofocus"]["dominance_db"] == pytest.approx(report.dominance_db, abs=0.01)


def test_pga_judges_clutter_where_there_is_signal():
    """Rough ground 20 m across in an image three times as wide in range (the rest empty, lit only
    by sidelobes about 23 dB below the clutter): the dominance is the clutter's (below 16 dB, as
    for clutter filling the image; measured 14.8 dB), PGA warns and hands the image back
    unchanged. Catches the median taken over every non-zero pixel, which the empty part drags
    down (measured 27.5 dB there, and PGA ran)."""
    plate = trimesh.Trimesh([[-10, -10, 0], [10, -10, 0], [10, 10, 0], [-10, 10, 0]], [[0, 1, 2], [0, 2, 3]])
    image = _render(-14.0, trihedral=False, ground=plate, pixels=((160, 0.1), (120, 0.5)))[1]
    inside = np.abs(image.range) < 9.0
    assert 0.2 < inside.mean() < 0.4                                   # a third of the image holds the ground
    with pytest.warns(AutofocusWarning, match="no dominant scatterer"):
        out, report = pga(image)
    assert np.array_equal(out.data, image.data)
    assert report.dominance_db < 16.0


def _peak_db(image, half_m: float = 2.0) -> float:
    """Largest magnitude [dB] within ``half_m`` of the scene centre (PGA leaves a shift of about 1 m)."""
    rows = np.abs(image.azimuth) <= half_m
    cols = np.abs(image.range) <= half_m
    return float(20.0 * np.log10(np.abs(image.data[np.ix_(rows, cols)]).max()))


def test_pga_still_restores_a_trihedral_in_clutter():
    """Catches a dominance threshold so strict that it refuses a real target: the trihedral stands
    29.8 dB above the median of rough ground at gamma 0 dB on the nominal track, and PGA restores
    its peak (measured: 16.1 dB on the nominal track, 21.3 dB after PGA and on the true track)."""
    true, nominal, _ = _render(0.0, trihedral=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AutofocusWarning)   # no refusal, and it converges
        out, report = pga(nominal)
    assert report.applied and report.iterations > 0
    assert report.dominance_db > 27.0
    assert _peak_db(nominal) < _peak_db(true) - 3.0                    # visibly defocused before
    assert abs(_peak_db(out) - _peak_db(true)) < 0.5                   # restored after


def test_the_cli_says_pga_was_not_applied(clutter, tmp_path, capsys):
    """Catches the CLI reporting "PGA 0 iterations, phase error 0 rad rms" as if PGA had run."""
    from sarmitsuba.cli import main
    raw = clutter[2].save(tmp_path / "raw.npz")
    assert main(["focus", str(raw), "--algorithm", "ffbp", "--autofocus", "pga", "--out", str(tmp_path / "out"),
                 "--no-progress"]) == 0
    captured = capsys.readouterr()
    assert "PGA not applied" in captured.out, captured.out
    assert "no dominant scatterer" in captured.err and "Traceback" not in captured.err
