"""Benchmark: the same renders on the GPU (``cuda_ad_mono``) and the CPU (``llvm_ad_mono``), on a
machine with an NVIDIA GPU, in one command.

1. ``tests/test_gpu.py``: the cuda raw data of the trihedral against llvm's (within -60 dB NRMSE).
2. ``urban`` and ``sionna:munich`` rendered with each variant (each render twice, the second
   timed: the first fills the kernel cache), in subprocesses (a process keeps the variant it
   started with): seconds by pipeline stage and by trace stage (``summary.json``'s ``timings``
   and ``trace_stages``), and the raw data's and image's NRMSE between the variants,
   ``10 log10(sum |cuda - llvm|^2 / sum |llvm|^2)`` [dB].

Writes ``gpu.csv`` and ``gpu.json`` (in the output folder, ``_table.output_dir``). ``--quick``: urban
only; ``--pulses N``: Munich with N pulses (default: its own 2,326). Needs a GPU, its driver and
Sionna RT (for Munich); without a GPU it says so and exits 2.
Usage: ``python benchmarks/gpu.py [--quick] [--pulses N]``
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from _table import machine, output_dir, write_csv

ROOT = Path(__file__).resolve().parents[1]
VARIANTS = ("llvm_ad_mono", "cuda_ad_mono")


def render(scene: str, variant: str, out: Path, pulses: int = 0) -> dict:
    """One render in a subprocess with ``variant``: its summary.json, with the wall seconds."""
    env = {**os.environ, "SARMITSUBA_VARIANT": variant}
    argv = [sys.executable, "-m", "sarmitsuba", "render", scene, "--out", str(out), "--no-progress"]
    if pulses:
        argv += ["--pulses", str(pulses)]
    start = time.perf_counter()
    result = subprocess.run(argv, env=env, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if result.returncode != 0:
        raise SystemExit(f"{variant} {scene}: exit {result.returncode}\n{result.stderr[-2000:]}")
    summary = json.loads((out / "summary.json").read_text())
    summary["wall"] = wall
    return summary


def nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB]."""
    return float(10.0 * np.log10(np.sum(np.abs(a - b) ** 2) / max(float(np.sum(np.abs(b) ** 2)), 1e-300)))


def compare(scene: str, out: Path, pulses: int = 0) -> dict:
    """Both variants on ``scene`` (the second render of each timed) and their NRMSE."""
    runs = {}
    for variant in VARIANTS:
        folder = out / f"{scene.replace(':', '_')}_{variant}"
        render(scene, variant, folder, pulses)                 # fills the kernel cache
        runs[variant] = (render(scene, variant, folder, pulses), folder)
    (llvm, llvm_dir), (cuda, cuda_dir) = runs["llvm_ad_mono"], runs["cuda_ad_mono"]
    row = {"scene": scene, "pulses": cuda["n_pulses"]}
    for name, (summary, _) in runs.items():
        short = name.split("_")[0]
        row[f"{short}_wall_s"] = round(summary["wall"], 2)
        for stage, seconds in summary["timings"].items():
            row[f"{short}_{stage}_s"] = round(seconds, 2)
        for stage, seconds in summary.get("trace_stages", {}).items():
            row[f"{short}_trace_{stage.replace(' ', '_')}_s"] = round(seconds, 2)
    for name in ("raw", "image"):
        a, b = (np.load(folder / f"{name}.npz")["data"] for folder in (cuda_dir, llvm_dir))
        row[f"{name}_nrmse_db"] = round(nrmse_db(a, b), 1)
    row["trace_speedup"] = round(llvm["timings"]["trace"] / max(cuda["timings"]["trace"], 1e-9), 2)
    print(json.dumps(row), flush=True)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="urban only")
    parser.add_argument("--pulses", type=int, default=0, help="Munich's pulse count (default: its own)")
    args = parser.parse_args()
    gpu = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True, text=True) \
        if _has("nvidia-smi") else None
    if gpu is None or gpu.returncode != 0:
        print("no NVIDIA GPU here (nvidia-smi found none): nothing to measure", file=sys.stderr)
        raise SystemExit(2)
    print(machine(), "| GPU:", gpu.stdout.strip(), flush=True)
    test = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:xdist", "tests/test_gpu.py"], cwd=ROOT,
                          capture_output=True, text=True)
    print(test.stdout[-3000:], flush=True)
    out = output_dir() / "gpu"
    rows = [compare("urban", out)]
    if not args.quick:
        rows.append(compare("sionna:munich", out, args.pulses))
    write_csv("gpu.csv", rows)
    (output_dir() / "gpu.json").write_text(json.dumps({"machine": machine(), "gpu": gpu.stdout.strip(),
                                                        "test_gpu": test.stdout[-3000:], "rows": rows}, indent=1))
    for row in rows:
        print(f"{'PASS' if row['raw_nrmse_db'] <= -60 else 'FAIL'}  {row['scene']}: cuda raw data within -60 dB of "
              f"llvm's  {row['raw_nrmse_db']} dB; trace {row['trace_speedup']}x the CPU's")


def _has(program: str) -> bool:
    return any((Path(p) / program).exists() for p in os.environ.get("PATH", "").split(os.pathsep))


if __name__ == "__main__":
    main()
