"""Ctrl-C at any moment of ``python -m sarmitsuba render``: exit code 130 and one line, never a
traceback (issue 55, item 7).

The plausible bug: a SIGINT that lands while the package, Mitsuba and Dr.Jit are still importing
(the first one or two seconds) raises KeyboardInterrupt outside the command line's handler (a
traceback from runpy), or inside an extension module's import, which turns it into another error
(an AttributeError of a half-initialised module, a SystemError, or a VariantError that says the
variant "needs an NVIDIA GPU"). Before the fix, delays of 0.05 s and 0.3 s gave tracebacks
(return code -2), 0.2 s a SystemError from ``mi.set_variant`` and 0.7 s an AttributeError from
shapely's import (return code 1); 1 s and later gave the one line.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import sarmitsuba

ROOT = Path(sarmitsuba.__file__).resolve().parent.parent


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process is POSIX")
@pytest.mark.parametrize("delay", [0.05, 0.3, 1.0, 2.0])
def test_ctrl_c_while_starting_exits_130_with_one_line(delay, tmp_path):
    """SIGINT after ``delay`` seconds, while the package imports (0.05-0.3 s), while Mitsuba and the
    pipeline import (about 0.3-1.5 s) and while the render runs (a 3000-pulse trihedral, several
    seconds): return code 130 and exactly the one ``interrupted`` line on stderr, no traceback, no
    GPU message, and no output directory left half-written."""
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}
    env.pop("SARMITSUBA_VARIANT", None)
    process = subprocess.Popen([sys.executable, "-m", "sarmitsuba", "render", "trihedral", "--pulses", "3000",
                                "--out", str(out), "--no-progress"], cwd=tmp_path, env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    lines = err.strip().splitlines()
    assert process.returncode == 130, f"after {delay} s: return code {process.returncode}, stderr:\n{err}"
    assert lines == ["interrupted: no output file was left half-written"], err
    assert "Traceback" not in err and "GPU" not in err
    assert not (out / "image.npz").exists()
