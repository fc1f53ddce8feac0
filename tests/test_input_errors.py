"""A newcomer's mistakes reach them as one line, exit 2, naming the parameter, its range and the fix.

Wrong units (9.6 for 9.6 GHz), bad values and misspelt names in a scene file (the file, the line
of the element, the message, no traceback) and a render too large for the machine's memory
(checked before tracing, also listed by ``info``).
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from sarmitsuba.cli import main
from sarmitsuba.info import scene_info
from sarmitsuba.pipeline import simulate
from sarmitsuba.core.radar import ParameterError, RadarParameters
from sarmitsuba.scene.loader import SceneError, builtin_scenes, load_scene

DIHEDRAL = builtin_scenes()["dihedral"]


def one_line_error(capsys) -> str:
    """stderr of a failed command: exactly one line, 'error: ...', no traceback."""
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and 'File "' not in err, err
    assert err.startswith("error: ") and "\n" not in err, err
    return err


# ---------------------------------------------------------------------------------------- units
@pytest.mark.parametrize("values, meant", [
    ({"frequency": 9.6}, "9.6e9"),             # X band written in GHz
    ({"frequency": 1.3}, "1.3e9"),             # L band in GHz
    ({"frequency": 435}, "435e6"),             # P band written in MHz (BIOMASS)
    ({"frequency": 35}, "35e9"),               # Ka band in GHz
    ({"bandwidth": 150}, "150e6"),             # 150 MHz chirp
    ({"sampling_rate": 180}, "180e6"),         # 180 MHz sampling
    ({"pulse_length": 10}, "10e-6"),           # a 10 us chirp
    ({"prf": 0.25}, "0.25e3"),                 # 0.25 kHz
    ({"altitude": 0.8}, "0.8e3"),              # 0.8 km flight level
    ({"antenna_length": 120}, "120e-2"),       # a 1.2 m antenna in cm
], ids=lambda v: str(v))
def test_value_in_the_wrong_unit_names_range_unit_and_the_value_meant(values, meant):
    """A bug that checks only > 0 (today's 9.6 Hz carrier passes) or drops the hint fails here."""
    (name, value), = values.items()
    with pytest.raises(ParameterError) as info:
        RadarParameters(**values)
    message = str(info.value)
    assert message.startswith(f"{name} = {value:g} ") and "outside the valid range" in message
    assert f"did you mean {meant} " in message


@pytest.mark.parametrize("values, fragment", [
    ({"velocity": 7.6e6}, "velocity is in m/s"),                          # mm/s: no power-of-ten hint, typical speeds
    ({"antenna_gain_db": 1000.0, "transmit_power": 10.0}, "30.0 dBi"),    # a linear gain of 1000 = 30 dBi
    ({"heading": 720.0}, "[-360, 360] deg"),
    ({"losses_db": -3.0}, "[0, 100] dB"),
    ({"scene_center": (0.0, 0.0, 6.4e9)}, "z = 6400000000.0 m"),         # 6400 km in mm
    ({"frequency": -9.6e9}, "frequency = -9.6e9 must be a finite number > 0"),
])
def test_other_out_of_range_values_name_the_range(values, fragment):
    with pytest.raises(ParameterError, match=re.escape(fragment)):
        RadarParameters(**values)


@pytest.mark.parametrize("values", [
    {"frequency": 1.3e9},                                           # L band
    {"frequency": 35e9, "bandwidth": 1e9},                          # Ka band, 1 GHz chirp
    {"frequency": 435e6, "bandwidth": 6e6},                         # P band (BIOMASS)
    {"frequency": 94e9, "bandwidth": 1e9, "velocity": 10.0, "altitude": 50.0},   # W-band drone
    {"frequency": 5.405e9, "velocity": 7600.0, "altitude": 693e3, "prf": 1700.0,
     "pulse_length": 52e-6, "antenna_length": 12.3},                # Sentinel-1-like
    {"altitude": 20.2e6, "velocity": 3900.0},                       # MEO
    {"prf": 1.0, "velocity": 0.05},                                 # ground-based rail SAR
], ids=lambda v: str(v))
def test_real_systems_are_accepted(values):
    """The ranges admit VHF to sub-THz radars and drones to MEO (too tight a range fails here)."""
    p = RadarParameters(**values)
    assert all(getattr(p, k) == v for k, v in values.items())


@pytest.mark.parametrize("setting, meant", [("frequency=9.6", "9.6e9"), ("bandwidth=150", "150e6")])
def test_cli_wrong_unit_exits_2_with_one_line(tmp_path, capsys, setting, meant):
    out = tmp_path / "out"
    assert main(["render", "dihedral", "--set", setting, "--out", str(out), "--no-progress"]) == 2
    err = one_line_error(capsys)
    assert f"error: {setting.split('=')[0]} = " in err and f"did you mean {meant}" in err
    assert not out.exists() or not any(out.iterdir())


# ------------------------------------------------------------------------------ scene file errors
def _edited(tmp_path: Path, old: str, new: str) -> tuple[Path, int]:
    """A copy of scenes/dihedral.xml with ``old`` replaced, and the (1-based) line it is on."""
    text = DIHEDRAL.read_text()
    assert text.count(old) == 1
    line = text[:text.index(old)].count("\n") + 1
    path = tmp_path / "scene.xml"
    path.write_text(text.replace(old, new))
    return path, line


@pytest.mark.parametrize("old, new, fragment", [
    ('name="frequency" value="9.6e9"', 'name="frequency" value="-9.6e9"', "frequency = -9.6e9 must be a finite number"),
    ('name="frequency" value="9.6e9"', 'name="frequency" value="9.6"', "did you mean 9.6e9"),
    ('name="frequency"', 'name="frequncy"', "unknown parameter 'frequncy' (did you mean 'frequency'?)"),
    ('name="max_depth"', 'name="max_dpeth"', "sbr integrator: unknown parameter 'max_dpeth' (did you mean 'max_depth'?)"),
    ('name="prf" value="250"', 'name="prf" value="250 Hz"', 'could not parse floating point value "250 Hz"'),
], ids=["negative-frequency", "frequency-in-GHz", "misspelt-sensor-parameter", "misspelt-integrator-parameter",
        "value-with-unit"])
def test_scene_file_error_names_file_line_and_message_only(tmp_path, capsys, old, new, fragment):
    """File, line of the element, the message: no traceback frames, no Mitsuba source prefix."""
    path, line = _edited(tmp_path, old, new)
    assert main(["info", str(path)]) == 2
    err = one_line_error(capsys)
    assert err.startswith(f"error: cannot load scene {str(path)!r}, line {line}: ")
    assert fragment in err
    assert ".cpp" not in err and "failed to instantiate" not in err and "ParameterError" not in err


def test_line_of_the_element_in_a_hand_written_scene(tmp_path):
    """The sensor after a shape, single-quoted attributes: the line of the offending element."""
    path = tmp_path / "scene.xml"
    path.write_text("<scene version='3.0.0'>\n"
                    "  <shape type='rectangle'/>\n"
                    "  <sensor type='sar'>\n"
                    "    <float name='bandwidth' value='150e6'/>\n"
                    "    <float name='azimuth_beamwidth' value='70'/>\n"
                    "  </sensor>\n"
                    "</scene>\n")
    with pytest.raises(SceneError, match=r"scene\.xml', line 5: azimuth_beamwidth = 70"):
        load_scene(str(path))


def test_parameter_the_plugin_does_not_set_points_at_the_plugin(tmp_path):
    """A name the failing element does not write (a default) gives the element's own line, never a
    same-named parameter of a later plugin."""
    from sarmitsuba.scene.mitsuba_errors import parameter_line
    path = tmp_path / "scene.xml"
    path.write_text("<scene version='3.0.0'>\n"
                    "  <sensor type='sar'>\n"
                    "    <float name='prf' value='250'/>\n"
                    "  </sensor>\n"
                    "  <sensor type='sar'>\n"
                    "    <float name='sampling_rate' value='180e6'/>\n"
                    "  </sensor>\n"
                    "</scene>\n")
    assert parameter_line(str(path), 2, "sensor", "prf") == 3
    assert parameter_line(str(path), 2, "sensor", "sampling_rate") == 2
    assert parameter_line(str(path / "missing"), 2, "sensor", "prf") == 2


# ------------------------------------------------------------------------------------- memory
LIMIT = 16 * 2**30        # a 16 GiB machine, whatever this one has


def test_render_too_large_for_memory_stops_before_tracing(tmp_path, capsys, monkeypatch):
    """urban with 200000 pulses: about 200 GiB of spectra and raw data (the issue's crash)."""
    monkeypatch.setenv("SARMITSUBA_MEMORY_LIMIT", str(LIMIT))
    out = tmp_path / "out"
    assert main(["render", "urban", "--pulses", "200000", "--out", str(out), "--no-progress"]) == 2
    err = one_line_error(capsys)
    assert "memory" in err and "16.0 GiB is available" in err and "--pulses" in err
    needed = float(re.search(r"need about ([\d.]+) GiB", err).group(1))
    # raw data alone: 200000 pulses x at least the urban scene's slant depth (> 100 m, 120 samples at 180 MHz)
    assert needed > 200000 * 120 * 8 / 2**30
    assert not out.exists() or not any(out.iterdir())


def test_info_lists_the_memory_problem_and_its_fix_works(capsys, monkeypatch):
    """info warns (exit 0); the pulse count it suggests fits, so the fix is real."""
    monkeypatch.setenv("SARMITSUBA_MEMORY_LIMIT", str(2**30))
    assert main(["info", "dihedral", "--pulses", "20000"]) == 0
    text = capsys.readouterr().out
    warnings = text.split("\nWarnings\n", 1)[1]
    assert "the render would need about" in warnings and "none" not in warnings
    suggested = int(re.search(r"--pulses (\d+) or fewer", warnings).group(1))
    assert 1 < suggested < 20000
    assert not any("memory" in w for w in scene_info("dihedral", sensor_overrides={"n_pulses": suggested}).warnings)


def test_memory_estimate_matches_a_real_render(monkeypatch):
    """The model's raw data and image sizes are those of the arrays a small render makes."""
    sensor, integrator = {"n_pulses": 8}, {"max_depth": 1}
    cost = scene_info("dihedral", sensor_overrides=sensor, integrator_overrides=integrator).cost
    sim = simulate("dihedral", sensor_overrides=sensor, integrator_overrides=integrator)
    assert cost.raw_bytes == sim.raw.data.nbytes and cost.image_bytes == sim.image.data.nbytes
    assert cost.peak_memory_bytes >= sim.raw.data.nbytes + sim.image.data.nbytes + sim.trace.spectrum.nbytes


def test_bad_memory_limit_is_named(capsys, monkeypatch):
    monkeypatch.setenv("SARMITSUBA_MEMORY_LIMIT", "lots")
    assert main(["info", "dihedral"]) == 2
    assert "SARMITSUBA_MEMORY_LIMIT = 'lots'" in one_line_error(capsys)
