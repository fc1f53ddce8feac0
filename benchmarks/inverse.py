"""Benchmark: an inverse problem solved with the simulator's gradients (issue 57).

A dihedral (the built-in one, its metal ground kept) whose wall is a half-space of relative
permittivity 5 (0.05 S/m) is imaged: 32 pulses, direct backprojection onto a 32 x 32 ground grid
of 0.5 m. Starting 30 % off (6.5), scipy's L-BFGS-B minimises the amplitude loss
``sum (|I| - |T|)^2`` against that image with ``sarmitsuba.gradients`` giving ``L`` and
``dL/d eps_r`` (reverse mode through backprojection's adjoint, the binning's and the tracer's).
Per evaluation: the permittivity, the loss, the gradient and the wall seconds; the result's
relative error. Writes ``inverse.csv`` and ``inverse.png`` (the loss and the permittivity
against evaluations).

Usage: ``python benchmarks/inverse.py [--quick] [--tiny]`` (the same small problem; ``--tiny``
stops after 4 evaluations).
"""
from __future__ import annotations

import re
import tempfile
import time
from pathlib import Path

import numpy as np

from _table import bench_main, machine, output_dir, write_csv

NAME = "inverse"
TRUE, START = 5.0, 6.5
SIZE = {"image_size": (32, 32), "image_spacing": 0.5, "sensor_overrides": {"n_pulses": 32}}
REPO = Path(__file__).resolve().parents[1]


def dihedral(folder: Path, eps_r: float) -> str:
    """The built-in dihedral with its wall a half-space of ``eps_r`` (0.05 S/m)."""
    xml = (REPO / "scenes" / "dihedral.xml").read_text()
    wall = (f'<bsdf type="radar" id="wall_material"><string name="model" value="half_space"/>'
            f'<float name="relative_permittivity" value="{eps_r!r}"/><float name="conductivity" value="0.05"/></bsdf>')
    xml = re.sub(r'(<shape type="rectangle" id="wall">.*?)<ref id="metal"/>', r'\1<ref id="wall_material"/>',
                 xml.replace("</bsdf>", "</bsdf>" + wall, 1), flags=re.S)
    path = folder / f"dihedral_{eps_r!r}.xml"
    path.write_text(xml)
    return str(path)


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Solve the problem, print and write the table and plot; returns one row per evaluation."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import scipy.optimize

    import sarmitsuba
    from sarmitsuba.derivatives import AmplitudeLoss, MaterialParameter
    print(machine())
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        target = sarmitsuba.gradients(dihedral(folder, TRUE), AmplitudeLoss(np.zeros(SIZE["image_size"])), [],
                                      **SIZE).image
        loss, parameter = AmplitudeLoss(target), MaterialParameter("wall_material", "relative_permittivity")

        def value_and_gradient(x):
            start = time.perf_counter()
            result = sarmitsuba.gradients(dihedral(folder, float(x[0])), loss, [parameter], **SIZE)
            rows.append({"evaluation": len(rows) + 1, "relative_permittivity": float(x[0]), "loss": result.loss,
                         "gradient": result.gradient[parameter], "seconds": round(time.perf_counter() - start, 3)})
            return result.loss, np.array([result.gradient[parameter]])

        found = scipy.optimize.minimize(value_and_gradient, [START], jac=True, method="L-BFGS-B",
                                        bounds=[(1.5, 20.0)], options={"maxiter": 2 if tiny else 20})
    for row in rows:
        row["relative_error"] = abs(row["relative_permittivity"] - TRUE) / TRUE
        print("  ".join(f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()))
    print(f"found eps_r = {found.x[0]:.6f} (true {TRUE}) after {found.nit} iterations, {len(rows)} evaluations, "
          f"{sum(r['seconds'] for r in rows):.1f} s")
    suffix = "_tiny" if tiny else ""
    write_csv(f"{NAME}{suffix}.csv", rows)
    fig, axes = plt.subplots(1, 2, figsize=(8, 3.2), dpi=120)
    evaluations = [r["evaluation"] for r in rows]
    axes[0].semilogy(evaluations, [max(r["loss"], 1e-30) for r in rows], "o-")
    axes[0].set_ylabel("amplitude loss")
    axes[1].plot(evaluations, [r["relative_permittivity"] for r in rows], "o-", label="estimate")
    axes[1].axhline(TRUE, color="0.5", ls="--", label="truth")
    axes[1].set_ylabel("wall's relative permittivity")
    axes[1].legend(fontsize=8)
    for ax in axes:
        ax.set_xlabel("evaluation (loss and gradient)")
        ax.grid(True, alpha=0.3)
    fig.suptitle("recovering a dihedral wall's permittivity from 30 % off (L-BFGS-B)", fontsize=10)
    fig.tight_layout()
    fig.savefig(output_dir() / f"{NAME}{suffix}.png")
    plt.close(fig)
    return rows


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """The issue's bounds for the permittivity: within 2 % of the truth in under 5 minutes."""
    last, seconds = rows[-1], sum(r["seconds"] for r in rows)
    best = min(rows, key=lambda r: r["loss"])
    return [("permittivity recovered within 2 % from 30 % off", bool(best["relative_error"] <= 0.02),
             f"eps_r = {best['relative_permittivity']:.5f}, error {best['relative_error']:.2e} after {last['evaluation']} "
             "evaluations"),
            ("in under 5 minutes", bool(seconds < 300.0), f"{seconds:.1f} s")]


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "the same problem", "two iterations (smoke test)")
