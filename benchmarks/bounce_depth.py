"""Benchmark: what bounce depth costs and what it changes (accuracy against time).

For ``max_depth`` 1..N on the built-in urban scene and on a Sionna RT city (Munich, fewer
pulses so that the sweep stays minutes long), measured in one run, each setting after a warm-up run
(kernel compilation not counted): trace and focus seconds, closest-hit and shadow casts, the energy
captured per bounce order (the terms' incoherent sum, and the deepest order's share of the raw
data's, docs/physics.md (D6)), and the image difference from the deepest setting,
``NRMSE = ||I_d - I_N|| / ||I_N||`` in dB.

Floor: two images of identical paths differ by about -30 dB NRMSE when only the fast-time
window length changes (backprojection interpolates each range line by 8x FFT upsampling
plus linear interpolation), so differences below about -30 dB are not physics.

Writes ``bounce_depth.csv`` (in the output folder, ``_table.output_dir``) and ``bounce_depth.png`` (NRMSE against trace
seconds, one point per depth, one line per scene).

Usage: ``python benchmarks/bounce_depth.py [--quick] [--max-depth 6] [--scenes urban sionna:munich]``
"""
from __future__ import annotations

import argparse
import gc
import importlib.util

import numpy as np

import sarmitsuba  # noqa: F401
from _plot import plot_cost
from _table import machine, write_csv
from sarmitsuba.pipeline import simulate

#: Scene -> sensor overrides that keep the sweep affordable (Munich: 128 pulses instead of ~1000).
SCENES = {"urban": {}, "sionna:munich": {"n_pulses": 128}}


def bounce_depth(scene: str, depths: list[int], sensor: dict | None = None) -> list[dict]:
    """One row per depth: seconds, casts, energy per order, NRMSE against the deepest image.

    Only the numbers and the image of each run are kept: a live Mitsuba scene slows the
    tracing (host side) of every later scene, so a finished simulation is dropped at once.
    """
    sensor = sensor or {}
    rows, images = [], {}
    for d in depths:            # every depth compiles its own kernel: the first run is the warm-up
        simulate(scene, sensor_overrides=sensor, integrator_overrides={"max_depth": d})
        gc.collect()
        sim = simulate(scene, sensor_overrides=sensor, integrator_overrides={"max_depth": d})
        energy = sim.trace.energy_per_order
        images[d] = sim.image.data
        rows.append({
            "scene": scene, "max_depth": d, "trace_s": round(sim.timings["trace"], 3),
            "focus_s": round(sim.timings["focus"], 3),
            "closest_hit_casts": int(sim.trace.rays_per_order.sum()), "shadow_casts": int(sim.trace.shadow_rays),
            "energy_per_order": " ".join(f"{e:.4g}" for e in energy),
            "energy_deepest_order_fraction": round(float(energy[-1] / max(energy.sum(), 1e-300)), 6),
            # the deepest order's share of the orders' raw-data energy (docs/physics.md (D6)), which
            # summary.json's depth_warning reads
            "raw_energy_deepest_order_share": round(float(sim.trace.raw_energy_per_order[-1]
                                                          / max(sim.trace.raw_energy_per_order.sum(), 1e-300)), 6),
        })
        del sim
        gc.collect()
    ref = images[depths[-1]]
    for row in rows:
        diff = np.linalg.norm(images[row["max_depth"]] - ref) / max(np.linalg.norm(ref), 1e-30)
        row["nrmse_vs_deepest_db"] = round(float(20 * np.log10(diff)), 1) if diff > 0 else float("-inf")
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Ratios the suite asserts on: casts grow with depth, the image converges with depth."""
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = [r for r in rows if r["scene"] == scene]
        casts = [r["closest_hit_casts"] for r in mine]
        out.append((f"{scene}: closest-hit casts non-decreasing with depth", all(np.diff(casts) >= 0), str(casts)))
        err = [r["nrmse_vs_deepest_db"] for r in mine[:-1]]
        out.append((f"{scene}: depth 1 differs most from the deepest image", err[0] == max(err), str(err)))
    return out


def run(quick: bool = False, max_depth: int = 6, scenes: list[str] | None = None) -> list[dict]:
    """Run the sweep, print the table, write CSV and PNG; returns the rows."""
    print(machine())
    if scenes is None:
        scenes = ["urban"] if quick or importlib.util.find_spec("sionna") is None else list(SCENES)
    depths = list(range(1, (3 if quick else max_depth) + 1))
    rows = []
    for scene in scenes:
        sensor = {"n_pulses": 128} if quick else SCENES.get(scene, {})
        rows += bounce_depth(scene, depths, sensor)
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    write_csv("bounce_depth.csv", rows)
    plot_cost("bounce_depth.png", {
        scene: [(r["trace_s"], r["nrmse_vs_deepest_db"], f"depth {r['max_depth']}") for r in rows
                if r["scene"] == scene and np.isfinite(r["nrmse_vs_deepest_db"])] for scene in scenes},
        xlabel="trace time [s]", ylabel="image NRMSE vs deepest [dB]",
        title=f"bounce depth: image change against trace time (deepest = {depths[-1]})")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="depths 1..3, 128 pulses, urban only")
    parser.add_argument("--max-depth", type=int, default=6)
    parser.add_argument("--scenes", nargs="+", default=None, help="default: urban and sionna:munich")
    args = parser.parse_args()
    rows = run(args.quick, args.max_depth, args.scenes)
    for name, ok, detail in checks(rows):
        print(f"{'PASS' if ok else 'FAIL'}  {name}  {detail}")


if __name__ == "__main__":
    main()
