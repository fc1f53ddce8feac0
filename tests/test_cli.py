"""``python -m sarmitsuba render``: outputs, summary, errors before any long work."""
from __future__ import annotations

import json
import re
import subprocess
import sys

import matplotlib.image
import numpy as np
import OpenEXR
import pytest

from sarmitsuba.cli import main
from sarmitsuba.core.image import SarImage
from sarmitsuba.core.raw import RawData

FILES = ("raw.npz", "image.npz", "image.exr", "image.png", "summary.json")


def test_render_writes_all_products(tmp_path, capsys):
    out = tmp_path / "dihedral"
    assert main(["render", "dihedral", "--out", str(out), "--no-progress", "--max-depth", "2"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES)
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert line.startswith("rendered dihedral:") and "rays cast" in line and "pulses" in line
    assert "pulse-paths/s" in line and "pulses per trace" in line

    summary = json.loads((out / "summary.json").read_text())
    raw = RawData.load(out / "raw.npz")
    image = SarImage.load(out / "image.npz")
    assert summary["n_pulses"] == raw.n_pulses == summary["radar"]["n_pulses"]
    assert len(summary["energy_per_order"]) == 2 and summary["rays_traced"] > 0
    assert set(summary["timings"]) >= {"load", "trace", "bin", "focus", "products", "total"}
    assert summary["outputs"]["png"] == str(out / "image.png")
    # the returns evaluated: every pulse sees the dihedral's double bounce
    assert 1 < summary["pulses_per_trace"] <= raw.n_pulses and summary["pulse_paths"] > raw.n_pulses
    assert summary["pulse_paths_per_second"] > 0

    with np.load(out / "raw.npz") as f:                       # loads without sarmitsuba
        assert f["data"].dtype == np.complex64 and f["data"].shape == raw.data.shape
    png = matplotlib.image.imread(out / "image.png")
    assert png.shape[0] > 400 and png.shape[1] > 400 and png[..., :3].std() > 0.01
    exr = OpenEXR.File(str(out / "image.exr"))
    intensity = exr.channels()["intensity"].pixels
    assert np.allclose(intensity, np.abs(image.data) ** 2, rtol=1e-5, atol=0)


def test_missing_scene_exits_2_with_message(tmp_path, capsys):
    out = tmp_path / "x"
    assert main(["render", str(tmp_path / "missing.xml"), "--out", str(out)]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert not any(out.glob("*.npz"))


def test_unwritable_output_directory_fails_before_tracing(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    assert main(["render", "dihedral", "--out", str(blocker / "sub"), "--no-progress"]) == 2
    assert "is not writable" in capsys.readouterr().err


def test_bad_override_exits_2(tmp_path, capsys):
    assert main(["render", "dihedral", "--out", str(tmp_path), "--set", "incidence_angle=0"]) == 2
    assert "incidence_angle" in capsys.readouterr().err
    assert not any(tmp_path.glob("*.npz"))


def test_python_dash_m_entry_point(tmp_path):
    result = subprocess.run([sys.executable, "-m", "sarmitsuba", "render", "trihedral", "--out", str(tmp_path),
                             "--no-progress"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "rendered trihedral" in result.stdout and (tmp_path / "image.png").is_file()



def test_warnings_print_one_clean_line_each(tmp_path):
    """A PRF below the Doppler bandwidth warns (azimuth ambiguities): the command line prints it
    as ``warning: ...`` on one line, with no Python ``file.py:NN:`` prefix and no source line."""
    result = subprocess.run([sys.executable, "-m", "sarmitsuba", "render", "trihedral", "--out", str(tmp_path),
                             "--no-progress", "--set", "prf=100"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert any(line.startswith("warning: prf = 100 Hz is below the Doppler bandwidth") for line in lines), lines
    assert not [line for line in lines if re.search(r"\.py:\d+:", line) or line.startswith(" ")], lines


def test_analyze_prints_point_target_report(tmp_path, capsys):
    """render trihedral, then analyze the apex: JSON with the peak on the apex within 1/20 cell."""
    assert main(["render", "trihedral", "--out", str(tmp_path), "--no-progress"]) == 0
    capsys.readouterr()
    assert main(["analyze", str(tmp_path / "image.npz"), "--target", "0,0,0"]) == 0
    report = json.loads(capsys.readouterr().out)
    text = json.dumps(report)
    assert "irw" in text and "pslr" in text
    errors = [v for k, v in _flatten(report) if "error" in k and "cell" in k and isinstance(v, (int, float))]
    assert errors and max(abs(e) for e in errors) < 0.05


def _flatten(d, prefix=""):
    for k, v in d.items():
        if isinstance(v, dict):
            yield from _flatten(v, prefix + k + ".")
        else:
            yield prefix + k, v


def test_focus_command_with_every_algorithm(tmp_path, capsys):
    """render, then refocus raw.npz with bp, omegak and rda: each writes an image whose peak sits
    on the trihedral's apex (position from point-target analysis within 1/20 cell)."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    assert main(["render", "trihedral", "--out", str(tmp_path / "r"), "--no-progress"]) == 0
    for algorithm in ("bp", "omegak", "rda"):
        out = tmp_path / algorithm
        assert main(["focus", str(tmp_path / "r" / "raw.npz"), "--algorithm", algorithm, "--out", str(out),
                     "--no-progress"]) == 0
        report = analyze_point_target(SarImage.load(out / "image.npz"), [0.0, 0.0, 0.0], chip=32)
        assert abs(report.azimuth_error_cells) < 0.05 and abs(report.range_error_cells) < 0.05, algorithm


def _nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    a, b = np.asarray(a, np.complex128), np.asarray(b, np.complex128)
    return float(10 * np.log10(max(np.sum(np.abs(a - b) ** 2), 1e-300) / np.sum(np.abs(b) ** 2)))


def test_focus_with_the_render_flags_gives_the_render_image(tmp_path):
    """``render`` and ``focus`` share one window default (Taylor) and one set of flags: focusing
    a render's raw.npz with no options gives the render's own image, and the same window flags
    given to both give the same image again. A focus default of rect (the old one) differs
    from the Taylor render by far more than -60 dB."""
    cases = {"default": [], "mixed": ["--window", "rect", "--window-range", "hann"]}
    for name, flags in cases.items():
        assert main(["render", "trihedral", "--pulses", "128", "--out", str(tmp_path / f"r_{name}"),
                     "--no-progress", *flags]) == 0
        assert main(["focus", str(tmp_path / f"r_{name}" / "raw.npz"), "--out", str(tmp_path / f"f_{name}"),
                     "--no-progress", *flags]) == 0
        rendered, focused = (SarImage.load(tmp_path / f"{k}_{name}" / "image.npz") for k in ("r", "f"))
        assert _nrmse_db(focused.data, rendered.data) < -60.0, name
        windows = [focused.metadata["focus"][f"window_{axis}"]["name"] for axis in ("range", "azimuth")]
        assert windows == (["taylor", "taylor"] if name == "default" else ["hann", "rect"])
    default, mixed = (SarImage.load(tmp_path / f"r_{k}" / "image.npz").data for k in cases)
    assert _nrmse_db(mixed, default) > -30.0          # the flags changed the render's image


def test_focus_rejects_corrupt_raw_file(tmp_path, capsys):
    bad = tmp_path / "raw.npz"
    bad.write_bytes(b"not an npz")
    assert main(["focus", str(bad), "--out", str(tmp_path / "o")]) == 2
    assert "cannot read RawData" in capsys.readouterr().err
    mismatched = tmp_path / "other.npz"
    np.savez(mismatched, data=np.zeros((3, 4), np.complex64))
    assert main(["focus", str(mismatched), "--out", str(tmp_path / "o")]) == 2
    assert "not a RawData file" in capsys.readouterr().err


def test_bench_forwards_its_arguments_to_the_suite(capsys):
    """``sarmitsuba bench ...`` runs benchmarks/run.py with the arguments after ``bench``."""
    from sarmitsuba.cli import benchmarks_dir
    assert (benchmarks_dir() / "run.py").is_file()
    with pytest.raises(SystemExit) as exc:
        main(["bench", "--only", "no_such_benchmark"])
    assert exc.value.code == 2
    assert "invalid choice: 'no_such_benchmark'" in capsys.readouterr().err


def test_fft_focusers_refuse_spotlight_data_and_name_backprojection(tmp_path, capsys):
    """Spotlight raw data (the beam steered at the scene centre) given to omega-K or RDA: exit 2,
    one line naming bp and ffbp, no output; backprojection focuses the same file."""
    assert main(["render", "trihedral", "--out", str(tmp_path / "render"), "--no-progress",
                 "--set", "mode=spotlight"]) == 0
    raw = tmp_path / "render" / "raw.npz"
    capsys.readouterr()
    for algorithm in ("omegak", "rda"):
        out = tmp_path / algorithm
        assert main(["focus", str(raw), "--algorithm", algorithm, "--out", str(out), "--no-progress"]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("error:") and "spotlight" in err and "bp" in err and "ffbp" in err, err
        assert len(err.splitlines()) == 1 and not out.exists()
    assert main(["focus", str(raw), "--algorithm", "bp", "--out", str(tmp_path / "bp"), "--no-progress"]) == 0


def test_refocus_with_no_window_gives_the_simulated_image():
    """The Python API shares the command line's default: ``refocus(raw, "ffbp")`` and
    ``sarmitsuba.focus.focus(raw, "ffbp")`` with no window argument give ``simulate``'s own (Taylor) image again; a rect default would differ by far
    more than -60 dB."""
    import sarmitsuba
    sim = sarmitsuba.simulate("trihedral", sensor_overrides={"n_pulses": 128})
    for again in (sarmitsuba.refocus(sim.raw, "ffbp"), sarmitsuba.focus.focus(sim.raw, "ffbp")):
        assert _nrmse_db(again.data, sim.image.data) < -60.0
        assert again.metadata["focus"]["window_azimuth"]["name"] == "taylor"
