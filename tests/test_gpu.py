"""The same code on the cuda backend (``SARMITSUBA_VARIANT=cuda_ad_mono``), and the variant's
errors. Runs in subprocesses: a process keeps the variant it started with.

On a machine without an NVIDIA GPU the cuda comparison is skipped, saying so; the error path
(one message, exit code 2, no traceback) is tested everywhere.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(tmp_path: Path, variant: str, out: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "SARMITSUBA_VARIANT": variant}
    return subprocess.run([sys.executable, "-m", "sarmitsuba", "render", "trihedral", "--out", str(tmp_path / out),
                           "--no-progress", "--pulses", "32"], env=env, cwd=ROOT, capture_output=True, text=True,
                          timeout=600)


def test_bad_variant_exits_2_with_one_message(tmp_path):
    result = _run(tmp_path, "scalar_rgb", "x")
    assert result.returncode == 2 and "SARMITSUBA_VARIANT = 'scalar_rgb'" in result.stderr
    assert "llvm_ad_mono" in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["render", "--help"]])
def test_bad_variant_still_answers_help_and_version(argv):
    """An unusable variant blocks tracing, not the command line's own answers: ``--help`` and
    ``--version`` exit 0 with their usual text, while a command that traces exits 2 (above)."""
    env = {**os.environ, "SARMITSUBA_VARIANT": "no_such_variant"}
    result = subprocess.run([sys.executable, "-m", "sarmitsuba", *argv], env=env, cwd=ROOT, capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert ("sarmitsuba 0.1" if argv == ["--version"] else "usage: sarmitsuba") in result.stdout
    assert result.stderr == ""


#: The llvm variant's raw data of the same render, for a GPU machine where llvm cannot start (no
#: libLLVM >= 16 there); rewritten by ``python benchmarks/gpu.py --store-reference``.
REFERENCE = ROOT / "tests" / "data" / "gpu" / "trihedral_llvm_raw.npz"


def _nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    return float(10 * np.log10(np.sum(np.abs(a - b) ** 2) / np.sum(np.abs(b) ** 2)))


def _raw(folder: Path) -> np.ndarray:
    from sarmitsuba.core.raw import RawData
    return RawData.load(folder / "raw.npz").data


def test_stored_llvm_reference_is_current(tmp_path):
    """The stored llvm raw data (what a GPU machine without libLLVM compares with) equal a fresh
    llvm render within -60 dB: a physics change that moves the trihedral makes this fail here, on
    every machine, until the reference is rewritten (``python benchmarks/gpu.py --store-reference``)."""
    cpu = _run(tmp_path, "llvm_ad_mono", "llvm")
    if cpu.returncode == 2 and "libLLVM" in cpu.stderr:
        pytest.skip("the llvm variant cannot start here (no libLLVM >= 16): nothing to compare the reference with")
    assert cpu.returncode == 0, cpu.stderr
    stored = np.load(REFERENCE)["data"]
    fresh = _raw(tmp_path / "llvm")
    assert stored.shape == fresh.shape
    assert _nrmse_db(stored, fresh) < -60.0, "rewrite it: python benchmarks/gpu.py --store-reference"


def test_cuda_render_equals_llvm_render(tmp_path):
    """The trihedral's raw data from the cuda variant equal the llvm variant's within -60 dB NRMSE
    (float32 arithmetic in another order on another device): a fresh llvm render where that variant
    starts, else the stored one (checked against a fresh one above)."""
    gpu = _run(tmp_path, "cuda_ad_mono", "cuda")
    if gpu.returncode == 2 and "cannot start on this machine" in gpu.stderr:
        pytest.skip("no NVIDIA GPU here: SARMITSUBA_VARIANT=cuda_ad_mono cannot start (the CPU variant is tested "
                    "everywhere else)")
    assert gpu.returncode == 0, gpu.stderr
    cpu = _run(tmp_path, "llvm_ad_mono", "llvm")
    llvm = _raw(tmp_path / "llvm") if cpu.returncode == 0 else np.load(REFERENCE)["data"]
    assert _nrmse_db(_raw(tmp_path / "cuda"), llvm) < -60.0
