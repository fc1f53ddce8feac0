"""Benchmark: what a receiver on its own platform costs, and what the sub-apertures leave (docs/physics.md (B1)-(B4)).

On ``urban`` with two receivers, in one run after a warm-up:

* a drone 300 m up, flying north at 15 m/s on the scene's west side (a bistatic angle of 60 deg);
* a second aircraft beside the transmitter, 1000 m up at 100 m/s on a heading 20 deg off its
  track (14 deg);

each traced with one pulse per trace (the reference: every pulse's pieces cut from its own two
positions), with 4 and 8 pulses per trace and with the automatic sub-aperture (the boundaries
that the receiver's shadows draw move with it, (B2), (M8)); and the monostatic ``urban`` the same
way, for the error the sub-apertures leave without a receiver and for what the receiver costs.
Columns: trace seconds, the trace time over monostatic urban's automatic one, the image NRMSE
against the same scene's reference ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB]. Writes
``bistatic.csv`` and ``bistatic.png``.

Usage: ``python benchmarks/bistatic.py [--quick]`` (``--quick``: 260 of the 779 pulses).
"""
from __future__ import annotations

from _lattice import nrmse_db, trace_numbers
from _plot import report_per_scene
from _table import bench_main, machine

import sarmitsuba  # noqa: F401
from sarmitsuba.pipeline import simulate

NAME = "bistatic"
RECEIVERS = {
    "drone": {"receiver_altitude": 300.0, "receiver_heading": 90.0, "receiver_velocity": 15.0},
    "beside": {"receiver_altitude": 1000.0, "receiver_heading": 20.0, "receiver_velocity": 100.0},
    "monostatic": {},
}


def _run(sensor: dict, pulses_per_trace: int):
    """One render of urban (0: the automatic sub-aperture): its numbers and image."""
    integrator = {"pulses_per_trace": pulses_per_trace} if pulses_per_trace else {}
    return trace_numbers(simulate("urban", sensor_overrides=sensor, integrator_overrides=integrator))


def run(quick: bool = False) -> list[dict]:
    """Run the settings, print the table, write CSV and PNG; returns the rows."""
    print(machine())
    pulses = {"n_pulses": 260} if quick else {}
    _run({**pulses, **RECEIVERS["drone"]}, 0)                     # warm-up: the kernels compiled
    rows = []
    for scene, receiver in RECEIVERS.items():
        sensor = {**pulses, **receiver}
        reference, image = _run(sensor, 1)
        rows.append({"scene": scene, "setting": "N=1 (reference)", **reference, "nrmse_db": float("-inf")})
        for setting, n in (("N=4", 4), ("N=8", 8), ("automatic (default)", 0)):
            if scene == "monostatic" and n in (4, 8):
                continue
            numbers, other = _run(sensor, n)
            rows.append({"scene": scene, "setting": setting, **numbers, "nrmse_db": round(nrmse_db(other, image), 1)})
    urban = next(r["trace_s"] for r in rows if r["scene"] == "monostatic" and r["setting"].startswith("automatic"))
    for row in rows:
        row["trace_over_urban"] = round(row["trace_s"] / urban, 2)
    report_per_scene(NAME, rows, RECEIVERS, "nrmse_db", ylabel="image NRMSE vs one pulse per trace [dB]",
                     title="bistatic urban: the sub-apertures against trace time")
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Both receivers' automatic sub-apertures within -30 dB of one pulse per trace and at least 5x
    faster than it; 8 pulses per trace within -35 dB; a bistatic trace at most 4x the monostatic
    one at the automatic sub-aperture."""
    by = {(r["scene"], r["setting"]): r for r in rows}
    out = []
    for scene in ("drone", "beside"):
        ref, auto, eight = (by[(scene, s)] for s in ("N=1 (reference)", "automatic (default)", "N=8"))
        out += [(f"{scene}: automatic sub-aperture image NRMSE <= -30 dB against one pulse per trace, >= 5x faster",
                 bool(auto["nrmse_db"] <= -30.0 and 5 * auto["trace_s"] <= ref["trace_s"]),
                 f"{auto['nrmse_db']} dB, {ref['trace_s'] / auto['trace_s']:.1f}x"),
                (f"{scene}: 8 pulses per trace within -35 dB", bool(eight["nrmse_db"] <= -35.0),
                 f"{eight['nrmse_db']} dB"),
                (f"{scene}: automatic trace at most 4x the monostatic one", bool(auto["trace_over_urban"] <= 4.0),
                 f"{auto['trace_over_urban']}x")]
    return out


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "260 of the 779 pulses")
