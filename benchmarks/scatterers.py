"""Benchmark: what the scatterer catalogue costs, and how much of the brightest pixels it explains.

Cost: on the built-in urban scene and Sionna's Munich (512 central pulses, the scene's default
``max_depth``, ``auto``), ``simulate`` without and with ``scatterers=True`` (share 0.9), measured
in one run, each after an untimed warm-up of the same run (kernel compilation not counted), then
timed runs alternating without / with (3 each on urban, 2 each on Munich), the fastest counting:
the simulation's seconds (``load``, ``depth_probe`` where ``auto`` probes, ``trace``, ``bin``,
``focus``: the catalogue's own build after focusing is not among them, so the wall-clock seconds of
the whole ``simulate`` call are reported beside them) and the trace's alone, and with over without.
Memory: the peak resident set (``ru_maxrss``) of a fresh Python process that runs one ``simulate``
without, and one of another that runs it with the catalogue, and their ratio (worker processes
of the trace, where the render starts them, are reported apart: the largest child's peak).
Targets (reported, not asserted): time ratio at most :data:`TIME_TARGET`, memory ratio at most
:data:`MEMORY_TARGET`.

Explanation: on Munich's image with the catalogue, the :data:`N_PIXELS` brightest pixels of
``|I|`` that are local maxima (3 x 3 neighbourhood) and at least :data:`MIN_SEPARATION` pixels
apart (Euclidean, in pixels); for each ``sarmitsuba.analysis.scatterers.explain`` at its
coordinates: the catalogue's share of the pixel's power resynthesised (``explained``), the
strongest row within its resolution cell (shapes, order, share), and the number of such rows.
The explanation's catalogue is a second Munich simulation that lists every scatterer within
:data:`EXPLAIN_FLOOR_DB` of the strongest. Per pixel also the residual ``|I - sum p_i|^2 / |I|^2``
and, where no scatterer lies in its cell, the listed scatterer whose azimuth ambiguity falls
there (``explain``'s ``ghosts``). Target: every pixel at least :data:`EXPLAINED_TARGET`. Also the
catalogue's row count, the share of the image's RCS it lists and its rows by bounce order.

Writes ``scatterers.csv``, ``scatterers.md`` (the cost and pixel tables) and ``scatterers.png``
(Munich's image in dB with the pixels circled, green where explained >= 0.8, red otherwise; and
each pixel's explained share) into the output folder (``_table.output_dir``); run alone (not
``--quick``), it also copies the CSV and PNG to ``docs/benchmarks/data/standalone/scatterers-<date>.*``
(the Markdown tables go into ``docs/benchmarks/scatterers.md`` by hand).

Usage: ``python benchmarks/scatterers.py [--quick]`` (``--quick``: the cost on urban only, the
explanation on 128 of Munich's pulses).
"""
from __future__ import annotations

import argparse
import datetime
import gc
import importlib.util
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import sarmitsuba  # noqa: F401
from _table import machine, output_dir, write_csv
from sarmitsuba.analysis.scatterers import explain
from sarmitsuba.pipeline import simulate

ROOT = Path(__file__).resolve().parents[1]
#: Scene -> (sensor overrides, integrator overrides, timed runs each): Munich on its 512 central
#: pulses of about 2,300, at its default max_depth (auto).
SCENES = {"urban": ({}, {}, 3), "sionna:munich": ({"n_pulses": 512}, {}, 2)}
SHARE = 0.9
TIME_TARGET, MEMORY_TARGET = 1.2, 1.3
N_PIXELS, MIN_SEPARATION, EXPLAINED_TARGET = 20, 3.0, 0.8
#: The explanation's catalogue lists every scatterer within this many dB of the strongest (the
#: default share 0.9 lists Munich's few brightest only).
EXPLAIN_FLOOR_DB = -80.0
#: The stages summed into a simulation's seconds.
STAGES = ("load", "depth_probe", "trace", "bin", "focus")


def _seconds(sim) -> float:
    return float(sum(sim.timings.get(k, 0.0) for k in STAGES))


def _run(scene: str, sensor: dict, overrides: dict, catalogue: bool):
    """One ``simulate`` and its wall-clock seconds."""
    start = time.perf_counter()
    sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=overrides or None,
                   scatterers=catalogue, scatterers_share=SHARE)
    return sim, time.perf_counter() - start


_PEAK = """
import json, resource, sys
from sarmitsuba.pipeline import simulate
scene, sensor, overrides, catalogue, share = json.loads(sys.argv[1])
sim = simulate(scene, sensor_overrides=sensor, integrator_overrides=overrides or None, scatterers=catalogue,
               scatterers_share=share)
note = getattr(sim.trace, "workers_note", "")
print(json.dumps({"self_kib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                  "children_kib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, "workers": note}))
"""


def _peak(scene: str, sensor: dict, overrides: dict, catalogue: bool) -> dict:
    """The peak resident memory [KiB] of a fresh process running one ``simulate`` (the JSON its
    last stdout line prints)."""
    out = subprocess.run([sys.executable, "-c", _PEAK, json.dumps([scene, sensor, overrides, catalogue, SHARE])],
                         capture_output=True, text=True, cwd=ROOT)
    if out.returncode != 0:
        raise RuntimeError(f"memory run of {scene} (scatterers={catalogue}) failed:\n{out.stderr[-4000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def cost(scene: str, sensor: dict, overrides: dict, repeats: int):
    """The cost row of ``scene``, and the image and catalogue of its fastest run with the catalogue.

    A finished simulation is dropped at once (a live Mitsuba scene slows the tracing of later ones);
    only the image and catalogue of the runs with the catalogue are kept."""
    for catalogue in (False, True):                     # untimed warm-ups
        sim, _ = _run(scene, sensor, overrides, catalogue)
        del sim
        gc.collect()
    best = {False: None, True: None}
    kept = None
    for _ in range(repeats):
        for catalogue in (False, True):
            sim, wall = _run(scene, sensor, overrides, catalogue)
            entry = dict(time_s=_seconds(sim), trace_s=float(sim.timings["trace"]), wall_s=wall,
                         depth=len(sim.trace.energy_per_order), workers=getattr(sim.trace, "workers_note", ""))
            old = best[catalogue]
            if old is None:
                best[catalogue] = entry
            else:                                       # each column's fastest
                best[catalogue] = dict(old, time_s=min(old["time_s"], entry["time_s"]),
                                       trace_s=min(old["trace_s"], entry["trace_s"]),
                                       wall_s=min(old["wall_s"], entry["wall_s"]))
            if catalogue:
                kept = (sim.image, sim.scatterers)
            del sim
            gc.collect()
    memory = {flag: _peak(scene, sensor, overrides, flag) for flag in (False, True)}
    off, on = best[False], best[True]
    row = {"section": "cost", "scene": scene, "pulses": sensor.get("n_pulses", ""),
           "max_depth": overrides.get("max_depth", "default (auto)"),
           "depth": on["depth"], "runs_each": repeats,
           "time_without_s": round(off["time_s"], 3), "time_with_s": round(on["time_s"], 3),
           "time_ratio": round(on["time_s"] / off["time_s"], 3),
           "trace_without_s": round(off["trace_s"], 3), "trace_with_s": round(on["trace_s"], 3),
           "trace_ratio": round(on["trace_s"] / off["trace_s"], 3),
           "wall_without_s": round(off["wall_s"], 3), "wall_with_s": round(on["wall_s"], 3),
           "wall_ratio": round(on["wall_s"] / off["wall_s"], 3),
           "peak_rss_without_mib": round(memory[False]["self_kib"] / 1024, 1),
           "peak_rss_with_mib": round(memory[True]["self_kib"] / 1024, 1),
           "memory_ratio": round(memory[True]["self_kib"] / memory[False]["self_kib"], 3),
           "child_peak_rss_without_mib": round(memory[False]["children_kib"] / 1024, 1),
           "child_peak_rss_with_mib": round(memory[True]["children_kib"] / 1024, 1),
           "workers": on["workers"]}
    row["time_target_pass"] = row["time_ratio"] <= TIME_TARGET
    row["memory_target_pass"] = row["memory_ratio"] <= MEMORY_TARGET
    return row, kept


def brightest(data: np.ndarray, n: int = N_PIXELS, separation: float = MIN_SEPARATION) -> list[tuple[int, int]]:
    """The ``n`` brightest local maxima (3 x 3) of ``|data|``, each at least ``separation`` pixels
    from every brighter one chosen."""
    from scipy.ndimage import maximum_filter
    a = np.abs(data)
    peaks = np.argwhere((a == maximum_filter(a, size=3, mode="constant", cval=0.0)) & (a > 0))
    peaks = peaks[np.argsort(-a[peaks[:, 0], peaks[:, 1]], kind="stable")]
    chosen: list[tuple[int, int]] = []
    for i, j in peaks:
        if all((i - k) ** 2 + (j - m) ** 2 >= separation ** 2 for k, m in chosen):
            chosen.append((int(i), int(j)))
            if len(chosen) == n:
                break
    return chosen


def explanation(image, catalogue, scene: str) -> tuple[list[dict], dict]:
    """One row per bright pixel (``explain`` there), and the summary row of the catalogue."""
    peak = float(np.max(np.abs(image.data)))
    rows = []
    for rank, (i, j) in enumerate(brightest(image.data), start=1):
        az, rg = float(image.azimuth[i]), float(image.range[j])
        out = explain(image, catalogue.columns, az, rg)
        top = out["rows"][0] if out["rows"] else {}
        ghost = out["ghosts"][0] if out["ghosts"] else {}
        power = float(np.abs(image.data[i, j])) ** 2
        rows.append({"section": "pixel", "scene": scene, "pixel_rank": rank, "row": i, "column": j,
                     "azimuth_m": round(az, 2), "range_m": round(rg, 2),
                     "power_db": round(float(10 * np.log10(power)), 2),
                     "power_rel_db": round(float(10 * np.log10(power / peak ** 2)), 2),
                     "explained": round(out["explained"], 4), "top_shapes": top.get("shapes", ""),
                     "top_order": top.get("order", ""), "top_share": round(top["share"], 4) if top else "",
                     "rows_in_cell": len(out["rows"]), "residual": round(out["residual"], 4),
                     "ghost_of_rank": ghost.get("rank", ""), "ghost_order": ghost.get("order_m", ""),
                     "ghost_level_db": round(ghost["level_db"], 1) if ghost else "",
                     "explained_pass": out["explained"] >= EXPLAINED_TARGET,
                     "ghost_only": not out["rows"] and bool(ghost)})
    orders = np.asarray(catalogue.columns["order"], int)
    explained = [r["explained"] for r in rows]
    summary = {"section": "catalogue", "scene": scene, "catalogue_rows": len(catalogue),
               "listed_share": round(catalogue.listed_share, 4), "selection": catalogue.selection,
               "rows_by_order": " ".join(f"{k}:{int((orders == k).sum())}" for k in np.unique(orders)),
               "pixels": len(rows), "pixels_explained_pass": sum(r["explained_pass"] for r in rows),
               "pixels_ghosts": sum(r["ghost_only"] for r in rows),
               "median_residual": round(float(np.median([r["residual"] for r in rows])), 4) if rows else "",
               "median_explained": round(float(np.median(explained)), 4) if explained else "",
               "line": catalogue.line()}
    return rows, summary


def _markdown(cost_rows: list[dict], pixel_rows: list[dict], summary: dict | None, title: str) -> str:
    lines = [f"# {title}", "", machine(), "",
             "## Cost: simulate without and with `scatterers=True` (fastest of the timed runs)", "",
             "| scene | pulses | depth | s without | s with | time ratio | trace ratio | wall ratio "
             "| peak MiB without | peak MiB with | memory ratio | time <= 1.2 | memory <= 1.3 |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in cost_rows:
        lines.append(f"| {r['scene']} | {r['pulses'] or 'all'} | {r['depth']} | {r['time_without_s']:.2f} | "
                     f"{r['time_with_s']:.2f} | {r['time_ratio']:.3f} | {r['trace_ratio']:.3f} | {r['wall_ratio']:.3f} | "
                     f"{r['peak_rss_without_mib']:.0f} | {r['peak_rss_with_mib']:.0f} | {r['memory_ratio']:.3f} | "
                     f"{'pass' if r['time_target_pass'] else 'FAIL'} | "
                     f"{'pass' if r['memory_target_pass'] else 'FAIL'} |")
    lines += ["", "Seconds: load + depth_probe + trace + bin + focus (the catalogue's build after focusing is in "
              "the wall ratio only). Memory: `ru_maxrss` of a fresh process running one simulate.", ""]
    if summary is not None:
        lines += [f"## Explanation: the {len(pixel_rows)} brightest separated local maxima of {summary['scene']}", "",
                  f"Catalogue: {summary['line']}. Explained >= {EXPLAINED_TARGET}: "
                  f"{summary['pixels_explained_pass']} of {summary['pixels']}, and {summary['pixels_ghosts']} azimuth "
                  f"ghosts of listed scatterers; median {summary['median_explained']}, median residual "
                  f"{summary['median_residual']}.",
                  "", "| # | pixel (row, col) | az [m] | rg [m] | dB | dB rel. max | explained | residual | top shapes "
                  "| order | top share | rows | ghost of # (order, dB) |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in pixel_rows:
            ghost = f"{r['ghost_of_rank']} ({r['ghost_order']}, {r['ghost_level_db']})" if r["ghost_of_rank"] != "" else ""
            lines.append(f"| {r['pixel_rank']} | ({r['row']}, {r['column']}) | {r['azimuth_m']:.2f} | "
                         f"{r['range_m']:.2f} | {r['power_db']:.1f} | {r['power_rel_db']:.1f} | {r['explained']:.3f} | "
                         f"{r['residual']:.3f} | {r['top_shapes']} | {r['top_order']} | {r['top_share']} | "
                         f"{r['rows_in_cell']} | {ghost} |")
    return "\n".join(lines) + "\n"


def _figure(path: Path, image, pixel_rows: list[dict], title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    a = np.abs(image.data).astype(float)
    with np.errstate(divide="ignore"):
        db = 20 * np.log10(a / max(a.max(), 1e-300))
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.5), dpi=120, gridspec_kw={"width_ratios": [1.4, 1]})
    extent = [image.range[0], image.range[-1], image.azimuth[0], image.azimuth[-1]]
    shown = left.imshow(db, cmap="gray", vmin=-50, vmax=0, origin="lower", extent=extent, aspect="equal",
                        interpolation="nearest")
    fig.colorbar(shown, ax=left, label="dB relative to max", shrink=0.8)
    for r in pixel_rows:
        colour = "lime" if r["explained_pass"] else "red"
        left.plot(r["range_m"], r["azimuth_m"], "o", mfc="none", mec=colour, ms=9, mew=1.2)
        left.annotate(str(r["pixel_rank"]), (r["range_m"], r["azimuth_m"]), color=colour, fontsize=6,
                      textcoords="offset points", xytext=(5, 5))
    left.set_xlabel("range [m]")
    left.set_ylabel("azimuth [m]")
    left.set_title(title, fontsize=9)
    ranks = [r["pixel_rank"] for r in pixel_rows]
    explained = [r["explained"] for r in pixel_rows]
    right.bar(ranks, explained, color=["tab:green" if r["explained_pass"] else "tab:red" for r in pixel_rows])
    right.axhline(EXPLAINED_TARGET, color="k", ls="--", lw=0.8, label=f"target {EXPLAINED_TARGET}")
    right.set_xlabel("pixel (brightest first)")
    right.set_ylabel("explained share of the pixel's power")
    right.set_xticks(ranks)
    right.tick_params(axis="x", labelsize=7)
    right.legend(fontsize=8)
    right.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    print(f"wrote {path}")


def run(quick: bool = False) -> list[dict]:
    """Measure the cost and the explanation, print them, write CSV, Markdown and PNG; returns the rows."""
    print(machine())
    munich = importlib.util.find_spec("sionna") is not None
    cost_rows, kept = [], {}
    for scene, (sensor, overrides, repeats) in SCENES.items():
        if scene != "urban" and (quick or not munich):
            continue
        row, kept[scene] = cost(scene, sensor, overrides, repeats)
        print("  ".join(f"{k}={v}" for k, v in row.items()))
        cost_rows.append(row)
    pixel_rows, summary, image = [], None, None
    if munich:
        scene = "sionna:munich"
        if quick:
            sim, _ = _run(scene, {"n_pulses": 128}, {}, True)
            image, catalogue = sim.image, sim.scatterers
            del sim
            gc.collect()
        else:                            # every scatterer within EXPLAIN_FLOOR_DB of the strongest
            sim = simulate(scene, sensor_overrides=SCENES[scene][0], scatterers=True, scatterers_db=EXPLAIN_FLOOR_DB)
            image, catalogue = sim.image, sim.scatterers
            del sim
            gc.collect()
        pixel_rows, summary = explanation(image, catalogue, scene)
        summary["pulses"] = 128 if quick else SCENES[scene][0]["n_pulses"]
        for row in [*pixel_rows, summary]:
            print("  ".join(f"{k}={v}" for k, v in row.items()))
    rows = [*cost_rows, *pixel_rows, *([summary] if summary else [])]
    keys = list(dict.fromkeys(k for row in rows for k in row))
    write_csv("scatterers.csv", [{k: row.get(k, "") for k in keys} for row in rows])
    pulses = summary["pulses"] if summary else 0
    title = f"scatterer catalogue: cost and explained power (Munich, {pulses} pulses)"
    md = output_dir() / "scatterers.md"
    md.write_text(_markdown(cost_rows, pixel_rows, summary, title))
    print(f"wrote {md}")
    if image is not None:
        _figure(output_dir() / "scatterers.png", image, pixel_rows,
                f"Munich ({pulses} pulses), |I| dB; circles: the {len(pixel_rows)} brightest separated maxima "
                f"(green: explained >= {EXPLAINED_TARGET})")
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The targets: time ratio and memory ratio per scene, and every bright pixel explained."""
    out = []
    for r in (r for r in rows if r["section"] == "cost"):
        out.append((f"{r['scene']}: time with the catalogue at most {TIME_TARGET}x without", r["time_target_pass"],
                    f"{r['time_with_s']:.2f} s / {r['time_without_s']:.2f} s = {r['time_ratio']:.3f} "
                    f"(wall {r['wall_ratio']:.3f}, trace {r['trace_ratio']:.3f})"))
        out.append((f"{r['scene']}: peak memory with the catalogue at most {MEMORY_TARGET}x without",
                    r["memory_target_pass"], f"{r['peak_rss_with_mib']:.0f} MiB / {r['peak_rss_without_mib']:.0f} MiB "
                                             f"= {r['memory_ratio']:.3f}"))
    for s in (r for r in rows if r["section"] == "catalogue"):
        out.append((f"{s['scene']}: each of the {s['pixels']} brightest pixels explained >= {EXPLAINED_TARGET}",
                    s["pixels_explained_pass"] == s["pixels"],
                    f"{s['pixels_explained_pass']} of {s['pixels']} (and {s['pixels_ghosts']} azimuth ghosts of listed "
                    f"scatterers), median {s['median_explained']}, median residual {s['median_residual']}; {s['line']}"))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the cost on urban only; Munich's explanation on 128 pulses")
    args = parser.parse_args()
    rows = run(args.quick)
    for name, ok, detail in checks(rows):
        print(f"{'PASS' if ok else 'FAIL'}  {name}  {detail}")
    if not args.quick:                                  # the record beside the other standalone runs
        docs = ROOT / "docs" / "benchmarks" / "data" / "standalone"
        stamp = datetime.date.today().isoformat()
        for ext in ("csv", "png"):                     # the tables: docs/benchmarks/scatterers.md
            source = output_dir() / f"scatterers.{ext}"
            if source.exists():
                shutil.copyfile(source, docs / f"scatterers-{stamp}.{ext}")
                print(f"copied {source} -> {docs / f'scatterers-{stamp}.{ext}'}")


if __name__ == "__main__":
    main()
