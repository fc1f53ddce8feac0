"""Benchmark: canonical-target RCS against closed forms, against ray density and time.

For each canonical target (metal plate, dihedral, trihedral, sphere; a concrete trihedral)
and each ray spacing, it measures the RCS from the focused image by integrated point energy
(docs/physics.md (K)). It reports the error against the closed form, the rays cast per pulse
and the seconds of the whole simulation (warm kernels). Writes ``rcs.csv`` (in the output folder, ``_table.output_dir``).

Usage: ``python benchmarks/rcs.py [--spacings 0.05 0.02 0.01]``
"""
from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path


import sarmitsuba  # noqa: F401
from _table import write_csv
from sarmitsuba.analysis import point_target as analysis
from sarmitsuba.scene import canonical as C
from sarmitsuba.scene import materials
from sarmitsuba.pipeline import simulate

WAVELENGTH = 299_792_458.0 / 9.6e9


def integrated_rcs(sim, half_cells: float = 6.0) -> float:
    """RCS of the target at the scene centre from the focused image (integrated point energy)."""
    return analysis.integrated_rcs(sim.image, half_cells=half_cells)  # energy widths from the metadata


def cases() -> dict:
    concrete = materials.Material("concrete", materials.itu_permittivity("concrete", 9.6e9), "half_space")
    r = abs(complex(materials.reflection_coefficient(concrete, 1 / math.sqrt(3), 9.6e9, "HH")))
    return {
        "plate 0.3 m (PEC)": (C.plate(0.3), C.PEC, 1, "", C.rcs_plate(0.3, WAVELENGTH)),
        "dihedral 0.3 x 0.3 m (PEC)": (C.dihedral(0.3, 0.3), C.PEC, 2, "", C.rcs_dihedral(0.3, 0.3, WAVELENGTH)),
        "trihedral 0.5 m (PEC)": (C.trihedral(0.5), C.PEC, 3, "", C.rcs_trihedral(0.5, WAVELENGTH)),
        "sphere r 0.5 m (PEC)": (None, C.PEC, 1, C.SPHERE, C.rcs_sphere(0.5)),
        "trihedral 0.5 m (concrete, HH)": (C.trihedral(0.5), '<string name="material" value="concrete"/>', 3, "",
                                       C.rcs_trihedral(0.5, WAVELENGTH) * r**6),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spacings", type=float, nargs="+", default=[0.05, 0.02, 0.01])
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for k, (name, (mesh, material, depth, extra, expected)) in enumerate(cases().items()):
            xml = C.scene_xml(Path(tmp), mesh, material, depth, extra, name=f"case{k}")
            sensor = {"polarization": "HH"} if "HH" in name else {}
            simulate(str(xml), sensor_overrides=sensor, integrator_overrides={"ray_spacing": args.spacings[0]})
            for spacing in args.spacings:
                start = time.perf_counter()
                sim = simulate(str(xml), sensor_overrides=sensor, integrator_overrides={"ray_spacing": spacing})
                seconds = time.perf_counter() - start
                measured = integrated_rcs(sim)
                rows.append({"target": name, "ray_spacing_m": spacing,
                             "expected_dbsm": round(10 * math.log10(expected), 2),
                             "measured_dbsm": round(10 * math.log10(measured), 2),
                             "error_db": round(10 * math.log10(measured / expected), 2),
                             "rays_per_pulse": int(sim.trace.rays_per_order[0] / sim.raw.n_pulses),
                             "pulses": sim.raw.n_pulses, "seconds": round(seconds, 3)})
                print("  ".join(f"{key}={value}" for key, value in rows[-1].items()), flush=True)
    write_csv("rcs.csv", rows)


if __name__ == "__main__":
    main()
