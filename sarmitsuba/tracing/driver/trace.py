"""Tracing an acquisition: pulses in batches through the shoot-and-bounce-rays kernel
(:mod:`sarmitsuba.tracing.driver.kernel`), each batch's deposit reduced to a band-limited spectrum
(:mod:`sarmitsuba.tracing.deposit.fast_time`), docs/design.md sections 5 and 6.

Triangle meshes are traced by the mesh tracer (:mod:`sarmitsuba.tracing.driver.mesh_trace`,
docs/physics.md (M1)-(M10)). In the tube preview, ray tubes leave the antenna toward a world-fixed
lattice of aim points (:func:`sarmitsuba.scene.planning.ray_footprint`), follow specular bounces
up to ``max_depth``, and each lit footprint returns its physical-optics integral as point terms
((PO1)-(PO3)); rough surfaces add the scatterers of their own lattice ((C)).

Precision (docs/design.md section 5): float64 legs from the exact hit points, and a per-pulse
float64 reference length subtracted before anything becomes float32.

Output (:class:`TraceResult`): per pulse, the spectrum of the path sum
``sum_i a_i exp(-j k (L_i - L_ref))`` over the coarse sampling band, on a padded grid; or, for
the ``exact`` range kernel, every term (:class:`PathList`). :mod:`sarmitsuba.signal.binning` restores
the reference phase in float64, band-limits (range compression) or chirps it.
"""
from __future__ import annotations

import dataclasses
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, fields

import drjit as dr
import mitsuba as mi
import numpy as np
from tqdm import tqdm

from ..deposit.fast_time import LANCZOS_A, SPECTRAL_ORDERS, padded_length, reduce_deposit
from ..deposit.order_energy import spectra_by_order
from ...scene.effects import EffectSet, rough_materials
from ...scene import planning
from ...scene.effects import active_effects
from .kernel import Kernel
from .launches import Blocks, Launch, receiver_launch
from ..integration.catalogue import CatalogueRows, merge_rows
from ..integration.pulse_view import antenna_axes
from .stages import STAGES, by_order
from .subapertures import (SUBAPERTURE_CELLS, SubApertures, lattice_blocks, pulses_per_trace,  # noqa: F401
                           subapertures)
from .threads import caused_by_interrupt, host_threads, kernel_pool
from ...core.radar import ParameterError, RadarParameters
from ...core.geometry import AcquisitionGeometry, acquisition_geometry
from ...scene.loader import LoadedScene, material_table
from ...scene.trace_inputs import FastTimeWindow, MaterialTable, RayFootprint, TraceSettings

__all__ = ["TraceSetup", "prepare_trace", "TraceSettings", "FastTimeWindow", "RayFootprint", "MaterialTable", "PathList",
           "TraceResult", "trace", "caused_by_interrupt", "LANCZOS_A", "SubApertures", "subapertures", "pulses_per_trace",
           "SUBAPERTURE_CELLS"]


@dataclass(frozen=True)
class TraceSetup:
    """What :func:`trace` needs besides the scene, derived from a loaded scene alone (so any
    process that loads the same scene with the same overrides derives the same setup)."""

    geometry: AcquisitionGeometry
    window: FastTimeWindow
    footprint: RayFootprint
    effects: EffectSet
    table: MaterialTable


def prepare_trace(loaded: LoadedScene) -> TraceSetup:
    """Acquisition geometry, fast-time window, ray footprint, active effects and material table of
    ``loaded``; checks the acquisition (ParameterError) before any tracing."""
    params, settings = loaded.params, loaded.settings
    geometry = acquisition_geometry(params)
    window = planning.fast_time_window(params, geometry, loaded.bbox_lo, loaded.bbox_hi, settings)
    footprint = planning.ray_footprint(params, geometry, loaded.bbox_lo, loaded.bbox_hi, settings,
                                       shape_boxes=loaded.shape_boxes)
    planning.check_acquisition(params, geometry, window, loaded.bbox_lo, loaded.bbox_hi)
    effects = active_effects(loaded)                     # docs/design.md section 7: decided once, handed on
    table = material_table(loaded.scene, params.frequency, params.polarization)
    return TraceSetup(geometry, window, footprint, effects, table)


@dataclass(frozen=True)
class PathList:
    """Every visible term of an acquisition, kept for the ``exact`` range kernel.

    Attributes
    ----------
    pulse : int32 [n_paths]
        Pulse index.
    order : uint8 [n_paths]
        Bounce order (1 = single bounce).
    position : float64 [n_paths]
        Two-way delay in coarse samples from the window's first sample,
        ``(L - c t0) fs / c``.
    value : complex64 [n_paths]
        ``a exp(-j k (L - L_ref))`` at the carrier: the term's amplitude relative to the pulse's
        reference phase (the same quantity the gridded kernels deposit).
    spectral : int8 [n_paths]
        Spectral order ``m``: the term's amplitude scales as ``(f / fc)^m`` (docs/physics.md (PO3)).
    channel : uint8 [n_paths] or None
        Polarimetric channel, an index into :attr:`TraceResult.channels` (``quad`` only; None
        for one channel).
    """

    pulse: np.ndarray
    order: np.ndarray
    position: np.ndarray
    value: np.ndarray
    spectral: np.ndarray
    channel: np.ndarray | None = None

    def select(self, keep: np.ndarray) -> "PathList":
        """The terms where the bool array ``keep`` is true."""
        return PathList(*(None if getattr(self, f.name) is None else getattr(self, f.name)[keep]
                          for f in fields(PathList)))

    def of_order(self, order: int) -> "PathList":
        """The terms of one bounce order."""
        return self.select(self.order == order)

    @staticmethod
    def concatenate(parts: list["PathList"]) -> "PathList":
        """One list from per-batch lists."""
        if not parts:
            return PathList(np.zeros(0, np.int32), np.zeros(0, np.uint8), np.zeros(0), np.zeros(0, np.complex64),
                            np.zeros(0, np.int8))
        return PathList(*(None if getattr(parts[0], f.name) is None else
                          np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(PathList)))


@dataclass(frozen=True)
class TraceResult:
    """What the tracer returns for the whole acquisition.

    Attributes
    ----------
    spectrum : complex64 [n_pulses, n_pad]
        Per pulse, the spectrum (FFT order, ``scipy.fft.fftfreq(n_pad, 1 / fs)``) of the term sum
        ``sum_i a_i (1 + f / fc)^m_i exp(-j 2 pi f (tau_i - t0)) exp(-j k (L_i - L_ref))`` over the
        coarse sampling band (docs/physics.md (D5)); shape [n_pulses, 0] for the ``exact`` kernel,
        which keeps ``paths`` instead.
    reference_length : float64 [n_pulses], m
        Per-pulse reference two-way length ``L_ref = 2 |A - scene_center|``.
    energy_per_order : float64 [max_depth], m^2
        Incoherent sum, per bounce order (1, 2, ...), of the visible returns' ``|a|^2`` at the
        carrier: each tube's whole PO value and each clutter scatterer.
    raw_energy_per_order : float64 [max_depth] or None, m^2
        Energy of each bounce order's range-compressed raw data (docs/physics.md (D6); quad: the
        channels' mean); None for the ``exact`` kernel and the derivatives' traces.
    energy_outside_window : float, m^2
        Energy of visible returns whose delay fell outside the fast-time window.
    rays_per_order : int64 [max_depth]
        Closest-hit casts per bounce order (order 1 = primary rays).
    shadow_rays : int
        Shadow (visibility) casts toward the receiving antenna. Tubes: one per visible hit. Patches:
        one per visibility sample whose return leg is a ray of its own, past the first bounce, and
        bistatic at every bounce (the leg to the receiver, docs/physics.md (B2)); at the monostatic
        first bounce the one ray to the sample is both ways, counted in ``rays_per_order``.
    seconds : float
        Wall time of tracing, s.
    spectrum_per_order : complex64 [max_depth, n_pulses, n_pad] or None
        The same split by bounce order (order k at index k - 1) when ``split_bounces`` is on;
        ``spectrum`` is then their sum.
    carried_power_per_order : float64 [max_depth], sr
        Power carried into each bounce order by the tubes that hit there, ``sum Omega |r_1 ... r_{k-1}|^2``
        (solid angle times the reflection losses so far): non-increasing with the order for
        passive materials, the energy-conservation check of the bounce loop.
    paths : PathList or None
        Every visible term (``exact`` range kernel only).
    split : bool
        Whether the result was traced with ``split_bounces``.
    scatterers_per_order : int64 [max_depth]
        Clutter scatterers deposited per bounce order.
    n_pad : int
        Coarse samples of the padded grid of ``spectrum`` (0 for ``exact``).
    pulses_per_trace : int
        Pulses per sub-aperture: each sub-aperture's tubes were traced once (docs/physics.md (T3)).
    pulse_paths : int
        Returns evaluated: PO terms times the pulses they were evaluated for, plus clutter
        scatterers deposited (the tracer's unit of work after the casts).
    channels : tuple of str
        ``quad``: the polarimetric channels (:data:`sarmitsuba.core.radar.CHANNELS`), one trace for
        all; ``spectrum`` and ``spectrum_per_order`` then have a leading channel axis and
        :meth:`channel` gives each as a one-channel result. Empty for one channel. The energy
        tallies are the channels' mean (docs/physics.md (P4)).
    stage_seconds : dict
        The mesh tracer's wall seconds per stage (:data:`sarmitsuba.tracing.driver.stages.STAGES`,
        summed over its launches; empty for the tube preview).
    stage_seconds_by_order : dict
        The same by bounce order, ``{order: {stage: seconds}}`` (orders from 1; the ``deposit``
        stage, shared by the orders, only in :attr:`stage_seconds`).
    overflow_rows : int
        Rows the fused geometry kernels left to their NumPy references (docs/design.md section 10.1).
    rays_beyond : int or None
        The mesh tracer's specular rays from the deepest order that meet another part
        (:func:`~sarmitsuba.tracing.discovery.specular.rays_beyond`; 0: nothing lies beyond the
        traced orders); None where not looked for (tubes, or a deepest order of little power).
    workers : int
        Processes that traced the batches (1: this one alone).
    workers_note : str
        Why that many (:class:`~sarmitsuba.tracing.driver.workers.WorkerPlan`'s reason; empty
        where the caller traced directly).
    catalogue : CatalogueRows or None
        With ``scatterers = true``: every chain's lanes summed at their image points, merged by
        chain and quantisation cube (:mod:`sarmitsuba.tracing.integration.catalogue`, (SC1)-(SC2)),
        every channel's sums. None: the catalogue is off.
    """

    spectrum: np.ndarray
    reference_length: np.ndarray
    energy_per_order: np.ndarray
    energy_outside_window: float
    rays_per_order: np.ndarray
    shadow_rays: int
    seconds: float
    spectrum_per_order: np.ndarray | None = None
    carried_power_per_order: np.ndarray | None = None
    paths: PathList | None = None
    split: bool = False
    scatterers_per_order: np.ndarray | None = None
    n_pad: int = 0
    pulses_per_trace: int = 1
    pulse_paths: int = 0
    channels: tuple = ()
    stage_seconds: dict = dataclasses.field(default_factory=dict)
    stage_seconds_by_order: dict = dataclasses.field(default_factory=dict)
    raw_energy_per_order: np.ndarray | None = None
    overflow_rows: int = 0
    rays_beyond: int | None = None
    workers: int = 1
    workers_note: str = ""
    catalogue: CatalogueRows | None = None

    def channel(self, name: str) -> "TraceResult":
        """The one-channel result of channel ``name`` (``"HH"``, ...) of a ``quad`` trace; the
        result itself for a one-channel trace of that channel. Raises ParameterError otherwise."""
        if not self.channels:
            return self
        if name not in self.channels:
            raise ParameterError(f"channel {name!r}: the trace holds {', '.join(self.channels)}")
        c = self.channels.index(name)
        return dataclasses.replace(
            self, spectrum=self.spectrum[c], channels=(),
            spectrum_per_order=None if self.spectrum_per_order is None else self.spectrum_per_order[c],
            paths=None if self.paths is None else dataclasses.replace(self.paths.select(self.paths.channel == c),
                                                                      channel=None))

    @property
    def n_orders(self) -> int:
        """Bounce orders available separately (``split_bounces``), 0 when not split."""
        if self.spectrum_per_order is not None:
            return self.spectrum_per_order.shape[0]
        return len(self.energy_per_order) if self.split else 0

    def contributions(self, order: int | None = None) -> "np.ndarray | PathList":
        """What :func:`sarmitsuba.signal.binning.to_raw_data` turns into samples: the spectrum
        (complex64 [n_pulses, n_pad]) or, for the ``exact`` kernel, the :class:`PathList`; of all
        bounce orders, or of bounce order ``order`` (1, 2, ...; needs ``split_bounces``)."""
        if order is None:
            return self.paths if self.paths is not None else self.spectrum
        if not 1 <= order <= self.n_orders:
            raise ParameterError(f"bounce order {order}: the result holds orders 1..{self.n_orders} "
                                 "(trace with split_bounces = true)")
        return self.paths.of_order(order) if self.paths is not None else self.spectrum_per_order[order - 1]


#: Complex entries of a batch's fine-grid histogram (orders x pulses x fine samples), at most: four
#: int64 words each on the device, 128 MiB (docs/physics.md (D7)). A quarter of it kept the
#: device's bytes of the float32 histogram but made urban's trace 1.5 times as long (smaller
#: launches); the memory is in ``info``'s model (:data:`sarmitsuba.analysis.cost.HISTOGRAM_DEVICE_BYTES`).
HISTOGRAM_ENTRIES = 1 << 22


@dataclass(frozen=True)
class TracePlan:
    """How :func:`trace` splits an acquisition into batches of sub-apertures; the same inputs
    give the same plan in any process, so a batch can be traced anywhere (docs/design.md section 11).

    Attributes
    ----------
    subs : SubApertures
    per_batch : int
        Sub-apertures per batch; batch ``b`` covers sub-apertures ``[b per_batch, (b + 1) per_batch)``.
    lref : float64 [n_pulses], m
        Per-pulse reference length ``2 |P - scene_center|``.
    n_channels, groups, n_pad : int
        Channels, spectra per channel of a batch (one per bounce order, ``EffectSet.deposit_groups``),
        padded spectrum length.
    kept, bandwidth : int, float [Hz]
        Spectra kept per channel (``groups`` with ``split_bounces``, else 1); the band of (D6).
    exact : bool
        ``range_kernel = exact``: batches return path lists instead of spectra.
    axes : float64 [n_pulses, 3, 3] or None
        A curved track's per-pulse antenna axes (:func:`~sarmitsuba.tracing.integration.pulse_view.antenna_axes`).
    """

    subs: SubApertures
    per_batch: int
    lref: np.ndarray
    n_channels: int
    groups: int
    n_pad: int
    exact: bool
    axes: np.ndarray | None = None
    kept: int = 1
    bandwidth: float = 0.0
    #: Sub-apertures traced, one per batch, when only some are (the depth probe,
    #: :mod:`sarmitsuba.tracing.driver.depth`); empty: all of them.
    only: tuple = ()

    @property
    def batches(self) -> list[int]:
        """First sub-aperture of each batch."""
        if self.only:
            return list(self.only)
        return list(range(0, len(self.subs.first), self.per_batch))

    def pulses(self, g0: int) -> tuple[int, int]:
        """Pulse range ``[p0, p1)`` of the batch starting at sub-aperture ``g0``."""
        g = slice(g0, min(len(self.subs.first), g0 + self.per_batch))
        return int(self.subs.first[g][0]), int(self.subs.first[g][-1] + self.subs.count[g][-1])


def plan_trace(scene: mi.Scene, params: RadarParameters, geometry: AcquisitionGeometry, window: FastTimeWindow,
               footprint: RayFootprint, settings: TraceSettings, effects: EffectSet) -> TracePlan:
    """The :class:`TracePlan` of an acquisition: sub-apertures and the batch size that keeps a
    launch within ``max_batch_rays`` tubes and the histogram within :data:`HISTOGRAM_ENTRIES`."""
    n_pulses = geometry.positions.shape[0]
    n_channels, groups = len(effects.channels), effects.groups      # the device's histogram: (D5)
    subs = subapertures(geometry, footprint, scene, pulses_per_trace(params, settings, n_pulses, effects.moving_shapes))
    per_sub = subs.n_i * footprint.n_range + footprint.refined_rays // max(1, len(subs.first))
    pulse_budget = max(subs.size, HISTOGRAM_ENTRIES // (len(SPECTRAL_ORDERS) * max(window.n_fine, 1) * groups
                                                        * n_channels))
    per_batch = 1 if effects.moving_shapes is not None else \
        max(1, min(len(subs.first), settings.max_batch_rays // max(per_sub, 1), pulse_budget // subs.size))
    return TracePlan(subs=subs, per_batch=per_batch,
                     lref=geometry.reference_length,
                     n_channels=n_channels, groups=effects.deposit_groups, n_pad=padded_length(window.n_samples),
                     exact=settings.range_kernel == "exact", axes=antenna_axes(params, geometry),
                     kept=effects.groups, bandwidth=params.bandwidth)


def trace_batch(kernel: Kernel, plan: TracePlan, g0: int, geometry: AcquisitionGeometry, window: FastTimeWindow,
                footprint: RayFootprint, settings: TraceSettings, frequency: float) -> dict:
    """Trace the batch of sub-apertures starting at ``g0``: ``{"pulses": (p0, p1), "spectrum":
    complex64 [n_channels kept, p1 - p0, n_pad] (None for exact), "paths": PathList or None,
    "totals": {counter: value}}``; ``totals["order_energy"]``: each bounce order's energy (D6),
    when every order has its own deposit group."""
    subs = plan.subs
    g = slice(g0, min(len(subs.first), g0 + plan.per_batch))
    p0, p1 = plan.pulses(g0)
    n_groups = plan.n_channels * plan.groups
    hist = None if plan.exact else np.zeros((len(SPECTRAL_ORDERS), n_groups, p1 - p0, window.n_fine), np.complex64)
    totals, paths, catalogue = {}, None, []
    motion = dict(velocity=geometry.velocity[p0:p1], acceleration=geometry.acceleration[p0:p1]) \
        if geometry.continuous else receiver_launch(geometry, p0, p1, subs, g, kernel.effects.continuous_motion)
    if kernel.effects.moving_shapes is not None:        # (V1): the shapes' times, from mid-aperture
        motion["pulse_time"] = geometry.pulse_time[p0:p1] - geometry.pulse_time[[0, -1]].mean()
    groups = [Blocks.of([])] if settings.lit_regions == "patches" else []
    if kernel.tubes:
        groups = [*groups, *lattice_blocks(subs, g, footprint, settings.max_batch_rays)]
    for blocks in groups:
        launch = Launch(antenna=geometry.positions[p0:p1], lref=plan.lref[p0:p1], first=subs.first[g] - p0,
                        count=subs.count[g], reference=subs.reference[g], r_near=subs.r_near[g],
                        along_limits=subs.along_limits[g], blocks=blocks,
                        axes=None if plan.axes is None else plan.axes[p0:p1], **motion)
        try:
            out = kernel(launch)
        except RuntimeError as exc:        # Dr.Jit wraps a Ctrl-C that lands while it traces a loop body
            if caused_by_interrupt(exc):
                raise KeyboardInterrupt from exc
            raise
        if plan.exact:
            part = _path_list(out["paths"], p0, plan.n_channels > 1)
            paths = part if paths is None else PathList.concatenate([paths, part])
        else:
            hist += out["hist"]
        for name in TOTALS:
            totals[name] = totals.get(name, 0) + out.get(name, 0)
        catalogue.append(out.get("catalogue"))
    def reduce(h):
        return reduce_deposit(h, window.fs, window.oversample, frequency, settings.range_kernel, plan.n_pad)
    spectrum = None
    if not plan.exact and plan.groups == settings.depth:            # one group per order: (D6)
        spectrum, totals["order_energy"] = spectra_by_order(hist, plan.n_channels, plan.kept > 1, reduce, window.fs,
                                                            plan.bandwidth)
    elif not plan.exact:
        spectrum = np.stack([reduce(hist[:, k]) for k in range(n_groups)])
    return {"pulses": (p0, p1), "spectrum": spectrum, "paths": paths, "totals": totals,
            "catalogue": merge_rows(catalogue)}


#: Counters every kernel launch returns and :func:`trace` sums (``stages``: the mesh tracer's
#: seconds per stage, :data:`sarmitsuba.tracing.driver.stages.STAGES`; absent from a tube launch).
TOTALS = ("energy", "carried", "rays", "scatterers", "outside", "shadow", "evaluated", "stages", "order_energy",
          "overflow", "beyond_rays", "beyond_unchecked")


def trace(scene: mi.Scene, params: RadarParameters, geometry: AcquisitionGeometry,
          window: FastTimeWindow, footprint: RayFootprint, settings: TraceSettings,
          material_table: MaterialTable, progress: bool = False, effects: EffectSet | None = None,
          run_batches=None, batch_size=None, trace_here: bool = False, sample=None) -> TraceResult:
    """Trace all pulses of an acquisition (see module docstring for the model).

    Parameters
    ----------
    scene : mitsuba.Scene
        Loaded scene (any ``*_mono`` variant).
    params : RadarParameters
    geometry : AcquisitionGeometry
        float64 antenna positions [n_pulses, 3].
    window : FastTimeWindow
    footprint : RayFootprint
    settings : TraceSettings
        ``pulses_per_trace`` sets the sub-aperture: its pulses share one trace (docs/physics.md (T3)).
    material_table : MaterialTable
        Reflection coefficient against cos(incidence) and clutter model per shape.
    progress : bool
        Show a tqdm bar over pulses.
    effects : EffectSet, optional
        The effects to trace (:func:`sarmitsuba.scene.effects.active_effects` of the loaded scene);
        default: those of ``params``, ``settings`` and the rough materials of ``material_table``.
    run_batches : callable, optional
        ``run_batches(plan, batches)`` yields the :func:`trace_batch` results of the batches
        (first sub-aperture indices) in any order, traced elsewhere (for instance on Dask
        workers, :mod:`sarmitsuba.tracing.driver.distributed`). Default: traced here, in order.
    batch_size : callable, optional
        ``batch_size(per_batch, n_subapertures)``: the sub-apertures per batch to use instead of
        the plan's (worker processes cut them smaller, :mod:`sarmitsuba.tracing.driver.workers`);
        the raw data do not depend on it.
    trace_here : bool
        With ``run_batches``: this process traces batches too. ``run_batches`` is then called as
        ``run_batches(plan, batches, here)``, where ``here(g0)`` traces the batch ``g0`` in this
        process (one launch at a time).
    sample : sequence of int, optional
        Trace only these sub-apertures (indices into the plan's, one per batch); the other pulses'
        spectra stay zero and the tallies count the traced ones alone (the depth probe).

    Returns
    -------
    TraceResult
    """
    n_pulses = geometry.positions.shape[0]
    if effects is None:
        effects = EffectSet.of(params, settings, rough_materials(material_table))
    plan = plan_trace(scene, params, geometry, window, footprint, settings, effects)
    if batch_size is not None:
        plan = dataclasses.replace(plan, per_batch=batch_size(plan.per_batch, len(plan.subs.first)))
    if sample is not None:
        plan = dataclasses.replace(plan, per_batch=1, only=tuple(int(g) for g in sample))
    spectrum = np.zeros((plan.n_channels * plan.kept, n_pulses, 0 if plan.exact else plan.n_pad), np.complex64)
    paths = {}
    totals = dict(energy=np.zeros(settings.depth), carried=np.zeros(settings.depth),
                  rays=np.zeros(settings.depth, np.int64), scatterers=np.zeros(settings.depth, np.int64),
                  outside=0.0, shadow=0, evaluated=0, stages=np.zeros((settings.depth + 1, len(STAGES))),
                  order_energy=np.zeros(settings.depth), overflow=0, beyond_rays=0, beyond_unchecked=0)
    start = time.perf_counter()
    kernel = None if run_batches is not None else Kernel(scene, params, window, footprint, settings,
                                                         material_table, effects)
    threads = host_threads(kernel) if run_batches is None else 1
    made = {}                            # trace_here: the kernel, built at the first batch (workers start first)
    if threads > 1:                      # launches of 1 / threads the size, as many at once: no more memory
        plan = dataclasses.replace(plan, per_batch=max(1, plan.per_batch // threads))
        kernel.returns.sums.shared_by(threads)
    bar = tqdm(total=n_pulses, desc="trace", unit="pulse", disable=not progress)
    batch_totals, rows = {}, {}          # by first pulse: summed in pulse order, whatever order batches arrive in
    pool = ThreadPoolExecutor(threads, thread_name_prefix="trace") if threads > 1 else None
    with kernel_pool(threads):           # host threads that fill the cores run their own blocks
        try:
            def one(g0):
                here = kernel if kernel is not None else made.get("kernel")
                if here is None:
                    here = made["kernel"] = Kernel(scene, params, window, footprint, settings, material_table, effects)
                return trace_batch(here, plan, g0, geometry, window, footprint, settings, params.frequency)
            if run_batches is not None:
                results = run_batches(plan, plan.batches, one) if trace_here else run_batches(plan, plan.batches)
            else:
                results = pool.map(one, plan.batches) if pool is not None else (one(g0) for g0 in plan.batches)
            for out in results:
                p0, p1 = out["pulses"]
                if plan.exact:
                    paths[p0] = out["paths"]
                else:
                    spectrum[:, p0:p1] = out["spectrum"]
                batch_totals[p0] = out["totals"]
                rows[p0] = out.get("catalogue")
                bar.update(p1 - p0)
        finally:
            if pool is not None:
                pool.shutdown(wait=True, cancel_futures=True)
            bar.close()
            del kernel
            made.clear()
            dr.flush_malloc_cache()          # Dr.Jit keeps freed arrays cached: give them back for focusing
    for p0 in sorted(batch_totals):
        for name in totals:
            totals[name] = totals[name] + batch_totals[p0].get(name, 0)
    seconds = time.perf_counter() - start
    result = _result(plan, spectrum, paths, totals, seconds, effects)
    return dataclasses.replace(result, catalogue=merge_rows([rows[p0] for p0 in sorted(rows)])) \
        if effects.scatterers else result


def _result(plan: TracePlan, spectrum: np.ndarray, paths: dict, totals: dict, seconds: float,
            effects: EffectSet) -> TraceResult:
    """The TraceResult of the merged batches (paths keyed by their batch's first pulse)."""
    n_pulses = spectrum.shape[1]
    spectrum = spectrum.reshape(plan.n_channels, plan.kept, n_pulses, -1)
    quad = plan.n_channels > 1
    exact = plan.exact
    merged = PathList.concatenate([paths[k] for k in sorted(paths) if paths[k] is not None]) if exact else None
    return TraceResult(spectrum=spectrum.sum(axis=1) if quad else spectrum[0].sum(axis=0), reference_length=plan.lref,
                       energy_per_order=totals["energy"], energy_outside_window=float(totals["outside"]),
                       rays_per_order=totals["rays"], shadow_rays=int(totals["shadow"]), seconds=seconds,
                       spectrum_per_order=(spectrum if quad else spectrum[0]) if effects.split_bounces and not exact
                       else None, channels=effects.channels if quad else (),
                       carried_power_per_order=totals["carried"],
                       paths=merged, split=effects.split_bounces,
                       scatterers_per_order=totals["scatterers"], n_pad=0 if exact else plan.n_pad,
                       pulses_per_trace=plan.subs.size, pulse_paths=int(totals["evaluated"]),
                       overflow_rows=int(totals["overflow"]),
                       rays_beyond=None if totals["beyond_unchecked"] or plan.exact else int(totals["beyond_rays"]),
                       stage_seconds={name: float(t) for name, t in zip(STAGES, totals["stages"].sum(axis=0)) if t > 0},
                       stage_seconds_by_order=by_order(totals["stages"]),
                       raw_energy_per_order=None if exact or plan.groups != len(totals["energy"])
                       else np.asarray(totals["order_energy"], np.float64))


def _path_list(found: dict, p0: int, channels: bool) -> "PathList":
    """The exact kernel's terms as a PathList with acquisition pulse indices."""
    return PathList(pulse=found["path_pulse"].astype(np.int32) + np.int32(p0),
                    order=found["path_order"].astype(np.uint8), position=found["path_pos"],
                    value=(found["path_re"] + 1j * found["path_im"]).astype(np.complex64),
                    spectral=(np.asarray(SPECTRAL_ORDERS)[found["path_spectral"]]).astype(np.int8),
                    channel=found["path_channel"].astype(np.uint8) if channels else None)
