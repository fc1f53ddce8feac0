"""Benchmark: the renders on the GPU (``cuda_ad_mono``), timed by stage, and compared with the CPU
variant (``llvm_ad_mono``), in one command on a machine with an NVIDIA GPU.

1. ``tests/test_gpu.py``: the cuda raw data of the trihedral against llvm's (within -60 dB NRMSE;
   against the stored llvm reference ``tests/data/gpu/trihedral_llvm_raw.npz`` where the llvm
   variant cannot start, e.g. on a GPU machine without libLLVM >= 16).
2. The trihedral on cuda three ways, to place any difference: the default render with its raw data
   per bounce order (``--split-bounces``), with Dr.Jit's fast math off, and without diffraction.
3. ``urban`` and ``sionna:munich`` on cuda at ``--max-depth 3`` (:data:`MAX_DEPTH`), each rendered
   twice: the first run (kernels compiled) and the second (kernel cache warm) timed, with seconds
   by pipeline stage and by trace stage (``summary.json``'s ``timings`` and ``trace_stages``).
   Where the llvm variant starts too, it renders the same and the NRMSE
   ``10 log10(sum |cuda - llvm|^2 / sum |llvm|^2)`` [dB] of the raw data and the image is
   computed there.

Everything is written under ``--out`` (default: the benchmarks' output folder, ``_table.output_dir``):
``gpu.json`` and one folder per render. ``--against DIR`` runs on the CPU machine instead: for each
render folder in ``DIR`` (brought back from the GPU machine) it renders the same with llvm, focuses
the cuda raw data with the same command, and prints the NRMSE of raw data and image.
``--store-reference`` rewrites the stored llvm reference of the GPU test (after a physics change).

Usage: ``python benchmarks/gpu.py [--quick] [--pulses N] [--out DIR]``,
``python benchmarks/gpu.py --against DIR``, ``python benchmarks/gpu.py --store-reference``.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from _table import machine, output_dir

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "tests" / "data" / "gpu" / "trihedral_llvm_raw.npz"
#: The GPU test's render (tests/test_gpu.py renders the same, at the default ``max_depth = auto``).
TRIHEDRAL = ("trihedral", ["--pulses", "32"])
#: The bounce orders of the timed renders (urban, Munich): 3, the default render's depth before
#: ``max_depth = auto``, so that the speed figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3
#: Dr.Jit's fast math off for one render (the flag is per process, set before the variant).
NO_FAST_MATH = "import drjit as dr; dr.set_flag(dr.JitFlag.FastMath, False); "


def render(scene: str, variant: str, out: Path, extra=(), prefix: str = "") -> dict:
    """One render in a subprocess with ``variant`` (a process keeps the variant it started with):
    its summary.json, with the wall seconds and the host threads used. A render that fails on two
    host threads is retried on one (``SARMITSUBA_HOST_THREADS=1``), and the failure recorded."""
    argv = ["render", scene, "--out", str(out), "--no-progress", *extra]
    code = prefix + f"import sys; from sarmitsuba.cli import run; sys.argv = ['sarmitsuba'] + {argv!r}; run()"
    failures = []
    for threads in ("", "1"):
        env = {**os.environ, "SARMITSUBA_VARIANT": variant}
        if threads:
            env["SARMITSUBA_HOST_THREADS"] = threads
        start = time.perf_counter()
        result = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True)
        wall = time.perf_counter() - start
        if result.returncode == 0:
            summary = json.loads((out / "summary.json").read_text())
            summary.update(wall=wall, host_threads=threads or "default", failures=failures)
            print(f"{variant} {scene} {' '.join(extra)}: {wall:.1f} s wall; {result.stdout.strip()[-300:]}",
                  flush=True)
            return summary
        failures.append(f"exit {result.returncode}: {result.stderr[-1500:]}")
        print(f"{variant} {scene} (host threads {threads or 'default'}) FAILED: {failures[-1]}", flush=True)
    return {"failed": failures, "wall": None}


def nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB]."""
    return float(10.0 * np.log10(np.sum(np.abs(a - b) ** 2) / max(float(np.sum(np.abs(b) ** 2)), 1e-300)))


def llvm_starts() -> bool:
    """Whether the llvm variant can start here (a libLLVM >= 16 is found)."""
    sys.path.insert(0, str(ROOT))
    from sarmitsuba.tracing._llvm import LibLLVMError, find_libllvm
    try:
        find_libllvm(os.environ)
        return True
    except LibLLVMError:
        return False


def stage_row(summary: dict, key: str) -> dict:
    """Seconds by pipeline stage and trace stage of one render, prefixed ``key``."""
    row = {f"{key}_wall_s": round(summary["wall"], 2) if summary.get("wall") else None}
    for stage, seconds in summary.get("timings", {}).items():
        row[f"{key}_{stage}_s"] = round(seconds, 2)
    for stage, seconds in summary.get("trace_stages", {}).items():
        row[f"{key}_trace_{stage.replace(' ', '_')}_s"] = round(seconds, 2)
    return row


def timed(scene: str, out: Path, pulses: int, with_llvm: bool) -> dict:
    """``scene`` on cuda twice (first run, then warm), and on llvm twice where it starts: stages
    of each, and the NRMSE of raw data and image between the variants' warm renders."""
    extra = ["--max-depth", str(MAX_DEPTH), *(["--pulses", str(pulses)] if pulses else [])]
    row = {"scene": scene}
    folders = {}
    for variant in ("cuda_ad_mono", "llvm_ad_mono") if with_llvm else ("cuda_ad_mono",):
        short = variant.split("_")[0]
        folder = folders[short] = out / f"{scene.replace(':', '_')}_{short}"
        row.update(stage_row(render(scene, variant, folder, extra), f"{short}_first"))
        warm = render(scene, variant, folder, extra)
        row.update(stage_row(warm, f"{short}_warm"), pulses=warm.get("n_pulses"),
                   rays=warm.get("rays_traced"), host_threads=warm.get("host_threads"))
    if with_llvm and all((folders[v] / "raw.npz").is_file() for v in folders):
        for name in ("raw", "image"):
            a, b = (np.load(folders[v] / f"{name}.npz")["data"] for v in ("cuda", "llvm"))
            row[f"{name}_nrmse_db"] = round(nrmse_db(a, b), 1)
    print(json.dumps(row), flush=True)
    return row


def trihedral_diagnostics(out: Path) -> dict:
    """The GPU test's trihedral on cuda: default with raw data per order, fast math off, no
    diffraction. Each summary's energy per order, for comparison with llvm's."""
    scene, extra = TRIHEDRAL
    runs = {"default": ([*extra, "--split-bounces"], ""), "no_fast_math": (extra, NO_FAST_MATH),
            "no_diffraction": ([*extra, "--integrator-set", "diffraction=false"], "")}
    found = {}
    for name, (argv, prefix) in runs.items():
        summary = render(scene, "cuda_ad_mono", out / f"trihedral_{name}", argv, prefix)
        found[name] = {k: summary.get(k) for k in ("energy_per_order", "rays_per_order", "wall", "failed")}
    return found


def gpu_run(args) -> None:
    """The GPU machine's side: test, diagnostics, timed renders; ``gpu.json`` in ``args.out``."""
    out = Path(args.out) if args.out else output_dir() / "gpu"
    out.mkdir(parents=True, exist_ok=True)
    gpu = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version", "--format=csv,noheader"],
                         capture_output=True, text=True) if shutil.which("nvidia-smi") else None
    if gpu is None or gpu.returncode != 0:
        print("no NVIDIA GPU here (nvidia-smi found none): nothing to measure", file=sys.stderr)
        raise SystemExit(2)
    report = {"machine": machine(), "gpu": gpu.stdout.strip(), "llvm_starts": llvm_starts()}
    print(report, flush=True)

    def save():
        (out / "gpu.json").write_text(json.dumps(report, indent=1))

    if args.renders_only:
        return timed_renders(args, out, report, save)
    test = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests/test_gpu.py"],
                          cwd=ROOT, capture_output=True, text=True)
    report["test_gpu"] = test.stdout[-3000:]
    print(test.stdout[-3000:], flush=True)
    save()
    report["trihedral"] = trihedral_diagnostics(out)
    save()
    timed_renders(args, out, report, save)


def timed_renders(args, out: Path, report: dict, save) -> None:
    """Item 3 of the module's list: urban and Munich timed (and compared where llvm starts)."""
    report["rows"] = []
    for scene in ("urban",) if args.quick else ("urban", "sionna:munich"):
        report["rows"].append(timed(scene, out, args.pulses if scene != "urban" else 0, report["llvm_starts"]))
        save()
    print(f"wrote {out / 'gpu.json'}")


def against(folder: Path) -> None:
    """The CPU machine's side: for each cuda render folder in ``folder`` (``*_cuda`` and
    ``trihedral_*``), the same render with llvm here, the cuda raw data focused here, and the
    NRMSE of raw data (per bounce order where written) and image."""
    rows = []
    for cuda_dir in sorted(p for p in folder.iterdir() if (p / "raw.npz").is_file()):
        summary = json.loads((cuda_dir / "summary.json").read_text())
        scene = summary["scene"]
        extra = ["--pulses", str(summary["n_pulses"])]
        if summary.get("depth", {}).get("mode") != "auto":       # a fixed depth (the timed renders'), as traced
            extra += ["--max-depth", str(summary["settings"]["max_depth"])]
        extra += ["--split-bounces"] if (cuda_dir / "raw_order1.npz").is_file() else []
        extra += [] if summary["settings"].get("diffraction", True) else ["--integrator-set", "diffraction=false"]
        llvm_dir = folder.parent / f"{folder.name}_llvm" / cuda_dir.name
        render(scene, "llvm_ad_mono", llvm_dir, extra)
        refocused = llvm_dir.parent / f"{cuda_dir.name}_cuda_focused"
        subprocess.run([sys.executable, "-m", "sarmitsuba", "focus", str(cuda_dir / "raw.npz"), "--out",
                        str(refocused), "--no-progress"], cwd=ROOT, check=True, capture_output=True)
        row = {"render": cuda_dir.name}
        for name, a_dir, b_dir in [("raw", cuda_dir, llvm_dir), ("image", refocused, llvm_dir)] + \
                [(f"raw_order{k}", cuda_dir, llvm_dir) for k in (1, 2, 3) if (cuda_dir / f"raw_order{k}.npz").is_file()]:
            a, b = (np.load(d / f"{name}.npz")["data"] for d in (a_dir, b_dir))
            row[name] = round(nrmse_db(a, b), 1)
            fit = np.vdot(b, a) / max(np.vdot(b, b).real, 1e-300)        # the best single complex factor
            row[f"{name}_factor"] = (round(float(abs(fit)), 5), round(float(np.degrees(np.angle(fit))), 3),
                                     round(nrmse_db(a, fit * b), 1))
        print(json.dumps(row), flush=True)
        rows.append(row)
    (folder / "against.json").write_text(json.dumps(rows, indent=1))


def store_reference() -> None:
    """Render the GPU test's trihedral with llvm and store its raw data as the test's reference."""
    out = output_dir() / "gpu_reference"
    summary = render(TRIHEDRAL[0], "llvm_ad_mono", out, TRIHEDRAL[1])
    if summary.get("failed"):
        raise SystemExit(1)
    REFERENCE.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(REFERENCE, data=np.load(out / "raw.npz")["data"])
    print(f"wrote {REFERENCE}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="urban only")
    parser.add_argument("--pulses", type=int, default=0, help="Munich's pulse count (default: its own)")
    parser.add_argument("--out", default="", help="output folder (default: the benchmarks' output folder / gpu)")
    parser.add_argument("--renders-only", action="store_true", help="skip the GPU test and the trihedral")
    parser.add_argument("--against", default="", help="compare cuda renders in this folder with llvm here")
    parser.add_argument("--store-reference", action="store_true", help="rewrite the GPU test's llvm reference")
    args = parser.parse_args()
    if args.store_reference:
        store_reference()
    elif args.against:
        against(Path(args.against))
    else:
        gpu_run(args)


if __name__ == "__main__":
    main()
