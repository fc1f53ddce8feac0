"""What a new user hits with tracks and footprints (issue 55, item 7): refusals and warnings that
name the right thing, each test failing on the code before its fix."""
from __future__ import annotations

import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.cli import main


# ============================================================================ refusals naming the track
def test_omega_k_refuses_circular_data_by_their_track(tmp_path, capsys):
    """Circular raw data given to omega-K and RDA: exit 2 with a message that calls them circular
    (trajectory = circular) and names bp/ffbp. The bug it catches: a circular acquisition runs in
    spotlight mode internally, and the refusal read only ``mode``, so it called the data
    "spotlight", which the user never asked for."""
    from sarmitsuba.pipeline import simulate
    sim = simulate("trihedral", sensor_overrides={"trajectory": "circular", "arc_deg": 2.0})
    path = tmp_path / "raw.npz"
    sim.raw.save(path)
    for algorithm in ("omegak", "rda"):
        rc = main(["focus", str(path), "--algorithm", algorithm, "--out", str(tmp_path / algorithm), "--no-progress"])
        err = capsys.readouterr().err
        assert rc == 2, err
        assert "circular" in err and "are spotlight" not in err and "--algorithm bp or ffbp" in err, err


# ============================================================================ a track that never sees the scene
def _shifted_track(tmp_path, dx: float):
    """scenes/drone_track.csv (the README's example) with every x moved by ``dx`` metres."""
    import csv
    from pathlib import Path
    rows = list(csv.reader(open(Path(sarmitsuba.__file__).resolve().parent.parent / "scenes" / "drone_track.csv")))
    path = tmp_path / f"drone_{dx:+g}.csv"
    with open(path, "w", newline="") as fh:
        csv.writer(fh).writerows([rows[0]] + [[r[0], f"{float(r[1]) + dx:.6f}"] + r[2:] for r in rows[1:]])
    return path


@pytest.mark.parametrize("mode", ["stripmap", "spotlight"])
def test_a_track_ending_500_m_before_the_scene_is_refused_by_info_and_render(tmp_path, capsys, mode):
    """The README's drone track moved 500 m back along x, so that it ends 489 m before the
    trihedral: ``info`` and ``render`` exit 2 with one message naming the trajectory file and the
    beam, and render writes nothing. The bug it catches: before, stripmap rendered an all-zero image
    (0 rays) and spotlight steered the beam 74 deg off broadside (the peak 81 dB down), both with
    exit 0, and info said "Warnings: none". The unmoved track is the control: info accepts it."""
    track = _shifted_track(tmp_path, -500.0)
    for command in (["info"], ["render", "--out", str(tmp_path / "out"), "--no-progress"]):
        rc = main(command + ["trihedral", "--set", f"trajectory={track}", "--set", f"mode={mode}"])
        err = capsys.readouterr().err
        assert rc == 2, err
        message = [line for line in err.splitlines() if line.startswith("error:")]
        assert len(message) == 1 and f"trajectory = '{track.name}'" in message[0], err
        assert "no pulse's beam reaches the scene" in message[0] and "fly the track past the scene" in message[0]
        assert ("60 deg" in message[0]) == (mode == "spotlight"), message[0]
    assert not (tmp_path / "out").exists()
    rc = main(["info", "trihedral", "--set", f"trajectory={_shifted_track(tmp_path, 0.0)}", "--set", f"mode={mode}"])
    assert rc == 0 and "no pulse's beam" not in capsys.readouterr().out


def test_a_circle_about_a_point_off_the_scene_is_refused():
    """trajectory = circular flies a 2 deg arc about a scene_center 200 m along track from the
    trihedral: its beam (+-1.35 deg, on scene_center) never reaches the trihedral, 8 deg off
    broadside. The same arc about the trihedral loads. Catches a check that skips circular tracks
    (no straight track_direction to test against, as check_acquisition does)."""
    from sarmitsuba.core.radar import ParameterError
    from sarmitsuba.scene.loader import load_scene
    arc = {"trajectory": "circular", "arc_deg": 2.0}
    with pytest.raises(ParameterError, match=r"trajectory = 'circular': no pulse's beam reaches the scene"):
        load_scene("trihedral", {**arc, "scene_center": "200, 0, 0"})
    assert load_scene("trihedral", arc).params.n_pulses > 1


def _one_pulse(incidence: float, squint: float, heading: float = 0.0):
    """A one-pulse straight stripmap acquisition with the scene centre at the origin, and its
    antenna worked out by hand (docs/design.md section 4: heading 0 flies +x, looking right looks
    toward -y): ``A = (-R0 tan(squint), H tan(theta), H)``, ``R0 = H / cos(theta)``."""
    import math

    import numpy as np

    from sarmitsuba.core.radar import RadarParameters
    height = 1000.0
    r0 = height / math.cos(math.radians(incidence))
    antenna = np.array([-r0 * math.tan(math.radians(squint)), height * math.tan(math.radians(incidence)), height])
    params = RadarParameters(scene_center=(0.0, 0.0, 0.0), n_pulses=1, incidence_angle=incidence, squint=squint,
                             altitude=height, azimuth_beamwidth=1.2, heading=heading)
    return params, antenna


@pytest.mark.parametrize("incidence, squint", [(30.0, 0.0), (60.0, 20.0), (45.0, -35.0)])
def test_the_stripmap_beam_reaches_to_its_first_nulls_and_no_farther(incidence, squint):
    """A 2 cm box at along-track angle ``squint +- 0.97 h`` from broadside is in the beam and at
    ``squint +- 1.03 h`` is refused, ``h`` the first null of the two-way tapered pattern
    ``sinc^2(L sin(phi) / lambda)`` whose 3 dB width is azimuth_beamwidth = 1.2 deg: the 3 dB point
    is ``L sin(phi) / lambda = 0.4429`` (sinc^2 = 1/2), the first null 1, so
    ``sin(h) = sin(0.6 deg) / 0.4429`` (h = 1.355 deg). Catches testing against the 3 dB width
    (refuses 0.97 h), ignoring the squint, or measuring the angle from the track instead of from
    broadside."""
    import math

    import numpy as np

    from sarmitsuba.core.radar import ParameterError
    from sarmitsuba.scene.track_checks import check_beam_reach
    params, antenna = _one_pulse(incidence, squint)
    h = math.asin(math.sin(math.radians(0.6)) / 0.4429)
    broadside = np.array([0.0, -antenna[1], -antenna[2]]) / math.hypot(antenna[1], antenna[2])
    for side in (-1.0, 1.0):
        for factor, seen in ((0.97, True), (1.03, False)):
            phi = math.radians(squint) + side * factor * h
            point = antenna + 1500.0 * (math.cos(phi) * broadside + math.sin(phi) * np.array([1.0, 0.0, 0.0]))
            lo, hi = point - 0.01, point + 0.01
            if seen:
                check_beam_reach(params, lo, hi)
            else:
                with pytest.raises(ParameterError, match="trajectory = 'straight'.*outside the beam"):
                    check_beam_reach(params, lo, hi)


@pytest.mark.parametrize("incidence, squint", [(30.0, 0.0), (60.0, 20.0)])
def test_a_long_scene_whose_end_reaches_into_the_beam_is_seen(incidence, squint):
    """A box 120 m long along track, 1,500 m from the one pulse, on either side: its centre
    1.5 deg beyond the beam's first null ``h``, its near end (half its length, 2.3 deg, nearer)
    0.8 deg inside the beam: accepted; its centre 4.5 deg beyond, its near end 2.2 deg beyond:
    refused. Catches the scene taken as a point (its extent dropped: the first box is refused),
    which a test with a target of 2 cm cannot tell apart."""
    import math

    import numpy as np

    from sarmitsuba.core.radar import ParameterError
    from sarmitsuba.scene.track_checks import check_beam_reach
    params, antenna = _one_pulse(incidence, squint)
    h = math.asin(math.sin(math.radians(0.6)) / 0.4429)
    broadside = np.array([0.0, -antenna[1], -antenna[2]]) / math.hypot(antenna[1], antenna[2])
    half = np.array([60.0, 1.0, 1.0])
    for side in (-1.0, 1.0):
        for beyond, seen in ((1.5, True), (4.5, False)):
            phi = math.radians(squint) + side * (h + math.radians(beyond))
            centre = antenna + 1500.0 * (math.cos(phi) * broadside + math.sin(phi) * np.array([1.0, 0.0, 0.0]))
            if seen:
                check_beam_reach(params, centre - half, centre + half)
            else:
                with pytest.raises(ParameterError, match="outside the beam"):
                    check_beam_reach(params, centre - half, centre + half)


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_a_spotlight_beam_is_steered_no_farther_than_60_deg(side):
    """State vectors of a short level track, the scene centre 58 deg (accepted) and 62 deg
    (refused) from broadside, ahead of and behind the antenna: the spotlight beam is steered at the
    scene centre only within the 60 deg of the ``squint`` range. Catches a spotlight check that
    only asks whether the steered beam holds the scene (it always does)."""
    import math

    import numpy as np

    from sarmitsuba.core.radar import ParameterError, RadarParameters
    from sarmitsuba.core.trajectory import StateVectors
    from sarmitsuba.scene.track_checks import check_beam_reach
    for angle, seen in ((58.0, True), (62.0, False)):
        perpendicular = 500.0                                  # the antenna's distance from the track's line
        x = -side * perpendicular * math.tan(math.radians(angle))
        height = perpendicular / math.sqrt(2.0)
        time = np.array([0.0, 0.02])
        position = np.array([[x, height, height], [x + 0.2, height, height]])
        states = StateVectors(time, position, np.array([[10.0, 0.0, 0.0]] * 2))
        params = RadarParameters(scene_center=(0.0, 0.0, 0.0), n_pulses=2, trajectory=states, mode="spotlight")
        lo, hi = np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 1.0])
        if seen:
            check_beam_reach(params, lo, hi)
        else:
            with pytest.raises(ParameterError, match="beyond the 60 deg an antenna is steered to"):
                check_beam_reach(params, lo, hi)


# ============================================================================ parameters that do nothing
def test_arc_deg_without_a_circular_trajectory_is_refused(capsys):
    """``--set arc_deg=20`` on the default straight track: exit 2 naming arc_deg and the fix, as
    the project refuses other parameters its model does not use (a material's thickness
    without model = slab). The bug: the arc was ignored silently and a straight track rendered. With
    trajectory = circular it is accepted."""
    assert main(["info", "trihedral", "--set", "arc_deg=20"]) == 2
    err = capsys.readouterr().err
    assert "arc_deg = 20 deg is used only by trajectory = 'circular'" in err and "trajectory=circular" in err
    assert main(["info", "trihedral", "--set", "arc_deg=20", "--set", "trajectory=circular"]) == 0


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_a_motion_error_beyond_a_range_cell_is_warned_about(incidence):
    """A sinusoidal error across the track moves the antenna by ``A sin(theta)`` in slant range;
    beyond the slant-range resolution ``c / (2 B)`` (0.999 m at 150 MHz) a processor without the
    true track cannot focus it. At 30 and 60 deg incidence the limit is ``A = c / (2 B sin(theta))``
    (2.00 m and 1.15 m): 2 % below it no warning, 2 % above it one naming motion_error; a random
    error warns at a third of it (3 x RMS). Catches the bug (50 m accepted without a word), and a
    bound using cos instead of sin (the two only agree at 45 deg)."""
    import math

    from sarmitsuba.core.constants import SPEED_OF_LIGHT
    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.scene.track_checks import motion_error_note
    limit = SPEED_OF_LIGHT / (2.0 * 150e6 * math.sin(math.radians(incidence)))
    for error, warns in ((f"{0.98 * limit}, 40", False), (f"{1.02 * limit}, 40", True), ("50, 40", True),
                         (f"random, {0.98 * limit / 3}, 50", False), (f"random, {1.02 * limit / 3}, 50", True)):
        params = RadarParameters(scene_center=(0.0, 0.0, 0.0), bandwidth=150e6, incidence_angle=incidence,
                                 motion_error=error)
        note = motion_error_note(params)
        assert (note is not None) == warns, (incidence, error, note)
        assert note is None or note.startswith("motion_error = ")


def test_a_50_m_motion_error_is_listed_by_info(capsys):
    """``info trihedral --set motion_error=50,40`` lists the motion-error warning (it said
    "Warnings: none")."""
    assert main(["info", "trihedral", "--set", "motion_error=50,40"]) == 0
    out = capsys.readouterr().out
    warnings = out.split("Warnings", 1)[1]
    assert "motion_error = '50, 40'" in warnings and "35.4 m in slant range" in warnings


def test_replaced_platform_values_are_named_only_when_the_user_gave_them(capsys):
    """A trajectory file replaces the platform parameters: the warning "(the values given are not
    used)" appears when the user gave such a value with it (--set altitude=500), not when only the
    built-in scene's defaults are replaced. The bug: it named the scene's altitude 1000 and velocity
    100, which the user never gave."""
    track = str(_shifted_track_path())
    assert main(["info", "trihedral", "--set", f"trajectory={track}"]) == 0
    assert "not used" not in capsys.readouterr().err
    assert main(["info", "trihedral", "--set", f"trajectory={track}", "--set", "altitude=500"]) == 0
    err = capsys.readouterr().err
    assert "altitude 500 -> 150" in err and "(the values given are not used)" in err and "velocity" not in err


def _shifted_track_path():
    from pathlib import Path
    return Path(sarmitsuba.__file__).resolve().parent.parent / "scenes" / "drone_track.csv"


# ============================================================================ a track too short for its aperture
def _two_rows(tmp_path):
    """Two state vectors with velocities 1 m apart (0.1 s at 10 m/s), abeam of the trihedral at
    150 m height and 150 m ground range (slant range 212.1 m)."""
    path = tmp_path / "two.csv"
    path.write_text("time_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps\n0.0,-0.5,150,150,10,0,0\n0.1,0.5,150,150,10,0,0\n")
    return path


@pytest.mark.parametrize("mode", ["stripmap", "spotlight"])
def test_a_two_row_track_too_short_for_its_aperture_is_warned_about(tmp_path, capsys, mode):
    """A 1 m aperture from two state vectors: info lists a warning naming the file, its span and
    the aperture the resolution needs, ``lambda R / (2 rho)`` (Cumming and Wong eq. 4.37):
    stripmap ``rho = L / 2`` of the tapered beam (``L = 0.4429 lambda / sin(0.6 deg)``), so
    ``R sin(0.6 deg) / 0.4429`` = 5.02 m; spotlight ``rho = c / (2 B)``, so ``lambda R B / c`` =
    3.31 m. The README's 2.3 s drone track (23 m) is the control: no such warning. The bug: a 1 m
    aperture was accepted without a word."""
    import math
    import re

    from sarmitsuba.core.constants import SPEED_OF_LIGHT
    r = 150.0 * math.sqrt(2.0)
    needed = (r * math.sin(math.radians(0.6)) / 0.4429 if mode == "stripmap"
              else SPEED_OF_LIGHT / 9.6e9 * r * 150e6 / SPEED_OF_LIGHT)
    assert main(["info", "trihedral", "--set", f"trajectory={_two_rows(tmp_path)}", "--set", f"mode={mode}"]) == 0
    warnings = capsys.readouterr().out.split("Warnings", 1)[1]
    match = re.search(r"trajectory two.csv: 26 pulses over 0.1 s fly 1 m, .* needs a synthetic aperture of ([0-9.]+) m",
                      warnings)
    assert match, warnings
    assert float(match.group(1)) == pytest.approx(needed, rel=0.01)
    assert main(["info", "trihedral", "--set", f"trajectory={_shifted_track_path()}", "--set", f"mode={mode}"]) == 0
    assert "synthetic aperture of" not in capsys.readouterr().out.split("Warnings", 1)[1]
    # the file holds the aperture but n_pulses cuts it short: the fix names n_pulses (spotlight: the
    # stripmap beam of the middle ten pulses yaws 5 deg with the sway, off the trihedral)
    assert main(["info", "trihedral", "--set", f"trajectory={_shifted_track_path()}", "--set", "mode=spotlight",
                 "--pulses", "10"]) == 0
    assert "set n_pulses to at least" in capsys.readouterr().out.split("Warnings", 1)[1]


def test_spotlight_pulses_steered_beyond_60_deg_are_warned_about():
    """A level straight pass from x = -1000 m to 1000 m, 500 m from the scene centre's vertical
    line through the track (a 45 deg look): the beam steers past 60 deg where ``|x| > 500 tan(60
    deg) = 866 m``, 13.4 % of the pulses; the warning names that fraction and the largest steering,
    ``atan(1000 / 500)`` = 63.4 deg. The same pass from -800 to 800 m stays within 60 deg and does
    not warn. Catches a warning that never fires (pulses beyond the model's domain rendered
    without a word) or counts the angle from the track."""
    import math
    import re

    import numpy as np

    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.core.trajectory import StateVectors
    from sarmitsuba.scene.track_checks import steering_note
    height = 500.0 / math.sqrt(2.0)
    for end, fraction in ((1000.0, (1000.0 - 500.0 * math.tan(math.radians(60.0))) / 1000.0), (800.0, None)):
        time = np.linspace(0.0, 2.0 * end / 100.0, 41)
        position = np.stack([-end + 100.0 * time, np.full_like(time, height), np.full_like(time, height)], axis=1)
        states = StateVectors(time, position, np.tile([100.0, 0.0, 0.0], (41, 1)))
        params = RadarParameters(scene_center=(0.0, 0.0, 0.0), prf=50.0, trajectory=states, mode="spotlight",
                                 n_pulses=int(round(2.0 * end / 100.0 * 50.0)) + 1)
        note = steering_note(params, acquisition_geometry(params))
        if fraction is None:
            assert note is None, note
            continue
        match = re.search(r"pulses \(([0-9.]+) %\) steer the beam more than 60 deg from broadside \(up to ([0-9.]+) deg",
                          note)
        assert match, note
        assert float(match.group(1)) == pytest.approx(100.0 * fraction, abs=0.3)
        assert float(match.group(2)) == pytest.approx(math.degrees(math.atan(2.0)), abs=0.05)


def test_arc_deg_that_n_pulses_would_override_is_refused(capsys):
    """trajectory = circular with both arc_deg = 20 and n_pulses = 10: n_pulses sets the arc
    (10 pulses at 100 m/s and 250 Hz over a 1000 m radius fly 0.2063 deg, worked by hand:
    9 x 0.4 m / 1000 m), so arc_deg would do nothing; exit 2 naming both. With n_pulses alone, or
    arc_deg alone, it loads. The bug: the 20 deg were silently ignored."""
    assert main(["info", "trihedral", "--set", "trajectory=circular", "--set", "arc_deg=20", "--pulses", "10"]) == 2
    err = capsys.readouterr().err
    assert "n_pulses = 10 and arc_deg = 20 deg both set the arc" in err and "flies 0.2063 deg" in err, err
    assert main(["info", "trihedral", "--set", "trajectory=circular", "--pulses", "10"]) == 0
    assert main(["info", "trihedral", "--set", "trajectory=circular", "--set", "arc_deg=20"]) == 0
