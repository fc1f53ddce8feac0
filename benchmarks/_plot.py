"""Shared plot of the benchmark scripts: error (or any accuracy figure) against seconds, one point per setting."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from _table import output_dir  # noqa: E402


def plot_cost(name: str, series: dict[str, list[tuple[float, float, str]]], *, xlabel: str = "time [s]",
              ylabel: str, title: str, logx: bool = True, logy: bool = False) -> Path:
    """Write ``NAME`` (PNG) into the benchmarks' output folder (``_table.output_dir``): accuracy against cost, one point per setting.

    Parameters
    ----------
    name : str
        File name, e.g. ``"bounce_depth.png"``.
    series : dict
        Label -> list of ``(x, y, point_label)``; each series is drawn as a line through its
        points, each point annotated with its setting (e.g. ``"depth 3"``).
    xlabel, ylabel, title : str
    logx, logy : bool
        Logarithmic axes (time usually spans decades).
    """
    out = output_dir()
    fig, ax = plt.subplots(figsize=(6.4, 4.4), dpi=120)
    for label, points in series.items():
        xs = [p[0] for p in points]
        ys = [p[1] for p in points]
        ax.plot(xs, ys, "o-", label=label)
        for x, y, text in points:
            ax.annotate(text, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    if logx:
        ax.set_xscale("log")
    if logy:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    if len(series) > 1:
        ax.legend(fontsize=8)
    fig.tight_layout()
    path = out / name
    fig.savefig(path)
    plt.close(fig)
    print(f"wrote {path}")
    return path


def report_per_scene(name: str, rows: list[dict], scenes, metric: str, *, ylabel: str, title: str,
                     label=lambda setting: setting) -> None:
    """Print ``rows``, write them to ``NAME.csv`` and plot ``NAME.png``: per scene, ``metric``
    [dB] against ``trace_s`` [s], one point per ``setting`` (named by ``label``); rows whose
    metric is not a finite number are left off the plot."""
    from _table import write_csv
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    write_csv(f"{name}.csv", rows)
    plot_cost(f"{name}.png", {scene: [(r["trace_s"], r[metric], label(r["setting"])) for r in rows
                                      if r["scene"] == scene and isinstance(r[metric], (int, float))
                                      and math.isfinite(r[metric])] for scene in scenes},
              xlabel="trace time [s]", ylabel=ylabel, title=title)
