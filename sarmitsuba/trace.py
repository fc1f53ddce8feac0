"""Tracing an acquisition: pulses in batches through the shoot-and-bounce-rays kernel
(:mod:`sarmitsuba.kernel`), each batch's deposit reduced to a band-limited spectrum
(:mod:`sarmitsuba.deposit`), docs/design.md sections 5 and 6.

For every pulse, ray tubes leave the antenna toward a world-fixed lattice of aim points on a
horizontal plane through the scene centre, finer around small objects
(:func:`sarmitsuba.planning.ray_footprint`). Each tube follows specular bounces up to
``max_depth``; at every hit a shadow ray tests whether the antenna sees the hit point, and the
tube's footprint returns its physical-optics integral, exact at every frequency of the band,
as one, two or four point terms (docs/physics.md (PO1)-(PO3)); rough surfaces add the
scatterers of their own lattice that lie inside the footprint ((C)). The coherent sum over
tubes gives physical optics: canonical targets' radar cross-sections, and nothing from the
interior of a smooth plane.

Precision (docs/design.md section 5): rays start near the scene (float64 offset carried
separately); the first and return legs are float64 norms from the exact hit point; a per-pulse
float64 reference length is subtracted before anything becomes float32.

Output (:class:`TraceResult`): per pulse, the spectrum of the path sum
``sum_i a_i exp(-j k (L_i - L_ref))`` over the coarse sampling band, on a padded grid; or, for
the ``exact`` range kernel, every term (:class:`PathList`). :mod:`sarmitsuba.binning` restores
the reference phase in float64, band-limits (range compression) or chirps it.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, fields

import mitsuba as mi
import numpy as np
from tqdm import tqdm

from .deposit import LANCZOS_A, SPECTRAL_ORDERS, padded_length, reduce_deposit
from .kernel import Kernel, Launch
from .radar import AcquisitionGeometry, ParameterError, RadarParameters
from .trace_inputs import FastTimeWindow, MaterialTable, RayFootprint, Refinement, TraceSettings

__all__ = ["TraceSettings", "FastTimeWindow", "RayFootprint", "MaterialTable", "PathList", "TraceResult", "trace",
           "caused_by_interrupt", "LANCZOS_A"]


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
    """

    pulse: np.ndarray
    order: np.ndarray
    position: np.ndarray
    value: np.ndarray
    spectral: np.ndarray

    def of_order(self, order: int) -> "PathList":
        """The terms of one bounce order."""
        keep = self.order == order
        return PathList(*(getattr(self, f.name)[keep] for f in fields(PathList)))

    @staticmethod
    def concatenate(parts: list["PathList"]) -> "PathList":
        """One list from per-batch lists."""
        if not parts:
            return PathList(np.zeros(0, np.int32), np.zeros(0, np.uint8), np.zeros(0), np.zeros(0, np.complex64),
                            np.zeros(0, np.int8))
        return PathList(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(PathList)))


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
    energy_outside_window : float, m^2
        Energy of visible returns whose delay fell outside the fast-time window.
    rays_per_order : int64 [max_depth]
        Closest-hit casts per bounce order (order 1 = primary rays).
    shadow_rays : int
        Shadow (visibility) casts.
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

    @property
    def n_orders(self) -> int:
        """Bounce orders available separately (``split_bounces``), 0 when not split."""
        if self.spectrum_per_order is not None:
            return self.spectrum_per_order.shape[0]
        return len(self.energy_per_order) if self.split else 0

    def contributions(self, order: int | None = None) -> "np.ndarray | PathList":
        """What :func:`sarmitsuba.binning.to_raw_data` turns into samples: the spectrum
        (complex64 [n_pulses, n_pad]) or, for the ``exact`` kernel, the :class:`PathList`; of all
        bounce orders, or of bounce order ``order`` (1, 2, ...; needs ``split_bounces``)."""
        if order is None:
            return self.paths if self.paths is not None else self.spectrum
        if not 1 <= order <= self.n_orders:
            raise ParameterError(f"bounce order {order}: the result holds orders 1..{self.n_orders} "
                                 "(trace with split_bounces = true)")
        return self.paths.of_order(order) if self.paths is not None else self.spectrum_per_order[order - 1]


#: Histogram entries per launch: at most Dr.Jit's threshold for per-thread (non-atomic) scatter-adds.
EXPAND_THRESHOLD = 1 << 20


def trace(scene: mi.Scene, params: RadarParameters, geometry: AcquisitionGeometry,
          window: FastTimeWindow, footprint: RayFootprint, settings: TraceSettings,
          material_table: MaterialTable, progress: bool = False) -> TraceResult:
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
    material_table : MaterialTable
        Reflection coefficient against cos(incidence) and clutter model per shape.
    progress : bool
        Show a tqdm bar over pulse batches.

    Returns
    -------
    TraceResult
    """
    n_pulses = geometry.positions.shape[0]
    lref = 2.0 * np.linalg.norm(geometry.positions - geometry.scene_center, axis=1)
    radius, center = _bounding_sphere(scene)
    r_near = np.maximum(np.linalg.norm(geometry.positions - center, axis=1) - radius - 1.0, 0.0)
    exact = settings.range_kernel == "exact"
    groups = settings.max_depth if settings.split_bounces else 1
    n_pad = padded_length(window.n_samples)
    per_pulse = footprint.rays_per_pulse
    per_batch = max(1, min(n_pulses, settings.max_batch_rays // max(per_pulse, 1),
                           EXPAND_THRESHOLD // (len(SPECTRAL_ORDERS) * max(window.n_fine, 1) * groups)))
    rows_per_launch = footprint.n_range if per_pulse <= settings.max_batch_rays else \
        max(1, settings.max_batch_rays // footprint.n_azimuth)
    spectrum = np.zeros((groups, n_pulses, 0 if exact else n_pad), np.complex64)
    paths = []
    totals = dict(energy=np.zeros(settings.max_depth), carried=np.zeros(settings.max_depth),
                  rays=np.zeros(settings.max_depth, np.int64), scatterers=np.zeros(settings.max_depth, np.int64),
                  outside=0.0, shadow=0)
    start = time.perf_counter()
    kernel = Kernel(scene, params, window, footprint, settings, material_table)
    for p0 in tqdm(range(0, n_pulses, per_batch), desc="trace", unit="batch", disable=not progress):
        p1 = min(n_pulses, p0 + per_batch)
        batch = slice(p0, p1)
        launch = Launch(antenna=geometry.positions[batch], r_near=r_near[batch], lref=lref[batch],
                        k0=footprint.k0[batch], along_limits=footprint.along_limits[batch])
        hist = None if exact else np.zeros((len(SPECTRAL_ORDERS), groups, p1 - p0, window.n_fine), np.complex64)
        for offset, part in _launches(launch, footprint, rows_per_launch, settings.max_batch_rays):
            try:
                out = kernel(part)
            except RuntimeError as exc:        # Dr.Jit wraps a Ctrl-C that lands while it traces the loop body
                if caused_by_interrupt(exc):
                    raise KeyboardInterrupt from exc
                raise
            if exact:
                paths.append(_path_list(out["paths"], p0 + offset))
            else:
                hist[:, :, offset:offset + part.n_pulses] += out["hist"]
            for name in ("energy", "carried", "rays", "scatterers", "outside", "shadow"):
                totals[name] = totals[name] + out[name]
        if not exact:
            for g in range(groups):
                spectrum[g, batch] = reduce_deposit(hist[:, g], window.fs, window.oversample, params.frequency,
                                                    settings.range_kernel, n_pad)
    seconds = time.perf_counter() - start
    return TraceResult(spectrum=spectrum.sum(axis=0) if groups > 1 else spectrum[0], reference_length=lref,
                       energy_per_order=totals["energy"], energy_outside_window=float(totals["outside"]),
                       rays_per_order=totals["rays"], shadow_rays=int(totals["shadow"]), seconds=seconds,
                       spectrum_per_order=spectrum if settings.split_bounces and not exact else None,
                       carried_power_per_order=totals["carried"],
                       paths=PathList.concatenate(paths) if exact else None, split=settings.split_bounces,
                       scatterers_per_order=totals["scatterers"], n_pad=0 if exact else n_pad)


def _launches(launch: Launch, footprint: RayFootprint, rows: int, max_rays: int):
    """The kernel launches of one pulse batch: coarse tubes in chunks of ``rows`` lattice rows,
    then each refinement group's cells near the batch's beam, at most ``max_rays`` tubes each
    (a single pulse's tubes are split when they alone exceed it). Yields ``(offset, launch)``:
    the launch's first pulse within the batch, and the launch."""
    for j0 in range(0, footprint.n_range, rows):
        yield 0, dataclasses.replace(launch, rows=(j0, min(footprint.n_range, j0 + rows)))
    lo, hi = int(launch.k0.min()) - 1, int(launch.k0.max()) + footprint.n_azimuth + 1
    for group in footprint.refinements:
        near = group.cells[(group.cells[:, 0] >= lo) & (group.cells[:, 0] <= hi)]
        if near.shape[0] == 0:
            continue
        per_cell = group.factor ** 2
        pulses = max(1, min(launch.n_pulses, max_rays // (per_cell * near.shape[0])))
        cells = max(1, max_rays // (per_cell * pulses))
        for q0 in range(0, launch.n_pulses, pulses):
            q = slice(q0, q0 + pulses)
            part = dataclasses.replace(launch, antenna=launch.antenna[q], r_near=launch.r_near[q],
                                       lref=launch.lref[q], k0=launch.k0[q], along_limits=launch.along_limits[q])
            for c0 in range(0, near.shape[0], cells):
                yield q0, dataclasses.replace(part, refinement=Refinement(group.factor, near[c0:c0 + cells]))


def _path_list(found: dict, p0: int) -> "PathList":
    """The exact kernel's terms as a PathList with acquisition pulse indices."""
    return PathList(pulse=found["path_pulse"].astype(np.int32) + np.int32(p0),
                    order=found["path_order"].astype(np.uint8), position=found["path_pos"],
                    value=(found["path_re"] + 1j * found["path_im"]).astype(np.complex64),
                    spectral=(np.asarray(SPECTRAL_ORDERS)[found["path_spectral"]]).astype(np.int8))


def caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in the exception's cause/context chain."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _bounding_sphere(scene: mi.Scene) -> tuple[float, np.ndarray]:
    bbox = scene.bbox()
    lo, hi = np.array(bbox.min, float), np.array(bbox.max, float)
    return 0.5 * float(np.linalg.norm(hi - lo)), 0.5 * (lo + hi)


