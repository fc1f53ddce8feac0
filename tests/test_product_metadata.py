"""What travels with the products: the collection time (sensor ``collection_start``) and no
absolute path of the user's machine."""
from __future__ import annotations

import datetime
import json
import shutil
from pathlib import Path

import pytest

from sarmitsuba.cli import main
from sarmitsuba.core.radar import ParameterError, RadarParameters
from sarmitsuba.core.raw import RawData

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("given, stored", [
    ("2026-11-24T10:00:00Z", "2026-11-24T10:00:00+00:00"),
    ("2026-11-24T12:30:00.250+02:30", "2026-11-24T10:00:00.250000+00:00"),     # an offset, written in UTC
    ("2026-11-23T22:00:00-12:00", "2026-11-24T10:00:00+00:00"),                 # across midnight
])
def test_collection_start_is_stored_in_utc(given, stored):
    assert RadarParameters(collection_start=given).collection_start == stored


@pytest.mark.parametrize("given, problem", [("2026-11-24T10:00:00", "no UTC offset"),
                                            ("yesterday", "not an ISO 8601 time")])
def test_collection_start_without_offset_or_unreadable_is_refused(given, problem):
    with pytest.raises(ParameterError, match=f"collection_start: .*{problem}.*2026-11-24T10:00:00Z"):
        RadarParameters(collection_start=given)


def test_render_records_collection_start_given_or_now(tmp_path):
    before = datetime.datetime.now(datetime.timezone.utc)
    assert main(["render", "trihedral", "--pulses", "16", "--out", str(tmp_path / "now"), "--no-progress"]) == 0
    after = datetime.datetime.now(datetime.timezone.utc)
    start = RawData.load(tmp_path / "now" / "raw.npz").metadata["radar"]["collection_start"]
    assert before <= datetime.datetime.fromisoformat(start) <= after
    assert main(["render", "trihedral", "--pulses", "16", "--out", str(tmp_path / "set"), "--no-progress",
                 "--set", "collection_start=2026-11-24T10:00:00Z"]) == 0
    assert RawData.load(tmp_path / "set" / "raw.npz").metadata["radar"]["collection_start"] == "2026-11-24T10:00:00+00:00"


def test_products_carry_no_absolute_path_and_figures_still_find_the_scene(tmp_path):
    """A scene given by its absolute path: the npz and summary metadata name its file only, and
    ``render --figures`` still draws the scene overlay (the command line hands redraw its scene)."""
    scene = tmp_path / "deep" / "folder" / "my_scene.xml"
    scene.parent.mkdir(parents=True)
    shutil.copy(REPO / "scenes" / "dihedral.xml", scene)
    out = tmp_path / "out"
    assert main(["render", str(scene), "--pulses", "32", "--max-depth", "2", "--out", str(out), "--no-progress",
                 "--figures"]) == 0
    meta = RawData.load(out / "raw.npz").metadata
    assert meta["scene"] == "my_scene.xml" and meta["scene_path"] == "my_scene.xml"
    for name in ("raw.npz", "image.npz", "summary.json", "figures.json"):
        assert str(scene.parent) not in (out / name).read_bytes().decode("latin-1"), name
    assert "overlay" in json.loads((out / "figures.json").read_text())
