"""The benchmark pages' directives (docs/_ext/benchtables.py) on hand-written data: cells
formatted as stated, rows filtered, columns picked and renamed, a missing file a warning."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs" / "_ext"))

import benchtables  # noqa: E402


@pytest.mark.parametrize("cell, shown", [
    ("0.123456789", "0.1235"), ("-38.64217", "-38.64"), ("12345", "12,345"), ("250.0", "250"),
    ("1.5", "1.5"), ("-inf", "reference"), ("True", "yes"), ("urban", "urban"), ("", ""),
    ("3.2e-07", "3.2e-07"), ("123456.78", "123,457")])
def test_cells_are_shown_as_documented(cell, shown):
    assert benchtables._format(cell, 4) == shown


def _build(tmp_path: Path, page: str) -> subprocess.CompletedProcess:
    source = tmp_path / "src"
    (source / "data").mkdir(parents=True)
    (source / "data" / "knob.csv").write_text("scene,setting,nrmse_db,seconds\nurban,1,-12.345678,2.0\n"
                                              "urban,8,-41.987654,0.5\nmunich,8,-33.3,9.25\n")
    (source / "conf.py").write_text(f"import sys\nsys.path.insert(0, {str(ROOT / 'docs' / '_ext')!r})\n"
                                    "extensions = ['myst_parser', 'benchtables']\n")
    (source / "index.md").write_text(page)
    return subprocess.run([sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", str(source), str(tmp_path / "out")],
                          capture_output=True, text=True)


def test_a_table_keeps_the_rows_and_columns_asked_for(tmp_path):
    done = _build(tmp_path, "# Knob\n\n```{bench-table} data/knob.csv\n:columns: setting=pulses per trace, nrmse_db=NRMSE [dB]\n"
                            ":where: scene=urban\n```\n")
    assert done.returncode == 0, done.stderr
    html = (tmp_path / "out" / "index.html").read_text()
    for text in ("pulses per trace", "NRMSE [dB]", "-12.35", "-41.99"):
        assert text in html, text
    for text in ("-33.3", "munich", "seconds", "9.25"):       # the filtered row, the dropped columns
        assert text not in html, text


def test_a_missing_data_file_fails_a_strict_build(tmp_path):
    done = _build(tmp_path, "# Knob\n\n```{bench-table} data/missing.csv\n```\n")
    assert done.returncode != 0 and "missing.csv does not exist" in done.stderr
