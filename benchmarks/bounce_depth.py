"""Benchmark: what bounce depth costs and what it changes (accuracy against time), and what
``max_depth = auto`` chooses.

For ``max_depth`` 1..8 and ``auto`` on the built-in urban scene, Sionna's Munich (512 central
pulses) and a street canyon that needs four bounces (``tests/scenes/street_canyon.xml``),
measured in one run, each setting after an untimed warm-up of the same run (kernel compilation
not counted), the fastest of 3 timed runs where a run takes under 10 s: the simulation's seconds (load, for ``auto`` the probe, trace, bin, focus) and the
trace's alone, closest-hit casts, each order's share
of the raw data's energy (docs/physics.md (D6)), and the image difference from depth 8,
``NRMSE = ||I_d - I_8|| / ||I_8||`` in dB. For ``auto`` also the depth and why, and what ``info``
predicted: the depth, and each order's seconds against the render's.

Floor: two images of identical paths differ by about -30 dB NRMSE when only the fast-time
window length changes (backprojection interpolates each range line by 8x FFT upsampling
plus linear interpolation), so differences below about -30 dB are not physics.

Writes ``bounce_depth.csv`` (in the output folder, ``_table.output_dir``) and ``bounce_depth.png``
(NRMSE against seconds, one point per depth and a star for ``auto``, one line per scene).

Usage: ``python benchmarks/bounce_depth.py [--quick] [--cap 8] [--scenes urban sionna:munich ...]``
"""
from __future__ import annotations

import argparse
import gc
import importlib.util
import math
import time
from pathlib import Path

import numpy as np

import sarmitsuba  # noqa: F401
from _plot import plot_cost
from _table import machine, write_csv
from sarmitsuba.info import scene_info
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.driver.depth import depth_summary

CANYON = str(Path(__file__).resolve().parents[1] / "tests" / "scenes" / "street_canyon.xml")
#: Scene -> sensor overrides (Munich: its 512 central pulses of about 2,300).
SCENES = {"urban": {}, "sionna:munich": {"n_pulses": 512}, CANYON: {}}
#: The tolerance ``auto`` is held to: its own default (docs/physics.md (DEP2)).
TOLERANCE_DB = -20.0
#: ``auto``'s time may be at most this many times the smallest fixed depth within the tolerance.
AUTO_TIME_RATIO = 1.25
#: ``info``'s predicted seconds per order, within this factor of the render's.
PREDICTION_FACTOR = 2.0


def _name(scene: str) -> str:
    return Path(scene).stem if scene.endswith(".xml") else scene


#: Timed runs of a setting whose warm-up took under :data:`SHORT_S` seconds: the fastest counts
#: (a render of a second scatters by a fifth from run to run); longer ones run once.
REPEATS, SHORT_S = 3, 10.0


def _warm(scene: str, sensor: dict, overrides: dict) -> float:
    """Run the setting once, untimed: its kernels compile for its own fast-time window and launch
    sizes (a run on fewer pulses has another window, and compiles again). Returns its seconds."""
    start = time.perf_counter()
    simulate(scene, sensor_overrides=sensor, integrator_overrides=overrides)
    gc.collect()
    return time.perf_counter() - start


def _timed(scene: str, sensor: dict, overrides: dict, repeats: int):
    """The fastest of ``repeats`` runs (by the simulation's seconds)."""
    best = None
    for _ in range(repeats):
        sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=overrides)
        if best is None or sum(sim.timings.values()) < sum(best.timings.values()):
            best = sim
        gc.collect()
    return best


def bounce_depth(scene: str, depths: list[int], sensor: dict | None = None) -> list[dict]:
    """One row per fixed depth and one for ``auto``: seconds, casts, shares, NRMSE against the
    deepest fixed depth; ``auto``'s row adds its choice and ``info``'s prediction.

    Only the numbers and the image of each run are kept: a live Mitsuba scene slows the
    tracing (host side) of every later scene, so a finished simulation is dropped at once.
    """
    sensor = sensor or {}
    cap = depths[-1]
    rows, images = [], {}
    for setting in [*depths, "auto"]:
        overrides = {"max_depth": setting} if setting != "auto" else {"depth_cap": cap}
        warm = _warm(scene, sensor, overrides)
        sim = _timed(scene, sensor, overrides, REPEATS if warm < SHORT_S else 1)
        raw = sim.trace.raw_energy_per_order
        probe = sim.timings.get("depth_probe", 0.0)
        images[setting] = sim.image.data
        row = {"scene": _name(scene), "setting": str(setting), "depth": len(sim.trace.energy_per_order),
               "probe_s": round(probe, 3), "trace_s": round(sim.timings["trace"], 3),
               "time_s": round(sum(sim.timings.values()), 3),
               "closest_hit_casts": int(sim.trace.rays_per_order.sum()),
               "raw_share_per_order": " ".join(f"{e:.3g}" for e in raw / max(raw.sum(), 1e-300)),
               "raw_energy_deepest_order_share": round(float(raw[-1] / max(raw.sum(), 1e-300)), 6),
               **dict.fromkeys(("reason", "beyond_db", "probe_share_per_order", "info_depth",
                                "predicted_over_traced_s", "worst_prediction_factor"), "")}
        if setting == "auto":
            choice = depth_summary(sim.depth, sim.trace)
            info = scene_info(scene, sensor_overrides=sensor, integrator_overrides=overrides).depth
            traced = choice["seconds_by_order"]
            ratios = [max(info["probe"]["predicted_seconds"][k], 1e-9) / max(traced[k], 1e-9) for k in traced]
            row.update(reason=choice["reason"], beyond_db=choice["beyond_db"],
                       probe_share_per_order=" ".join(f"{s:.3g}" for s in choice["probe"]["share"].values()),
                       info_depth=info["depth"],
                       predicted_over_traced_s=" ".join(f"{r:.2f}" for r in ratios),
                       worst_prediction_factor=round(max(max(r, 1 / r) for r in ratios), 2))
        rows.append(row)
        del sim
        gc.collect()
    ref = images[cap]
    for row in rows:
        key = "auto" if row["setting"] == "auto" else int(row["setting"])
        diff = np.linalg.norm(images[key] - ref) / max(np.linalg.norm(ref), 1e-30)
        row["nrmse_vs_cap_db"] = round(float(20 * np.log10(diff)), 1) if diff > 0 else float("-inf")
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The ratios the issue's acceptance names, per scene: ``auto`` within the tolerance of the
    deepest image, at most :data:`AUTO_TIME_RATIO` times the smallest fixed depth that is; ``info``
    predicting its depth, and its seconds per order within :data:`PREDICTION_FACTOR`; and the sweep's
    own: casts grow with depth, depth 1 differs most."""
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = [r for r in rows if r["scene"] == scene]
        fixed = [r for r in mine if r["setting"] != "auto"]
        auto = next(r for r in mine if r["setting"] == "auto")
        casts = [r["closest_hit_casts"] for r in fixed]
        out.append((f"{scene}: closest-hit casts non-decreasing with depth", all(np.diff(casts) >= 0), str(casts)))
        err = [r["nrmse_vs_cap_db"] for r in fixed[:-1]]
        out.append((f"{scene}: depth 1 differs most from the deepest image", err[0] == max(err), str(err)))
        out.append((f"{scene}: auto within {TOLERANCE_DB:g} dB of depth {fixed[-1]['depth']}",
                     auto["nrmse_vs_cap_db"] <= TOLERANCE_DB,
                     f"depth {auto['depth']} ({auto['reason']}), NRMSE {auto['nrmse_vs_cap_db']} dB"))
        enough = [r for r in fixed if r["nrmse_vs_cap_db"] <= TOLERANCE_DB]
        if enough:
            ratio = auto["time_s"] / max(enough[0]["time_s"], 1e-9)
            out.append((f"{scene}: auto's time at most {AUTO_TIME_RATIO}x the smallest depth within the tolerance",
                        ratio <= AUTO_TIME_RATIO, f"{auto['time_s']:.2f} s (probe {auto['probe_s']:.2f} s) / "
                        f"{enough[0]['time_s']:.2f} s at depth {enough[0]['depth']} = {ratio:.2f}"))
        out.append((f"{scene}: info predicts the render's depth", auto["info_depth"] == auto["depth"],
                    f"info {auto['info_depth']}, render {auto['depth']}"))
        out.append((f"{scene}: info's seconds per order within {PREDICTION_FACTOR:g}x of the render's",
                    auto["worst_prediction_factor"] <= PREDICTION_FACTOR,
                    f"predicted / traced per order: {auto['predicted_over_traced_s']}"))
    return out


def run(quick: bool = False, cap: int = 8, scenes: list[str] | None = None) -> list[dict]:
    """Run the sweep, print the table, write CSV and PNG; returns the rows."""
    print(machine())
    if scenes is None:
        scenes = ["urban", CANYON] if quick or importlib.util.find_spec("sionna") is None else list(SCENES)
    depths = list(range(1, (5 if quick else cap) + 1))
    rows = []
    for scene in scenes:
        sensor = {"n_pulses": 128} if quick else SCENES.get(scene, {})
        rows += bounce_depth(scene, depths, sensor)
    for row in rows:
        print("  ".join(f"{k}={v}" for k, v in row.items()))
    write_csv("bounce_depth.csv", rows)
    series = {}
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = [r for r in rows if r["scene"] == scene and math.isfinite(r["nrmse_vs_cap_db"])]
        series[scene] = [(r["time_s"], r["nrmse_vs_cap_db"], f"{r['depth']}") for r in mine if r["setting"] != "auto"]
        series[f"{scene}: auto"] = [(r["time_s"], r["nrmse_vs_cap_db"], f"auto {r['depth']}") for r in mine
                                    if r["setting"] == "auto"]
    plot_cost("bounce_depth.png", series, xlabel="simulation time (load, probe, trace, focus) [s]",
              ylabel=f"image NRMSE vs depth {depths[-1]} [dB]",
              title=f"bounce depth: image change against time (depths 1-{depths[-1]}, auto)")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="depths 1..5 and auto, 128 pulses, urban and the canyon")
    parser.add_argument("--cap", type=int, default=8, help="the deepest fixed depth, and auto's depth_cap")
    parser.add_argument("--scenes", nargs="+", default=None,
                        help="default: urban, sionna:munich (512 pulses) and the street canyon")
    args = parser.parse_args()
    rows = run(args.quick, args.cap, args.scenes)
    for name, ok, detail in checks(rows):
        print(f"{'PASS' if ok else 'FAIL'}  {name}  {detail}")


if __name__ == "__main__":
    main()
