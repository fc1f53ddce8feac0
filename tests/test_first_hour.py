"""A newcomer's first hour (issue 13): nothing half-made, clear messages, a repo that stands alone.

Output directories are all or nothing (sarmitsuba/core/outputs.py): a failed run leaves no file and
no directory it created; a disk error names the file the user asked for. The CLI has
``--version`` and a plain-text ``--help``; the repository carries its licence and cites only
its own documents; the built-in trihedral faces the sensor as its comment says.
"""
from __future__ import annotations

import errno
import importlib.metadata
import math
import sys
import tomllib
import types
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.cli import main

REPO = Path(__file__).resolve().parents[1]
FILES = ("raw.npz", "image.npz", "image.exr", "image.png", "summary.json")


def _no_traceback(err: str) -> None:
    assert "Traceback" not in err and "File \"" not in err, err


# ---- output directories: all or nothing ---------------------------------------------------------

def test_bad_parameter_leaves_no_directory(tmp_path, capsys):
    out = tmp_path / "new" / "deeper"
    assert main(["render", "dihedral", "--out", str(out), "--set", "incidence_angle=95", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "incidence_angle" in err
    _no_traceback(err)
    assert not (tmp_path / "new").exists(), "a failed render left the directories it created"


def test_full_disk_names_the_file_and_writes_nothing(tmp_path, capsys, monkeypatch):
    """ENOSPC while writing image.exr (after raw.npz and image.npz were written): exit 2, the
    message names out/image.exr and the disk, and no product is left in the directory."""
    from sarmitsuba.products import image_files as products
    def full(image, path):
        raise OSError(errno.ENOSPC, "No space left on device")
    monkeypatch.setattr(products, "write_exr", full)
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")                    # a user's file survives the failure
    assert main(["render", "dihedral", "--out", str(out), "--no-progress", "--max-depth", "1"]) == 2
    err = capsys.readouterr().err
    _no_traceback(err)
    assert str(out / "image.exr") in err and "No space left on device" in err and "partial" not in err
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt"]


def test_success_writes_every_product_and_no_staging_folder(tmp_path):
    out = tmp_path / "a" / "b"
    assert main(["render", "dihedral", "--out", str(out), "--no-progress", "--max-depth", "1"]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(FILES)


def test_output_path_that_is_a_file(tmp_path, capsys):
    target = tmp_path / "taken"
    target.write_text("x")
    assert main(["render", "dihedral", "--out", str(target), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "is an existing file, not a directory" in err and str(target) in err
    assert "File exists" not in err
    assert target.read_text() == "x"


def test_interrupted_writer_leaves_nothing(tmp_path):
    """Ctrl-C inside a writer (BaseException): the staged files go, the new directory too."""
    from sarmitsuba.core.outputs import OutputDirectory
    out = tmp_path / "fresh"
    with pytest.raises(KeyboardInterrupt):
        with OutputDirectory(out) as staged:
            staged.write("a.txt", lambda p: p.write_text("first"))
            staged.write("b.txt", lambda p: (_ for _ in ()).throw(KeyboardInterrupt()))
    assert not out.exists()


def test_preview_failure_leaves_no_directory(tmp_path, capsys):
    out = tmp_path / "preview"
    assert main(["preview", "dihedral", "--out", str(out), "--set", "frequency=-1"]) == 2
    _no_traceback(capsys.readouterr().err)
    assert not out.exists()


# ---- the command line ---------------------------------------------------------------------------

def test_version_is_the_installed_distribution(capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--version"])
    assert stop.value.code == 0
    assert capsys.readouterr().out.strip() == f"sarmitsuba {importlib.metadata.version('sarmitsuba')}"


def test_top_level_help_is_plain_text(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    for markup in ("``", ":mod:", ":func:", ":class:"):
        assert markup not in text, f"raw RST {markup!r} in --help"
    assert "render" in text and "--version" in text and "exit codes" in text


# ---- the repository stands on its own -----------------------------------------------------------

def _shipped_files():
    for folder in ("sarmitsuba", "plugins", "scenes", "docs", "benchmarks", "tests"):
        for path in (REPO / folder).rglob("*"):
            if path.is_file() and path.suffix in (".py", ".md", ".xml", ".toml", ".obj", ".txt"):
                yield path
    yield from (REPO / name for name in ("README.md", "pyproject.toml", "Makefile"))


def test_no_reference_outside_the_repository():
    needle_shared, needle_design = "../" + "shared", "DESIGN" + ".md"      # not matched by this file
    offenders = [str(p.relative_to(REPO)) for p in _shipped_files()
                 if needle_shared in (text := p.read_text(errors="replace")) or needle_design in text]
    assert offenders == []


def test_licence_file_matches_the_package_metadata():
    licence = (REPO / "LICENSE").read_text()
    assert licence.startswith("BSD 3-Clause License")
    assert "Neither the name of the copyright holder" in licence          # clause 3
    meta = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert meta["license"] == "BSD-3-Clause" and meta["license-files"] == ["LICENSE"]       # SPDX (PEP 639)


def test_the_wheel_builds_quietly_with_the_scene_meshes(tmp_path):
    """Installing prints no setuptools deprecation banner (the ``project.license`` table, scene
    meshes missing from ``packages``), and the wheel carries the built-in scenes' meshes and the
    licence. Built from a copy, with the installed setuptools (the dev extra's >= 77)."""
    import shutil
    import subprocess
    import zipfile
    source = tmp_path / "src"
    for name in ("sarmitsuba", "plugins", "scenes"):
        shutil.copytree(REPO / name, source / name, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy(REPO / name, source / name)
    build = subprocess.run([sys.executable, "-c", "import sys; from setuptools import build_meta; "
                            "print(build_meta.build_wheel(sys.argv[1]))", str(tmp_path / "dist")],
                           cwd=source, capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stderr
    log = build.stdout + build.stderr
    assert "Deprecat" not in log and "!!" not in log and "absent from the `packages`" not in log, log
    names = zipfile.ZipFile(tmp_path / "dist" / build.stdout.strip().splitlines()[-1]).namelist()
    assert "sarmitsuba_scenes/meshes/trihedral.obj" in names and "sarmitsuba_scenes/urban.xml" in names
    assert any(n.endswith("licenses/LICENSE") for n in names)


# ---- the built-in trihedral faces the sensor -----------------------------------------------------

def test_trihedral_boresight_points_at_the_mid_aperture_antenna():
    """The symmetry axis of a trihedral with equal edges runs from the apex through the centroid
    of its three far vertices; it must point at the mid-aperture antenna within 0.1 deg."""
    import mitsuba as mi

    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.scene.loader import load_scene
    loaded = load_scene("trihedral")
    (shape,) = loaded.scene.shapes()
    vertices = np.array(mi.traverse(shape)["vertex_positions"], np.float64).reshape(-1, 3)
    apex = vertices[np.argmin(np.linalg.norm(vertices, axis=1))]
    far = vertices[np.linalg.norm(vertices - apex, axis=1) > 0.1]
    assert len(far) == 3 and np.allclose(np.linalg.norm(far - apex, axis=1), 1.5, atol=1e-5)
    axis = far.mean(axis=0) - apex
    geometry = acquisition_geometry(loaded.params)
    sight = geometry.positions[len(geometry.positions) // 2] - apex
    cos = axis @ sight / np.linalg.norm(axis) / np.linalg.norm(sight)
    assert math.degrees(math.acos(min(cos, 1.0))) < 0.1


# ---- bench writes where it is told, never into the checkout --------------------------------------

def test_bench_out_receives_tables_and_checks(tmp_path, monkeypatch):
    sys.path.insert(0, str(REPO / "benchmarks"))
    import run as suite
    import _table

    def fake_run(quick):
        rows = [{"setting": 1, "seconds": 0.5}]
        _table.write_csv("fake.csv", rows)
        return rows
    fake = types.ModuleType("fake_bench")
    fake.run = fake_run
    fake.checks = lambda rows: [("fake ratio", True, "1.0")]
    monkeypatch.setitem(sys.modules, "fake_bench", fake)
    monkeypatch.setattr(suite, "SUITE", {"fake": "fake_bench"})
    monkeypatch.setenv("SARMITSUBA_BENCH_OUT", "restored after the test")   # main() sets it from --out
    out = tmp_path / "bench"
    assert suite.main(["--only", "fake", "--out", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["checks.csv", "fake.csv", "machine.json"]
    assert not (REPO / "benchmarks" / "out" / "fake.csv").exists()
    import json
    run = json.loads((out / "machine.json").read_text())          # what the benchmark pages show of the run
    assert run["benchmarks"] == ["fake"] and run["quick"] is False and set(run["seconds"]) == {"fake"}
    assert "--only fake" in run["command"] and run["cpus"] >= 1 and run["started_utc"] <= run["finished_utc"]


# ---- every focuser takes every window the docs list ----------------------------------------------

@pytest.fixture(scope="module")
def trihedral_raw(tmp_path_factory):
    out = tmp_path_factory.mktemp("tri")
    assert main(["render", "trihedral", "--out", str(out), "--no-progress", "--window", "rect",
                 "--set", "beam=uniform"]) == 0                    # flat Doppler spectrum: no pattern
    return out / "raw.npz"


def _azimuth_irw(path) -> float:
    """-3 dB width [samples] of the azimuth cut through the peak, from a 32x band-limited upsampling."""
    from scipy.signal import resample

    from sarmitsuba.core.image import SarImage
    data = SarImage.load(path).data
    az, rg = np.unravel_index(np.argmax(np.abs(data)), data.shape)
    cut = data[max(az - 24, 0):az + 24, rg]
    fine = np.abs(resample(cut, 32 * cut.size)) ** 2
    above = np.flatnonzero(fine >= 0.5 * fine.max())
    return (above[-1] - above[0] + 1) / 32.0


@pytest.mark.parametrize("algorithm", ["bp", "ffbp", "omegak", "rda"])
def test_every_focuser_applies_the_hann_azimuth_window(trihedral_raw, tmp_path, algorithm):
    """Hann broadens the impulse response by 1.44 / 0.886 = 1.63 (Harris 1978, table 1: 3 dB
    widths in bins) against rect: the azimuth window is really applied, by every focuser. A
    uniform beam keeps the Doppler spectrum flat, so that ratio is the closed form."""
    widths = {}
    for window in ("rect", "hann"):
        out = tmp_path / window
        assert main(["focus", str(trihedral_raw), "--algorithm", algorithm, "--window-azimuth", window,
                     "--out", str(out), "--no-progress"]) == 0
        widths[window] = _azimuth_irw(out / "image.npz")
    assert widths["hann"] / widths["rect"] == pytest.approx(1.44 / 0.886, rel=0.1)


def test_rect_window_gives_the_textbook_sinc_only_with_a_uniform_beam(trihedral_raw, tmp_path):
    """What the README says of ``--window rect``. With ``beam = uniform`` both cuts are the sinc:
    PSLR -13.26 dB (the first sidelobe of sin(x)/x, Harris 1978 table 1). With the default
    tapered beam the two-way antenna pattern weights the echoes across the aperture, so the
    azimuth sidelobes fall below -30 dB while range stays a sinc."""
    import sarmitsuba
    uniform = sarmitsuba.analyze(trihedral_raw.with_name("image.npz"), (0.0, 0.0, 0.0))
    assert uniform.pslr_range_db == pytest.approx(-13.26, abs=0.5)
    assert uniform.pslr_azimuth_db == pytest.approx(-13.26, abs=0.5)
    out = tmp_path / "tapered"
    assert main(["render", "trihedral", "--out", str(out), "--no-progress", "--window", "rect"]) == 0
    tapered = sarmitsuba.analyze(out / "image.npz", (0.0, 0.0, 0.0))
    assert tapered.pslr_range_db == pytest.approx(-13.26, abs=0.5)
    assert tapered.pslr_azimuth_db < -30.0
