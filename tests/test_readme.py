"""Every command in the README's code blocks runs, in README order, in one working folder.

Commands run as written, with only these changes, each listed in :data:`SMALL` and
:data:`SUBSTITUTES`:

* small settings (``--pulses 16 --max-depth 1``, a 200 x 150 preview), so the whole README runs in
  about a minute; a command's own ``--max-depth`` is kept, and the trihedral renders as it is;
* renders of Sionna's Munich trace Sionna's ``simple_street_canyon`` instead (``info`` still
  reads Munich): the same code on a scene a hundred times smaller;
* ``my_scene.xml`` is a copy of the built-in dihedral, ``/tmp/bench`` a folder of the test,
  ``SCHEDULER:8786`` a ``dask scheduler`` started from the README's own line on 127.0.0.1;
* ``bench`` runs with stand-in benchmarks that record how they were called (the real suite
  takes 20 minutes; ``benchmarks/`` is exercised by its own tests), so the command line itself
  is what is tested (:data:`BENCH_COMMANDS`, the suite's command lines, run the same way);
* ``SARMITSUBA_VARIANT=cuda_ad_mono`` may exit 2 with "cannot start on this machine" where
  there is no NVIDIA GPU (tests/test_gpu.py).

``make render`` and ``make test`` are the fresh-clone commands: CI runs ``make test`` on a clean
clone, which is this suite. A line of another kind fails the test, so a new README command
cannot go untested. The README's Python example runs as written; tests/test_manual_pages.py runs
the manual's pages the same way.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import socket
import subprocess
import sys
import time
import types
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.cli import main

REPO = Path(__file__).resolve().parents[1]
PYTHON = ".venv/bin/python"
DASK = ".venv/bin/dask"

#: Flags added to a sub-command unless the command gives them itself.
SMALL = {"render": ["--pulses", "16", "--max-depth", "1", "--no-progress"],
         "preview": ["--pulses", "16", "--spp", "1", "--resolution", "200x150"],
         "info": ["--pulses", "16"], "focus": ["--no-progress"], "interferogram": ["--no-progress"],
         "stack": ["--pulses", "16", "--max-depth", "1", "--no-progress"], "tomography": ["--no-progress"]}
#: README text -> what the test runs instead (see the module docstring).
SUBSTITUTES = {"render sionna:munich": "render sionna:simple_street_canyon"}
#: The fresh-clone commands, run by CI on a clean clone rather than inside the suite.
FRESH_CLONE = {"make render", "make test"}
#: The benchmark suite's command lines (``make bench`` runs the first): whole, quick, a choice into a folder.
BENCH_COMMANDS = [f"{PYTHON} -m sarmitsuba bench", f"{PYTHON} -m sarmitsuba bench --quick",
                  f"{PYTHON} -m sarmitsuba bench --only range_kernel focus --out /tmp/bench"]


def code_blocks(language: str, page: Path = REPO / "README.md") -> list[tuple[int, str]]:
    """(first line number, text) of every ``language`` code block of ``page`` (README.md)."""
    blocks, lines = [], page.read_text().splitlines()
    inside, start, body = False, 0, []
    for number, line in enumerate(lines, start=1):
        if line.startswith("```"):
            if inside and body:
                blocks.append((start, "\n".join(body)))
            inside, start, body = (not inside and line[3:].strip() == language), number + 1, []
        elif inside:
            body.append(line)
    return blocks


def commands(block: str) -> list[str]:
    """The block's command lines: continuations joined, comments and blank lines dropped."""
    joined = re.sub(r"\\\n\s*", " ", block)
    return [line for line in (re.sub(r"\s+#.*$", "", raw).strip() for raw in joined.splitlines())
            if line and not line.startswith("#")]


def with_small_settings(argv: list[str]) -> list[str]:
    """``argv`` (after ``-m sarmitsuba``) with the flags of :data:`SMALL` its command lacks. The
    built-in trihedral renders as it is (a second; its SICD then holds a 64-pixel analysis chip)."""
    extra, given = SMALL.get(argv[0], []), set(argv)
    if argv[:2] == ["render", "trihedral"]:
        extra = ["--no-progress"]
    added, i = [], 0
    while i < len(extra):
        flag = extra[i]
        takes_value = i + 1 < len(extra) and not extra[i + 1].startswith("--")
        if flag not in given:
            added += extra[i:i + 2] if takes_value else [flag]
        i += 2 if takes_value else 1
    return argv + added


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Runner:
    """Runs README lines in ``folder``; dask processes started there are stopped by :meth:`close`."""

    def __init__(self, folder: Path, capsys, monkeypatch):
        self.folder, self.capsys, self.monkeypatch = folder, capsys, monkeypatch
        self.port, self.processes, self.bench_calls = free_port(), [], []

    def text(self, line: str) -> str:
        for old, new in SUBSTITUTES.items():
            line = line.replace(old, new)
        return (line.replace("SCHEDULER:8786", f"127.0.0.1:{self.port}").replace("--port 8786", f"--port {self.port}")
                .replace("--host 0.0.0.0", "--host 127.0.0.1").replace("/tmp/bench", str(self.folder / "bench")))

    def run(self, line: str) -> None:
        line = self.text(line)
        line, _, grep = line.partition(" | grep ")
        words = shlex.split(line)
        if words[0] in (DASK, "dask"):
            return self.start_dask(words, line)
        env = dict(w.split("=", 1) for w in words if re.fullmatch(r"[A-Z_]+=\S+", w))
        words = words[len(env):]
        words[:1] = [PYTHON] if words[:1] == ["python"] else words[:1]      # the manual's pages: a venv activated
        assert words[:3] == [PYTHON, "-m", "sarmitsuba"], f"a README command of an unknown kind: {line}"
        argv = with_small_settings(words[3:])
        if env:
            return self.run_in_subprocess(argv, env, line)
        if argv[0] == "bench":
            self.stand_in_benchmarks()
        code = main(argv)
        out, err = self.capsys.readouterr()
        assert code == 0, f"{line}\n-> exit {code}: {err}"
        assert grep.strip("'\"") in out, f"{line}: no {grep!r} in its output"

    def run_in_subprocess(self, argv: list[str], env: dict, line: str) -> None:
        result = subprocess.run([sys.executable, "-m", "sarmitsuba", *argv], cwd=self.folder, env={**os.environ, **env},
                                capture_output=True, text=True, timeout=600)
        no_gpu = result.returncode == 2 and "cannot start on this machine" in result.stderr
        assert result.returncode == 0 or no_gpu, f"{line}\n-> exit {result.returncode}: {result.stderr}"

    def start_dask(self, words: list[str], line: str) -> None:
        """``dask scheduler ... &`` or ``dask worker ... &``: started in the background, then waited for."""
        executable = Path(sys.executable).parent / "dask"
        assert executable.exists(), "the dask command is missing: dask[distributed] is a dependency of sarmitsuba"
        words = [w for w in words if w != "&"]
        self.processes.append(subprocess.Popen([str(executable), *words[1:]], cwd=self.folder,
                                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        if words[1] == "worker":
            self.wait_for_worker(line)

    def wait_for_worker(self, line: str) -> None:
        from distributed import Client
        deadline = time.monotonic() + 60
        with Client(f"tcp://127.0.0.1:{self.port}", timeout=60) as client:
            while not client.scheduler_info()["workers"]:
                assert time.monotonic() < deadline, f"{line}: no worker joined in 60 s"
                time.sleep(0.2)

    def stand_in_benchmarks(self) -> None:
        """Every suite module replaced by one that records (module, quick) and writes one table."""
        sys.path.insert(0, str(REPO / "benchmarks"))
        import _table
        import run as suite
        for module_name in suite.SUITE.values():
            def run(quick, name=module_name):
                self.bench_calls.append((name, quick))
                rows = [{"setting": 1, "seconds": 0.0}]
                _table.write_csv(f"{name}.csv", rows)
                return rows
            self.monkeypatch.setitem(sys.modules, module_name, types.SimpleNamespace(run=run))

    def close(self) -> None:
        for process in reversed(self.processes):
            process.terminate()
            process.wait(timeout=30)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """The README's working folder: ``scenes/`` (for the Python example's mesh) and my_scene.xml."""
    path = tmp_path_factory.mktemp("readme")
    (path / "scenes").symlink_to(REPO / "scenes", target_is_directory=True)
    shutil.copy(REPO / "scenes" / "dihedral.xml", path / "my_scene.xml")       # its plates are inline
    return path


def test_every_command_line_is_of_a_known_kind():
    lines = [line for _, block in code_blocks("bash") for line in commands(block)]
    unknown = [line for line in lines if line not in FRESH_CLONE
               and not re.match(rf"([A-Z_]+=\S+ )*({re.escape(PYTHON)} -m sarmitsuba|{re.escape(DASK)}) ", line)]
    assert unknown == []
    assert FRESH_CLONE <= set(lines) and len(lines) > len(FRESH_CLONE)


def test_readme_bash_blocks_run_in_order(folder, capsys, monkeypatch):
    """One test for all blocks: later blocks use earlier ones' outputs (``focus out/urban/raw.npz``),
    so they run in README order in one process whatever the test scheduler does."""
    monkeypatch.chdir(folder)
    runner = Runner(folder, capsys, monkeypatch)
    ran = []
    try:
        for start, block in code_blocks("bash"):
            for line in commands(block):
                if line not in FRESH_CLONE:
                    runner.run(line)
                    ran.append((start, line))
    finally:
        runner.close()
    assert ran


def test_bench_command_lines_reach_the_suite(folder, capsys, monkeypatch):
    """``bench``, ``bench --quick`` and ``bench --only ... --out DIR`` (:data:`BENCH_COMMANDS`), with
    stand-in benchmarks: every benchmark is called, ``--quick`` reaches it, ``--out`` is honoured."""
    monkeypatch.chdir(folder)
    runner = Runner(folder, capsys, monkeypatch)
    for line in BENCH_COMMANDS:
        runner.run(line)
    assert ("range_kernel", False) in runner.bench_calls and ("focus_algorithms", False) in runner.bench_calls
    assert ("bounce_depth", True) in runner.bench_calls                       # --quick reached the suite
    assert (folder / "bench" / "range_kernel.csv").is_file()                 # --out DIR honoured


def test_readme_python_example_runs(folder, monkeypatch, capsys):
    """The Python API example, as written (it renders into out/house), prints one line for the
    simulation and one for the reflector. The AASR it prints is within 1 dB of the reflector's
    ghosts measured in its own image (energy in 26 m x 10 m boxes at +-x_1 = prf lambda R / (2 v)
    along track, R to the reflector, over the same box on the reflector: -13.7 dB against -13.9 dB
    printed; the ground's clutter adds 0.2 dB); the ghost offset at the centre's range is the closed
    form 150 Hz x 31.2 mm x 1414.2 m / 200 m/s = 33.1 m; the reflector's numbers are the report's."""
    block = [text for _, text in code_blocks("python")][0]
    monkeypatch.chdir(folder)
    namespace: dict = {}
    exec(compile(block, "README.md (python example)", "exec"), namespace)
    sim, report = namespace["sim"], namespace["report"]
    assert np.isfinite(report.rcs_db) and (folder / "out" / "house" / "image.npz").is_file()
    printed = [line for line in capsys.readouterr().out.splitlines() if line.strip()]
    assert len(printed) == 2, printed
    assert f"{sim.raw.data.shape[0]} pulses at prf 150 Hz" in printed[0]
    assert "ghosts at +-33.1 m" in printed[0] and "raise the PRF above" in printed[0]
    aasr = float(re.search(r"AASR (-?[0-9.]+) dB", printed[0]).group(1))
    intensity, az, rg = np.abs(sim.image.data) ** 2, np.asarray(sim.image.azimuth), np.asarray(sim.image.range)
    x1 = 150.0 * 299_792_458.0 / 9.6e9 * np.hypot(1000.0, 970.0) / (2 * 100.0)

    def box(a0: float) -> float:
        inside = (np.abs(az - a0) <= 13.0)[:, None] & (np.abs(rg - report.range) <= 5.0)[None, :]
        return float(intensity[inside].sum())
    measured = 10 * np.log10((box(report.azimuth + x1) + box(report.azimuth - x1)) / box(report.azimuth))
    assert abs(measured - aasr) <= 1.0, (measured, aasr)
    assert f"RCS {report.rcs_db:.1f} dBsm" in printed[1] and f"IRW {report.irw_azimuth:.2f}" in printed[1]
    assert "range -30.0" in printed[1]                                  # the reflector at y = 30 m
