"""Benchmark: the same target from 10 km to 800 km slant range images the same.

The traced 1.5 m trihedral (built-in ``trihedral``) seen from each slant range with the same beam
and resolution (half its beam flown twice as fast, ``tests/test_hard_cases.py``'s
``NARROW_FAST``: 800 km takes about 24,000 pulses; no window), focused by the default focuser,
and compared with the 800 km image: IRW in azimuth and range (1 %), the peak sidelobe's
amplitude (within 1e-3 of the peak's), peak phase (2 deg) and position (1/20 cell), the bounds
of ``tests/test_hard_cases.py::test_same_target_from_10_km_to_100_km_is_identical``, which
checks 10 against 100 km in the suite. A float32 path length would be off by up to 12 rad at
800 km (float32 ulp 6.25 cm; docs/design.md section 5). About 30 s for 800 km on one core.

Prints one row per range and writes ``long_range.csv`` (in the output folder,
``_table.output_dir``); exits with code 1 if a range breaks a bound.

Usage: ``python benchmarks/long_range.py [--slants 10e3 100e3 400e3 800e3]`` (m; the last is the
reference)
"""
from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np

import sarmitsuba  # noqa: F401
from _table import write_csv
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.pipeline import simulate

#: Half the trihedral's beam flown twice as fast (tests/test_hard_cases.py).
NARROW_FAST = {"azimuth_beamwidth": 0.6, "velocity": 200.0}
SLANTS = (10e3, 100e3, 800e3)


def render(slant: float) -> tuple[object, int, float]:
    """The point-target report, pulse count and seconds of the trihedral at ``slant`` [m]."""
    start = time.perf_counter()
    sim = simulate("trihedral", sensor_overrides={"altitude": slant * math.cos(math.pi / 4), **NARROW_FAST},
                   window="rect")
    assert np.all(np.isfinite(sim.image.data)), f"non-finite image at {slant:g} m"
    return analyze_point_target(sim.image, np.zeros(3)), sim.raw.n_pulses, time.perf_counter() - start


def compare(r, ref) -> dict:
    """The differences the bounds apply to, and whether all are met."""
    amplitude = max(abs(10 ** (a / 20) - 10 ** (b / 20))
                    for a, b in ((r.pslr_azimuth_db, ref.pslr_azimuth_db), (r.pslr_range_db, ref.pslr_range_db)))
    row = {"irw_azimuth_err_pct": 100 * (r.irw_azimuth / ref.irw_azimuth - 1),
           "irw_range_err_pct": 100 * (r.irw_range / ref.irw_range - 1),
           "pslr_amplitude_err": amplitude,
           "phase_err_deg": (r.peak_phase_deg - ref.peak_phase_deg + 180) % 360 - 180,
           "azimuth_error_cells": r.azimuth_error_cells, "range_error_cells": r.range_error_cells}
    row["meets"] = bool(abs(row["irw_azimuth_err_pct"]) < 1 and abs(row["irw_range_err_pct"]) < 1
                        and amplitude < 1e-3 and abs(row["phase_err_deg"]) < 2.0
                        and abs(r.azimuth_error_cells) < 0.05 and abs(r.range_error_cells) < 0.05)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--slants", nargs="+", type=float, default=list(SLANTS))
    args = parser.parse_args()
    reports = [(slant, *render(slant)) for slant in args.slants]
    ref = reports[-1][1]
    rows = []
    for slant, report, pulses, seconds in reports:
        row = {"slant_m": slant, "pulses": pulses, "seconds": round(seconds, 2), **compare(report, ref)}
        rows.append(row)
        print("  ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()), flush=True)
    write_csv("long_range.csv", rows)
    sys.exit(0 if all(r["meets"] for r in rows) else 1)


if __name__ == "__main__":
    main()
