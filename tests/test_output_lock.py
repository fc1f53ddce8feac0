"""One output folder, one run (sarmitsuba/core/folder_lock.py).

Two renders into one ``--out`` must not mix their files: the second stops at once with exit
code 2 and one line saying the folder is in use. A killed render's staging folder is removed
by the next run into the folder, and no command reads from inside one.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.cli import main
from sarmitsuba.core.folder_lock import LOCK_FILE, hold_folder
from sarmitsuba.core.image import SarImage
from sarmitsuba.core.outputs import OutputDirectory
from sarmitsuba.core.raw import RawData

ROOT = Path(__file__).resolve().parents[1]
FAST = ["--no-progress", "--max-depth", "1"]


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "sarmitsuba", *args]


def _env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}


def _visible(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir() if not p.name.startswith(".")}


def _wait_for_lock(folder: Path, pid: int, proc: subprocess.Popen, timeout: float = 120.0) -> None:
    """Until the lock file inside ``folder`` holds ``pid`` (the run holds the lock)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and proc.poll() is None:
        try:
            if (folder / LOCK_FILE).read_text().strip() == str(pid):
                return
        except OSError:
            pass
        time.sleep(0.02)
    pytest.fail(f"the first render never held {folder} (exit {proc.poll()})")


def _incidence(path: Path) -> float:
    loader = RawData.load if path.name.startswith("raw") else SarImage.load
    return float(loader(path).metadata["radar"]["incidence_angle"])


def test_two_concurrent_renders_into_one_folder_never_mix(tmp_path):
    """A (35 deg, --figures) holds the folder; B (55 deg) started meanwhile exits 2 with the
    in-use line and writes nothing. Afterwards the folder's files are exactly summary.json's
    list, and raw, image and summary all record 35 deg: the figures belong to that render.
    (Before the lock, B's raw/image/summary at 55 deg sat beside A's figures, which the
    summary listed as its own.)"""
    out = tmp_path / "D"
    first = subprocess.Popen(_cli("render", "dihedral", "--out", str(out), *FAST, "--pulses", "64",
                                  "--set", "incidence_angle=35", "--figures"),
                             cwd=tmp_path, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    _wait_for_lock(out, first.pid, first)
    os.kill(first.pid, signal.SIGSTOP)          # held mid-run, however fast the machine: the runs overlap
    try:
        second = subprocess.run(_cli("render", "dihedral", "--out", str(out), *FAST, "--pulses", "32",
                                     "--set", "incidence_angle=55"),
                                cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=300)
    finally:
        os.kill(first.pid, signal.SIGCONT)
    stdout, stderr = first.communicate(timeout=600)
    assert first.returncode == 0, stderr
    assert second.returncode == 2, second.stderr
    lines = second.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in second.stderr
    assert "in use by another run" in lines[0] and f"pid {first.pid}" in lines[0] and "--out" in lines[0]
    assert "rendered" not in second.stdout
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["files"]) == _visible(out)
    assert {"fig_raw.png", "fig_image.png", "figures.json", "raw.npz", "image.npz"} <= _visible(out)
    assert summary["radar"]["incidence_angle"] == pytest.approx(35.0)
    assert _incidence(out / "raw.npz") == pytest.approx(35.0)
    assert _incidence(out / "image.npz") == pytest.approx(35.0)
    assert not (out / LOCK_FILE).exists() and not list(out.glob(".staging-*"))


def test_a_folder_held_by_another_process_refuses_at_once(tmp_path):
    """This process holds the folder (as a running render does); a render and a focus into
    it each exit 2 with the in-use line naming this pid, before any tracing."""
    out = tmp_path / "held"
    raw = tmp_path / "src"
    assert main(["render", "dihedral", "--out", str(raw), *FAST, "--pulses", "16"]) == 0
    with hold_folder(out):
        for args in (["render", "dihedral", "--out", str(out), *FAST, "--pulses", "16"],
                     ["focus", str(raw / "raw.npz"), "--out", str(out), "--no-progress"]):
            done = subprocess.run(_cli(*args), cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=300)
            assert done.returncode == 2, done.stderr
            assert f"in use by another run (pid {os.getpid()})" in done.stderr
            assert len(done.stderr.strip().splitlines()) == 1
            assert _visible(out) == set()
    assert not out.exists()                     # created by the hold, empty: removed again


def test_the_lock_is_per_process_and_counted(tmp_path):
    """A hold inside a hold (the CLI around render and its figures) is one lock: the inner
    OutputDirectory writes, and the folder is let go only at the outer end."""
    out = tmp_path / "o"
    with hold_folder(out):
        with OutputDirectory(out) as staged:
            staged.write("a.txt", lambda p: p.write_text("a"))
        assert (out / LOCK_FILE).exists()
    assert not (out / LOCK_FILE).exists()
    assert _visible(out) == {"a.txt"}


def test_a_killed_render_leaves_a_staging_folder_the_next_render_removes(tmp_path):
    """kill -9 while a render is writing: the staging folder stays (nothing can remove it), the
    lock goes with the process; the next render into the folder removes the leftover."""
    out = tmp_path / "D"
    proc = subprocess.Popen(_cli("render", "dihedral", "--out", str(out), *FAST, "--pulses", "64"),
                            cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _wait_for_lock(out, proc.pid, proc)
    end = time.monotonic() + 120
    while not list(out.glob(".staging-*")) and proc.poll() is None and time.monotonic() < end:
        time.sleep(0.005)                       # the staging folder exists from before the tracing
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=60)
    leftovers = list(out.glob(".staging-*"))
    assert leftovers, "the render ended before it could be killed mid-run"
    if not (leftovers[0] / "raw.npz").exists():     # killed while tracing: as if killed while writing
        np.savez(leftovers[0] / "raw.npz", a=np.zeros(3))
    assert main(["render", "dihedral", "--out", str(out), *FAST, "--pulses", "16"]) == 0
    assert not list(out.glob(".staging-*"))
    assert not (out / LOCK_FILE).exists()
    assert set(json.loads((out / "summary.json").read_text())["files"]) == _visible(out)


@pytest.mark.parametrize("command", ["focus", "analyze", "info"])
def test_no_command_reads_from_a_staging_folder(tmp_path, capsys, command):
    """focus, analyze and info of a file inside .staging-*: exit 2, one line saying it is an
    interrupted run's leftover; nothing is written."""
    out = tmp_path / "D"
    assert main(["render", "dihedral", "--out", str(out), *FAST, "--pulses", "16"]) == 0
    staging = out / ".staging-abc123"
    staging.mkdir()
    for name in ("raw.npz", "image.npz", "summary.json"):
        (staging / name).write_bytes((out / name).read_bytes())
    capsys.readouterr()
    target = {"focus": "raw.npz", "analyze": "image.npz", "info": "summary.json"}[command]
    args = [command, str(staging / target)] + {"focus": ["--out", str(tmp_path / "f")], "analyze": ["--target", "0,0,0"], "info": []}[command]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "interrupted" in err[0] and ".staging-abc123" in err[0]
    assert not (tmp_path / "f").exists()


def test_an_existing_file_as_the_folder_is_refused(tmp_path):
    target = tmp_path / "file"
    target.write_text("x")
    with pytest.raises(OSError, match="existing file"):
        with hold_folder(target):
            pass


def test_scene_from_footprints_holds_its_folder_and_clears_a_killed_runs_staging(tmp_path):
    """write_city (``scene from-footprints --out``) stages in the same way: a leftover staging
    folder goes, and the folder is refused while another process holds it."""
    from sarmitsuba.scene.city import build_city, write_city
    from sarmitsuba.scene.footprints import parse_footprints
    ring = [[[-10.0, -5.0], [10.0, -5.0], [10.0, 5.0], [-10.0, 5.0], [-10.0, -5.0]]]
    metres = 1.0 / 111_000.0                       # a 20 x 10 m block near (48 N, 11 E), in degrees
    ring = [[[11.0 + x * metres, 48.0 + y * metres] for x, y in ring[0]]]
    data = {"type": "FeatureCollection", "features": [
        {"type": "Feature", "properties": {"height": 10}, "geometry": {"type": "Polygon", "coordinates": ring}}]}
    out = tmp_path / "city"
    (out / ".staging-old").mkdir(parents=True)
    (out / ".staging-old" / "scene.xml").write_text("<scene/>")
    assert write_city(build_city(parse_footprints(data)), out) == out / "scene.xml"
    assert not list(out.glob(".staging-*")) and (out / "meshes").is_dir()
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from sarmitsuba.core.folder_lock import "
                               "hold_folder\nwith hold_folder(sys.argv[1]):\n    print('held', flush=True); "
                               "time.sleep(60)", str(out)], env=_env(), stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OSError, match=f"in use by another run \\(pid {holder.pid}\\)"):
            write_city(build_city(parse_footprints(data)), out)
    finally:
        holder.kill()
        holder.wait(timeout=30)


def test_a_lock_file_removed_while_it_was_being_locked_is_opened_again(tmp_path, monkeypatch):
    """The run before lets go as this one locks: it unlinks the lock file (``_release``) right
    after this run's ``flock`` succeeded on it. The lock then guards a file no other run can
    see, so ``_lock`` must open the path again and lock the file that is there. (Caught: the
    inode re-check skipped, which returned the removed file's descriptor: a second run could lock
    the new file at the same time.)"""
    import os
    from sarmitsuba.core import folder_lock
    lock = tmp_path / folder_lock.LOCK_FILE
    real, calls = folder_lock.fcntl.flock, []

    def flock(fd, operation):
        real(fd, operation)
        if not calls:
            lock.unlink()
        calls.append(fd)
    monkeypatch.setattr(folder_lock.fcntl, "flock", flock)
    fd = folder_lock._lock(lock)
    try:
        assert len(calls) == 2
        assert os.fstat(fd).st_ino == os.stat(lock).st_ino and lock.read_text() == str(os.getpid())
    finally:
        os.close(fd)
