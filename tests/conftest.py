"""Test configuration: put tests/ on ``sys.path`` so that test modules can import each other's
shared cases and checks (``test_stripmap``, ``test_omegak``, ``test_backprojection``); shared
fixtures."""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture
def drawn(monkeypatch):
    """The matplotlib Figures saved by the figure and quicklook writers, in order, kept for
    inspection after drawing (their texts, axes and legend boxes)."""
    from matplotlib.figure import Figure
    saved, savefig = [], Figure.savefig

    def keep(self, *args, **kwargs):
        saved.append(self)
        return savefig(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    return saved


@pytest.fixture
def unwritable_paths(tmp_path):
    """Files that cannot be written: under a missing folder, an existing folder, and (unless
    running as root, who ignores permissions) a file in a read-only folder."""
    import os
    targets = [tmp_path / "missing" / "target.png", tmp_path / "folder"]
    targets[1].mkdir()
    if os.geteuid() != 0:
        read_only = tmp_path / "ro"
        read_only.mkdir()
        read_only.chmod(0o555)
        targets.append(read_only / "target.png")
    return targets
