"""Benchmark: what derivatives cost against the render they differentiate.

For the built-in ``urban`` scene (``--quick``/``--tiny``: fewer pulses), each in a fresh process
run twice back to back (the second, warm, is measured: Dr.Jit's kernel cache on disk is then
filled), wall seconds and peak memory (the process's VmHWM) of:

* ``forward``: the render the loss sees, ``simulate`` with direct backprojection onto a 64 x 64
  ground grid (``focuser = bp``, no window);
* ``derivative``: forward mode, ``d raw / d eps_r`` of the ground (``sarmitsuba.derivatives.raw_derivative``);
* ``gradient``: reverse mode, ``sarmitsuba.gradients`` of an amplitude loss on that image with
  respect to four parameters at once (the ground's permittivity and conductivity, the brick
  walls' conductivity and thickness): its own forward render, the backprojection operator's
  image and adjoint, and the trace carrying the gradient back;
* ``geometry``: reverse mode as ``gradient``, with respect to two buildings' heights
  (``ShapeParameter``, docs/physics.md (AD4)): one trace of the geometry, the values pass running
  the host geometry with the derivatives' outlines and once more per parameter at +1 um, keeping
  the lanes and their tangents, and the reverse pass replaying them. Not in ``--tiny`` (its
  kernels would add a minute of compiling to the smoke test).

Outside ``--tiny``, ``forward`` and ``geometry`` are measured again at the scene's own pulse
count (urban's 779: four launches, each with its own geometry and sub-apertures).

The checks: each reverse-mode gradient of one loss at most 4 times the forward render at the
same pulse count, for materials and for geometry, and the geometric one's peak memory at most
3 times the render's. Writes ``gradients.csv`` and ``gradients.png`` (the ratios per kind and
pulse count).

Usage: ``python benchmarks/gradients.py [--quick] [--tiny]`` (``--tiny``: 16 pulses, one bounce order,
each kind's process run once, not warm: a smoke test)
"""
from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np

from _table import bench_main, machine, output_dir, write_csv

NAME = "gradients"
#: Pulses of the measured renders (full run, --quick, --tiny).
PULSES = {"full": 128, "quick": 64, "tiny": 16}
IMAGE = (64, 64)
PARAMETERS = (("soil", "relative_permittivity"), ("soil", "conductivity"), ("brick", "conductivity"),
              ("brick", "thickness"))
#: The pulse count that stands for the scene's own (no override): urban's 779.
DEFAULT = 0
#: The ``geometry`` kind's parameters: ShapeParameter arguments.
SHAPES = (("block_a", "height"), ("block_b", "height"))


def _measure(kind: str, pulses: int) -> dict:
    """One measurement in this process: seconds of ``kind``; the smoke test's pulse count
    (:data:`PULSES` ``tiny``) traces one bounce order (fewer kernels to compile)."""
    import time

    import sarmitsuba
    from sarmitsuba.derivatives import AmplitudeLoss, MaterialParameter, ShapeParameter, raw_derivative
    sensor = {"n_pulses": pulses} if pulses else None
    settings = {"max_depth": 1} if pulses == PULSES["tiny"] else None
    start = time.perf_counter()
    if kind == "forward":
        sarmitsuba.simulate("urban", sensor_overrides=sensor, integrator_overrides=settings, focuser="bp", window="rect",
                            image_size=IMAGE)
    elif kind == "derivative":
        raw_derivative("urban", MaterialParameter("soil", "relative_permittivity"), sensor_overrides=sensor,
                       integrator_overrides=settings)
    else:
        parameters = ([MaterialParameter(*p) for p in PARAMETERS] if kind == "gradient"
                      else [ShapeParameter(*p) for p in SHAPES])
        sarmitsuba.gradients("urban", AmplitudeLoss(np.zeros(IMAGE)), parameters, image_size=IMAGE,
                             sensor_overrides=sensor, integrator_overrides=settings)
    seconds = time.perf_counter() - start
    peak = int(re.search(r"VmHWM:\s+(\d+)", open("/proc/self/status").read()).group(1)) / 1024
    from sarmitsuba.scene.loader import load_scene
    return {"seconds": seconds, "peak_mib": peak, "pulses": pulses or load_scene("urban").params.n_pulses}


def measured(kind: str, pulses: int, runs: int = 2) -> dict:
    """``kind`` in a fresh process, ``runs`` times (the smoke test's ``--tiny``: once, its seconds not
    measured warm); the last (warm) run's numbers. Its stderr passes through."""
    out = None
    for _ in range(runs):
        done = subprocess.run([sys.executable, __file__, "--measure", kind, str(pulses)], stdout=subprocess.PIPE,
                              text=True, check=True)
        out = json.loads(done.stdout.strip().splitlines()[-1])
    return out


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Measure the three kinds, print and write the table and plot; returns the rows."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    print(machine())
    pulses = PULSES["tiny" if tiny else "quick" if quick else "full"]
    rows = []
    counts = {"forward": 0, "derivative": 1, "gradient": len(PARAMETERS), "geometry": len(SHAPES)}
    runs = [(kind, pulses) for kind in (("forward", "derivative", "gradient") if tiny else counts)]
    if not tiny:                                 # and at the scene's own pulse count
        runs += [("forward", DEFAULT), ("geometry", DEFAULT)]
    for kind, count in runs:
        numbers = measured(kind, count, 1 if tiny else 2)
        rows.append({"scene": "urban", "kind": kind, "pulses": count or numbers["pulses"], "parameters": counts[kind],
                     "seconds": round(numbers["seconds"], 3), "peak_mib": round(numbers["peak_mib"])})
    for row in rows:
        forward = next(r for r in rows if r["kind"] == "forward" and r["pulses"] == row["pulses"])
        row["over_forward"] = round(row["seconds"] / forward["seconds"], 2)
        row["memory_over_forward"] = round(row["peak_mib"] / forward["peak_mib"], 2)
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    suffix = "_tiny" if tiny else ""
    write_csv(f"{NAME}{suffix}.csv", rows)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), dpi=120)
    colour = {"forward": "0.6", "derivative": "tab:blue", "gradient": "tab:orange", "geometry": "tab:green"}
    for ax, key, label in zip(axes, ("over_forward", "memory_over_forward"),
                              ("wall seconds / forward render's (warm)", "peak memory / forward render's")):
        ax.bar([f"{r['kind']}\n{r['pulses']}" for r in rows], [r[key] for r in rows],
               color=[colour[r["kind"]] for r in rows])
        ax.axhline(4.0 if key == "over_forward" else 3.0, color="k", lw=0.8, ls="--")
        ax.set_ylabel(label)
        ax.tick_params(axis="x", labelsize=7)
    fig.suptitle(f"urban, {pulses} pulses and the scene's own count: derivatives against the forward render "
                 "(dashed: the bounds)", fontsize=9)
    fig.tight_layout()
    fig.savefig(output_dir() / f"{NAME}{suffix}.png")
    plt.close(fig)
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The bounds, as ratios of this run against the forward render at the same pulse count: each
    reverse-mode gradient at most 4x its seconds; the geometric one at most 3x its peak memory."""
    out = []
    for gradient in (r for r in rows if r["kind"] in ("gradient", "geometry")):
        what = "materials'" if gradient["kind"] == "gradient" else "geometry's"
        at = f"{gradient['parameters']} parameters, {gradient['pulses']} pulses"
        out.append((f"reverse-mode gradient, {what} ({at}) <= 4x the forward render",
                    bool(gradient["over_forward"] <= 4.0),
                    f"{gradient['seconds']} s = {gradient['over_forward']} x the forward render"))
        if gradient["kind"] == "geometry":
            out.append((f"reverse-mode gradient, geometry's ({at}): peak memory <= 3x the forward render's",
                        bool(gradient["memory_over_forward"] <= 3.0),
                        f"{gradient['peak_mib']} MiB = {gradient['memory_over_forward']} x the forward render's"))
    return out


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--measure":
        print(json.dumps(_measure(sys.argv[2], int(sys.argv[3]))))
    else:
        bench_main(__doc__, run, checks, "64 pulses", "16 pulses (smoke test)")
