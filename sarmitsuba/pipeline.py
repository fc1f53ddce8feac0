"""The render pipeline: scene -> trace -> raw data -> focus -> products (docs/design.md section 2)."""
from __future__ import annotations

import dataclasses
import json
import os
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .signal import binning
from .scene import planning
from .products import image_files
from .analysis.ambiguities import ambiguities
from .analysis.memory import available_memory, check_memory
from .analysis.scatterers import build_catalogue, check_selection
from .products.scatterer_files import CATALOGUE_FILES, Catalogue, write_catalogue_files
from .focus import backproject, ffbp
from .focus.dispatch import azimuth_pattern, backprojector, compressed_for_focus, focus_windows
from .focus.dispatch import focus as focus_by_name
from .focus.scene_grid import image_grid, sized_grid
from .core.image import SarImage
from .core.outputs import OutputDirectory, check_output_dir, json_default
from .core.radar import POLARIZATIONS, ParameterError
from .core.geometry import AcquisitionGeometry
from .core.raw import RawData
from .scene.loader import LoadedScene, load_scene
from .formats.exports import EXPORT_FILES, check_formats, write_exports
from .tracing.driver.depth import DepthChoice, choose_depth, depth_summary
from .tracing.driver.trace import TraceResult, prepare_trace, trace
from .tracing.driver.workers import plan_for, trace_in_workers

__all__ = ["Simulation", "simulate", "RenderSummary", "render", "refocus", "image_grid", "check_output_dir",
           "OUTPUT_FILES", "EXPORT_FILES", "check_formats", "write_exports"]

#: Files written by :func:`render`, by role.
OUTPUT_FILES = {"raw": "raw.npz", "image": "image.npz", "exr": "image.exr", "png": "image.png",
                "summary": "summary.json", "pauli": "pauli.png", "ati": "ati.npz", "dpca": "dpca.npz",
                "ati_png": "ati.png", "scatterers_csv": "scatterers.csv", "scatterers_geojson": "scatterers.geojson",
                "scatterers_png": "fig_scatterers.png"}


@dataclass(frozen=True)
class RenderSummary:
    """What a render did: timings [s] per stage, counts, energy per bounce order [m^2], outputs."""

    scene: str
    timings: dict
    n_pulses: int
    rays_traced: int
    rays_per_order: list
    shadow_rays: int
    energy_per_order: list
    energy_outside_window: float
    raw_shape: tuple
    image_shape: tuple
    outputs: dict
    pulses_per_trace: int = 1
    pulse_paths: int = 0
    #: The trace's seconds by stage of the mesh tracer (:data:`sarmitsuba.tracing.driver.stages.STAGES`).
    trace_stages: dict = dataclasses.field(default_factory=dict)
    #: The same by bounce order, ``{order: {stage: seconds}}`` (orders from 1; ``deposit`` only above).
    trace_stages_by_order: dict = dataclasses.field(default_factory=dict)
    #: Each bounce order's energy and share (:func:`sarmitsuba.analysis.orders.energy_by_order`; None:
    #: not measured) and the warning when the deepest one holds much (:func:`~sarmitsuba.analysis.orders.depth_warning`).
    energy_by_order: dict | None = None
    depth_warning: str | None = None
    #: Rows a fused geometry kernel left to its NumPy reference (``geometry = fused``,
    #: docs/design.md section 10.1).
    overflow_rows: int = 0
    #: Processes that traced, and why that many (:func:`sarmitsuba.tracing.driver.workers.worker_plan`).
    workers: int = 1
    workers_note: str = ""
    #: The depth traced and how it was chosen (:func:`depth_summary`): ``mode`` (``auto`` or ``fixed``),
    #: ``depth``; with ``auto`` the reason, the probe's shares and predicted seconds per order, and
    #: ``beyond_db``, the probe's share of the energy in the orders left out; ``seconds_by_order``
    #: the trace's own.
    depth: dict = dataclasses.field(default_factory=dict)
    #: ``--scatterers``: the catalogue's ``count``, ``listed_share``, ``selection`` and ``line``; else empty.
    scatterers: dict = dataclasses.field(default_factory=dict)

    @property
    def pulse_paths_per_second(self) -> float:
        """Returns evaluated per second of tracing: PO terms times their pulses plus clutter
        scatterers, over the trace time (docs/physics.md (T3))."""
        return self.pulse_paths / max(self.timings.get("trace", 0.0), 1e-9)

    def line(self) -> str:
        """One-line summary for the end of a run."""
        depth = self.depth or {}
        how = (f" (auto, {depth['reason']})" if depth.get("mode") == "auto" else "") if depth else ""
        return (f"rendered {self.scene}: {self.timings['total']:.1f} s (trace {self.timings['trace']:.1f} s, "
                f"focus {self.timings['focus']:.1f} s), {self.n_pulses} pulses, "
                + (f"depth {depth['depth']}{how}, " if depth else "") + f"{self.rays_traced:,} rays cast "
                f"({self.pulses_per_trace} pulses per trace), {self.pulse_paths_per_second:.3g} pulse-paths/s, "
                f"raw {self.raw_shape[0]}x{self.raw_shape[1]}, image {self.image_shape[0]}x{self.image_shape[1]} "
                f"-> {Path(next(iter(self.outputs.values()))).parent}")


@dataclass(frozen=True)
class Simulation:
    """Everything one simulation produced, in memory (see :func:`simulate`).

    With ``polarization = quad`` every channel has its own raw data and image on one image grid:
    :attr:`channels` maps ``"HH"``, ``"HV"``, ``"VH"``, ``"VV"`` to a one-channel Simulation each,
    and :attr:`raw` and :attr:`image` are the HH channel's."""

    loaded: LoadedScene
    raw: RawData
    image: SarImage
    trace: TraceResult
    timings: dict
    #: Raw data and images of each bounce order (1, 2, ...) when ``split_bounces`` is on.
    raw_per_order: tuple = ()
    images_per_order: tuple = ()
    #: ``quad``: one Simulation per channel (:data:`sarmitsuba.core.radar.CHANNELS`); else empty.
    channels: Mapping[str, "Simulation"] = dataclasses.field(default_factory=dict)
    #: Sensor ``ati_baseline`` > 0: the trailing channel's Simulation (its raw data and image on
    #: this one's grid, docs/physics.md (V6)); else None.
    aft: "Simulation | None" = None
    #: ``max_depth = auto``: the depth chosen and the probe's evidence; None for a fixed depth.
    depth: "DepthChoice | None" = None
    #: ``scatterers``: the scatterer catalogue (:func:`sarmitsuba.analysis.scatterers.build_catalogue`); else None.
    scatterers: "Catalogue | None" = None

    def summary(self) -> str:
        """One line: scene, pulses, raw and image sizes, trace and focus seconds, and the azimuth
        ambiguity-to-signal ratio at the PRF for the image's azimuth window (docs/physics.md (AMB1))."""
        p = self.loaded.params
        window = dict(self.image.metadata.get("focus", {}).get("window_azimuth") or {"name": "taylor"})
        amb = ambiguities(p, (window.pop("name"), window))
        ghosts = ""
        if amb is not None:
            advice = f"; raise the PRF above {amb.prf_min_aasr_hz:.0f} Hz" if amb.warning else ""
            ghosts = (" AASR none;" if amb.aasr_db is None else f" AASR {amb.aasr_db:.1f} dB (ghosts at "
                      f"+-{p.prf * p.wavelength * p.slant_range / (2 * p.velocity):.1f} m along track at the centre"
                      f"{advice});")
        depth = self.loaded.settings.max_depth
        how = f"depth {depth}" + (f" (auto: {self.depth.reason})" if self.depth is not None else "")
        return (f"simulated {self.loaded.source}: {p.n_pulses} pulses at prf {p.prf:g} Hz, {how}, "
                f"raw {self.raw.data.shape[0]}x{self.raw.data.shape[1]}, image {self.image.data.shape[0]}x{self.image.data.shape[1]};{ghosts} trace "
                f"{self.timings['trace']:.1f} s, focus {self.timings['focus']:.1f} s")


def simulate(source: str | None, *, sensor_overrides: Mapping[str, Any] | None = None,
             integrator_overrides: Mapping[str, Any] | None = None,
             material_overrides: Mapping[str, Any] | None = None, progress: bool = False,
             image_size: tuple[int, int] | None = None, image_spacing: float | None = None,
             window: Any = "taylor", focuser: str = "ffbp", scheduler: str | None = None,
             window_range: Any = None, window_azimuth: Any = None, formats: Sequence[str] = (),
             cphd_domain: str = "toa", scatterers: bool = False, scatterers_share: float = 0.9,
             scatterers_db: float | None = None) -> Simulation:
    """Load, trace, bin and focus a scene, in memory (no files written).

    Parameters are those of :func:`render` (``window``, ``window_range``, ``window_azimuth`` and
    ``focuser`` included), plus
    ``image_size = (n_azimuth, n_range)`` pixels and ``image_spacing`` [m] for a ground grid of
    exactly that size around the scene centre (:func:`sized_grid`; default: :func:`image_grid`,
    which covers the scene and its layover). ``scheduler`` (``"local"`` or ``"tcp://HOST:PORT"``)
    traces the pulse batches on Dask workers (:func:`sarmitsuba.tracing.driver.distributed.trace_on_cluster`).
    ``formats``: those :func:`render` will write, in ``cphd_domain``, checked against the sensor
    (:func:`check_formats`). ``scatterers``: also build the scatterer catalogue
    (``Simulation.scatterers``; the strongest holding ``scatterers_share`` of the image's RCS, or all
    within ``-scatterers_db`` dB of the strongest, :func:`sarmitsuba.analysis.scatterers.build_catalogue`).
    Raises SceneError, ParameterError or materials.MaterialError before tracing starts.
    """
    t = {"start": time.perf_counter()}
    range_window, azimuth_window = focus_windows(window, window_range, window_azimuth)   # checked before loading
    focus_with = _focuser(focuser)
    if scatterers and check_selection(scatterers_share, scatterers_db):      # checked before loading
        integrator_overrides = {**(integrator_overrides or {}), "scatterers": True}
    loaded = load_scene(source, sensor_overrides, integrator_overrides, material_overrides)
    scatterers = scatterers or loaded.settings.scatterers          # the scene's own sbr switch too
    check_formats(formats, params=loaded.params, cphd_domain=cphd_domain)
    loaded, depth, setup = _depth_and_setup(loaded)    # max_depth = auto: (DEP1)-(DEP3)
    params, settings = loaded.params, loaded.settings
    amb = ambiguities(params, azimuth_window)           # the ghosts `info` warns about, before they are traced
    if amb is not None and amb.warning:
        warnings.warn(amb.warning, planning.AcquisitionWarning, stacklevel=2)
    geometry, window, footprint, effects = setup.geometry, setup.window, setup.footprint, setup.effects
    cost = check_memory(loaded, geometry, window, footprint, effects=effects)      # peak memory, before tracing
    grid = image_grid(loaded, geometry) if image_size is None else sized_grid(params, geometry, image_size, image_spacing)
    grid = dataclasses.replace(grid, origin=grid.origin + loaded.offset)      # checked before tracing
    t["load"] = time.perf_counter()
    # other processes load the scene again: with the depth chosen here
    spec = (source, sensor_overrides, {**(integrator_overrides or {}), "max_depth": settings.max_depth},
            material_overrides)
    if scheduler is None:                                # every core: docs/design.md section 11.1
        cores = plan_for(spec, loaded, effects, cost, available_memory())
        if cores.workers > 1:
            result = trace_in_workers(spec, loaded, setup, cores.workers, progress=progress)
        else:
            result = trace(loaded.scene, params, geometry, window, footprint, settings, setup.table, progress=progress,
                           effects=effects)
        result = dataclasses.replace(result, workers_note=cores.reason)
    else:
        from .tracing.driver.distributed import trace_on_cluster
        result = trace_on_cluster(scheduler, spec, loaded, setup, progress=progress)
    t["trace"] = time.perf_counter()
    planning.check_window_energy(result.energy_outside_window, float(np.sum(result.energy_per_order)),
                                 settings.max_depth)
    metadata = _metadata(loaded, footprint.spacing_azimuth, result, effects)
    metadata["depth"] = depth_summary(depth, result)
    world = _shifted(geometry, loaded.offset)            # outputs in the world frame (float64)
    beam = params.traced_beamwidth if params.mode == "stripmap" else None   # spotlight: every pulse sees the patch
    pattern = azimuth_pattern(params)
    focus = lambda r, desc: _calibrated(focus_with(  # noqa: E731
        compressed_for_focus(r, range_window), grid, azimuth_beamwidth=beam, squint=params.squint, azimuth_pattern=pattern,
        window_azimuth=azimuth_window, progress=progress, desc=desc), params, world)
    products, spent = {}, {"bin": 0.0, "focus": 0.0}
    for name in params.channels:                         # one trace, then each channel's raw data and images
        channel = result.channel(name)
        meta = {**metadata, "polarization": name}
        label = f" {name}" if result.channels else ""
        raw = binning.to_raw_data(channel.contributions(), channel, window, params, world, meta,
                                  noise_seed=settings.seed + (POLARIZATIONS.index(name) << 32))
        per_order = tuple(
            binning.to_raw_data(channel.contributions(k), channel, window, params, world,
                                {**meta, "bounce_order": k}) for k in range(1, channel.n_orders + 1))
        binned = time.perf_counter()
        image = focus(raw, f"focus{label} all orders" if per_order else f"focus{label}")   # progress bar labels
        images = tuple(focus(r, f"focus{label} order {k}") for k, r in enumerate(per_order, start=1))
        spent["bin"] += binned - t["trace"] - spent["bin"] - spent["focus"]
        spent["focus"] += time.perf_counter() - binned
        products[name] = (raw, image, channel, per_order, images)
    timings = {"load": t["load"] - t["start"] - (depth.probe_seconds if depth is not None else 0.0),
               **({"depth_probe": depth.probe_seconds} if depth is not None else {}),
               "trace": t["trace"] - t["load"], **spent}
    if not result.channels:
        raw, image, _, per_order, images = products[params.polarization]
        aft = None
        if params.ati_baseline > 0:        # (V6): the trailing phase centre, traced and focused alike
            trailing = geometry.trailing(params.ati_baseline)
            aft_result = trace(loaded.scene, params, trailing, window, footprint, settings, setup.table,
                               progress=progress, effects=effects)
            aft_raw = binning.to_raw_data(aft_result.contributions(), aft_result, window, params,
                                          _shifted(trailing, loaded.offset), {**metadata, "ati_channel": "aft"},
                                          noise_seed=settings.seed + (1 << 40))
            aft = Simulation(loaded, aft_raw, focus(aft_raw, "focus aft"), aft_result, timings)
        sim = Simulation(loaded, raw, image, result, timings, per_order, images, aft=aft, depth=depth)
    else:
        channels = {name: Simulation(loaded, raw, image, channel, timings, per_order, images, depth=depth)
                    for name, (raw, image, channel, per_order, images) in products.items()}
        sim = dataclasses.replace(channels["HH"], trace=result, channels=channels)
    return dataclasses.replace(sim, scatterers=build_catalogue(sim, scatterers_share, scatterers_db)) \
        if scatterers else sim


def _depth_and_setup(loaded: LoadedScene):
    """(``loaded`` with its depth chosen, the choice or None, its trace setup); with ``auto`` the
    real track's checks, warnings and memory come first, once (:func:`choose_depth`)."""
    if auto := loaded.settings.auto_depth:
        first = prepare_trace(loaded)
        check_memory(loaded, first.geometry, first.window, first.footprint, effects=first.effects)
    loaded, depth = choose_depth(loaded)
    with warnings.catch_warnings():
        if auto:
            warnings.simplefilter("ignore")
        return loaded, depth, prepare_trace(loaded)


#: Focusers of :func:`simulate` / :func:`render`: fast factorised backprojection (the default) and
#: direct backprojection, its reference.
FOCUSERS = {"ffbp": ffbp, "bp": backproject}


def _focuser(name: str):
    """The backprojection of ``focuser``; ParameterError naming it for anything else. ``ffbp`` (bistatic data
    too, (F10)) hands what it does not factorise (a grid straddling the track) to direct backprojection,
    and says so in ``metadata["focus"]["fallback"]``."""
    if name not in FOCUSERS:
        raise ParameterError(f"focuser = {name!r}; valid: {', '.join(FOCUSERS)} (ffbp: fast factorised "
                             "backprojection, the default; bp: direct backprojection, its reference)")
    return backprojector(name)


def _shifted(geometry: AcquisitionGeometry, offset: np.ndarray) -> AcquisitionGeometry:
    """The same acquisition in the world frame (scenes far from the origin are traced locally)."""
    if not np.any(offset):
        return geometry
    return geometry.shifted(offset)


def _calibrated(image: SarImage, params, geometry: AcquisitionGeometry) -> SarImage:
    """In absolute radiometry, divide by the radar equation per pixel so the image is in sqrt(m^2)."""
    from .scene.radar_equation import radar_equation
    from .signal.radiometry import calibrate_image
    equation = radar_equation(params)
    if equation is None:
        return image
    mid = geometry.positions[len(geometry.positions) // 2]
    data = calibrate_image(image.data, image.positions(), mid, geometry.track_direction, equation)
    meta = {**image.metadata, "units": "sqrt(m^2) (calibrated from absolute radiometry)",
            "calibration": {"radar_constant_w_m2": equation.constant, "time_bandwidth": equation.time_bandwidth,
                            "noise_power_w": equation.noise_power}}
    return dataclasses.replace(image, data=data, metadata=meta)


def render(source: str | None, out_dir: str | os.PathLike, *, sensor_overrides: Mapping[str, Any] | None = None,
           integrator_overrides: Mapping[str, Any] | None = None,
           material_overrides: Mapping[str, Any] | None = None, progress: bool = True,
           window: Any = "taylor", focuser: str = "ffbp", formats: Sequence[str] = (),
           scheduler: str | None = None, window_range: Any = None, window_azimuth: Any = None,
           geotiff_north_up: bool = True, sicd_plane: str = "slant", sicd_weighting: str = "uniform",
           cphd_domain: str = "toa", scatterers: Mapping[str, Any] | None = None) -> RenderSummary:
    """Render a scene into raw data and a focused ground-range image, and write the products.

    Parameters
    ----------
    source : str or sarmitsuba.Scene or None
        XML path, built-in scene name, ``sionna:NAME`` or a scene built in Python
        (:class:`sarmitsuba.Scene`); None = built-in ``urban``.
    out_dir : path
        Output directory; receives :data:`OUTPUT_FILES`. Checked for writing before tracing.
        The render owns its products: the files an earlier render there listed in its
        ``summary.json`` (``"files"``) that this one does not write are removed when its files
        are moved into place; other files stay (:mod:`sarmitsuba.core.outputs`, "Products").
    sensor_overrides, integrator_overrides : mapping, optional
        Parameter values replacing the scene's ``sar`` sensor / ``sbr`` integrator ones.
    material_overrides : mapping, optional
        Roughness for every material (``gamma_db`` or ``scattering_coefficient``).
    progress : bool
        Show tqdm progress bars.
    window : str or (str, dict), default "taylor"
        Focusing window, applied in range (over the band, to the range-compressed data) and in
        azimuth (over the traced beam's along-track sines, in backprojection): a name of
        :mod:`sarmitsuba.focus.windows` (Taylor: nbar 4, -35 dB sidelobes; ``"rect"`` for
        none: the sinc impulse response with -13 dB sidelobes), or ``(name, {params})``. The
        image keeps unit peak gain for a point target; the window is recorded in
        ``image.metadata["focus"]`` (``window``, ``window_range``, ``window_azimuth``), which
        :mod:`sarmitsuba.analysis.point_target` reads to turn integrated energy into RCS.
        :func:`refocus` (the ``focus`` command) has the same default, so refocusing the raw
        data with ``ffbp`` gives this image again.
    window_range, window_azimuth : str or (str, dict), optional
        The window of one axis, when it differs from ``window`` (default: ``window``).
    focuser : {"ffbp", "bp"}, default "ffbp"
        Fast factorised backprojection (:func:`sarmitsuba.focus.ffbp`; exact for any track, its
        interpolation error measured in ``benchmarks/ffbp.py``: -33 dB NRMSE against direct
        backprojection on Munich) or direct backprojection (:func:`sarmitsuba.focus.backproject`,
        the reference, about 10 times slower on a city).
    formats : sequence of {"cphd", "sicd", "geotiff"}
        Standard-format files written beside the npz products (:data:`EXPORT_FILES`; per channel
        with a ``_XX`` suffix in quad-pol), placed on the WGS84 ellipsoid by the sensor's
        ``geo_origin`` (:mod:`sarmitsuba.core.georef`).
    geotiff_north_up : bool, default True
        GeoTIFF resampled onto a north-up UTM grid; False: the image's own grid with a rotated
        geotransform (:func:`sarmitsuba.formats.geotiff.write_geotiff`).
    sicd_plane : {"slant", "image"}, default "slant"
        The SICD's grid: the slant plane at the SCP, as producers write it, or the image's own
        (ground) plane (``plane`` of :func:`sarmitsuba.formats.sicd.write_sicd`).
    sicd_weighting : {"uniform", "image"}, default "uniform"
        The SICD's spectral weighting: the focusing weighting divided out, so that every reader's
        RCS agrees (docs/physics.md (K3')), or the image's own (``weighting`` of ``write_sicd``).
    cphd_domain : {"toa", "fx"}, default "toa"
        The CPHD's signal domain: time of arrival (the range-compressed fast-time samples,
        docs/physics.md (GEO2)) or frequency (their Fourier transform along fast time, (GEO2'),
        the form vendors deliver and FastSAR reads); ``fx`` needs range-compressed data
        (``output = "compressed"``, the default) (``domain`` of :func:`sarmitsuba.formats.cphd.write_cphd`).
    scheduler : str, optional
        ``"local"`` (a Dask ``LocalCluster`` of processes) or ``"tcp://HOST:PORT"`` (an existing
        Dask scheduler): trace the pulse batches on Dask workers (:mod:`sarmitsuba.tracing.driver.distributed`).
        None: in this process.
    scatterers : mapping, optional
        Write the scatterer catalogue too (``scatterers.csv``, ``scatterers.geojson``,
        ``fig_scatterers.png``): ``{"scatterers": True}`` plus ``scatterers_share`` or
        ``scatterers_db`` (those of :func:`simulate`). None: no catalogue.

    Returns
    -------
    RenderSummary
        Also written to ``out_dir/summary.json``, with ``"files"``: the names of every file
        the render wrote there.

    Raises
    ------
    SceneError, ParameterError, materials.MaterialError, OSError
        Before tracing starts, for a bad scene, parameter, window, material or output directory.
    """
    start = time.perf_counter()
    focus_windows(window, window_range, window_azimuth)
    _focuser(focuser)
    if scatterers:
        check_selection(scatterers.get("scatterers_share", 0.9), scatterers.get("scatterers_db"))
    check_formats(formats, sicd_plane, sicd_weighting, cphd_domain=cphd_domain)
    if scheduler is not None:
        from .tracing.driver.distributed import check_scheduler
        check_scheduler(scheduler)
    with OutputDirectory(out_dir, products="replace") as out:     # all files appear at the end, or none;
        # an earlier render's files that this one does not write go then (core/outputs.py, "Products")
        sim = simulate(source, sensor_overrides=sensor_overrides, integrator_overrides=integrator_overrides,
                       material_overrides=material_overrides, progress=progress, window=window, focuser=focuser,
                       scheduler=scheduler, window_range=window_range, window_azimuth=window_azimuth, formats=formats,
                       cphd_domain=cphd_domain, **(scatterers or {}))
        t_products = time.perf_counter()
        paths = {}
        for name, channel in (sim.channels or {"": sim}).items():      # quad: raw_HH.npz, image_HH.npz, ...
            label = f"_{name}" if name else ""
            paths.update(_write_products(out, channel.raw, channel.image, sim.loaded.params, suffix=label))
            paths.update(write_exports(out, channel.raw, channel.image, formats, suffix=label,
                                       geotiff_north_up=geotiff_north_up, sicd_plane=sicd_plane,
                                       sicd_weighting=sicd_weighting, cphd_domain=cphd_domain))
            for k, (raw_k, image_k) in enumerate(zip(channel.raw_per_order, channel.images_per_order), start=1):
                paths.update(_write_products(out, raw_k, image_k, sim.loaded.params, suffix=f"{label}_order{k}"))
        if sim.channels:
            paths["pauli"] = _write_pauli(out, sim)
        if sim.aft is not None:                     # (V6), (V7): the trailing channel, ATI and DPCA
            paths.update(_write_products(out, sim.aft.raw, sim.aft.image, sim.loaded.params, suffix="_aft"))
            paths.update(write_exports(out, sim.aft.raw, sim.aft.image, formats, suffix="_aft",
                                       geotiff_north_up=geotiff_north_up, sicd_plane=sicd_plane,
                                       sicd_weighting=sicd_weighting, cphd_domain=cphd_domain))
            paths.update(_write_along_track(out, sim))
        if sim.scatterers is not None:
            paths.update(write_catalogue_files(out, {k: OUTPUT_FILES[k] for k in CATALOGUE_FILES}, sim.image,
                                               sim.scatterers, sim.loaded, str(sim.raw.metadata["scene"])))
        summary = _summary(sim, paths, start, t_products)
        out.write(OUTPUT_FILES["summary"], lambda path: _write_summary(path, summary, sim.raw.metadata))
    return summary


def _write_pauli(out: OutputDirectory, sim: Simulation) -> Path:
    """``pauli.png`` of a quad-pol simulation: |HH - VV| red, |HV + VH| green, |HH + VV| blue."""
    from .products.figures_pol import write_pauli
    images = {name: channel.image for name, channel in sim.channels.items()}
    return out.write(OUTPUT_FILES["pauli"], lambda path: write_pauli(images, path, title=str(sim.raw.metadata["scene"])))


def _summary(sim: Simulation, paths: dict, start: float, t_products: float) -> RenderSummary:
    """The RenderSummary of a finished simulation whose products went to ``paths``."""
    timings = {**sim.timings, "products": time.perf_counter() - t_products}
    timings["total"] = time.perf_counter() - start
    from .analysis.orders import cap_warning, depth_warning, energy_by_order
    result = sim.trace
    return RenderSummary(
        scene=Path(sim.loaded.source).name, timings=timings, n_pulses=sim.raw.n_pulses,
        rays_traced=int(result.rays_per_order.sum() + result.shadow_rays),
        rays_per_order=result.rays_per_order.tolist(), shadow_rays=result.shadow_rays,
        energy_per_order=result.energy_per_order.tolist(), energy_outside_window=result.energy_outside_window,
        raw_shape=sim.raw.data.shape, image_shape=sim.image.data.shape,
        outputs={k: str(v) for k, v in paths.items()}, pulses_per_trace=result.pulses_per_trace,
        pulse_paths=result.pulse_paths, trace_stages=dict(result.stage_seconds),
        trace_stages_by_order={order: dict(stages) for order, stages in result.stage_seconds_by_order.items()},
        energy_by_order=energy_by_order(result.raw_energy_per_order),
        depth_warning=depth_warning(result.raw_energy_per_order, result.rays_beyond) if sim.depth is None
        else cap_warning(sim.depth.as_dict()), overflow_rows=result.overflow_rows,
        workers=result.workers, workers_note=result.workers_note, depth=depth_summary(sim.depth, result),
        scatterers={} if sim.scatterers is None else dict(
            count=len(sim.scatterers), listed_share=sim.scatterers.listed_share,
            selection=sim.scatterers.selection, clutter=list(sim.scatterers.clutter), line=sim.scatterers.line()))


def refocus(raw: RawData, algorithm: str = "bp", *, window: Any = "taylor", window_range: Any = None,
            window_azimuth: Any = None, progress: bool = False, track: str = "true",
            autofocus: str | None = None, autofocus_reference: Any = None) -> SarImage:
    """Focus any RawData honouring the contract (docs/design.md section 3) with the chosen algorithm.

    ``bp`` / ``ffbp``: direct or fast factorised backprojection onto the scene's ground grid when
    the metadata carry sarmitsuba's radar parameters and scene box (with their beam gating), else
    onto the straight track's slant-plane grid; ``omegak`` / ``rda``: the FFT focusers. Azimuth
    runs from the scene centre's closest approach in every image; range is ground or slant by
    plane (docs/design.md section 8). Chirped input is range-compressed first. Windows (rect, taylor, hamming, kaiser, hann): ``window`` in range and
    azimuth, default Taylor as in :func:`render` (refocusing a render's raw data with ``ffbp`` gives
    its image); ``window_range`` / ``window_azimuth`` for one axis (default: ``window``).
    Backprojection applies the azimuth window over the beam (else over the aperture) and divides
    out the recorded antenna pattern, as :func:`simulate` does.
    ``track = "nominal"`` focuses data simulated with motion errors on their nominal track
    (:meth:`RawData.on_track`, docs/physics.md (J4)); ``autofocus = "pga"`` then estimates the phase
    error on a backprojection and removes it from the pulses (:func:`~.focus.autofocus_pulses.pga_focus`,
    (PGA6)), recorded in ``metadata["autofocus"]``; ``autofocus_reference`` (3 floats, m), a surveyed
    point-like scatterer, lets it remove the linear part too ((PGA5)).

    Raises
    ------
    ValueError
        Unknown algorithm, window, track or autofocus; ``autofocus_reference`` without ``autofocus
        = "pga"``; ``track = "nominal"`` for data without a nominal track; a track the FFT focusers
        cannot handle (they name backprojection); PGA on an image whose azimuth follows no straight track.
    """
    if autofocus not in (None, "pga"):
        raise ValueError(f"autofocus = {autofocus!r}; valid: 'pga' or None")
    if autofocus_reference is not None and autofocus is None:
        raise ValueError("autofocus_reference (--pga-reference) is used only by phase gradient autofocus: "
                         "add autofocus = 'pga' (--autofocus pga), or leave the reference out")
    if autofocus == "pga":                      # through the pulses, docs/physics.md (PGA6)
        from .focus.autofocus_pulses import pga_focus
        return pga_focus(raw.on_track(track), algorithm, window_range=window_range or window,
                         window_azimuth=window_azimuth or window, reference=autofocus_reference, progress=progress)
    return focus_by_name(raw.on_track(track), algorithm, window=window, window_range=window_range,
                         window_azimuth=window_azimuth, progress=progress)


def window_title(image: SarImage) -> str:
    """The focusing window of an image for a title: ``"taylor"`` when range and azimuth share it,
    else ``"range/azimuth"`` names (``image.window`` when the metadata do not record them)."""
    focus = image.metadata.get("focus", {}) if isinstance(image.metadata, dict) else {}
    names = [(focus.get(key) or {}).get("name") for key in ("window_range", "window_azimuth")]
    if None in names:
        return image.window
    return names[0] if names[0] == names[1] else "/".join(names)


def write_image_products(out: OutputDirectory, image: SarImage, title: str) -> dict:
    """Write ``image.npz``, ``image.exr`` and ``image.png`` into the open output directory
    ``out``; returns their final paths by role."""
    return {"image": out.write(OUTPUT_FILES["image"], image.save),
            "exr": out.write(OUTPUT_FILES["exr"], lambda path: image_files.write_exr(image, path)),
            "png": out.write(OUTPUT_FILES["png"], lambda path: image_files.write_quicklook(
                image, path, title=title, figsize=(10.0, 8.0), dpi=110))}


def _write_products(out: OutputDirectory, raw: RawData, image: SarImage, params, suffix: str = "") -> dict:
    """Write raw, image, EXR and PNG into the open output directory ``out``; ``suffix`` (e.g.
    ``_order2``) goes before the extension. Returns the final paths by role."""
    names = {f"{role}{suffix}": OUTPUT_FILES[role].replace(".", f"{suffix}.") for role in ("raw", "image", "exr", "png")}
    order = f"  bounce order {raw.metadata['bounce_order']}" if "bounce_order" in raw.metadata else ""
    title = (f"{raw.metadata['scene']}  {params.frequency / 1e9:.2f} GHz  B={params.bandwidth / 1e6:.0f} MHz  "
             f"inc={params.incidence_angle:g} deg  {raw.metadata.get('polarization', params.polarization)}  "
             f"depth={raw.metadata['settings']['max_depth']}  "
             f"window {window_title(image)}{order}")

    def files() -> dict:
        return {f"raw{suffix}": out.write(names[f"raw{suffix}"], raw.save),
                f"image{suffix}": out.write(names[f"image{suffix}"], image.save),
                f"exr{suffix}": out.write(names[f"exr{suffix}"], lambda path: image_files.write_exr(image, path))}

    # the arrays stream to disk on a thread while matplotlib draws the quick-look here (a city's
    # products are 0.3 GB, mostly waiting on the disk); both finish before this returns
    with ThreadPoolExecutor(1) as pool:
        written = pool.submit(files)
        png = out.write(names[f"png{suffix}"], lambda path: image_files.write_quicklook(
            image, path, title=title, figsize=(10.0, 8.0), dpi=110))
        paths = written.result()
    paths[f"png{suffix}"] = png
    return paths


def _write_along_track(out: OutputDirectory, sim: Simulation) -> dict:
    """``ati.npz`` (the interferogram ``I_fore I_aft*``), ``dpca.npz`` (``I_fore - I_aft``) and
    ``ati.png``, on the fore image's grid (docs/physics.md (V6), (V7))."""
    from .stacks.along_track import ati_interferogram, dpca_image
    from .products.figures_ati import write_ati_figure
    meta = {**sim.image.metadata, "ati_baseline": sim.loaded.params.ati_baseline}
    ati, dpca = ati_interferogram(sim.image, sim.aft.image), dpca_image(sim.image, sim.aft.image)
    products = {name: dataclasses.replace(sim.image, data=data.astype(np.complex64), metadata={**meta, "product": name})
                for name, data in (("ati", ati), ("dpca", dpca))}
    paths = {name: out.write(OUTPUT_FILES[name], image.save) for name, image in products.items()}
    title = f"{sim.raw.metadata['scene']}  along-track baseline {sim.loaded.params.ati_baseline:g} m"
    paths["ati_png"] = out.write(OUTPUT_FILES["ati_png"], lambda path: write_ati_figure(sim.image, ati, dpca, path,
                                                                                         title))
    return paths


def _write_summary(path: Path, summary: RenderSummary, metadata: dict) -> None:
    body = {**dataclasses.asdict(summary), "pulse_paths_per_second": summary.pulse_paths_per_second,
            "radar": metadata["radar"], "settings": metadata["settings"],
            "scene_info": metadata["scene_info"], "effects": metadata["effects"]}
    path.write_text(json.dumps(body, indent=2, default=json_default))   # staged: appears whole


def _world_params(loaded: LoadedScene):
    """Radar parameters with the scene centre in the world frame, ``collection_start`` the first
    pulse's UTC time from an absolute-time trajectory (docs/physics.md (J5)), else the moment of the
    render (UTC) when the sensor does not give it, and state vectors named by
    their source (a file name, or ``"python"``)."""
    import datetime

    from .core.geometry import collection_start
    center = np.asarray(loaded.params.scene_center) + loaded.offset
    start = collection_start(loaded.params) or datetime.datetime.now(datetime.timezone.utc).isoformat()
    trajectory = loaded.params.trajectory                 # state vectors: their file's name (the raw data hold
    trajectory = getattr(trajectory, "source", trajectory)    # the positions)
    return dataclasses.replace(loaded.params, scene_center=tuple(center.tolist()), collection_start=start,
                               trajectory=trajectory)


def _metadata(loaded: LoadedScene, ray_spacing: float, result, effects) -> dict:
    import drjit
    import mitsuba

    from . import __version__
    settings = loaded.settings
    return {
        # names, not paths: no absolute path of the user's machine travels with the products
        "scene": Path(loaded.source).name, "scene_path": None if loaded.path is None else loaded.path.name,
        "radar": dataclasses.asdict(_world_params(loaded)), "settings": dataclasses.asdict(settings),
        "frame_offset": loaded.offset.tolist(),
        "ray_spacing": ray_spacing, "effects": [str(e) for e in effects], "units": "sqrt(m^2) (normalised radiometry)",
        "scene_info": {"shapes": loaded.n_shapes, "triangles": loaded.n_triangles, "has_sar_sensor": loaded.has_sensor,
                       "bbox_min": loaded.bbox_lo.tolist(), "bbox_max": loaded.bbox_hi.tolist()},
        "trace": {"seconds": result.seconds, "rays_per_order": result.rays_per_order.tolist(),
                  "shadow_rays": result.shadow_rays, "energy_per_order": result.energy_per_order.tolist(),
                  "pulses_per_trace": result.pulses_per_trace, "pulse_paths": result.pulse_paths},
        "versions": {"sarmitsuba": __version__, "mitsuba": mitsuba.__version__, "drjit": drjit.__version__},
    }
