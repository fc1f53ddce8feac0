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
