"""Benchmark: what tracing once per sub-aperture costs in accuracy and saves in time (issue 12).

``pulses_per_trace = N`` traces each run of ``N`` consecutive pulses once, from the middle of its
track, and evaluates every pulse's return from the recorded hits (docs/physics.md (T3)); ``N = 1``
traces every pulse on its own: the reference. For the built-in ``urban`` scene and Sionna's
Munich (as shipped, smooth; ``--quick``: urban only) it measures in one run, each setting after
a warm-up:

* trace seconds, closest-hit and shadow casts, returns evaluated (``pulse_paths``);
* the image NRMSE against ``N = 1``, ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB], all images
  focused alike (fast factorised backprojection);
* two references for that NRMSE: ``N = 1`` with the ray lattice moved by (0.37, 0.41) of a cell
  (what the tube lattice itself leaves undetermined: staircase edges of facets oblique to it),
  and ``N = 1`` evaluating every PO term (``cancel_interior = false``, docs/physics.md (PO5)).

The automatic sub-aperture (``N = 0``, 16 azimuth resolution cells of travel) is one of the
points. Writes ``subaperture.csv`` (in the output folder, ``_table.output_dir``) and ``subaperture.png`` (NRMSE against trace
seconds, one line per scene).

Usage: ``python benchmarks/subaperture.py [--quick] [--tiny]``
"""
from __future__ import annotations

import gc
import importlib.util

import numpy as np
from _lattice import moved_lattice, nrmse_db
from _plot import report_per_scene
from _table import bench_main, machine

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate

NAME = "subaperture"
#: Pulses per trace swept (0 = automatic).
SWEEP = (2, 4, 8, 0, 32, 64)
#: Scene -> sensor overrides (Munich: the 512 central pulses, a full synthetic aperture for the
#: scene's middle, so that the sweep stays minutes long).
SCENES = {"urban": {}, "sionna:munich": {"n_pulses": 512}}
#: Lattice offset of the lattice-noise reference, in cells (along track, ground range).
LATTICE_SHIFT = (0.37, 0.41)
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the speed figures stay comparable (``bounce_depth`` measures ``auto``).
MAX_DEPTH = 3


def _run(scene: str, sensor: dict, integrator: dict, shift=None, warm_up: bool = True) -> tuple[dict, np.ndarray]:
    """One simulation after a warm-up (``warm_up`` false: none, the smoke test's untimed run): its
    numbers and image (the simulation itself is dropped); ``max_depth`` :data:`MAX_DEPTH`."""
    integrator = {"max_depth": MAX_DEPTH, **integrator}
    with moved_lattice(shift):
        if warm_up:
            simulate(scene, sensor_overrides=sensor, integrator_overrides=integrator)
            gc.collect()
        sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=integrator)
    numbers = {"trace_s": round(sim.timings["trace"], 3), "pulses_per_trace": sim.trace.pulses_per_trace,
               "closest_hit_casts": int(sim.trace.rays_per_order.sum()), "shadow_casts": int(sim.trace.shadow_rays),
               "pulse_paths": sim.trace.pulse_paths, "pulses": sim.raw.n_pulses}
    image = sim.image.data
    del sim
    gc.collect()
    return numbers, image


def sweep(scene: str, sensor: dict, sweep: tuple, warm_up: bool = True) -> list[dict]:
    """Rows of one scene: the reference, the two NRMSE references and every ``N`` of ``sweep``
    (each after a warm-up unless ``warm_up`` is false)."""
    reference, image = _run(scene, sensor, {"pulses_per_trace": 1}, warm_up=warm_up)
    rows = [{"scene": scene, "setting": "N=1 (reference)", **reference, "nrmse_db": float("-inf")}]
    for setting, integrator, shift in (("N=1, lattice moved", {"pulses_per_trace": 1}, LATTICE_SHIFT),
                                       ("N=1, every PO term", {"pulses_per_trace": 1, "cancel_interior": False}, None)):
        numbers, other = _run(scene, sensor, integrator, shift, warm_up)
        rows.append({"scene": scene, "setting": setting, **numbers, "nrmse_db": round(nrmse_db(other, image), 1)})
    for n in sweep:
        numbers, other = _run(scene, sensor, {"pulses_per_trace": n}, warm_up=warm_up)
        label = f"N={numbers['pulses_per_trace']}" + (" (automatic)" if n == 0 else "")
        rows.append({"scene": scene, "setting": label, **numbers, "nrmse_db": round(nrmse_db(other, image), 1)})
    for row in rows:
        row["trace_ratio"] = round(row["trace_s"] / rows[0]["trace_s"], 3)
    return rows


#: A lattice move below this [dB] changes nothing but rounding (the mesh tracer's images
#: measured -134 dB apart on urban).
LATTICE_FREE_DB = -100.0
#: The automatic sub-aperture's image NRMSE against per-pulse tracing [dB]: -30 dB for every
#: scene (the invariance table's target), -50 dB on urban (measured -57.1 dB, README "Pulses per
#: trace").
AUTO_BOUND_DB = {"urban": -50.0}


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Ratios measured in one run: casts fall as 1 / N, the automatic sub-aperture is faster than
    per-pulse tracing, its error against per-pulse tracing is below :data:`AUTO_BOUND_DB`, and the image does not move
    with the ray lattice (:data:`LATTICE_FREE_DB`)."""
    out = []
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = {r["setting"].split(" (")[0] if "automatic" not in r["setting"] else "auto": r for r in rows
                if r["scene"] == scene}
        ref, auto, lattice = mine["N=1"], mine["auto"], mine["N=1, lattice moved"]
        n = auto["pulses_per_trace"]
        ratio = ref["closest_hit_casts"] / max(auto["closest_hit_casts"], 1)
        out.append((f"{scene}: automatic N = {n} casts at most 1.5 / N of per-pulse tracing", bool(ratio >= n / 1.5),
                    f"casts ratio {ratio:.1f}"))
        out.append((f"{scene}: automatic sub-aperture traces at least 3x faster", bool(auto["trace_ratio"] <= 1 / 3),
                    f"trace time ratio {auto['trace_ratio']}"))
        # the default mesh tracer: the ray lattice only seeds discovery, and moving it changes
        # nothing beyond rounding, so it is no yardstick for the sub-apertures' error (it was for
        # the ray tubes, whose staircase edges move with it); per-pulse tracing is
        out.append((f"{scene}: the ray lattice moved changes the image below {LATTICE_FREE_DB:g} dB (mesh tracer)",
                    bool(lattice["nrmse_db"] <= LATTICE_FREE_DB), f"{lattice['nrmse_db']} dB"))
        bound = AUTO_BOUND_DB.get(scene, -30.0)
        out.append((f"{scene}: automatic sub-aperture image NRMSE <= {bound:g} dB against per-pulse tracing",
                    bool(auto["nrmse_db"] <= bound), f"{auto['nrmse_db']} dB"))
    return out


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Run the sweep, print the table, write CSV and PNG; returns the rows."""
    print(machine())
    scenes = dict(SCENES)
    if quick or tiny or importlib.util.find_spec("sionna") is None:
        scenes = {"urban": {"n_pulses": 32} if tiny else {}}
    rows = []
    for scene, sensor in scenes.items():
        # --tiny, a smoke test: the automatic N only, no warm-ups (its seconds are not what it checks)
        rows += sweep(scene, sensor, (0,) if tiny else SWEEP, warm_up=not tiny)
    report_per_scene(f"{NAME}{'_tiny' if tiny else ''}", rows, scenes, "nrmse_db", ylabel="image NRMSE vs N = 1 [dB]",
                     title="pulses per trace: image change against trace time (* automatic)",
                     label=lambda setting: setting.replace(" (automatic)", "*"))
    return rows


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "urban only", "urban, 32 pulses, the automatic N only, no warm-up (smoke test)")
