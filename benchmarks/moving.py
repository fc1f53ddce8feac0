"""Benchmark: what moving shapes cost, and what the sub-apertures' rates leave (docs/physics.md (V1)-(V3)).

On ``traffic`` (urban with three metal cars at 2, 15 and 3.4 m/s), in one run, each setting
after a warm-up:

* one pulse per trace (every pulse's geometry traced where the wave meets the cars): the
  reference;
* the automatic sub-aperture with the lanes' rates from the lit geometry differenced (V2), the
  default (a car travels at most ``MOVING_TRAVEL`` = 0.5 m within one), and with that limit at
  2 m and lifted (the 16 azimuth cells of still scenes alone);
* the automatic sub-aperture with the rigid rates alone (V3): the cars' own faces move, the
  boundaries they draw on the still road (their shadows, their double bounces' footprints) do not;
* the automatic sub-aperture with the cars standing still at their mid-aperture places (the
  moving-target signature the rates carry);

and the still ``urban`` scene (the same scene without the cars' velocities, and without the cars),
for what a scene pays for motion. Columns: trace seconds, the trace time over urban's, the image
NRMSE against the reference ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB], and the launches that
fell back from (V2) to (V3). Writes ``moving.csv`` and ``moving.png``.

Usage: ``python benchmarks/moving.py [--quick]`` (``--quick``: 260 of the 779 pulses).
"""
from __future__ import annotations

import gc

import numpy as np
from _lattice import nrmse_db, trace_numbers
from _plot import report_per_scene
from _table import bench_main, machine

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.driver import moving

NAME = "moving"
#: The cars' ids in scenes/traffic.xml.
CARS = ("car_a", "car_b", "car_c")


def _still_traffic(path) -> str:
    """traffic.xml as one file: the urban scene it includes (mesh paths made absolute) and its
    cars without their velocities."""
    import xml.etree.ElementTree as ET
    folder = path.parent
    urban = ET.fromstring((folder / "urban.xml").read_text().replace('value="meshes/', f'value="{folder}/meshes/'))
    for element in ET.fromstring(path.read_text()):
        if element.tag in ("bsdf", "shape"):
            for velocity in element.findall("vector[@name='velocity']"):
                element.remove(velocity)
            urban.append(element)
    return ET.tostring(urban, encoding="unicode")


def _run(scene: str, sensor: dict, integrator: dict, differenced: bool = True,
         travel: float | None = None) -> tuple[dict, np.ndarray]:
    """One simulation after a warm-up (with ``moving.DIFFERENCED`` and ``moving.MOVING_TRAVEL``
    set as given): its numbers and image."""
    saved = moving.DIFFERENCED, moving.MOVING_TRAVEL
    moving.DIFFERENCED = differenced
    moving.MOVING_TRAVEL = saved[1] if travel is None else travel
    try:
        simulate(scene, sensor_overrides=sensor, integrator_overrides=integrator)
        gc.collect()
        sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=integrator)
    finally:
        moving.DIFFERENCED, moving.MOVING_TRAVEL = saved
    return trace_numbers(sim)


def run(quick: bool = False) -> list[dict]:
    """Run the settings, print the table, write CSV and PNG; returns the rows."""
    import tempfile
    from pathlib import Path

    from sarmitsuba.scene.loader import builtin_scenes
    print(machine())
    sensor = {"n_pulses": 260} if quick else {}
    traffic = builtin_scenes()["traffic"]
    with tempfile.TemporaryDirectory() as folder:
        still = Path(folder) / "traffic_still.xml"
        still.write_text(_still_traffic(traffic))
        reference, image = _run(str(traffic), sensor, {"pulses_per_trace": 1})
        rows = [{"scene": "traffic", "setting": "N=1 (reference)", **reference, "nrmse_db": float("-inf")}]
        for setting, scene, differenced, travel in (
                ("automatic, differenced rates (default)", str(traffic), True, None),
                ("automatic, cars travel up to 2 m per trace", str(traffic), True, 2.0),
                ("automatic, no limit on the cars' travel", str(traffic), True, float("inf")),
                ("automatic, rigid rates only", str(traffic), False, None),
                ("automatic, cars standing still", str(still), True, None),
                ("urban, automatic (no cars)", "urban", True, None)):
            numbers, other = _run(scene, sensor, {}, differenced, travel)
            error = round(nrmse_db(other, image), 1) if other.shape == image.shape else float("nan")
            rows.append({"scene": "traffic", "setting": setting, **numbers, "nrmse_db": error})
    urban = rows[-1]["trace_s"]
    for row in rows:
        row["trace_over_urban"] = round(row["trace_s"] / urban, 2)
    report_per_scene(NAME, rows, {"traffic": sensor}, "nrmse_db", ylabel="image NRMSE vs one pulse per trace [dB]",
                     title="moving cars: the sub-apertures' rates against trace time",
                     label=lambda setting: setting.split(",")[-1].strip())
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The default within -30 dB of one pulse per trace and faster than it; a car travelling up to
    2 m per trace also within -30 dB and at least 3x faster; the differenced rates closer to the
    reference than the rigid ones at the same sub-aperture; the moving cars' signature more than
    10 dB above the default's error."""
    by = {r["setting"]: r for r in rows}
    ref, auto = by["N=1 (reference)"], by["automatic, differenced rates (default)"]
    longer = by["automatic, cars travel up to 2 m per trace"]
    rigid, still = by["automatic, rigid rates only"], by["automatic, cars standing still"]
    return [("traffic: automatic sub-aperture image NRMSE <= -30 dB against one pulse per trace",
             bool(auto["nrmse_db"] <= -30.0), f"{auto['nrmse_db']} dB"),
            ("traffic: automatic sub-aperture traces faster than one pulse per trace",
             bool(auto["trace_s"] < ref["trace_s"]), f"{ref['trace_s'] / auto['trace_s']:.1f}x"),
            ("traffic: cars travelling up to 2 m per trace: NRMSE <= -30 dB, at least 3x faster than one pulse "
             "per trace", bool(longer["nrmse_db"] <= -30.0 and longer["trace_s"] * 3 <= ref["trace_s"]),
             f"{longer['nrmse_db']} dB, {ref['trace_s'] / longer['trace_s']:.1f}x"),
            ("traffic: the differenced rates closer to the reference than the rigid ones",
             bool(auto["nrmse_db"] < rigid["nrmse_db"]), f"{auto['nrmse_db']} vs {rigid['nrmse_db']} dB"),
            ("traffic: the moving cars' signature far above the default's error",
             bool(still["nrmse_db"] > auto["nrmse_db"] + 10.0), f"still cars {still['nrmse_db']} dB")]


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "260 of the 779 pulses")
