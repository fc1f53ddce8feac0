"""How much of a render's energy each bounce order holds, and whether the deepest order traced
leaves the series unconverged (``summary.json``'s ``energy_by_order`` and ``depth_warning``,
``sarmitsuba info`` of a render folder).

The energies are those of each order's range-compressed raw data (docs/physics.md (D6)), which
the tracer measures from each order's spectrum
(:attr:`sarmitsuba.tracing.driver.trace.TraceResult.raw_energy_per_order`).
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from ..core.radar import ParameterError

__all__ = ["DEEPEST_SHARE", "ENERGY_UNIT", "energy_by_order", "depth_warning", "cap_warning", "render_summary",
           "format_render", "format_depth"]

#: The deepest traced order holding at least this share of the orders' energy is warned about.
#: If the orders beyond it held as much as it does (no decay), the image would miss that share
#: of its energy: 10 % is an image NRMSE of -10 dB, the size of what depth 3 misses on Munich
#: (-11.8 dB against depth 6, README "Bounce depth") and far above the -30 dB at which two images
#: of identical paths differ (``benchmarks/bounce_depth.py``).
DEEPEST_SHARE = 0.10
#: Unit of the absolute energies (normalised radiometry: the sum over pulses and samples of ``|s|^2``).
ENERGY_UNIT = "m^2"


def energy_by_order(energy: "np.ndarray | None") -> dict | None:
    """``summary.json``'s ``energy_by_order`` of the per-order energies ``energy`` float64
    [max_depth] [m^2] (order ``d`` at index ``d - 1``): ``{"measure", "unit", "energy": {"1": E_1,
    ...}, "share": {"1": E_1 / sum E, ...}}``, shares of the sum over orders (docs/physics.md (D6));
    None when ``energy`` is None (not measured: the ``exact`` range kernel). All shares are 0
    when no order holds energy."""
    if energy is None:
        return None
    energy = np.asarray(energy, np.float64)
    total = float(energy.sum())
    return {"measure": "energy of each bounce order's range-compressed raw data (docs/physics.md (D6))",
            "unit": ENERGY_UNIT,
            "energy": {str(d): float(e) for d, e in enumerate(energy, start=1)},
            "share": {str(d): float(e / total) if total > 0 else 0.0 for d, e in enumerate(energy, start=1)}}


def depth_warning(energy: "np.ndarray | None", rays_beyond: int | None = None) -> str | None:
    """The warning for the per-order energies ``energy`` float64 [max_depth]: the deepest traced
    order holds at least :data:`DEEPEST_SHARE` of their sum, so the orders not traced may matter;
    None otherwise, when not measured, for one order (``max_depth = 1`` asks for single bounce
    alone, and its one order holds everything whatever the scene), and when ``rays_beyond`` is 0:
    the tracer looked, and no ray of the deepest order meets anything more (a trihedral's third
    bounce leaves toward the radar; :attr:`~sarmitsuba.tracing.driver.trace.TraceResult.rays_beyond`)."""
    if energy is None or len(energy) < 2 or not np.sum(energy) > 0 or rays_beyond == 0:
        return None
    energy = np.asarray(energy, np.float64)
    depth, share = len(energy), float(energy[-1] / energy.sum())
    if share < DEEPEST_SHARE:
        return None
    why = (f"{rays_beyond:,} of its specular rays meet more of the scene" if rays_beyond else
           "a corner's own order, a dihedral's second or a trihedral's third, may hold most with nothing beyond it")
    return (f"bounce order {depth}, the deepest traced, holds {100 * share:.1f} % of the energy: the orders "
            f"beyond it may hold as much ({why}); render once with --max-depth {depth + 1} to see")


def cap_warning(depth: dict) -> str | None:
    """The warning of a ``max_depth = auto`` render (``summary.json``'s ``depth``, a dict) that the
    cap stopped: the orders up to the cap still held more than the tolerance beyond each depth
    below it (docs/physics.md (DEP2)); None for any other reason."""
    if depth.get("reason") != "cap":
        return None
    probe = depth["probe"]
    last = probe["share"][str(depth["cap"])]
    goes_on = probe.get("rays_beyond_cap")
    rays = f"{goes_on:,} of its specular rays meet more of the scene" if goes_on else "its rays go on"
    return (f"max_depth auto stopped at the cap {depth['cap']}: order {depth['cap']} holds {100 * last:.2f} % of "
            f"the probe's energy and {rays}; the orders beyond are not traced (raise the sbr depth_cap, "
            "for instance --integrator-set depth_cap=12, to trace them)")


def format_depth(depth: dict | None) -> list[str]:
    """Text lines of ``summary.json``'s ``depth`` (dict; empty for summaries written without it)."""
    if not depth:
        return []
    if depth.get("mode") != "auto":
        return [f"depth: {depth['depth']} (fixed: sbr max_depth)"]
    beyond = "nothing" if depth.get("beyond_db") is None else f"{depth['beyond_db']:.1f} dB"
    probe = depth["probe"]
    lines = [f"depth: {depth['depth']} (max_depth auto, {depth['reason']}: {depth['why']}; tolerance "
             f"{depth['tolerance_db']:g} dB, cap {depth['cap']}); "
             + ("the orders beyond the cap were not probed" if depth["reason"] == "cap" else
                f"the orders beyond hold {beyond} of the probe's energy")
             + f" (probe: {probe['pulses']} pulses to order {depth['cap']} with {probe['lit_regions']}, "
               f"{probe['seconds']:.1f} s)"]
    seconds = depth.get("seconds_by_order", {})
    for k, share in probe["share"].items():
        if int(k) > depth["depth"] and share == 0:
            continue
        traced = (f", traced in {seconds[k]:.1f} s" if k in seconds else "" if int(k) <= depth["depth"]
                  else " (left out)")
        predicted = probe["predicted_seconds"].get(k)
        lines.append(f"  order {k:>2}: probe {100 * share:8.4f} %"
                     + (f", predicted {predicted:.1f} s" if predicted is not None else "") + traced)
    return lines


def render_summary(path: "str | os.PathLike | None") -> dict | None:
    """The ``summary.json`` of a finished render named by ``path`` (its folder, or the file),
    as a dict; None when ``path`` names a scene instead (an XML file, a folder with
    ``scene.xml``, a built-in or ``sionna:`` name, or None).

    Raises
    ------
    ParameterError
        ``path`` is a folder with neither ``scene.xml`` nor ``summary.json``, or a JSON file that
        is not a render's ``summary.json``.
    """
    if path is None:
        return None
    p = Path(path)
    if p.is_dir():
        if (p / "scene.xml").is_file():
            return None
        if not (p / "summary.json").is_file():
            raise ParameterError(f"{p}: the folder holds neither scene.xml (a scene) nor summary.json (a finished "
                                 "render); give a scene (XML, built-in name, sionna:NAME) or a render's folder")
        p = p / "summary.json"
    elif p.suffix.lower() != ".json":
        return None
    try:
        summary = json.loads(p.read_text())
    except (OSError, ValueError) as exc:
        raise ParameterError(f"{p}: not a readable render summary ({exc}); give a render's summary.json "
                             "or its folder") from None
    if not isinstance(summary, dict) or "rays_per_order" not in summary:
        raise ParameterError(f"{p}: a JSON file but not a render's summary.json; give a render's folder, "
                             "or a scene (XML, built-in name, sionna:NAME)")
    return summary


def format_render(summary: dict) -> str:
    """Text lines of a render's ``summary.json`` (dict): scene, pulses, depth, trace seconds, and
    the energy and share of each bounce order with the depth warning."""
    settings = summary.get("settings") or {}
    trace = (summary.get("timings") or {}).get("trace")
    lines = [f"render of {summary.get('scene')}: {summary.get('n_pulses')} pulses, max_depth "
             f"{settings.get('max_depth', len(summary['rays_per_order']))}"
             + (f", trace {trace:.1f} s" if trace is not None else "")]
    orders = summary.get("energy_by_order")
    if not orders:
        lines.append("energy by bounce order: not in this summary.json (the exact range kernel does not measure it, "
                     "and summaries written before it was measured lack it); render again to measure it")
    else:
        lines.append(f"energy by bounce order ({orders['unit']}, range-compressed raw data; share of the orders' sum):")
        lines += [f"  order {d:>2}: {orders['energy'][d]:11.4e}  {100 * orders['share'][d]:6.2f} %"
                  for d in orders["energy"]]
    lines += format_depth(summary.get("depth"))
    if summary.get("depth_warning"):
        lines.append(f"warning: {summary['depth_warning']}")
    return "\n".join(lines) + "\n"
