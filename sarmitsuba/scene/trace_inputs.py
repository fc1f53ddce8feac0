"""What the tracer consumes: its settings, the planned fast-time window and ray lattice, and
the material table (the contracts between scene loading, planning and tracing; docs/design.md section 2).

* :class:`TraceSettings` -- the ``sbr`` integrator's parameters (read by the plugin, overridden by
  the CLI);
* :class:`FastTimeWindow` -- fast-time sampling shared by all pulses (:func:`sarmitsuba.scene.planning.fast_time_window`);
* :class:`RayFootprint` -- the world-fixed lattice of ray-tube aim points, its refinement around
  small objects and the clutter scatterers' surface lattice (:func:`sarmitsuba.scene.planning.ray_footprint`);
* :class:`MaterialTable` -- reflection coefficients and clutter models per shape
  (:func:`sarmitsuba.scene.loader.material_table`).

All are frozen dataclasses of NumPy arrays and Python numbers: no Dr.Jit types cross a stage boundary.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.radar import ParameterError
from ..core.valid_ranges import unknown_name
from .rough_tables import RoughTables

__all__ = ["AUTO", "TraceSettings", "FastTimeWindow", "Refinement", "RayFootprint", "MaterialTable", "POLARIMETRY_MODELS",
           "LIT_REGIONS", "RANGE_KERNELS", "GEOMETRY_PIPELINES"]

#: ``max_depth = auto``: the depth the scene calls for (docs/physics.md (DEP1)).
AUTO = "auto"
#: Values of the ``sbr`` parameter ``polarimetry``: the Jones model (default) and the scalar one.
POLARIMETRY_MODELS = ("jones", "scalar")
#: Values of the ``sbr`` parameter ``lit_regions`` (docs/physics.md (M1)-(M8), (T3)).
LIT_REGIONS = ("patches", "tiles")
#: Values of the ``sbr`` parameter ``geometry``: the mesh tracer's NumPy stages, or their Dr.Jit
#: kernels where a stage has one (docs/design.md section 10.1).
GEOMETRY_PIPELINES = ("reference", "fused")
#: The range kernels (``sbr`` ``range_kernel``): how a traced term reaches the fast-time samples
#: (docs/physics.md (D1)-(D5); the deposit itself is :mod:`sarmitsuba.tracing.deposit.fast_time`).
RANGE_KERNELS = ("nearest", "linear", "sinc", "exact")


@dataclass(frozen=True)
class TraceSettings:
    """Settings of the ``sbr`` integrator (see :mod:`sarmitsuba_plugins.sbr_integrator` for the manual).

    Attributes
    ----------
    max_depth : int or str
        Bounce orders traced, [1, 64]; ``"auto"`` (the default): the depth the scene calls for,
        chosen by a probe before the trace (:func:`sarmitsuba.tracing.driver.depth.choose_depth`,
        docs/physics.md (DEP1)-(DEP3)).
    depth_cap : int
        ``max_depth = auto``: the deepest order the probe traces and the render may choose, [1, 64].
    depth_tolerance_db : float, dB
        ``max_depth = auto``: the share of the image's energy that the orders left out may hold
        together, in (-200, 0) dB; -20 dB is an image NRMSE of about -20 dB against the cap's image.
    ray_spacing : float, m
        Ray-tube width at the scene centre; 0 = automatic (:func:`sarmitsuba.scene.planning.ray_spacing`).
        At most one resolution cell or ``sqrt(2 R_near (pi/2) / k)``, whichever is larger
        (:func:`sarmitsuba.scene.planning.check_ray_spacing`, docs/physics.md (T1)).
    range_kernel : str
        ``nearest``, ``linear``, ``sinc`` or ``exact`` (docs/physics.md (D1)-(D4)).
    oversample : int
        Fine fast-time bins per sample of the deposit grid, [1, 64].
    max_batch_rays : int
        Ceiling on the ray tubes of one kernel launch (>= 1024): pulses are batched and a pulse's
        lattice split to stay below it (one refined cell's ``m^2`` tubes are never split).
    seed : int
        Seed of the clutter scatterers' phases and positions, [0, 2^32).
    split_bounces : bool
        Keep each bounce order's contributions separately.
    scatterers : bool
        Also sum every term coherently at its phase centre, for the scatterer catalogue
        (``render --scatterers``, docs/physics.md (SC1)-(SC4)). ``lit_regions = patches`` only.
    scatterer_spacing : float, m
        Cell size of the surface-attached clutter scatterer lattice; 0 = automatic
        (:func:`sarmitsuba.scene.planning.scatterer_spacing`). Independent of ``ray_spacing``.
    patch_size : float, m
        Side of the patches fixed on every face, the integration elements of
        ``lit_regions = patches`` (docs/physics.md (M1)); 0 = automatic
        (:func:`sarmitsuba.scene.planning.patch_size`). Rounded to a whole number of scatterer
        cells; a patch whose corners' quadratic phase ``k P^2 / (2 R_near)`` exceeds pi/4 (and that
        is larger than the automatic one) is refused when the scene is planned, with the largest
        valid value (docs/physics.md (M1')).
    tubes_per_object : int
        Objects (Mitsuba shapes) smaller than 8 default ray tubes are traced with tubes
        ``size / tubes_per_object`` wide (docs/physics.md (T2)); 0 = no refinement.
    pulses_per_trace : int
        Pulses of a sub-aperture, which share one trace of the ray tubes (docs/physics.md (T3)),
        [0, 65536]; 1 = every pulse traced on its own (the reference); 0 = automatic
        (:func:`sarmitsuba.tracing.driver.trace.pulses_per_trace`).
        Its range is its bound: the boundaries' motion (M8) keeps even one trace of the whole
        aperture close to per-pulse tracing (docs/physics.md (T3)).
    cancel_interior : bool
        Skip the PO terms that neighbouring tubes cancel exactly (docs/physics.md (PO5)); false
        evaluates every term (slower; the reference the cancellation is checked against).
    diffraction : bool
        Add the fringe waves of the mesh's edges to physical optics: equivalent edge currents on
        every wedge and free edge of the lit regions, at every bounce order (docs/physics.md
        (E1)-(E5), :mod:`sarmitsuba.tracing.integration.edges`). ``lit_regions = patches`` only; false is
        physical optics alone.
    polarimetry : str
        ``jones`` (default): every ray tube carries a Jones matrix (docs/physics.md (P1)-(P8)),
        for any ``polarization``; ``scalar``: a single co-polarised channel (``HH`` or ``VV``)
        takes the scalar coefficients of (R), (P6) instead, exact only where every facet of a
        path contains H (an accuracy knob, ``benchmarks/polarimetry.py``). Cross-polarised
        channels always need ``jones``.
    lit_regions : str
        ``patches`` (default): scattering anchored to the mesh (docs/physics.md (M1)-(M8)): every
        face's patches, fixed in its own frame, integrate physical optics exactly over what the
        antenna sees of them, through chains of mirrors found by rays, so the image depends on
        the scene alone. ``tiles``: the fast preview; each ray tube integrates its whole tile on
        the ray lattice, so a facet's lit region is bounded by the tubes' staircase, which moves
        with the lattice (T3). Shapes that are not triangle meshes (spheres) are always traced
        with tubes.
    ground_shapes : str
        The shapes that stand for ground continuing beyond the scene, whose free rims are
        truncations (no physical-optics rim terms, no edge currents, docs/physics.md (M10)):
        ``auto`` (ids ``ground``, ``*-ground``, ``*_ground``), ``none``, or a comma-separated list
        of shape ids (:func:`sarmitsuba.scene.ground.ground_shapes`). ``lit_regions = patches`` only.
    geometry : str
        How the mesh tracer's geometry runs (docs/design.md section 10.1): ``fused`` (default)
        the Dr.Jit kernels of the stages that have one (:mod:`sarmitsuba.tracing.fused`), the
        NumPy stages elsewhere; ``reference`` the NumPy stages alone, the readable reference. The same physics: the two
        agree but for rows that rounding decides. ``lit_regions = patches`` only.
    """

    max_depth: "int | str" = "auto"
    depth_cap: int = 8
    depth_tolerance_db: float = -20.0
    ray_spacing: float = 0.0
    range_kernel: str = "linear"
    oversample: int = 8
    max_batch_rays: int = 1 << 18
    seed: int = 0
    split_bounces: bool = False
    scatterers: bool = False
    scatterer_spacing: float = 0.0
    tubes_per_object: int = 48
    pulses_per_trace: int = 0
    cancel_interior: bool = True
    diffraction: bool = True
    polarimetry: str = "jones"
    lit_regions: str = "patches"
    patch_size: float = 0.0
    ground_shapes: str = "auto"
    geometry: str = "fused"

    def __post_init__(self) -> None:
        if self.max_depth != AUTO and (isinstance(self.max_depth, str) or int(self.max_depth) != self.max_depth
                                       or not 1 <= self.max_depth <= 64):
            raise ParameterError(f"max_depth = {self.max_depth!r} must be a whole number in [1, 64] or 'auto' "
                                 "(the depth the scene calls for)")
        if int(self.depth_cap) != self.depth_cap or not 1 <= self.depth_cap <= 64:
            raise ParameterError(f"depth_cap = {self.depth_cap} must be a whole number in [1, 64] (the deepest "
                                 "order max_depth = auto may trace; default 8)")
        if not -200 < self.depth_tolerance_db < 0:
            raise ParameterError(f"depth_tolerance_db = {self.depth_tolerance_db} dB must lie in (-200, 0) dB "
                                 "(the energy share the orders left out may hold; default -20)")
        for name in ("ray_spacing", "scatterer_spacing", "patch_size"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ParameterError(f"{name} = {value} m must be >= 0 (0 = automatic)")
        if self.range_kernel not in RANGE_KERNELS:
            raise ParameterError(f"range_kernel = {self.range_kernel!r}; valid values: {', '.join(RANGE_KERNELS)}")
        if int(self.oversample) != self.oversample or not 1 <= self.oversample <= 64:
            raise ParameterError(f"oversample = {self.oversample} must be a whole number in [1, 64]")
        if int(self.max_batch_rays) != self.max_batch_rays or self.max_batch_rays < 1024:
            raise ParameterError(f"max_batch_rays = {self.max_batch_rays} must be a whole number >= 1024")
        if int(self.seed) != self.seed or not 0 <= self.seed < 2**32:
            raise ParameterError(f"seed = {self.seed} must be a whole number in [0, 2^32)")
        if int(self.tubes_per_object) != self.tubes_per_object or not 0 <= self.tubes_per_object <= 256:
            raise ParameterError(f"tubes_per_object = {self.tubes_per_object} must be a whole number in [0, 256] "
                                 "(0 = no refinement around small objects)")
        if self.polarimetry not in POLARIMETRY_MODELS:
            raise ParameterError(f"polarimetry = {self.polarimetry!r}; valid values: "
                                 f"{', '.join(repr(m) for m in POLARIMETRY_MODELS)} (jones: a Jones matrix per "
                                 "ray tube; scalar: one co-polarised channel with scalar coefficients)")
        if self.lit_regions not in LIT_REGIONS:
            raise ParameterError(f"lit_regions = {self.lit_regions!r}; valid values: "
                                 f"{', '.join(repr(m) for m in LIT_REGIONS)} (patches: scattering anchored to the mesh, "
                                 "docs/physics.md (M1)-(M8); tiles: the ray tubes' tiles, a fast preview)")
        if self.scatterers and self.lit_regions != "patches":
            raise ParameterError(f"scatterers = true needs lit_regions = patches (got {self.lit_regions!r}): the "
                                 "catalogue names the mesh's surfaces, which the tiles' tubes do not follow")
        if self.geometry not in GEOMETRY_PIPELINES:
            raise ParameterError(f"geometry = {self.geometry!r}; valid values: "
                                 f"{', '.join(repr(m) for m in GEOMETRY_PIPELINES)} (reference: the NumPy stages; "
                                 "fused: the Dr.Jit kernels where a stage has one)")
        if int(self.pulses_per_trace) != self.pulses_per_trace or not 0 <= self.pulses_per_trace <= 65536:
            raise ParameterError(f"pulses_per_trace = {self.pulses_per_trace} must be a whole number in [0, 65536] "
                                 "(1 = trace every pulse, 0 = automatic)")

    @property
    def auto_depth(self) -> bool:
        """``max_depth = auto``: the depth is still to be chosen (:func:`~sarmitsuba.tracing.driver.depth.choose_depth`)."""
        return self.max_depth == AUTO

    @property
    def depth(self) -> int:
        """The bounce orders to plan and trace for: ``max_depth``, or ``depth_cap`` while it is ``auto``
        (the deepest the choice can reach: windows and cost bounds are sized for it)."""
        return int(self.depth_cap if self.max_depth == AUTO else self.max_depth)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Names of all settings."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def from_mapping(cls, values) -> "TraceSettings":
        """Build from a name -> value mapping (strings allowed), checking the names.

        Raises
        ------
        ParameterError
            Unknown names (listing the valid ones) or values that cannot be converted.
        """
        types = {f.name: f.type for f in fields(cls)}
        kwargs = {}
        for name, value in values.items():
            if name not in types:
                raise ParameterError(unknown_name("sbr integrator parameter", name, types))
            try:
                if name == "max_depth":
                    kwargs[name] = _depth(value)
                    continue
                kwargs[name] = {"int": int, "float": float, "str": str, "bool": _boolean}[types[name]](value)
            except (TypeError, ValueError):
                expected = {"int": "a whole number", "float": "a number", "str": "a string",
                            "bool": "true or false", "int | str": "a whole number or 'auto'"}[types[name]]
                raise ParameterError(f"sbr integrator parameter {name}: cannot use value {value!r}; give {expected}") \
                    from None
        return cls(**kwargs)


def _depth(value) -> "int | str":
    """``max_depth`` from a mapping: ``"auto"`` or a whole number (ValueError otherwise)."""
    if isinstance(value, str) and value.strip().lower() == AUTO:
        return AUTO
    if isinstance(value, float) and not value.is_integer():
        raise ValueError(value)
    return int(value)


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
class Refinement:
    """Cells of the coarse ray lattice traced with finer tubes (docs/physics.md (T2)).

    Attributes
    ----------
    factor : int
        Each cell is split into ``factor x factor`` tubes.
    cells : int64 [n, 2]
        World-fixed lattice indices ``(i, j)`` (along track, ground range) of the cells.
    """

    factor: int
    cells: np.ndarray


@dataclass(frozen=True)
class RayFootprint:
    """World-fixed ground-plane lattice the ray tubes are aimed at (docs/physics.md (T1)).

    Cell ``(i, j)`` has its centre at ``origin + (i + 1/2) spacing_azimuth track +
    (range_min + (j + 1/2) spacing_range) look`` (float64, m; the aim plane is horizontal
    through ``origin``). Pulse ``p`` aims one tube at each cell ``i`` in
    ``[k0[p], k0[p] + n_azimuth)``, ``j`` in ``[0, n_range)`` whose centre lies inside the
    pulse's along-track limits and whose direction lies inside the traced beam; cells listed
    in ``refinements`` are traced with ``factor^2`` smaller tubes instead.

    Attributes
    ----------
    origin, track, look : float64 [3]
        Lattice origin (the scene centre), unit track direction, unit horizontal look direction.
    spacing_azimuth, spacing_range : float, m
        Cell size along track (the tube width ``s``) and in ground range (``s / cos(theta)``).
    range_min : float, m
        Ground-range offset of the lattice's first row from ``origin``.
    n_azimuth, n_range : int
        Cells per pulse along track, and rows in ground range.
    k0 : int64 [n_pulses]
        First along-track cell of each pulse.
    along_limits : float64 [n_pulses, 2], m
        Along-track interval of aim points (relative to ``origin``) through which a pulse's
        rays can reach the scene's bounding box: its corners projected from the antenna onto
        the aim plane.
    scatterer_spacing : float, m
        Cell size of the surface-attached clutter scatterer lattice (docs/physics.md (C)).
    refinements : tuple of Refinement
        Finer tubes around objects smaller than ``planning.SMALL_OBJECT_TUBES`` tubes.
    patch_size : float, m
        Side of the patches fixed on every face (docs/physics.md (M1)), a whole number of
        scatterer cells.
    """

    origin: np.ndarray
    track: np.ndarray
    look: np.ndarray
    spacing_azimuth: float
    spacing_range: float
    range_min: float
    n_azimuth: int
    n_range: int
    k0: np.ndarray
    along_limits: np.ndarray
    scatterer_spacing: float
    refinements: tuple = ()
    patch_size: float = 0.0

    @property
    def rays_per_pulse(self) -> int:
        """Coarse cells per pulse (an upper bound of the coarse rays cast per pulse)."""
        return self.n_azimuth * self.n_range

    @property
    def refined_rays(self) -> int:
        """Fine tubes of all refined cells (each traced only by the pulses whose beam holds it)."""
        return int(sum(r.cells.shape[0] * r.factor**2 for r in self.refinements))

    def refined_mask(self) -> tuple[int, np.ndarray]:
        """``(i0, mask)``: uint8 [n_i, n_range], 1 where cell ``(i0 + a, j)`` is refined."""
        if not self.refinements:
            return 0, np.zeros((1, self.n_range), np.uint8)
        cells = np.concatenate([r.cells for r in self.refinements])
        i0 = int(cells[:, 0].min())
        mask = np.zeros((int(cells[:, 0].max()) - i0 + 1, self.n_range), np.uint8)
        mask[cells[:, 0] - i0, cells[:, 1]] = 1
        return i0, mask


@dataclass(frozen=True)
class MaterialTable:
    """Reflection coefficient tables and clutter models indexed by shape id, for the kernel.

    Attributes
    ----------
    row_of_shape : uint32 [max_shape_id + 1]
        Table row of each Mitsuba shape id (``reinterpret(UInt32, ShapePtr)``).
    table : complex64 [n_rows, n_cos]
        The material's reflection coefficient ``r(cos_i)`` of the channel's own polarisation
        (``r_tm`` for ``VV``, else ``r_te``) sampled uniformly for cos_i in [0, 1]; interpolated
        linearly. The scalar model's coefficient (R).
    names : list of str
        Material name of each row.
    clutter : float32 [n_rows, 2]
        Distributed-clutter model of each row: ``(kind, value)`` with kind 0 = none,
        1 = constant gamma (``sigma0 = value * sqrt(cos_i cos_b)``, value = gamma),
        2 = Lambertian (``sigma0 = value * |r|^2 cos_i cos_b``, value = 4 S^2), 3 = a randomly
        rough surface (sigma0 from the ``rough`` tables, value 1). See docs/physics.md (C), (RS6).
    shape_key : uint32 [max_shape_id + 1]
        Stable identity of each shape (CRC-32 of its scene id), so that clutter scatterers do
        not change between loads of the same scene.
    shape_origin : float64 [max_shape_id + 1, 3], m
        A point fixed to each shape (its vertex 0, :func:`sarmitsuba.scene.loader.shape_frame`) that
        anchors its clutter scatterer lattice: the scatterers move with the shape.
    shape_axes : float64 [max_shape_id + 1, 3, 3]
        Each shape's own orthonormal axes (rows), which orient its lattice in every facet plane
        and key the plane's hash: the scatterers turn with the shape (docs/physics.md (C)).
    specular : float32 [n_rows]
        Factor on the specular (PO and reflected) field of each row: ``sqrt(1 - S^2)`` for a
        Lambertian scattering coefficient ``S`` (the power the surface scatters diffusely), else
        1 (docs/physics.md (C)).
    table_te, table_tm : complex64 [n_rows, n_cos] or None
        ``r_te(cos_i)`` and ``r_tm(cos_i)`` on the same samples, for the Jones model
        (docs/physics.md (P3')).
    cross_pol : float32 [n_rows] or None
        The clutter's ``sigma0_HV`` relative to the mean co-polarised sigma0 of each row
        (docs/physics.md (P7)).
    grazing_delta : complex128 [n_rows] or None
        Each row's normalised surface impedance at grazing
        (:func:`sarmitsuba.scene.materials.grazing_impedance`; 0 for ``pec``): the grazing wave's
        numerical distance across a face (docs/physics.md (E6)).
    rough : RoughTables or None
        Sigma nought tables of the rows whose clutter kind is 3, a randomly rough surface
        (:class:`sarmitsuba.scene.rough_tables.RoughTables`, docs/physics.md (RS6)); None without one.
    """

    row_of_shape: np.ndarray
    table: np.ndarray
    names: list
    clutter: np.ndarray | None = None
    shape_key: np.ndarray | None = None
    shape_origin: np.ndarray | None = None
    shape_axes: np.ndarray | None = None
    specular: np.ndarray | None = None
    table_te: np.ndarray | None = None
    table_tm: np.ndarray | None = None
    cross_pol: np.ndarray | None = None
    grazing_delta: np.ndarray | None = None
    rough: RoughTables | None = None

    @property
    def has_clutter(self) -> bool:
        """Whether any material has a distributed-clutter model (switches the term on)."""
        return self.clutter is not None and bool(np.any(self.clutter[:, 0] > 0))
