"""A tomographic stack in one call: N passes of one scene, each an ordinary render folder on one
ground grid (docs/physics.md (TS1); the guide's tomography page).

:func:`render_stack` plans the passes' track offsets (:func:`sarmitsuba.scene.baseline.stack_baselines`),
refuses baselines whose elevation ambiguity is shorter than the scene's height range, renders
every pass with :func:`sarmitsuba.pipeline.render` (in this process or, with ``scheduler``, as
one Dask task a pass) into ``OUT/pass-00``, ``OUT/pass-01``, ..., and writes last

* ``stack.json``: the passes (folder, track offset, perpendicular baseline), the reference pass,
  ``rho_s``, the ambiguity, the elevation interval to invert and the seconds each pass took;
* ``truth.npz``: ``heights`` float32 [n_az, n_rg, K], the heights above the grid plane at which
  each pixel's iso-range circle meets geometry the reference pass sees
  (:func:`sarmitsuba.products.elevation_truth.iso_range_heights`), NaN-padded.

The grid depends only on the scene and the track's direction, so every pass focuses onto the same
pixels; the clutter is fixed to the surfaces, so each pass sees the same speckle. A folder
without ``stack.json`` is not a finished stack.
"""
from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .stacks.tomo_products import STACK_FILE, TRUTH_FILE, pass_folder
from .core.outputs import OutputDirectory, atomic_savez, json_default
from .core.radar import ParameterError
from .scene.baseline import StackBaselines, stack_baselines

__all__ = ["StackPlan", "StackSummary", "plan_stack", "render_stack", "render_pass"]


@dataclass(frozen=True)
class StackPlan:
    """The passes of a stack and the elevations they can map.

    Attributes
    ----------
    baselines : StackBaselines
    interval : (float, float), m
        Elevations ``s`` to invert: the scene's heights above the grid plane, ``h / sin(theta)``,
        widened by up to ``rho_s`` each side within the ambiguity.
    heights : (float, float), m
        The scene's lowest and highest point above the grid plane.
    """

    baselines: StackBaselines
    interval: tuple[float, float]
    heights: tuple[float, float]


def plan_stack(loaded: Any, **description: Any) -> StackPlan:
    """The plan of a stack of ``loaded`` (a :class:`~sarmitsuba.scene.loader.LoadedScene`):
    ``description`` as :func:`~sarmitsuba.scene.baseline.stack_baselines` (``track_offsets``,
    ``baselines``, or ``span`` with ``count``, ``spacing``, ``seed``).

    Raises
    ------
    ParameterError
        A bad description, or baselines that alias the scene: its elevation extent
        ``(h_max - h_min) / sin(theta)`` reaches the ambiguity ``lambda R / (2 d_b)`` (naming both and
        the largest mean spacing that would do).
    """
    b = stack_baselines(loaded.params, **description)
    z0 = float(loaded.params.scene_center[2])
    heights = (min(0.0, float(loaded.bbox_lo[2]) - z0), max(0.0, float(loaded.bbox_hi[2]) - z0))
    sin_theta = math.sin(math.radians(b.incidence))
    extent = (heights[1] - heights[0]) / sin_theta
    if extent >= b.elevation_ambiguity:
        largest = b.wavelength * b.slant_range / (2.0 * extent)
        raise ParameterError(
            f"the stack's baselines alias the scene: its heights span {heights[1] - heights[0]:.2f} m, "
            f"{extent:.2f} m of elevation at {b.incidence:g} deg incidence, but a mean baseline spacing of "
            f"{b.mean_spacing:.3f} m repeats elevation every {b.elevation_ambiguity:.2f} m (lambda R / (2 d_b)): "
            f"space the passes at most {largest:.3f} m apart (more passes, or a smaller span)")
    margin = min(b.elevation_resolution, 0.5 * (b.elevation_ambiguity - extent))
    return StackPlan(baselines=b, interval=(heights[0] / sin_theta - margin, heights[1] / sin_theta + margin),
                     heights=heights)


@dataclass(frozen=True)
class StackSummary:
    """What :func:`render_stack` wrote: ``path`` (the stack folder), ``plan``, ``seconds_per_pass``
    (each pass's render, s), ``truth_seconds`` and ``seconds`` (all of it)."""

    path: Path
    plan: StackPlan
    seconds_per_pass: tuple[float, ...]
    truth_seconds: float
    seconds: float

    def line(self) -> str:
        """One-line summary for the CLI."""
        b = self.plan.baselines
        return (f"stack of {len(b.perpendicular)} passes over {b.span:.2f} m of perpendicular baseline: rho_s "
                f"{b.elevation_resolution:.2f} m, ambiguity {b.elevation_ambiguity:.1f} m; {self.seconds:.1f} s "
                f"({np.mean(self.seconds_per_pass):.1f} s a pass, truth {self.truth_seconds:.1f} s) -> {self.path}")


def render_pass(source: Any, folder: str | os.PathLike, options: Mapping[str, Any]) -> float:
    """Render one pass (:func:`sarmitsuba.pipeline.render` with ``options``) into ``folder``;
    returns its seconds. A module-level function, so that Dask workers can run it."""
    from .pipeline import render
    start = time.perf_counter()
    render(source, folder, **options)
    return time.perf_counter() - start


def render_stack(source: Any, out_dir: str | os.PathLike, *, sensor_overrides: Mapping[str, Any] | None = None,
                 integrator_overrides: Mapping[str, Any] | None = None,
                 material_overrides: Mapping[str, Any] | None = None, progress: bool = True,
                 scheduler: str | None = None, truth: bool = True, **description: Any) -> StackSummary:
    """Render a tomographic stack (module docstring).

    Parameters
    ----------
    source : str or sarmitsuba.Scene or None
        As :func:`sarmitsuba.pipeline.render` (a Python Scene only without ``scheduler``).
    out_dir : path
        The stack folder.
    sensor_overrides, integrator_overrides, material_overrides : mapping, optional
        As :func:`sarmitsuba.pipeline.render`, for every pass; ``track_offset`` is the stack's.
    progress : bool
        A tqdm bar over the passes.
    scheduler : str, optional
        ``"local"`` or ``"tcp://HOST:PORT"``: one Dask task a pass (the passes are independent).
    truth : bool, default True
        Write ``truth.npz``.
    **description
        The passes: ``track_offsets``, ``baselines``, or ``span`` and ``count`` (with ``spacing``
        and ``seed``), as :func:`sarmitsuba.scene.baseline.stack_baselines`.

    Returns
    -------
    StackSummary

    Raises
    ------
    SceneError, ParameterError, MaterialError, OSError
        Before any pass is traced: a bad scene, parameter, stack description (fewer than 3 passes,
        aliasing baselines) or output folder.
    """
    from tqdm.auto import tqdm

    from .scene.loader import load_scene
    start = time.perf_counter()
    sensor = dict(sensor_overrides or {})
    if "track_offset" in sensor:
        raise ParameterError("track_offset is set by the stack for each pass: give the passes as track_offsets, "
                             "baselines, or span and count instead")
    loaded = load_scene(source, sensor, integrator_overrides, material_overrides)
    plan = plan_stack(loaded, **description)
    if scheduler is not None:
        from .tracing.driver.distributed import check_scheduler
        check_scheduler(scheduler)
    offsets = plan.baselines.track_offsets
    options = [dict(sensor_overrides={**sensor, "track_offset": tuple(float(v) for v in o)},
                    integrator_overrides=integrator_overrides, material_overrides=material_overrides,
                    progress=False) for o in offsets]
    with OutputDirectory(out_dir, products=None) as out:
        folders = [out.path / pass_folder(n) for n in range(len(offsets))]
        if scheduler is None:
            seconds = [render_pass(source, f, o) for f, o in tqdm(list(zip(folders, options)), desc="stack",
                                                                  unit="pass", disable=not progress)]
        else:
            seconds = _on_cluster(scheduler, source, folders, options, progress)
        t_truth = time.perf_counter()
        if truth:
            out.write(TRUTH_FILE, lambda path: _write_truth(path, source, sensor, integrator_overrides,
                                                            material_overrides, plan, folders))
        t_truth = time.perf_counter() - t_truth
        summary = StackSummary(path=out.path, plan=plan, seconds_per_pass=tuple(seconds), truth_seconds=t_truth,
                               seconds=time.perf_counter() - start)
        out.write(STACK_FILE, lambda path: path.write_text(json.dumps(_description(summary, loaded, truth), indent=2,
                                                                      default=json_default)))
    return summary


def _on_cluster(scheduler: str, source: Any, folders: list[Path], options: list[dict], progress: bool) -> list[float]:
    """Each pass as one Dask task; their seconds in pass order."""
    from tqdm.auto import tqdm

    from .tracing.driver.distributed import connect
    with connect(scheduler) as client:
        from distributed import as_completed
        futures = [client.submit(render_pass, source, str(f), o, pure=False) for f, o in zip(folders, options)]
        for _ in tqdm(as_completed(futures), total=len(futures), desc="stack", unit="pass", disable=not progress):
            pass
        return [float(f.result()) for f in futures]


def _write_truth(path: Path, source: Any, sensor: dict, integrator: Any, materials: Any, plan: StackPlan,
                 folders: list[Path]) -> None:
    """``truth.npz`` of the reference pass (module docstring)."""
    from .core.image import SarImage
    from .products.elevation_truth import iso_range_heights
    from .scene.loader import load_scene
    ref = plan.baselines.reference
    offset = tuple(float(v) for v in plan.baselines.track_offsets[ref])
    loaded = load_scene(source, {**sensor, "track_offset": offset}, integrator, materials)
    image = SarImage.load(folders[ref] / "image.npz")
    heights = iso_range_heights(loaded, image).astype(np.float32)
    atomic_savez(path, heights=heights, reference=np.int64(ref))


def _description(summary: StackSummary, loaded: Any, truth: bool) -> dict:
    """The body of ``stack.json``."""
    plan, b = summary.plan, summary.plan.baselines
    return {"passes": [{"folder": pass_folder(n), "track_offset": o.tolist(), "perpendicular_baseline": float(p),
                        "seconds": s}
                       for n, (o, p, s) in enumerate(zip(b.track_offsets, b.perpendicular, summary.seconds_per_pass))],
            "reference": b.reference, "span": b.span, "mean_spacing": b.mean_spacing,
            "elevation_resolution": b.elevation_resolution, "elevation_ambiguity": b.elevation_ambiguity,
            "slant_range": b.slant_range, "wavelength": b.wavelength, "incidence": b.incidence,
            "elevation_interval": list(plan.interval), "heights": list(plan.heights),
            "scene": str(loaded.source), "truth": TRUTH_FILE if truth else None,
            "seconds": summary.seconds, "truth_seconds": summary.truth_seconds}
