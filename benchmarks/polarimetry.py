"""Benchmark: what quad-pol costs against single-channel renders, and what the Jones model costs
against the scalar one (issue 15).

``polarization = quad`` traces once and carries a Jones matrix per path, so that one trace gives
all four channels (docs/physics.md (P1)-(P8)); each channel is then binned and focused on its own.
Single channels carry the Jones matrix too, by default; ``VV scalar`` is the same render with the
``sbr`` parameter ``polarimetry = scalar`` (scalar coefficients, no Jones algebra).
For the built-in ``urban`` scene and Sionna's Munich (128 pulses, as in ``bounce_depth``;
``--quick``: urban only, 128 pulses) it measures in one run, each polarization ``VV``, ``HH``,
``HV`` and ``quad`` after a warm-up run of the same setting (kernel compilation not counted),
the fastest of two runs (``--tiny``: one):

* load, trace and bin + focus seconds (``Simulation.timings``) and their sum, ``total_s``;
* closest-hit and shadow casts, and whether they equal those of ``VV`` (one trace for four channels);
* the cost ratios against ``VV``: total and trace seconds, and ``quad`` total over four ``VV``
  totals (``quad_over_4_vv``: "well under 4 single-channel renders" means well under 1);
* consistency: ``NRMSE = 10 log10(sum |a - b|^2 / sum |b|^2)`` [dB] between ``quad``'s ``HH``
  (``VV``) image and the single-channel ``HH`` (``VV``) image (the same model: float rounding
  only); and the error of the scalar model, ``VV scalar`` against the Jones ``VV``, which is
  exact only where every facet of a path contains H (docs/physics.md (P6)).

A finished simulation is dropped at once: a live Mitsuba scene slows every later trace.
Writes ``polarimetry.csv`` (in the output folder, ``_table.output_dir``) and ``polarimetry.png``
(seconds per channel image against render seconds, one line per scene).

Usage: ``python benchmarks/polarimetry.py [--quick] [--tiny]``
"""
from __future__ import annotations

import gc
import importlib.util

import numpy as np

import sarmitsuba  # noqa: F401
from _plot import plot_cost
from _table import bench_main, machine, write_csv
from sarmitsuba.pipeline import simulate

NAME = "polarimetry"
#: Settings measured, the reference (``VV``) first: name -> (sensor polarization, sbr polarimetry).
POLARIZATIONS = {"VV": ("VV", "jones"), "VV scalar": ("VV", "scalar"), "HH": ("HH", "jones"),
                 "HV": ("HV", "jones"), "quad": ("quad", "jones")}
#: Scene -> sensor overrides (Munich: 128 pulses, as in ``bounce_depth``).
SCENES = {"urban": {}, "sionna:munich": {"n_pulses": 128}}
#: Measured runs per setting (after the warm-up); the fastest counts (other work shares the CPU).
REPEATS = 2
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the speed figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3


def nrmse_db(image: np.ndarray, reference: np.ndarray) -> float:
    """``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB] (-inf when identical)."""
    error = float(np.sum(np.abs(image - reference) ** 2))
    return 10.0 * np.log10(error / float(np.sum(np.abs(reference) ** 2))) if error > 0 else float("-inf")


def _run(scene: str, sensor: dict, setting: str, repeats: int = REPEATS) -> tuple[dict, dict]:
    """The fastest of ``repeats`` simulations after a warm-up: its numbers and its co-polarised
    images (each simulation is dropped as soon as it is measured)."""
    polarization, model = POLARIZATIONS[setting]
    overrides, integrator = {**sensor, "polarization": polarization}, {"max_depth": MAX_DEPTH, "polarimetry": model}
    simulate(scene, sensor_overrides=overrides, integrator_overrides=integrator)
    gc.collect()
    best = None
    for _ in range(repeats):
        sim = simulate(scene, sensor_overrides=overrides, integrator_overrides=integrator)
        numbers, images = _measured(sim, polarization)
        del sim
        gc.collect()
        if best is None or numbers["total_s"] < best[0]["total_s"]:
            best = numbers, images
    return best


def _measured(sim, polarization: str) -> tuple[dict, dict]:
    """Seconds, casts and the co-polarised images of one simulation."""
    t = sim.timings
    numbers = {"pulses": sim.raw.n_pulses, "load_s": round(t["load"], 3), "trace_s": round(t["trace"], 3),
               "bin_focus_s": round(t["bin"] + t["focus"], 3),
               "total_s": round(t["load"] + t["trace"] + t["bin"] + t["focus"], 3),
               "closest_hit_casts": int(sim.trace.rays_per_order.sum()), "shadow_casts": int(sim.trace.shadow_rays)}
    images = ({name: sim.channels[name].image.data for name in ("HH", "VV")} if sim.channels
              else {sim.loaded.params.polarization: sim.image.data})
    return numbers, images


def polarimetry(scene: str, sensor: dict, repeats: int = REPEATS) -> list[dict]:
    """Rows of one scene: each of :data:`POLARIZATIONS`, with their ratios to ``VV``."""
    rows, single = [], {}
    for polarization in POLARIZATIONS:
        numbers, images = _run(scene, sensor, polarization, repeats)
        row = {"scene": scene, "polarization": polarization, **numbers}
        if polarization == "quad":
            row["nrmse_hh_db"] = round(nrmse_db(images["HH"], single["HH"]), 1)
            row["nrmse_vv_db"] = round(nrmse_db(images["VV"], single["VV"]), 1)
        elif polarization == "VV scalar":
            row["nrmse_vv_db"] = round(nrmse_db(images["VV"], single["VV"]), 1)
        else:
            single.update((k, v) for k, v in images.items() if k in ("HH", "VV"))
        rows.append(row)
        del images
    vv = rows[0]
    for row in rows:
        quad = row["polarization"] == "quad"
        row.update({
            "casts_as_vv": (row["closest_hit_casts"], row["shadow_casts"]) == (vv["closest_hit_casts"],
                                                                                vv["shadow_casts"]),
            "total_over_vv": round(row["total_s"] / vv["total_s"], 3),
            "trace_over_vv": round(row["trace_s"] / vv["trace_s"], 3),
            "quad_over_4_vv": round(row["total_s"] / (4 * vv["total_s"]), 3) if quad else "",
            "nrmse_hh_db": row.pop("nrmse_hh_db", ""), "nrmse_vv_db": row.pop("nrmse_vv_db", "")})
    return rows


def print_table(rows: list[dict]) -> None:
    """The rows as an aligned text table, one line per scene and polarization."""
    keys = list(rows[0])
    cells = [keys] + [[str(r[k]) for k in keys] for r in rows]
    widths = [max(len(line[i]) for line in cells) for i in range(len(keys))]
    for line in cells:
        print("  ".join(c.rjust(w) for c, w in zip(line, widths)))


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Ratios measured in one run: quad casts exactly the rays of VV (one trace for four channels)
    and costs less than four single-channel renders."""
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = {r["polarization"]: r for r in rows if r["scene"] == scene}
        quad, vv = mine["quad"], mine["VV"]
        out.append((f"{scene}: quad casts exactly the rays of VV", bool(quad["casts_as_vv"]),
                    f"{quad['closest_hit_casts']} + {quad['shadow_casts']} against "
                    f"{vv['closest_hit_casts']} + {vv['shadow_casts']}"))
        out.append((f"{scene}: quad costs less than 4 VV renders", bool(quad["quad_over_4_vv"] < 1.0),
                    f"quad / (4 VV) = {quad['quad_over_4_vv']}, quad / VV = {quad['total_over_vv']}"))
    return out


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Run the comparison, print the table, write CSV and PNG; returns the rows."""
    print(machine())
    scenes = dict(SCENES)
    if quick or tiny or importlib.util.find_spec("sionna") is None:
        scenes = {"urban": {"n_pulses": 32 if tiny else 128} if quick or tiny else {}}
    rows = []
    for scene, sensor in scenes.items():
        rows += polarimetry(scene, sensor, 1 if tiny else REPEATS)
    print_table(rows)
    suffix = "_tiny" if tiny else ""
    write_csv(f"{NAME}{suffix}.csv", rows)
    plot_cost(f"{NAME}{suffix}.png", {
        scene: [(r["total_s"], r["total_s"] / (4 if r["polarization"] == "quad" else 1), r["polarization"])
                for r in rows if r["scene"] == scene] for scene in scenes},
        xlabel="render time [s]", ylabel="seconds per channel image",
        title="polarization: seconds per channel image against render time")
    return rows


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "urban only, 128 pulses", "urban, 32 pulses (smoke test)")
