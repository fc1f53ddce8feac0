"""Shared output of the benchmark scripts: the output folder, a CSV table in it, and the machine line.

The folder is ``$SARMITSUBA_BENCH_OUT`` when set (``run.py --out DIR`` sets it), else ``out/bench``
under the current directory: the suite never writes into the source checkout unless asked to.
"""
from __future__ import annotations

import csv
import os
import platform
from pathlib import Path


def machine() -> str:
    """One line naming the machine the benchmark ran on (ratios, not absolute times, are comparable)."""
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), cpu)
    except OSError:
        pass
    return f"machine: {cpu}, {os.cpu_count()} cpus, Python {platform.python_version()}, {platform.system()}"


def machine_info() -> dict:
    """The machine and software of a run, for ``machine.json`` beside the CSV tables.

    Keys: ``machine`` (the line of :func:`machine`), ``cpu``, ``cpus``, ``memory_gib``, ``python``,
    ``system``, ``mitsuba``, ``drjit``, ``numpy`` (``None`` where not installed).
    """
    import importlib.metadata
    info = {"machine": machine(), "cpu": machine().split(": ", 1)[1].split(",")[0], "cpus": os.cpu_count(),
            "memory_gib": None, "python": platform.python_version(), "system": platform.platform()}
    try:
        with open("/proc/meminfo") as f:
            kib = next(int(line.split()[1]) for line in f if line.startswith("MemTotal"))
        info["memory_gib"] = round(kib / 2 ** 20, 1)
    except (OSError, StopIteration, ValueError):
        pass
    for package in ("mitsuba", "drjit", "numpy"):
        try:
            info[package] = importlib.metadata.version(package)
        except importlib.metadata.PackageNotFoundError:
            info[package] = None
    return info


def output_dir() -> Path:
    """The folder the benchmarks write to (created): ``$SARMITSUBA_BENCH_OUT``, else ``./out/bench``."""
    out = Path(os.environ.get("SARMITSUBA_BENCH_OUT") or Path("out") / "bench")
    out.mkdir(parents=True, exist_ok=True)
    return out


def write_csv(name: str, rows: list[dict]) -> Path:
    """Write ``rows`` (dicts with the same keys) to ``output_dir() / NAME``; returns the path."""
    path = output_dir() / name
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {path}")
    return path


def descent_figure(name: str, rows: list[dict], panels, title: str, size=(10, 3.6)) -> Path:
    """The figure of an inverse problem's descent, written to ``output_dir() / NAME``: the loss
    against evaluations (``rows``: ``evaluation``, ``loss``), then one panel per entry of
    ``panels`` (callables drawing on an axis, given the evaluations); returns the path."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 1 + len(panels), figsize=size, dpi=120)
    evaluations = [r["evaluation"] for r in rows]
    axes[0].semilogy(evaluations, [max(r["loss"], 1e-30) for r in rows], "o-")
    axes[0].set_ylabel("amplitude loss")
    for ax, panel in zip(axes[1:], panels):
        panel(ax, evaluations)
    for ax in axes:
        ax.set_xlabel("evaluation (loss and gradient)")
        ax.grid(True, alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path = output_dir() / name
    fig.savefig(path)
    plt.close(fig)
    return path


def bench_main(doc: str, run, checks, quick_help: str, tiny_help: str | None = None) -> None:
    """Command line of one benchmark script: ``--quick`` (and ``--tiny``), run, print the ratio checks."""
    import argparse
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help=quick_help)
    if tiny_help:
        parser.add_argument("--tiny", action="store_true", help=tiny_help)
    args = parser.parse_args()
    rows = run(args.quick, tiny=True) if getattr(args, "tiny", False) else run(args.quick)
    for check, ok, detail in checks(rows):
        print(f"{'PASS' if ok else 'FAIL'}  {check}  {detail}")


def report_rows(name: str, rows: list[dict]) -> list[dict]:
    """Print every row, write them to ``output_dir() / name``; returns ``rows``."""
    for row in rows:
        print(row)
    write_csv(name, rows)
    return rows
