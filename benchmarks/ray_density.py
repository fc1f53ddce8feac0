"""Benchmark: rays per resolution cell (the ``ray_spacing`` knob): accuracy against time.

For each ray spacing ``s`` (the ``sbr`` integrator's ``ray_spacing``), measured in one run,
each setting warmed up once (untimed: kernel compilation is not counted), best of
``repeat`` timed runs of the whole simulation (load, trace, bin, focus):

* **canonical targets** (metal plate 0.3 m, dihedral 0.3 x 0.3 m, trihedral 0.5 m; scenes
  and closed forms from ``benchmarks/rcs.py`` / :mod:`sarmitsuba.canonical`): RCS by
  integrated point energy, error in dB against the closed form;
* **rough ground** (80 m x 80 m, gamma -10 dB, the scene of ``tests/scenes/rough_ground.xml``):
  over the interior 60 m x 60 m, the mean sigma0 (mean intensity / (rho_E,az rho_E,gr), the energy widths) against
  the model ``gamma cos(theta)`` in dB, and the speckle contrast std / mean of the intensity
  (1 for fully developed speckle, Goodman 1976), also as ``10 log10(contrast)`` dB.
  The contrast is an estimate from ~2,800 resolution cells: about +-2 % statistical scatter.

Rays per resolution cell: tubes are ``s`` wide, ``s`` apart along track and ``s / cos(theta)``
apart in ground range, so a ground cell ``rho_az x rho_gr`` holds
``rho_az rho_gr cos(theta) / s^2 = (cell / s)^2`` rays with ``cell = sqrt(rho_az rho_gr cos theta)``
(0.945 m for the default X-band 150 MHz, 45 deg sensor). The tracer's automatic spacing is
``min(rho_slant, rho_az) / 2`` (about 4.5 rays per cell).

Writes ``benchmarks/out/ray_density.csv`` and ``ray_density.png`` (|error| in dB against
seconds, one point per spacing). ``time_ratio`` is each setting's time over the coarsest
setting of the same case (ratios, not absolute times, are what the suite compares).

Usage: ``python benchmarks/ray_density.py [--quick]``
"""
from __future__ import annotations

import math
import tempfile
import time
from pathlib import Path

import numpy as np

import sarmitsuba  # noqa: F401
from _plot import plot_cost
from _table import bench_main, machine, write_csv
from rcs import cases, integrated_rcs
from sarmitsuba import analysis
from sarmitsuba import canonical as C
from sarmitsuba.pipeline import simulate

NAME = "ray_density"
#: The three canonical targets of ``rcs.cases()`` benchmarked here.
TARGETS = ("plate 0.3 m (PEC)", "dihedral 0.3 x 0.3 m (PEC)", "trihedral 0.5 m (PEC)")
GAMMA = 0.1  # -10 dB, as in the ground scene below
GROUND_XML = """<scene version="3.0.0">
    <sensor type="sar">
        <float name="bandwidth" value="150e6"/>
        <float name="azimuth_beamwidth" value="1.2"/>
        <float name="prf" value="250"/>
        <string name="scene_center" value="0, 0, 0"/>
    </sensor>
    <integrator type="sbr"><integer name="max_depth" value="1"/></integrator>
    <bsdf type="radar" id="field">
        <string name="material" value="medium_dry_ground"/>
        <float name="gamma_db" value="-10"/>
    </bsdf>
    <shape type="rectangle" id="ground">
        <transform name="to_world"><scale x="40" y="40"/></transform>
        <ref id="field"/>
    </shape>
</scene>"""
#: (canonical spacings, ground spacings, timed repeats) per mode [m]
SETTINGS = {
    "tiny": ([0.1, 0.05], [0.8, 0.5], 1),
    "quick": ([0.1, 0.05, 0.02, 0.01, 0.005], [0.8, 0.5, 0.3, 0.2, 0.1], 1),
    "full": ([0.2, 0.1, 0.05, 0.02, 0.01, 0.005, 0.002], [0.8, 0.6, 0.4, 0.3, 0.2, 0.14, 0.1, 0.07, 0.05], 2),
}


def rays_per_cell(params, spacing: float) -> float:
    """Ray tubes per ground resolution cell ``rho_az x rho_gr`` for tube width ``spacing``."""
    cos_t = math.cos(math.radians(params.incidence_angle))
    return params.azimuth_resolution * params.ground_range_resolution * cos_t / spacing**2


def timed(xml: str, repeat: int, **kwargs):
    """(best seconds of ``repeat`` runs after one untimed warm-up, that run's Simulation)."""
    simulate(xml, **kwargs)                                   # warm-up: compile this configuration
    best, sim = math.inf, None
    for _ in range(repeat):
        start = time.perf_counter()
        result = simulate(xml, **kwargs)
        seconds = time.perf_counter() - start
        if seconds < best:
            best, sim = seconds, result
    return best, sim


def ground_statistics(sim) -> tuple[float, float, float]:
    """(measured sigma0, model sigma0, speckle contrast) over the interior 60 m x 60 m."""
    im = sim.image
    az, gr = np.meshgrid(im.azimuth, im.range, indexing="ij")
    box = (np.abs(az) < 30.0) & (np.abs(gr) < 30.0)
    values, positions = im.data[box], im.positions()[box]
    antenna = sim.raw.tx_position.mean(axis=0)
    cos_theta = (antenna[2] - positions[:, 2]) / np.linalg.norm(antenna - positions, axis=1)
    intensity = np.abs(values.astype(np.complex128)) ** 2
    # sigma0 = mean intensity over the weighted impulse response's energy widths (physics (K2))
    measured = intensity.mean() / float(np.prod(analysis.energy_widths(im)))
    return float(measured), float(np.mean(GAMMA * cos_theta)), float(intensity.std() / intensity.mean())


def _row(case: str, spacing: float, sim, seconds: float, expected: float, measured: float,
         contrast: float | str = "") -> dict:
    p = sim.loaded.params
    return {"case": case, "ray_spacing_m": spacing, "rays_per_cell": round(rays_per_cell(p, spacing), 2),
            "rays_per_pulse": int(sim.trace.rays_per_order[0] / sim.raw.n_pulses), "pulses": sim.raw.n_pulses,
            "seconds": round(seconds, 4), "trace_s": round(sim.timings["trace"], 4), "time_ratio": 1.0,
            "expected_db": round(10 * math.log10(expected), 3), "measured_db": round(10 * math.log10(measured), 3),
            "error_db": round(10 * math.log10(measured / expected), 3),
            "speckle_contrast": round(contrast, 4) if contrast != "" else "",
            "speckle_contrast_error_db": round(10 * math.log10(contrast), 3) if contrast != "" else ""}


def run(quick: bool = False, *, tiny: bool = False) -> list[dict]:
    """Run the benchmark; prints the table, writes the CSV and PNG, returns the rows.

    ``quick``: fewer spacings (< 60 s); ``tiny``: two spacings per case (smoke test).
    """
    canonical_spacings, ground_spacings, repeat = SETTINGS["tiny" if tiny else "quick" if quick else "full"]
    name = f"{NAME}_tiny" if tiny else NAME          # tiny (smoke test) keeps the real outputs
    print(machine(), flush=True)
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        all_cases = cases()
        for k, target in enumerate(TARGETS):
            mesh, material, depth, extra, expected = all_cases[target]
            xml = str(C.scene_xml(folder, mesh, material, depth, extra, name=f"case{k}"))
            first = None
            for spacing in canonical_spacings:
                seconds, sim = timed(xml, repeat, integrator_overrides={"ray_spacing": spacing})
                row = _row(target, spacing, sim, seconds, expected, integrated_rcs(sim))
                first = first or seconds
                row["time_ratio"] = round(seconds / first, 3)
                rows.append(row)
                print("  ".join(f"{key}={value}" for key, value in row.items()), flush=True)
        ground = folder / "rough_ground.xml"
        ground.write_text(GROUND_XML)
        first = None
        for spacing in ground_spacings:
            seconds, sim = timed(str(ground), repeat, integrator_overrides={"ray_spacing": spacing, "seed": 0})
            measured, expected, contrast = ground_statistics(sim)
            row = _row("rough ground gamma -10 dB", spacing, sim, seconds, expected, measured, contrast)
            first = first or seconds
            row["time_ratio"] = round(seconds / first, 3)
            rows.append(row)
            print("  ".join(f"{key}={value}" for key, value in row.items()), flush=True)
    write_csv(f"{name}.csv", rows)
    series: dict[str, list] = {}
    for row in rows:
        label = row["case"] if row["speckle_contrast"] == "" else "ground mean sigma0"
        series.setdefault(label, []).append((row["seconds"], abs(row["error_db"]), f"{row['rays_per_cell']:.3g}"))
        if row["speckle_contrast"] != "":
            series.setdefault("ground speckle contrast (10 log10 std/mean)", []).append(
                (row["seconds"], abs(row["speckle_contrast_error_db"]), f"{row['rays_per_cell']:.3g}"))
    plot_cost(f"{name}.png", series, ylabel="|error| [dB]",
              title="ray density: error against time (labels: rays per resolution cell)")
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Suite checks: accuracy at the densest setting, and the cost ratio of the ground sweep."""
    out = []
    for case in TARGETS:
        sel = [r for r in rows if r["case"] == case]
        if sel:
            r = min(sel, key=lambda r: r["ray_spacing_m"])
            out.append((f"{case}: RCS within 1 dB of the closed form at {r['rays_per_cell']:.0f} rays/cell",
                        abs(r["error_db"]) < 1.0, f"error {r['error_db']:+.2f} dB"))
    ground = [r for r in rows if r["speckle_contrast"] != ""]
    if ground:
        fine, coarse = ground[-1], ground[0]
        out.append(("rough ground: mean sigma0 within 0.5 dB of gamma cos(theta) at the densest setting",
                    abs(fine["error_db"]) < 0.5, f"error {fine['error_db']:+.2f} dB at {fine['rays_per_cell']} rays/cell"))
        out.append(("rough ground: speckle contrast within 10 % of 1 (fully developed) at the densest setting",
                    abs(fine["speckle_contrast"] - 1.0) < 0.1, f"std/mean {fine['speckle_contrast']:.3f}"))
        rays = fine["rays_per_pulse"] / coarse["rays_per_pulse"]
        ratio = fine["seconds"] / coarse["seconds"]
        out.append(("rough ground: densest setting costs more than the coarsest, at most in proportion to rays",
                    1.0 < ratio <= 1.5 * rays, f"time ratio {ratio:.2f} for {rays:.1f}x rays"))
    return out


def main() -> None:
    bench_main(__doc__, run, checks, quick_help="fewer spacings (< 60 s)",
               tiny_help="two spacings per case (smoke test)")


if __name__ == "__main__":
    main()
