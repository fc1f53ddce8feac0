"""Test configuration: put tests/ on ``sys.path`` so that test modules can import each other's
shared cases and checks (``test_stripmap``, ``test_omegak``, ``test_backprojection``); shared
fixtures."""
import os
import sys
from pathlib import Path

#: One BLAS thread in each of pytest-xdist's workers (set before NumPy loads OpenBLAS): with two
#: workers on two cores, each OpenBLAS's second thread spins for a core the other worker holds.
#: Measured on ten of the heaviest test files, two workers: 156 s wall (265 CPU-s) with the
#: default threads, 133 s and 126 s (230 and 216 CPU-s) with one, in two runs.
if os.environ.get("PYTEST_XDIST_WORKER") and "numpy" not in sys.modules:
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")
    #: and no trace worker processes: the xdist workers already fill the cores (tests/test_workers.py
    #: sets its own counts).
    os.environ.setdefault("SARMITSUBA_WORKERS", "1")

import pytest  # noqa: E402

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
