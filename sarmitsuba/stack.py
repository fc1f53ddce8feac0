"""A tomographic stack in one call: N passes of one scene, each an ordinary render folder on one
ground grid (docs/physics.md (TS1); the guide's tomography page).

:func:`render_stack` plans the passes' track offsets (:func:`sarmitsuba.scene.baseline.stack_baselines`),
refuses baselines whose elevation ambiguity is shorter than the scene's height range, a render's
folder as the stack folder, and a stack whose files (:func:`stack_cost`, from the cost model's
estimate of one pass) would not fit on the output folder's file system, warns
(:class:`LargeStackWarning`) of one estimated at more than :data:`LARGE_STACK_SECONDS` or
:data:`LARGE_STACK_BYTES`, all before the first pass, then renders
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
import shutil
import time
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .stacks.tomo_products import STACK_FILE, TRUTH_FILE, pass_folder
from .core.outputs import OutputDirectory, atomic_savez, json_default
from .core.radar import ParameterError
from .scene.baseline import StackBaselines, stack_baselines

__all__ = ["StackPlan", "StackSummary", "StackCost", "LargeStackWarning", "plan_stack", "stack_cost", "render_stack",
           "render_pass", "LARGE_STACK_SECONDS", "LARGE_STACK_BYTES", "QUICKLOOK_BYTES", "EXR_PER_IMAGE"]

#: A stack estimated to render longer than this [s], or to write more than
#: :data:`LARGE_STACK_BYTES`, is announced by a :class:`LargeStackWarning` before its first pass.
LARGE_STACK_SECONDS = 600.0
LARGE_STACK_BYTES = 4 * 2**30
#: Bytes counted for each product's PNG quicklook, ``summary.json`` and the npz and EXR files' axes
#: and headers (urban's: 0.13 to 0.28 MiB, the 103 x 159-pixel image of three trihedrals' 0.1 MiB).
QUICKLOOK_BYTES = 2**19
#: ``image.exr`` holds three float32 channels (intensity, real, imag): 1.5 times ``image.npz``'s
#: complex64 pixels.
EXR_PER_IMAGE = 1.5


class LargeStackWarning(UserWarning):
    """A stack whose estimated time or disk is large (:data:`LARGE_STACK_SECONDS`,
    :data:`LARGE_STACK_BYTES`), announced before its first pass."""


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
class StackCost:
    """The estimated work and disk of a stack: ``passes`` renders of one scene
    (:func:`stack_cost`).

    Attributes
    ----------
    passes : int
    seconds_per_pass : float, s
        One render's trace and focusing (the cost model's ``trace_time_s + focus_time_s``,
        :class:`~sarmitsuba.analysis.cost.CostEstimate`: an idle 2-core machine, within a factor of 2).
    bytes_per_pass : int
        One render folder: per product, ``raw.npz`` (complex64 [pulses, fast-time samples]),
        ``image.npz`` (complex64 pixels), ``image.exr`` (three float32 channels) and
        :data:`QUICKLOOK_BYTES` for ``image.png`` and ``summary.json``.
    truth_bytes : int
        ``truth.npz``: float32 [n_az, n_rg, MAX_CROSSINGS] (0 without truth).
    """

    passes: int
    seconds_per_pass: float
    bytes_per_pass: int
    truth_bytes: int

    @property
    def seconds(self) -> float:
        """All passes' rendering, one after another [s]."""
        return self.passes * self.seconds_per_pass

    @property
    def bytes(self) -> int:
        """The stack folder's files [bytes]."""
        return self.passes * self.bytes_per_pass + self.truth_bytes


def stack_cost(cost: Any, passes: int, truth: bool = True) -> StackCost:
    """:class:`StackCost` of ``passes`` renders each of estimated ``cost`` (a
    :class:`~sarmitsuba.analysis.cost.CostEstimate`), with ``truth.npz`` when ``truth``."""
    from .products.elevation_truth import MAX_CROSSINGS
    pixels = int(cost.image_shape[0]) * int(cost.image_shape[1])
    per_product = cost.raw_bytes + cost.image_bytes * (1.0 + EXR_PER_IMAGE) + QUICKLOOK_BYTES
    return StackCost(passes=int(passes), seconds_per_pass=float(cost.trace_time_s + cost.focus_time_s),
                     bytes_per_pass=int(cost.n_products * per_product),
                     truth_bytes=pixels * MAX_CROSSINGS * 4 if truth else 0)


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
        Before any pass is traced and anything is written: a bad scene, parameter, stack
        description (fewer than 3 passes, aliasing baselines) or output folder (a render's
        folder; a file system without room for the stack's estimated files, :func:`stack_cost`).

    Warns
    -----
    LargeStackWarning
        Before the first pass, when the estimated time or disk is large.
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
    if loaded.settings.auto_depth:         # one depth for every pass (the reference track's probe): coherent passes
        from .tracing.driver.depth import choose_depth
        loaded = choose_depth(loaded)[0]
        integrator_overrides = {**(integrator_overrides or {}), "max_depth": loaded.settings.max_depth}
    if scheduler is not None:
        from .tracing.driver.distributed import check_scheduler
        check_scheduler(scheduler)
    _check_out(out_dir)
    _check_size(out_dir, stack_cost(_pass_cost(loaded), len(plan.baselines.perpendicular), truth))
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


def _pass_cost(loaded: Any) -> Any:
    """The cost model's estimate of one pass (:func:`sarmitsuba.analysis.cost.cost_estimate`);
    the acquisition's warnings are left to each pass's render."""
    from .analysis.cost import cost_estimate
    from .scene.planning import AcquisitionWarning
    from .tracing.driver.trace import prepare_trace
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AcquisitionWarning)
        setup = prepare_trace(loaded)
    return cost_estimate(loaded, setup.geometry, setup.window, setup.footprint, setup.effects)


def _check_out(out_dir: str | os.PathLike) -> None:
    """Refuse a render's folder as the stack folder: the passes would lie beside its files."""
    from .core.outputs import MANIFEST_FILE
    path = Path(out_dir)
    if not path.is_dir() or (path / STACK_FILE).is_file():
        return
    found = [name for name in (MANIFEST_FILE, "raw.npz", "image.npz") if (path / name).is_file()]
    if found:
        raise ParameterError(f"out_dir = {str(path)!r} is a render folder (it holds {', '.join(found)}): the "
                             f"stack's pass-00, pass-01, ..., {STACK_FILE} and {TRUTH_FILE} would lie beside its "
                             f"files; give the stack a folder of its own, e.g. "
                             f"{str(path.with_name(path.name + '-stack'))!r}")


def _check_size(out_dir: str | os.PathLike, cost: StackCost) -> None:
    """Refuse a stack whose files do not fit on the output folder's file system; warn of a large one."""
    from .analysis.cost import format_bytes
    where = Path(out_dir).absolute()
    while not where.exists():
        where = where.parent
    free = shutil.disk_usage(where).free
    what = (f"about {format_bytes(cost.bytes)} ({cost.passes} passes x {format_bytes(cost.bytes_per_pass)}: raw data "
            f"and images{', and ' + format_bytes(cost.truth_bytes) + ' of truth' if cost.truth_bytes else ''})")
    if cost.bytes > free:
        fit = max(0, (free - cost.truth_bytes) // max(cost.bytes_per_pass, 1))
        raise ParameterError(f"out_dir = {str(out_dir)!r}: the stack would write {what}, but the file system of "
                             f"{where} has {format_bytes(free)} free: render at most {fit} passes there, fewer "
                             "pulses, or give a folder on a disk with more room")
    if cost.seconds > LARGE_STACK_SECONDS or cost.bytes > LARGE_STACK_BYTES:
        minutes = cost.seconds / 60.0
        warnings.warn(f"a large stack: {cost.passes} passes, about {cost.seconds:,.0f} s ({minutes:,.0f} min; "
                      f"{cost.seconds_per_pass:.1f} s a pass, one after another, by the cost model for an idle 2-core "
                      f"machine) and {what} written to {out_dir} ({format_bytes(free)} free); `info` with the same "
                      "options gives both before anything starts", LargeStackWarning, stacklevel=3)


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
