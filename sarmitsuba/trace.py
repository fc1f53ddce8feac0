"""Shoot-and-bounce-rays tracer with a physical-optics return at every bounce (DESIGN.md sections 5, 6).

For every pulse, ray tubes leave the antenna toward a fixed ground-plane grid covering the
beam footprint (a world-fixed grid, so every pulse samples the surfaces identically). Each
tube follows specular bounces up to ``max_depth``; at every hit a shadow ray tests whether
the antenna sees the hit point, and the tube's footprint contributes the physical-optics
integral over that footprint (``docs/physics.md``, eq. (PO)):

    a = j (2 sqrt(pi) / lambda) * A_perp * (cos_b + cos_i) / (2 cos_i)
        * sinc(g . e1 / 2) * sinc(g . e2 / 2) * prod(r_1 .. r_k)

with ``A_perp = Omega s^2`` the tube cross-section at unfolded length ``s``, ``g = k (d - b)``
the phase gradient, ``e1, e2`` the tube edges projected on the facet and ``r_i`` the
reflection coefficients of this and all earlier bounces. The coherent sum over tubes gives
the PO radar cross-section (Ling, Chou and Lee, IEEE TAP 37(2), 1989; Knott, Shaeffer and
Tuley, *Radar Cross Section*, ch. 5).

Precision (DESIGN.md section 5): rays start near the scene (float64 offset carried
separately); the first leg and the return leg are float64 norms from the exact hit point;
a per-pulse float64 reference length is subtracted before anything becomes float32.

Output: per pulse, a complex deposit on a fine fast-time grid (``oversample`` x the
sampling rate) holding ``a * exp(-j k (L - L_ref))``; :mod:`sarmitsuba.binning` restores
the reference phase in float64 and range-compresses. The deposit kernel is the
``range_kernel`` accuracy knob (DESIGN.md section 5, docs/physics.md (D1)-(D4)):

* ``nearest``: the nearest fine bin (1 scatter; envelope shifted by up to half a fine bin);
* ``linear``: linear splatting on two bins (2 scatters; spectral droop ``sinc^2`` divided out);
* ``sinc``: Lanczos-windowed sinc on 8 bins (8 scatters; droop divided out, aliasing
  below the linear kernel's);
* ``exact``: no grid at all. Every visible path is kept (:class:`PathList`) and
  :mod:`sarmitsuba.binning` evaluates ``sum_i a_i sinc(B (t_n - tau_i))`` at every sample,
  the reference the other kernels are measured against; its cost grows as
  paths x samples.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, fields

import drjit as dr
import mitsuba as mi
import numpy as np
from tqdm import tqdm

from .constants import SPEED_OF_LIGHT
from .radar import AcquisitionGeometry, ParameterError, RadarParameters

__all__ = ["TraceSettings", "FastTimeWindow", "RayFootprint", "PathList", "TraceResult", "trace"]

_RANGE_KERNELS = ("nearest", "linear", "sinc", "exact")
#: Half-width (lobes) of the Lanczos window of the ``sinc`` deposit kernel: 2 * LANCZOS_A taps.
LANCZOS_A = 4


@dataclass(frozen=True)
class TraceSettings:
    """Settings of the ``sbr`` integrator (see :mod:`sarmitsuba_plugins.sbr_integrator`)."""

    max_depth: int = 3
    ray_spacing: float = 0.0
    range_kernel: str = "linear"
    oversample: int = 8
    max_batch_rays: int = 1 << 22
    seed: int = 0
    split_bounces: bool = False

    def __post_init__(self) -> None:
        if int(self.max_depth) != self.max_depth or not 1 <= self.max_depth <= 64:
            raise ParameterError(f"max_depth = {self.max_depth} must be a whole number in [1, 64]")
        if not (math.isfinite(self.ray_spacing) and self.ray_spacing >= 0):
            raise ParameterError(f"ray_spacing = {self.ray_spacing} m must be >= 0 (0 = automatic)")
        if self.range_kernel not in _RANGE_KERNELS:
            raise ParameterError(f"range_kernel = {self.range_kernel!r}; valid values: {', '.join(_RANGE_KERNELS)}")
        if int(self.oversample) != self.oversample or not 1 <= self.oversample <= 64:
            raise ParameterError(f"oversample = {self.oversample} must be a whole number in [1, 64]")
        if int(self.max_batch_rays) != self.max_batch_rays or self.max_batch_rays < 1024:
            raise ParameterError(f"max_batch_rays = {self.max_batch_rays} must be a whole number >= 1024")
        if int(self.seed) != self.seed or not 0 <= self.seed < 2**32:
            raise ParameterError(f"seed = {self.seed} must be a whole number in [0, 2^32)")

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Names of all settings."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def from_mapping(cls, values) -> "TraceSettings":
        """Build from a name -> value mapping (strings allowed), checking the names."""
        types = {f.name: f.type for f in fields(cls)}
        kwargs = {}
        for name, value in values.items():
            if name not in types:
                raise ParameterError(f"unknown sbr integrator parameter {name!r}; valid: {', '.join(types)}")
            try:
                kwargs[name] = {"int": int, "float": float, "str": str, "bool": _boolean}[types[name]](value)
            except (TypeError, ValueError):
                raise ParameterError(f"sbr integrator parameter {name}: cannot use value {value!r}") from None
        return cls(**kwargs)


def _boolean(value) -> bool:
    if isinstance(value, str):
        if value.lower() not in ("true", "false", "1", "0"):
            raise ValueError(value)
        return value.lower() in ("true", "1")
    return bool(value)


@dataclass(frozen=True)
class FastTimeWindow:
    """The fast-time sampling window shared by all pulses.

    Attributes
    ----------
    t0 : float, s
        Two-way delay of sample 0.
    fs : float, Hz
        Sampling rate.
    n_samples : int
        Samples per pulse.
    oversample : int
        Fine-grid factor used by the tracer's deposit.
    """

    t0: float
    fs: float
    n_samples: int
    oversample: int

    @property
    def fast_time(self) -> np.ndarray:
        """float64 [n_samples] sample delays, s."""
        return self.t0 + np.arange(self.n_samples, dtype=np.float64) / self.fs

    @property
    def n_fine(self) -> int:
        """Samples of the fine deposit grid."""
        return self.n_samples * self.oversample

    @property
    def fine_step_length(self) -> float:
        """Two-way path length of one fine bin, m."""
        return SPEED_OF_LIGHT / (self.fs * self.oversample)


@dataclass(frozen=True)
class RayFootprint:
    """World-fixed ground-plane grid the rays are aimed at.

    Ray ``(i, j)`` of pulse ``p`` aims at ``origin + (k0[p] + i + 1/2) * spacing_azimuth * track
    + (range_min + (j + 1/2) * spacing_range) * look`` (float64, m): cell centres, so that no
    aim point lies on the edges scenes tend to put at round coordinates. Rays whose point lies outside the
    ideal beam (``|along-track offset| > R sin(beta / 2)``, R the slant distance) or outside the scene's along-track
    extent are never cast.
    """

    origin: np.ndarray
    track: np.ndarray
    look: np.ndarray
    spacing_azimuth: float
    spacing_range: float
    range_min: float
    n_azimuth: int
    n_range: int
    azimuth_limits: tuple[float, float]
    k0: np.ndarray

    @property
    def rays_per_pulse(self) -> int:
        """Grid points per pulse (an upper bound of the rays cast per pulse)."""
        return self.n_azimuth * self.n_range


@dataclass(frozen=True)
class PathList:
    """Every visible path of an acquisition, kept for the ``exact`` range kernel.

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
        ``a exp(-j k (L - L_ref))``, the path's amplitude relative to the pulse's reference
        phase (the same quantity the gridded kernels deposit).
    """

    pulse: np.ndarray
    order: np.ndarray
    position: np.ndarray
    value: np.ndarray

    def of_order(self, order: int) -> "PathList":
        """The paths of one bounce order."""
        keep = self.order == order
        return PathList(self.pulse[keep], self.order[keep], self.position[keep], self.value[keep])

    @staticmethod
    def concatenate(parts: list["PathList"]) -> "PathList":
        """One list from per-batch lists."""
        if not parts:
            return PathList(np.zeros(0, np.int32), np.zeros(0, np.uint8), np.zeros(0), np.zeros(0, np.complex64))
        return PathList(*(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(PathList)))


@dataclass(frozen=True)
class TraceResult:
    """What the tracer returns for the whole acquisition.

    Attributes
    ----------
    deposit : complex64 [n_pulses, n_fine]
        Sum of ``a * exp(-j k (L - L_ref))`` per fine fast-time bin (kernel-weighted); all
        zero (shape [n_pulses, 0]) for the ``exact`` kernel, which keeps ``paths`` instead.
    carried_power_per_order : float64 [max_depth], sr
        Power carried into each bounce order by the rays that hit there, ``sum Omega |r_1 ... r_{k-1}|^2``
        (solid angle times the reflection losses so far): non-increasing with the order for
        passive materials, the energy-conservation check of the bounce loop.
    deposit_per_order : complex64 [max_depth, n_pulses, n_fine] or None
        The same split by bounce order (order k at index k - 1) when ``split_bounces`` is on;
        ``deposit`` is then their sum.
    reference_length : float64 [n_pulses], m
        Per-pulse reference two-way length ``L_ref = 2 |A - scene_center|``.
    energy_per_order : float64 [max_depth], m^2
        Incoherent sum of ``|a|^2`` of visible contributions per bounce order (1, 2, ...).
    energy_outside_window : float, m^2
        Energy of visible contributions whose delay fell outside the fast-time window.
    rays_per_order : int64 [max_depth]
        Closest-hit casts per bounce order (order 1 = primary rays).
    shadow_rays : int
        Shadow (visibility) casts.
    seconds : float
        Wall time of tracing, s.
    """

    deposit: np.ndarray
    reference_length: np.ndarray
    energy_per_order: np.ndarray
    energy_outside_window: float
    rays_per_order: np.ndarray
    shadow_rays: int
    seconds: float
    deposit_per_order: np.ndarray | None = None
    carried_power_per_order: np.ndarray | None = None
    #: Every visible path (``exact`` range kernel only).
    paths: PathList | None = None
    #: Whether the result was traced with ``split_bounces`` (paths keep their order anyway).
    split: bool = False

    @property
    def n_orders(self) -> int:
        """Bounce orders available separately (``split_bounces``), 0 when not split."""
        if self.deposit_per_order is not None:
            return self.deposit_per_order.shape[0]
        return len(self.energy_per_order) if self.split else 0

    def contributions(self, order: int | None = None) -> "np.ndarray | PathList":
        """What :func:`sarmitsuba.binning.to_raw_data` range-compresses: the fine deposit
        (complex64 [n_pulses, n_fine]) or, for the ``exact`` kernel, the :class:`PathList`;
        of all bounce orders, or of bounce order ``order`` (1, 2, ...; needs ``split_bounces``)."""
        if order is None:
            return self.paths if self.paths is not None else self.deposit
        if not 1 <= order <= self.n_orders:
            raise ParameterError(f"bounce order {order}: the result holds orders 1..{self.n_orders} "
                                 "(trace with split_bounces = true)")
        return self.paths.of_order(order) if self.paths is not None else self.deposit_per_order[order - 1]


def trace(scene: mi.Scene, params: RadarParameters, geometry: AcquisitionGeometry,
          window: FastTimeWindow, footprint: RayFootprint, settings: TraceSettings,
          material_table: "MaterialTable", progress: bool = False) -> TraceResult:
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
        Reflection coefficient against cos(incidence) per shape.
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
    offset = lref - SPEED_OF_LIGHT * window.t0

    exact = settings.range_kernel == "exact"
    groups = settings.max_depth if settings.split_bounces else 1
    n_fine = 0 if exact else window.n_fine
    per_batch = max(1, min(n_pulses, settings.max_batch_rays // max(footprint.rays_per_pulse * (
        settings.max_depth if exact else 1), 1), (1 << 23) // (max(n_fine, 1) * groups)))
    deposit = np.zeros((groups, n_pulses, n_fine), np.complex64)
    paths = []
    energy = np.zeros(settings.max_depth)
    carried = np.zeros(settings.max_depth)
    rays = np.zeros(settings.max_depth, np.int64)
    outside = 0.0
    shadow = 0
    start = time.perf_counter()
    kernel = _Kernel(scene, params, window, footprint, settings, material_table)
    for p0 in tqdm(range(0, n_pulses, per_batch), desc="trace", unit="batch", disable=not progress):
        p1 = min(n_pulses, p0 + per_batch)
        try:
            out = kernel(geometry.positions[p0:p1], r_near[p0:p1], lref[p0:p1], offset[p0:p1],
                         footprint.k0[p0:p1])
        except RuntimeError as exc:        # Dr.Jit wraps a Ctrl-C that lands while it traces the loop body
            if _caused_by_interrupt(exc):
                raise KeyboardInterrupt from exc
            raise
        if exact:
            paths.append(_offset_pulses(out["paths"], p0))
        else:
            deposit[:, p0:p1] = out["deposit"]
        energy += out["energy"]
        carried += out["carried"]
        rays += out["rays"]
        outside += out["outside"]
        shadow += out["shadow"]
    seconds = time.perf_counter() - start
    total = deposit.sum(axis=0) if groups > 1 else deposit[0]
    return TraceResult(total, lref, energy, float(outside), rays, int(shadow), seconds,
                       deposit_per_order=deposit if settings.split_bounces and not exact else None,
                       carried_power_per_order=carried, paths=PathList.concatenate(paths) if exact else None,
                       split=settings.split_bounces)


def _caused_by_interrupt(exc: BaseException) -> bool:
    """Whether a KeyboardInterrupt is in the exception's cause/context chain."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return False


def _offset_pulses(paths: PathList, p0: int) -> PathList:
    """Batch-local pulse indices to acquisition indices."""
    return PathList(paths.pulse + np.int32(p0), paths.order, paths.position, paths.value)


def _bounding_sphere(scene: mi.Scene) -> tuple[float, np.ndarray]:
    bbox = scene.bbox()
    lo, hi = np.array(bbox.min, float), np.array(bbox.max, float)
    return 0.5 * float(np.linalg.norm(hi - lo)), 0.5 * (lo + hi)


@dataclass(frozen=True)
class MaterialTable:
    """Reflection coefficient tables indexed by shape id, for the Dr.Jit kernel.

    Attributes
    ----------
    row_of_shape : uint32 [max_shape_id + 1]
        Table row of each Mitsuba shape id (``reinterpret(UInt32, ShapePtr)``).
    table : complex64 [n_rows, n_cos]
        ``r(cos_i)`` sampled uniformly for cos_i in [0, 1]; interpolated linearly.
    names : list of str
        Material name of each row.
    shape_key : uint32 [max_shape_id + 1]
        Stable identity of each shape (CRC-32 of its scene id), for clutter phases that do
        not change between loads of the same scene.
    clutter : float32 [n_rows, 2]
        Distributed-clutter model of each row: ``(kind, value)`` with kind 0 = none,
        1 = constant gamma (``sigma0 = value * sqrt(cos_i cos_b)``, value = gamma),
        2 = Lambertian (``sigma0 = value * |r|^2 cos_i cos_b``, value = 4 S^2). See
        docs/physics.md (C).
    """

    row_of_shape: np.ndarray
    table: np.ndarray
    names: list
    clutter: np.ndarray | None = None
    shape_key: np.ndarray | None = None

    @property
    def has_clutter(self) -> bool:
        """Whether any material has a distributed-clutter model (switches the term on)."""
        return self.clutter is not None and bool(np.any(self.clutter[:, 0] > 0))


class _Kernel:
    """One compiled tracing kernel per configuration; called once per pulse batch."""

    def __init__(self, scene, params, window, footprint, settings, material_table):
        self.scene = scene
        self.settings = settings
        self.window = window
        self.fp = footprint
        self.k = 2.0 * math.pi * params.frequency / SPEED_OF_LIGHT
        self.lam = params.wavelength
        half = math.sin(params.traced_half_angle)
        # along-track sines bounding the beam: squinted stripmap, or spotlight relative to the centre
        self.beam_sines = params.beam_sines if params.mode == "stripmap" else (-half, half)
        self.spotlight = params.mode == "spotlight"
        n_cos = material_table.table.shape[1]
        self.n_cos = n_cos
        self.row_of_shape = mi.UInt32(material_table.row_of_shape.astype(np.uint32))
        self.tab_re = mi.Float(material_table.table.real.ravel().astype(np.float32))
        self.tab_im = mi.Float(material_table.table.imag.ravel().astype(np.float32))
        self.clutter = material_table.has_clutter
        # absolute radiometry: 1 / (R_tx R_rx) spreading, relative to the pulse's R_ref^2 (eq. (R1))
        self.radiometry = params.transmit_power is not None
        # antenna pattern (an effect: absent from the kernel unless the sensor has dimensions)
        self.pattern = params.pattern_length > 0 or params.antenna_height > 0
        if self.pattern:
            boresight = footprint.look * params.ground_range - np.array([0.0, 0.0, params.altitude])
            boresight /= np.linalg.norm(boresight)
            # the aperture's long axis, turned with the squinted boresight (in the track-boresight plane)
            squint = math.radians(params.squint) if params.mode == "stripmap" else 0.0
            self.track = (math.cos(squint) * footprint.track - math.sin(squint) * boresight).tolist()
            self.elevation_axis = np.cross(footprint.track, boresight).tolist()
            self.length_in_wavelengths = params.pattern_length / params.wavelength
            self.height_in_wavelengths = params.antenna_height / params.wavelength
        if self.clutter:
            self.clutter_kind = mi.UInt32(material_table.clutter[:, 0].astype(np.uint32))
            self.clutter_value = mi.Float(material_table.clutter[:, 1].astype(np.float32))
            self.shape_key = mi.UInt32(material_table.shape_key.astype(np.uint32))

    def __call__(self, ant, r_near, lref, offset, k0):
        fp, win, st = self.fp, self.window, self.settings
        n_b = ant.shape[0]
        groups = st.max_depth if st.split_bounces else 1
        n_lanes = n_b * fp.rays_per_pulse
        f64, a64 = mi.Float64, mi.Array3f64

        # ---- lanes -> (pulse, i, j) -> ground aim point (float64) ----
        lane = dr.arange(mi.UInt32, n_lanes)
        pulse = lane // fp.rays_per_pulse
        rest = lane - pulse * fp.rays_per_pulse
        i = rest // fp.n_range
        j = rest - i * fp.n_range
        A = dr.gather(a64, a64(*(ant[:, c].copy() for c in range(3))), pulse)
        kk0 = dr.gather(mi.Int32, mi.Int32(k0.astype(np.int32)), pulse)
        along = (f64(mi.Int32(i) + kk0) + 0.5) * fp.spacing_azimuth    # cell centres: no aim point
        across = (f64(j) + 0.5) * fp.spacing_range + fp.range_min      # on edges at round coordinates
        P = a64(*fp.origin.tolist()) + a64(*fp.track.tolist()) * along + a64(*fp.look.tolist()) * across
        to_p = P - A
        r = dr.norm(to_p)
        d64 = to_p / r
        # ---- ideal beam and scene extent: sin(squint - beta / 2) <= sin(phi_ray) <= sin(squint + beta / 2),
        #      spotlight: |sin(phi_ray) - sin(phi_centre)| <= sin(beta / 2) ----
        track64 = a64(*fp.track.tolist())
        sin_ray = dr.dot(to_p, track64) / r
        if self.spotlight:                 # beam steered at the scene centre for every pulse
            to_c = a64(*fp.origin.tolist()) - A
            sin_ray -= dr.dot(to_c, track64) / dr.norm(to_c)
        active = mi.Bool((sin_ray >= self.beam_sines[0]) & (sin_ray <= self.beam_sines[1]))
        active &= (along >= fp.azimuth_limits[0]) & (along <= fp.azimuth_limits[1])
        # ---- tube: the ground cell's edges seen perpendicular to the ray, per metre of path ----
        # At the aim point (distance r) the tube's edges are the cell edges E_j projected
        # normal to d; at unfolded length s they scale by s / r, so on the ground plane the
        # footprints tile the cells exactly (area Omega s^2 with Omega = dA cos / r^2).
        e1 = mi.Vector3f((a64(*fp.track.tolist()) * fp.spacing_azimuth) / r)
        e2 = mi.Vector3f((a64(*fp.look.tolist()) * fp.spacing_range) / r)
        d = mi.Vector3f(d64)
        e1 = e1 - d * dr.dot(d, e1)
        e2 = e2 - d * dr.dot(d, e2)
        rn = dr.gather(f64, f64(r_near), pulse)
        origin = mi.Point3f(A + d64 * rn)
        ray = mi.Ray3f(origin, d)
        ctx = dict(
            A=A, cell_a=mi.UInt32(mi.Int32(i) + kk0), cell_r=j, g_tx=self._gain(d) if self.pattern else None,
            lref=dr.gather(f64, f64(lref), pulse), off=dr.gather(f64, f64(offset), pulse),
            rref=mi.Float(dr.gather(f64, f64(lref), pulse) * 0.5),
            base=pulse * win.n_fine, order_stride=n_b * win.n_fine,
            lane=lane,
            energy=dr.zeros(mi.Float, st.max_depth + 1), rays=dr.zeros(mi.UInt32, st.max_depth + 1),
            carried=dr.zeros(mi.Float, st.max_depth),
        )
        if st.range_kernel == "exact":          # every visible path: (lane, order) slots
            slots = n_lanes * st.max_depth
            ctx.update(path_pos=dr.zeros(f64, slots), path_re=dr.zeros(mi.Float, slots),
                       path_im=dr.zeros(mi.Float, slots), path_order=dr.zeros(mi.UInt32, slots))
            outputs = ("path_pos", "path_re", "path_im", "path_order")
        else:
            ctx.update(hist_re=dr.zeros(mi.Float, groups * n_b * win.n_fine),
                       hist_im=dr.zeros(mi.Float, groups * n_b * win.n_fine))
            outputs = ("hist_re", "hist_im")
        state = (ray, e1, e2, f64(0.0), a64(A), mi.Float(1.0), mi.Float(0.0), mi.Float(0.0), mi.UInt32(0), active)
        body = lambda *s: self._bounce(ctx, *s)   # noqa: E731
        if st.max_depth == 1:                       # no reflection loop in the kernel at all
            body(*state)
        else:
            dr.while_loop(state=state, cond=lambda *s: s[-1], body=body, labels=(
                "ray", "e1", "e2", "s", "p_prev", "gamma_re", "gamma_im", "r_tx", "depth", "active"), label="sbr")
        dr.eval(*(ctx[name] for name in outputs), ctx["energy"], ctx["rays"], ctx["carried"])
        energy = ctx["energy"].numpy().astype(np.float64)
        rays = ctx["rays"].numpy().astype(np.int64)
        if st.range_kernel == "exact":
            order = ctx["path_order"].numpy()
            keep = np.flatnonzero(order)
            found = dict(paths=PathList(
                pulse=(keep // (st.max_depth * fp.rays_per_pulse)).astype(np.int32), order=order[keep].astype(np.uint8),
                position=ctx["path_pos"].numpy()[keep],
                value=(ctx["path_re"].numpy()[keep] + 1j * ctx["path_im"].numpy()[keep]).astype(np.complex64)))
        else:
            hist = (ctx["hist_re"].numpy() + 1j * ctx["hist_im"].numpy()).astype(np.complex64)
            found = dict(deposit=hist.reshape(groups, n_b, win.n_fine))
        return dict(**found, energy=energy[:st.max_depth],
                    outside=float(energy[st.max_depth]), rays=rays[:st.max_depth],
                    carried=ctx["carried"].numpy().astype(np.float64),
                    shadow=int(rays[st.max_depth]))

    def _bounce(self, ctx, ray, t1, t2, s, p_prev, g_re, g_im, r_tx, depth, active):
        """One bounce: intersect, PO return to the antenna, reflect. Returns the new loop state."""
        f64 = type(s)
        a64 = type(ctx["A"])
        st, win = self.settings, self.window
        # ---- intersect ----
        dr.scatter_add(ctx["rays"], mi.UInt32(1), depth, active)
        si = self.scene.ray_intersect(ray, ray_flags=mi.RayFlags.Minimal, coherent=False, active=active)
        n = mi.Vector3f(si.n)
        active = active & si.is_valid() & (dr.squared_norm(n) > 0.5)   # degenerate triangle: NaN normal
        d = ray.d
        n = dr.select(dr.dot(n, d) > 0, -n, n)
        cos_i = -dr.dot(d, n)
        cos_safe = dr.maximum(cos_i, 1e-4)
        p64 = a64(si.p)
        to_ant = ctx["A"] - p64
        dist = dr.norm(to_ant)
        b = mi.Vector3f(to_ant / dist)
        cos_b = dr.dot(n, b)
        # leg length in float64 between exact hit points (not si.t: spawn_ray moves each
        # secondary origin ~1e-4 (1 + |p|) m off the surface, a position-dependent mm)
        s_new = s + dr.norm(p64 - p_prev)
        # ---- reflection coefficient r(cos_i) of the hit material ----
        row = dr.gather(mi.UInt32, self.row_of_shape, dr.reinterpret_array(mi.UInt32, si.shape), active)
        x = dr.clip(cos_i, 0.0, 1.0) * (self.n_cos - 1)
        i0 = mi.UInt32(dr.minimum(dr.floor(x), self.n_cos - 2))
        w = x - mi.Float(i0)
        idx = row * self.n_cos + i0
        r_re = dr.lerp(dr.gather(mi.Float, self.tab_re, idx, active), dr.gather(mi.Float, self.tab_re, idx + 1, active), w)
        r_im = dr.lerp(dr.gather(mi.Float, self.tab_im, idx, active), dr.gather(mi.Float, self.tab_im, idx + 1, active), w)
        dr.scatter_add(ctx["carried"], dr.norm(dr.cross(t1, t2)) * (g_re * g_re + g_im * g_im), depth, active)
        c_re = g_re * r_re - g_im * r_im          # prod r_1..r_k (this bounce included)
        c_im = g_re * r_im + g_im * r_re
        # ---- PO return of the tube footprint, eq. (PO) ----
        sf = mi.Float(s_new)
        e1, e2 = t1 * sf, t2 * sf                  # tube edges at this hit, normal to d
        area = dr.norm(dr.cross(e1, e2))          # A_perp = Omega s^2
        g = self.k * (d - b)
        x1 = 0.5 * dr.dot(g, e1 + d * (dr.dot(n, e1) / cos_safe))
        x2 = 0.5 * dr.dot(g, e2 + d * (dr.dot(n, e2) / cos_safe))
        mag = (2.0 * math.sqrt(math.pi) / self.lam) * area * (cos_b + cos_i) / (2.0 * cos_safe) \
            * _sinc(x1) * _sinc(x2)
        a_re, a_im = -mag * c_im, mag * c_re      # the PO factor j
        # ---- distributed clutter: a fixed scatterer per tube cell, eq. (C) ----
        if self.clutter:
            k_re, k_im = self._clutter(ctx, si, row, depth, cos_i, cos_b, area / cos_safe,
                                       r_re * r_re + r_im * r_im, g_re, g_im, active)
            a_re, a_im = a_re + k_re, a_im + k_im
        if self.pattern:                          # two-way antenna pattern, eq. (A)
            gain = ctx["g_tx"] * self._gain(-b)
            a_re, a_im = a_re * gain, a_im * gain
        if self.radiometry:                       # spreading R_ref^2 / (R_tx R_rx), eq. (R1)
            r_tx = dr.select(depth == 0, mi.Float(s_new), r_tx)
            spread = ctx["rref"] * ctx["rref"] / (r_tx * mi.Float(dist))
            a_re, a_im = a_re * spread, a_im * spread
        # ---- shadow test toward the antenna ----
        vis = active & (cos_b > 0)
        vis &= ~self.scene.ray_test(_spawn(si.p, n, b), vis)
        dr.scatter_add(ctx["rays"], mi.UInt32(1), st.max_depth, vis)
        # ---- deposit a * exp(-j k (L - L_ref)) on the fine fast-time grid ----
        rel = s_new + dist - ctx["lref"]
        phase = -self.k * rel
        phase = mi.Float(phase - (2.0 * math.pi) * dr.round(phase * (1.0 / (2.0 * math.pi))))
        sn, cs = dr.sincos(phase)
        v_re = a_re * cs - a_im * sn
        v_im = a_re * sn + a_im * cs
        pos = (ctx["off"] + rel) * (1.0 / win.fine_step_length)
        k_lo = dr.floor(pos)
        frac = mi.Float(pos - k_lo)
        k_lo = mi.Int32(k_lo)
        base = ctx["base"] + depth * ctx["order_stride"] if st.split_bounces else ctx["base"]
        if st.range_kernel == "nearest":
            k_lo = mi.Int32(dr.round(pos))
            inside = vis & (k_lo >= 0) & (k_lo < win.n_fine)
            self._deposit(ctx, base, k_lo, v_re, v_im, inside)
        elif st.range_kernel == "linear":
            inside = vis & (k_lo >= 0) & (k_lo < win.n_fine - 1)
            self._deposit(ctx, base, k_lo, v_re * (1.0 - frac), v_im * (1.0 - frac), inside)
            self._deposit(ctx, base, k_lo + 1, v_re * frac, v_im * frac, inside)
        elif st.range_kernel == "sinc":
            inside = vis & (k_lo >= LANCZOS_A - 1) & (k_lo < win.n_fine - LANCZOS_A)
            for m, w in _lanczos_weights(frac):
                self._deposit(ctx, base, k_lo + m, v_re * w, v_im * w, inside)
        else:                                     # exact: keep the path itself
            slot = ctx["lane"] * st.max_depth + depth
            coarse = pos * (1.0 / win.oversample)
            inside = vis & (coarse >= 0) & (coarse <= win.n_samples - 1)
            dr.scatter(ctx["path_pos"], coarse, slot, vis)
            dr.scatter(ctx["path_re"], v_re, slot, vis)
            dr.scatter(ctx["path_im"], v_im, slot, vis)
            dr.scatter(ctx["path_order"], depth + 1, slot, vis)
        power = a_re * a_re + a_im * a_im
        dr.scatter_add(ctx["energy"], power, depth, vis)
        dr.scatter_add(ctx["energy"], power, mi.UInt32(st.max_depth), vis & ~inside)
        # ---- next bounce: specular reflection ----
        d_next = d - 2.0 * dr.dot(d, n) * n
        t1 = t1 - 2.0 * dr.dot(t1, n) * n
        t2 = t2 - 2.0 * dr.dot(t2, n) * n
        ray = _spawn(si.p, n, d_next)
        depth = depth + 1
        active = active & (depth < st.max_depth)
        return ray, t1, t2, dr.select(active, s_new, s), dr.select(active, p64, p_prev), c_re, c_im, r_tx, depth, active

    def _gain(self, v):
        """One-way field pattern of the uniform aperture toward unit direction ``v`` (antenna -> scene):
        ``sinc(L_a sin(phi_az) / lambda) sinc(H_a sin(phi_el) / lambda)``, eq. (A)."""
        track = mi.Vector3f(*self.track)
        along = dr.dot(v, track)
        gain = mi.Float(1.0)
        if self.length_in_wavelengths > 0:
            gain *= _sinc_pi(self.length_in_wavelengths * along)
        if self.height_in_wavelengths > 0:
            across = dr.normalize(v - track * along)
            gain *= _sinc_pi(self.height_in_wavelengths * dr.dot(across, mi.Vector3f(*self.elevation_axis)))
        return gain

    def _clutter(self, ctx, si, row, depth, cos_i, cos_b, footprint, r2, g_re, g_im, active):
        """Clutter amplitude sqrt(sigma0 A_footprint) prod(r_1..r_{k-1}) exp(j phi_cell), eq. (C).

        ``phi_cell`` is uniform in [0, 2 pi), a hash (TEA) of the tube's world-fixed ground cell,
        the shape, the bounce order and the seed: the same scatterer for every pulse (coherent
        across the aperture), the same for the same seed, independent for another seed.
        """
        kind = dr.gather(mi.UInt32, self.clutter_kind, row, active)
        value = dr.gather(mi.Float, self.clutter_value, row, active)
        cosines = dr.maximum(cos_i, 0.0) * dr.maximum(cos_b, 0.0)
        sigma0 = dr.select(kind == 1, value * dr.sqrt(cosines), dr.select(kind == 2, value * r2 * cosines, 0.0))
        amp = dr.sqrt(sigma0 * footprint)
        key = dr.gather(mi.UInt32, self.shape_key, dr.reinterpret_array(mi.UInt32, si.shape), active)
        h0, h1 = mi.sample_tea_32(ctx["cell_a"], ctx["cell_r"] ^ (depth << 27))
        u = mi.sample_tea_float32(h0 ^ key, h1 ^ mi.UInt32(self.settings.seed))
        sn, cs = dr.sincos(2.0 * math.pi * u)
        return amp * (g_re * cs - g_im * sn), amp * (g_re * sn + g_im * cs)

    @staticmethod
    def _deposit(ctx, base, k, v_re, v_im, mask):
        index = base + mi.UInt32(k)
        dr.scatter_add(ctx["hist_re"], v_re, index, mask)
        dr.scatter_add(ctx["hist_im"], v_im, index, mask)


def _spawn(p, n, d):
    """Ray leaving the surface point ``p`` (normal ``n`` on the side of ``d``) toward ``d``.

    The origin is lifted ``1e-4 m + 1e-6 |p|`` off the surface: enough to clear float32
    rounding of ``p`` and Embree's own error, and (unlike Mitsuba's ``spawn_ray``, which lifts
    by ~9e-5 (1 + max|p_i|)) almost independent of where the scene sits, so a translated
    scene decides visibility near edges the same way.
    """
    lift = 1e-4 + 1e-6 * dr.norm(p)
    return mi.Ray3f(p + n * lift, d)


def _lanczos_weights(frac):
    """Taps ``(m, w_m)``, m = -A+1 .. A, of the Lanczos kernel ``L(x) = sinc(x) sinc(x / A)`` at
    ``x = m - frac`` (``frac`` in [0, 1), A = :data:`LANCZOS_A`); docs/physics.md (D3).

    Uses ``sin(pi (m - f)) = -(-1)^m sin(pi f)`` and the angle-sum form of ``sin(pi (m - f) / A)``:
    one ``sincos`` per path, not one per tap.
    """
    a = LANCZOS_A
    s1 = dr.sin(math.pi * frac)
    s2, c2 = dr.sincos((math.pi / a) * frac)
    taps = []
    for m in range(-a + 1, a + 1):
        x = m - frac
        num = -(1.0 if m % 2 == 0 else -1.0) * s1 * (math.sin(math.pi * m / a) * c2 - math.cos(math.pi * m / a) * s2)
        w = dr.select(dr.abs(x) < 1e-6, 1.0, num * (a / (math.pi * math.pi)) / dr.maximum(x * x, 1e-12))
        taps.append((m, w))
    return taps


def _sinc(x):
    """sin(x) / x, 1 at 0 (unnormalised sinc)."""
    return dr.select(dr.abs(x) < 1e-4, 1.0, dr.sin(x) / x)


def _sinc_pi(x):
    """sin(pi x) / (pi x), 1 at 0 (normalised sinc, as numpy.sinc)."""
    return _sinc(math.pi * x)
