"""Damaged standard-format files and the placeholder map origin (issue 28).

- A truncated, empty or foreign ``.cphd`` given to ``focus`` or ``analyze --raw``, or ``.nitf``
  given to ``analyze``, exits 2 with one line that names the file, says what is wrong
  (empty, truncated, not a CPHD / NITF file, damaged) and the fix, never a traceback.
- ``--geotiff`` without a ``geo_origin`` warns once (the map would sit at 0 N 0 E), and not
  when one is set.
- ``analyze --help`` names both image formats it reads (.npz and SICD .nitf).

The damage is done here (cuts at known lengths, random bytes, a PNG, a NITF whose XML segment
is renamed), so what each message must say is known without the code under test.
"""
from __future__ import annotations

import io
import random

import numpy as np
import pytest

pytest.importorskip("sarkit.sicd")

from sarmitsuba import pipeline  # noqa: E402
from sarmitsuba.cli import main  # noqa: E402
from sarmitsuba.formats.cphd import write_cphd  # noqa: E402
from sarmitsuba.formats.sicd import write_sicd  # noqa: E402


@pytest.fixture(scope="module")
def intact(tmp_path_factory):
    """Folder with an intact raw.cphd, image.nitf and image.npz of a 16-pulse trihedral (small grid)."""
    folder = tmp_path_factory.mktemp("intact")
    sim = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 16}, image_size=(32, 32), image_spacing=1.0)
    write_cphd(sim.raw, folder / "raw.cphd")
    write_sicd(sim.image, folder / "image.nitf", raw=sim.raw)
    sim.image.save(folder / "image.npz")
    return folder


def png_bytes() -> bytes:
    import matplotlib.image
    buffer = io.BytesIO()
    matplotlib.image.imsave(buffer, np.zeros((4, 4)), format="png")
    return buffer.getvalue()


#: name -> (damage of the intact file's bytes, what the message must say)
DAMAGE = {
    "empty": (lambda b: b"", "empty"),
    "cut-10": (lambda b: b[:10], "truncated"),
    "cut-half": (lambda b: b[: len(b) // 2], "truncated"),
    "cut-last-100": (lambda b: b[:-100], "truncated"),
    "random": (lambda b: random.Random(0).randbytes(5000), "not a {kind} file"),
    "png": (lambda b: png_bytes(), "not a {kind} file"),
}


def damaged(intact, tmp_path, name, damage):
    path = tmp_path / name
    path.write_bytes(damage((intact / name).read_bytes()))
    return path


def assert_one_line(capsys, path, *fragments):
    """stderr is one ``error:`` line naming ``path`` and holding every fragment; no traceback."""
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith("error: ") and str(path) in lines[0], lines[0]
    for fragment in fragments:
        assert fragment in lines[0], (fragment, lines[0])
    assert "Traceback" not in captured.err + captured.out


@pytest.mark.parametrize("case", DAMAGE)
def test_focus_of_a_damaged_cphd_exits_2_saying_what_is_wrong(intact, tmp_path, capsys, case):
    damage, what = DAMAGE[case]
    path = damaged(intact, tmp_path, "raw.cphd", damage)
    out = tmp_path / "out"
    assert main(["focus", str(path), "--out", str(out), "--no-progress"]) == 2
    assert_one_line(capsys, path, what.format(kind="CPHD"), "render --cphd")
    assert not out.exists()


@pytest.mark.parametrize("case", ["cut-half", "cut-last-100"])
def test_analyze_with_a_damaged_cphd_raw_exits_2(intact, tmp_path, capsys, case):
    damage, what = DAMAGE[case]
    path = damaged(intact, tmp_path, "raw.cphd", damage)
    assert main(["analyze", str(intact / "image.npz"), "--target", "0,0,0", "--raw", str(path)]) == 2
    assert_one_line(capsys, path, what, "render --cphd")


@pytest.mark.parametrize("case", DAMAGE)
def test_analyze_of_a_damaged_nitf_exits_2_saying_what_is_wrong(intact, tmp_path, capsys, case):
    damage, what = DAMAGE[case]
    path = damaged(intact, tmp_path, "image.nitf", damage)
    assert main(["analyze", str(path), "--target", "0,0,0"]) == 2
    assert_one_line(capsys, path, what.format(kind="NITF"), "render --sicd")


def test_a_nitf_without_sicd_xml_is_named_as_such(intact, tmp_path, capsys):
    """An intact NITF whose data extension is not SICD's (its 'urn:SICD' tag renamed)."""
    payload = (intact / "image.nitf").read_bytes()
    assert payload.count(b"urn:SICD") >= 1
    path = tmp_path / "image.nitf"
    path.write_bytes(payload.replace(b"urn:SICD", b"urn:XXXX", 1))
    assert main(["analyze", str(path), "--target", "0,0,0"]) == 2
    assert_one_line(capsys, path, "SICD", "render --sicd")


def geotiff_warnings(capsys, tmp_path, *extra):
    out = tmp_path / "r"
    assert main(["render", "trihedral", "--pulses", "16", "--geotiff", "--out", str(out), "--no-progress",
                 *extra]) == 0
    assert (out / "image.tif").is_file()
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return [line for line in err.splitlines() if line.startswith("warning:")]


def test_geotiff_warns_once_at_the_placeholder_origin_and_not_with_a_geo_origin(tmp_path, capsys):
    lines = [line for line in geotiff_warnings(capsys, tmp_path / "default") if "geo_origin" in line]
    assert len(lines) == 1, lines
    assert "--set geo_origin=" in lines[0] and "0 N" in lines[0]
    lines = geotiff_warnings(capsys, tmp_path / "placed", "--set", "geo_origin=48.1,11.6,520")
    assert not [line for line in lines if "geo_origin" in line], lines


def test_analyze_help_names_sicd_nitf_images(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["analyze", "--help"])
    assert exit_info.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert ".nitf" in text and "SICD" in text
