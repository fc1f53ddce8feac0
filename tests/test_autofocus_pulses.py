"""Phase gradient autofocus through the pulses (docs/physics.md (PGA6)): the per-pulse phase
against closed forms, and the built-in trihedral's sways that the image-domain estimate failed.

Deliberate bugs tried (each fails a test below): ``pulse_correction`` interpolating linearly
(0.03 rad on a 1 m grid of a 30 m sway), reading the spectrum at ``+s`` for ``-s`` (the mirrored
sway), ``ambiguity_spacing`` with ``v`` for ``2 v``; ``response_spread`` without its ``2 sqrt 2``;
the samples read where the smear's centroid puts the point; the round loop skipped without a
refusal and the command line's made-up reason (the original defect); the band test left out of
(PGA4) (the wall).
"""
from __future__ import annotations

import math
import warnings

import trimesh

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.analysis import analyze_point_target
from sarmitsuba.focus.autofocus import AutofocusReport, AutofocusWarning
from sarmitsuba.focus.autofocus_pulses import ambiguity_spacing, outcome_line, pulse_correction, response_spread
from sarmitsuba.focus.dispatch import autofocus_image, render_focusing
from sarmitsuba.pipeline import refocus, simulate


class _Raw:
    def __init__(self, along):
        self.tx_position = np.c_[along, np.full_like(along, 1000.0), np.full_like(along, 1000.0)]


def _report(aperture, correction, support=None):
    n = aperture.size
    return AutofocusReport(phase_error=correction, support=np.ones(n, bool) if support is None else support,
                           iterations=1, rms_phase_error=0.0, converged=True, lines=3, window=[n],
                           deramp=True, correction=correction, aperture_position=aperture)


@pytest.mark.parametrize("period", [30.0, 13.0])
def test_pulse_phase_is_the_sway_read_at_each_antenna_position(period):
    """A sinusoidal correction sampled on spectral cells 0.95 m apart (descending, as a deramped
    spectrum orders them) read at pulses 0.4 m apart, on a track that starts 0.2 m off the
    mid-aperture position: the closed form sin(2 pi s / P) within 2e-3 rad (linear interpolation
    leaves 0.03 rad at 30 m)."""
    aperture = -0.95 * (np.arange(80) - 40.0)
    correction = 5.0 * np.sin(2 * np.pi * aperture / period)
    along = np.arange(-30.0, 30.0, 0.4) + 0.2
    track = {"position": [0.2, 1000.0, 1000.0], "direction": [1.0, 0.0, 0.0]}
    phase = pulse_correction(_report(aperture, correction), _Raw(along), track)
    assert np.max(np.abs(phase - 5.0 * np.sin(2 * np.pi * (along - 0.2) / period))) < 2e-3


def test_pulses_beyond_the_support_keep_its_end_values():
    """Outside the supported cells the correction is held at the support's ends (a linear
    function there: the pulses at -10 m and +10 m get the values at -5 m and +5 m)."""
    aperture = np.linspace(20.0, -20.0, 41)
    correction = 0.3 * aperture
    track = {"position": [0.0, 0.0, 0.0], "direction": [1.0, 0.0, 0.0]}
    phase = pulse_correction(_report(aperture, correction, np.abs(aperture) <= 5.0), _Raw(np.array([-10.0, 2.0, 10.0])),
                             track)
    assert phase == pytest.approx([-1.5, 0.6, 1.5], abs=1e-9)


def test_ambiguity_spacing_is_the_closed_form_for_the_builtin_trihedral():
    """lambda R0 PRF / (2 v): 9.6 GHz, 250 Hz, 100 m/s, the farthest column's closest approach
    from a track 1000 m up and 1000 m across."""
    raw = simulate("trihedral", focuser="ffbp").raw
    grid = render_focusing(raw).grid
    far = grid.origin + grid.range[:, None] * grid.range_direction
    r0 = np.max(np.hypot(far[:, 1] - 1000.0, far[:, 2] - 1000.0))
    assert ambiguity_spacing(raw, grid) == pytest.approx(299792458.0 / 9.6e9 * r0 * 250.0 / 200.0, rel=1e-3)


@pytest.mark.parametrize("period", [30.0, 60.0])
def test_pga_through_the_pulses_meets_the_true_track(period):
    """A 2 cm sway (1.41 cm line of sight) of 30 m and 60 m period on the built-in trihedral,
    FFBP on the nominal track with PGA: azimuth PSLR within 3 dB of the true track's and IRW
    within 10 % (the image-domain estimate gave -26.9 and -33.1 dB against -58.1)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = simulate("trihedral", sensor_overrides={"motion_error": f"0.02, {period:g}"}, focuser="ffbp").raw
        true = analyze_point_target(refocus(raw, "ffbp"), (0, 0, 0), chip=32)
        image = refocus(raw, "ffbp", track="nominal", autofocus="pga")
    fixed = analyze_point_target(image, (0, 0, 0), chip=32)
    assert image.metadata["autofocus"]["applied_to"] == "pulses"
    assert fixed.pslr_azimuth_db <= true.pslr_azimuth_db + 3.0
    assert math.isclose(fixed.irw_azimuth, true.irw_azimuth, rel_tol=0.10)


def _sway(los: float, period: float):
    """Raw data of the built-in trihedral with a sinusoidal sway of line-of-sight amplitude ``los``
    [m] (the horizontal amplitude over sin 45 deg) and ``period`` [m]."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate("trihedral", sensor_overrides={"motion_error": f"{los * math.sqrt(2):.6g}, {period:g}"},
                        focuser="ffbp").raw


def test_the_defocused_response_spans_the_sweep_of_its_instantaneous_position():
    """A 2 cm line-of-sight sway of 20 m period: the estimation image's response spreads over
    lambda R0 max|phi'| / (2 pi) = lambda R0 (4 pi a / lambda)(2 pi / P) / (2 pi) = 17.8 m, within 5 %."""
    raw = _sway(0.02, 20.0).on_track("nominal")
    spacing = ambiguity_spacing(raw, render_focusing(raw).grid)
    image = autofocus_image(raw, "ffbp", window_range="taylor", azimuth_margin=spacing / 2)
    expected = 1414.2136 * 4 * math.pi * 0.02 * (2 * math.pi / 20.0) / (2 * math.pi)
    assert response_spread(image, spacing) == pytest.approx(expected, rel=0.05)


@pytest.mark.parametrize("los, period", [(0.05, 10.0), (0.01, 20.0)])
def test_a_point_smeared_however_far_is_found(los, period):
    """5 cm of 10 m period: an 89 m response (4 pi R0 a / P) where the 250 Hz PRF leaves 55.3 m
    between ambiguities, folding round them (the error turns by up to 50 rad from one pulse to the
    next); 1 cm of 20 m: 8.9 m on the 23 m image asked for, no longer point-like there. Both were
    refused; on the pulses (docs/physics.md (PGA7)) PGA finds the trihedral and meets the true
    track: azimuth PSLR within 3 dB, IRW within 10 %. Catches the samples read where the smear's
    centroid puts the point instead of where the beam saw it (the 5 cm sway stays smeared)."""
    raw = _sway(los, period)
    true = analyze_point_target(refocus(raw, "ffbp"), (0, 0, 0), chip=32)
    with warnings.catch_warnings():
        warnings.simplefilter("error", AutofocusWarning)                    # found: no refusal
        image = refocus(raw, "ffbp", track="nominal", autofocus="pga", autofocus_reference=(0.0, 0.0, 0.0))
    fixed = analyze_point_target(image, (0, 0, 0), chip=32)
    record = image.metadata["autofocus"]
    assert record["applied"] and record["rounds"] >= 1 and record["refusal"] == ""
    assert fixed.pslr_azimuth_db <= true.pslr_azimuth_db + 3.0
    assert math.isclose(fixed.irw_azimuth, true.irw_azimuth, rel_tol=0.10)


def test_an_image_that_cannot_be_deramped_is_refused_saying_so(monkeypatch, tmp_path, capsys):
    """The original defect: an estimation image that needs more azimuth upsampling than allowed
    (here: none allowed) cannot be read at the pulses' positions; PGA used to converge on it, skip
    every round, record ``applied: false`` with no refusal, and the command line said "no dominant
    scatterer" of a trihedral 56 dB over its clutter. Now the metadata give the reason and the
    command line prints the metadata's. Catches the round loop skipped silently (an empty refusal)."""
    import sarmitsuba.focus.pga_deramp as deramp
    from sarmitsuba.cli import main
    raw = _sway(0.02, 40.0)
    monkeypatch.setattr(deramp, "MAX_UPSAMPLE", 0)
    path = raw.save(tmp_path / "raw.npz")
    assert main(["focus", str(path), "--track", "nominal", "--autofocus", "pga", "--out", str(tmp_path / "out"),
                 "--no-progress"]) == 0
    from sarmitsuba.core.image import SarImage
    record = SarImage.load(tmp_path / "out" / "image.npz").metadata["autofocus"]
    assert record["applied"] is False and record["rounds"] == 0 and "cannot be deramped" in record["refusal"]
    captured = capsys.readouterr()
    assert f"PGA not applied ({record['refusal']}; image unchanged)" in captured.out and "dominant" not in captured.out
    assert "cannot be deramped" in captured.err                      # the warning, as the command line shows it


def test_the_command_line_says_what_the_metadata_say():
    """The line is read from the record alone: an applied record gives its rounds, iterations and rms;
    a refused one its refusal; a record refused without a reason (the defect's) says so rather than
    naming one. Catches the old fallback "no dominant scatterer"."""
    applied = {"method": "pga", "applied": True, "rounds": 6, "iterations": 24, "rms_phase_error_rad": 1.234,
               "refusal": "", "linear_part": {"estimated": True, "shift_m": -1.25}}
    assert outcome_line(applied) == ("PGA applied through the pulses: 6 round(s), 24 iterations, phase removed "
                                     "1.23 rad rms, shift -1.25 m removed at the reference")
    refused = {"method": "pga", "applied": False, "rounds": 0, "iterations": 0, "refusal": "3 point-like range line(s)"}
    assert outcome_line(refused) == "PGA not applied (3 point-like range line(s); image unchanged)"
    silent = {"method": "pga", "applied": False, "rounds": 0, "iterations": 8, "converged": True, "refusal": ""}
    assert "dominant" not in outcome_line(silent) and "no reason recorded" in outcome_line(silent)


def test_a_wall_without_a_point_is_refused_through_the_pulses_too():
    """A PEC wall on a 16 m rough plate, no point scatterer, a 2 cm, 40 m sway: the wall stands
    above (PGA3)'s dominance, and on the widened rectangular-window estimation image 14 of its
    lines gather their energy as a point's would (PGA there collapses the wall and the image ends
    +0.2 dB NRMSE from the true track's, against -9 dB on the nominal track). The wall's double
    bounce fills a third of the beam's Doppler band (a point fills it however smeared, eq.
    (PGA4)): no line is point-like, PGA warns and the nominal image comes back unchanged. Catches
    (PGA4) judged by how the energy gathers on the estimation image."""
    ground = trimesh.Trimesh([[-8, -8, 0], [8, -8, 0], [8, 8, 0], [-8, 8, 0]], [[0, 1, 2], [0, 2, 3]])
    wall = trimesh.creation.box((20.0, 0.3, 6.0)).apply_translation((0, 0, 3.0))
    scene = sarmitsuba.Scene(meshes=[(ground, {"material": "medium_dry_ground", "gamma_db": -14.0}, "ground"),
                                     (wall, "pec", "wall")], integrator={"max_depth": 3},
                             sensor={"frequency": 9.6e9, "bandwidth": 150e6, "incidence_angle": 45.0, "prf": 250.0,
                                     "velocity": 100.0, "altitude": 1000.0, "scene_center": (0, 0, 0),
                                     "azimuth_beamwidth": 1.2, "motion_error": "0.02, 40"})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = simulate(scene, focuser="ffbp").raw
    with pytest.warns(AutofocusWarning, match="not applied"):
        image = refocus(raw, "ffbp", track="nominal", autofocus="pga")
    assert image.metadata["autofocus"]["applied"] is False
    assert np.array_equal(image.data, refocus(raw, "ffbp", track="nominal").data)


def test_a_large_sway_needs_the_rounds_through_the_pulses():
    """5 cm of 60 m period (line of sight): one round leaves -54.3 dB (measured), six meet the true
    track within 3 dB of PSLR and 10 % of IRW, the linear part removed at the trihedral's apex."""
    raw = _sway(0.05, 60.0)
    true = analyze_point_target(refocus(raw, "ffbp"), (0, 0, 0), chip=32)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        image = refocus(raw, "ffbp", track="nominal", autofocus="pga", autofocus_reference=(0.0, 0.0, 0.0))
    fixed = analyze_point_target(image, (0, 0, 0), chip=32)
    assert image.metadata["autofocus"]["rounds"] > 1
    assert fixed.pslr_azimuth_db <= true.pslr_azimuth_db + 3.0
    assert math.isclose(fixed.irw_azimuth, true.irw_azimuth, rel_tol=0.10)
