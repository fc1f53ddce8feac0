"""Derivatives of the raw data and the image with respect to scene parameters.

Forward mode, one parameter at a time: :func:`raw_derivative` traces the scene once with the
parameter's tangent carried through the tracing kernels by Dr.Jit's automatic differentiation
(:mod:`sarmitsuba.tracing.derivatives.tangents`) and bins it as the raw data are binned, giving
``d raw / d p`` (complex, per range sample and pulse, in the raw data's units per unit of ``p``).
The focusers are linear in the raw data (docs/physics.md (AD1)), so the image's derivative is the
derivative focused as the raw data are (:func:`sarmitsuba.refocus` with the render's options).

Reverse mode, for many parameters at once: :func:`raw_gradient` takes the gradient of a real loss
with respect to the raw data, carries it back through the binning's adjoint
(:func:`sarmitsuba.signal.binning.raw_data_adjoint`,
:func:`sarmitsuba.tracing.deposit.fast_time.reduce_deposit_adjoint`) to each launch's histogram, and through
the tracing kernels to the reflection tables (Dr.Jit's reverse mode), then to each parameter.

Parameters: a material's relative permittivity, conductivity or (slabs) thickness, for
``half_space`` and ``slab`` materials (``radar`` and ITU-named), and a rough material's
scattering coefficient (:class:`MaterialParameter`); a mesh's translation, rotation, height or
vertices (:class:`ShapeParameter`, docs/physics.md (AD4): the host geometry differenced in
float64 with the lit regions' topology held, the kernels by Dr.Jit; shadow edges and mirrored
windows move with the shapes, :class:`~sarmitsuba.tracing.derivatives.lane_pairs.GeometryChange`
where the topology changes). With the
gridded range kernels (``linear``, ``sinc``) and without ``split_bounces``. ``at=`` moves shapes
before the trace (:func:`moved_raw` gives those raw data).

A loss on the image: :func:`gradients` (``sarmitsuba.gradients``) focuses the raw data by direct
or fast factorised backprojection as a float64 linear map
(:class:`sarmitsuba.focus.linear.BackprojectionOperator`,
:class:`sarmitsuba.focus.ffbp_linear.FFBPOperator`),
evaluates the loss and its gradient there, carries it to the raw data by the map's adjoint (AD1)
and from there by :func:`raw_gradient`.

Example::

    d = raw_derivative("scene.xml", MaterialParameter("wall", "relative_permittivity"))
    d.data            # complex64 [n_pulses, n_samples]: d raw / d eps_r
    g = sarmitsuba.gradients("scene.xml", AmplitudeLoss(target), [MaterialParameter("wall", "conductivity")])
    g.loss, g.gradient    # L and {parameter: dL/dp}
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import Any, Mapping

import drjit as dr
import numpy as np

from .core.radar import ParameterError
from .core.raw import RawData
from .scene.loader import TABLE_SIZE, load_scene
from .signal import binning
from .tracing.mesh.facets import scene_meshes
from .tracing.driver.depth import choose_depth
from .tracing.derivatives.geometry_tangents import GeometryMove, move_scene
from .tracing.derivatives.lane_pairs import GeometryChange, GeometryChangeWarning
from .tracing.loops import evaluated_loops
from .tracing.deposit.adjoint import seed_scale
from .tracing.deposit.fast_time import adjoint_gain, reduce_deposit_adjoint
from .tracing.driver.kernel import Kernel
from .tracing.derivatives.tangents import MATERIAL_PARAMETERS, AdjointKernel, TangentKernel, flat_tangents, moved_tracer, row_tangent
from .tracing.driver.trace import prepare_trace, trace, trace_batch

__all__ = ["MaterialParameter", "ShapeParameter", "raw_derivative", "moved_raw", "raw_gradient", "AmplitudeLoss", "Gradients", "gradients"]


@dataclass(frozen=True)
class MaterialParameter:
    """A material's parameter: ``material`` its id in the scene (the BSDF's ``id``), ``name``
    ``"relative_permittivity"`` (the real part ``eps_r`` of ``eta``, 1), ``"conductivity"``
    (``sigma``, S/m; ``eta = eps_r - j sigma / (omega eps_0)``), ``"thickness"`` (a slab's, m),
    ``"scattering_coefficient"`` (``S`` of an itu-radio-material's Lambertian clutter, 1) or
    ``"gamma"`` (a radar material's constant-gamma clutter, linear: ``10^(gamma_db / 10)``, 1),
    ``"rms_height"`` or ``"correlation_length"`` (a rough surface's, m; docs/physics.md (RS6)).
    For ITU-named materials these are the values at the carrier."""

    material: str
    name: str

    def __post_init__(self):
        if self.name not in MATERIAL_PARAMETERS:
            raise ParameterError(f"MaterialParameter name = {self.name!r}; valid: {', '.join(MATERIAL_PARAMETERS)}")


#: The geometric parameters' kinds and units (:class:`ShapeParameter`).
SHAPE_PARAMETERS = {"translation": "m", "rotation": "rad", "vertices": "m", "height": "m"}
#: The host geometry's central-difference step (docs/physics.md (AD4)), m of displacement.
GEOMETRY_STEP = 1e-6


@dataclass(frozen=True)
class ShapeParameter:
    """A shape's geometry (docs/physics.md (AD4)): ``shape`` its id in the scene, ``kind``

    * ``"translation"``: the shape moves along ``axis`` (m);
    * ``"rotation"``: it turns about ``axis`` (right-handed) through ``center`` (world, m; default
      the centre of its bounding box), rad;
    * ``"vertices"``: its vertices of index ``vertices`` (in the loaded mesh's vertex buffer,
      ``shape.vertex_positions_buffer()``: an OBJ's vertices in the order its faces first use
      them, not the file's order) move along ``axis`` (m); one vertex and one axis is one
      coordinate of the vertex gradient;
    * ``"height"``: every vertex rises in proportion to its height above the shape's lowest one,
      so that its top rises by one (m): a building's height, its base kept.

    ``axis`` is any non-zero vector (made unit)."""

    shape: str
    kind: str
    axis: tuple = (0.0, 0.0, 1.0)
    vertices: tuple | None = None
    center: tuple | None = None

    def __post_init__(self):
        for name in ("axis", "vertices", "center"):           # hashable: a gradient's dict key
            if getattr(self, name) is not None:
                object.__setattr__(self, name, tuple(np.asarray(getattr(self, name)).ravel().tolist()))
        if self.kind not in SHAPE_PARAMETERS:
            raise ParameterError(f"ShapeParameter kind = {self.kind!r}; valid: {', '.join(SHAPE_PARAMETERS)}")
        axis = np.asarray(self.axis, float)
        if axis.shape != (3,) or not np.all(np.isfinite(axis)) or not np.any(axis):
            raise ParameterError(f"ShapeParameter axis = {self.axis!r}: give three finite numbers, not all zero")
        if self.kind == "vertices" and not self.vertices:
            raise ParameterError("ShapeParameter kind 'vertices' needs vertices = (indices of the mesh's vertices)")

    def index(self, loaded) -> int:
        """The shape's index in ``loaded.scene.shapes()``; ParameterError naming the scene's shapes
        where it has none of that id, or where it is not a mesh."""
        shapes = list(loaded.scene.shapes())
        index = [k for k, shape in enumerate(shapes) if shape.id() == self.shape]
        if not index:
            raise ParameterError(f"shape {self.shape!r} is not in the scene; its shapes: "
                                 f"{', '.join(sorted(s.id() for s in shapes))}")
        if not shapes[index[0]].is_mesh():
            raise ParameterError(f"shape {self.shape!r} is not a mesh: geometric derivatives are taken of meshes")
        return index[0]

    def displaced(self, loaded, vertices: np.ndarray, amount: float) -> np.ndarray:
        """``vertices`` (float64 [n_v, 3], the shape's, tracing frame) with the parameter moved by
        ``amount`` (its unit): a rotation turns them exactly (Rodrigues), every other kind adds
        ``amount`` times its displacement field."""
        if self.kind != "rotation":
            return vertices + float(amount) * self._field(loaded, vertices)
        axis = np.asarray(self.axis, float) / np.linalg.norm(self.axis)
        c = self._center(loaded, vertices)
        r = vertices - c
        cos, sin = math.cos(amount), math.sin(amount)
        return c + r * cos + np.cross(axis, r) * sin + np.outer(r @ axis, axis) * (1.0 - cos)

    def _center(self, loaded, v):
        return 0.5 * (v.min(axis=0) + v.max(axis=0)) if self.center is None else \
            np.asarray(self.center, float) - loaded.offset

    def move(self, loaded) -> GeometryMove:
        """The :class:`~sarmitsuba.tracing.derivatives.geometry_tangents.GeometryMove` of this parameter in
        ``loaded`` (a LoadedScene): each vertex's displacement per unit, in its tracing frame."""
        k = self.index(loaded)
        v = scene_meshes(loaded.scene)[k][0]
        field = self._field(loaded, v)
        step = GEOMETRY_STEP
        if self.kind == "rotation":
            step = GEOMETRY_STEP / max(float(np.linalg.norm(v - self._center(loaded, v), axis=1).max()), 1e-9)
        return GeometryMove(k, field, step)

    def _field(self, loaded, v):
        """Each vertex's displacement per unit of the parameter, float64 [n_v, 3]."""
        axis = np.asarray(self.axis, float) / np.linalg.norm(self.axis)
        field = np.zeros_like(v)
        if self.kind == "translation":
            field[:] = axis
        elif self.kind == "rotation":
            field = np.cross(axis, v - self._center(loaded, v))
        elif self.kind == "vertices":
            rows = np.asarray(self.vertices, np.int64)
            if rows.min() < 0 or rows.max() >= len(v):
                raise ParameterError(f"ShapeParameter vertices {self.vertices!r}: shape {self.shape!r} has vertices "
                                     f"0 .. {len(v) - 1}")
            field[rows] = axis
        else:
            low, high = v[:, 2].min(), v[:, 2].max()
            if high - low <= 0:
                raise ParameterError(f"shape {self.shape!r} is flat: it has no height")
            field[:, 2] = (v[:, 2] - low) / (high - low)
        return field


def _unit(parameter) -> str:
    if isinstance(parameter, ShapeParameter):
        return SHAPE_PARAMETERS[parameter.kind]
    return MATERIAL_PARAMETERS[parameter.name]


def _checked(parameter):
    if not isinstance(parameter, (MaterialParameter, ShapeParameter)):
        raise ParameterError(f"parameters must be MaterialParameter or ShapeParameter, got {type(parameter).__name__}")
    return parameter


def _material(scene, table, name: str, frequency: float):
    """The table row, the electromagnetic model and the BSDF of the material ``name``; ParameterError
    naming the scene's materials when there is none of that name."""
    if name not in table.names:
        raise ParameterError(f"material {name!r} is not in the scene; its materials: {', '.join(sorted(set(table.names)))}")
    for shape in scene.shapes():
        bsdf = shape.bsdf()
        if getattr(bsdf, "name", None) == name:
            if getattr(bsdf, "role_surfaces", None):
                raise ParameterError(f"material {name!r} gives its {', '.join(sorted(bsdf.role_surfaces))} shapes the "
                                     "roughness preset's role surfaces (docs/physics.md (RS8)), so it is more than "
                                     "one table row; derive it without --material-set roughness=..., or give those "
                                     "shapes a material of their own")
            return table.names.index(name), bsdf.material_at(frequency), bsdf
    raise ParameterError(f"material {name!r} is not used by any shape")


def _material_tangents(loaded, setup, parameters) -> dict:
    """MaterialParameter -> (table row, its tangent), after checking every parameter against the
    scene (a material that is not there, a ``pec`` one, a shape that is not a mesh), so that a
    refusal comes before any tracing."""
    for parameter in parameters:
        if isinstance(parameter, ShapeParameter):
            parameter.index(loaded)
    rows = {}
    for parameter in parameters:
        if isinstance(parameter, MaterialParameter):
            row, material, bsdf = _material(loaded.scene, setup.table, parameter.material, loaded.params.frequency)
            rows[parameter] = row, row_tangent(material, bsdf, parameter.name, loaded.params.frequency, TABLE_SIZE)
    return rows


def raw_derivative(source: Any, parameter, *, sensor_overrides: Mapping[str, Any] | None = None,
                   integrator_overrides: Mapping[str, Any] | None = None, at: Mapping | None = None) -> "RawData | dict":
    """``d raw / d p``: the derivative of the scene's raw data with respect to ``parameter``.

    Parameters
    ----------
    source : str or Path or Scene
        As :func:`sarmitsuba.simulate` (XML path, built-in name, ``sionna:NAME``).
    parameter : MaterialParameter or ShapeParameter
    sensor_overrides, integrator_overrides : mapping, optional
        As :func:`sarmitsuba.simulate`.
    at : mapping, optional
        ShapeParameter -> amount (its unit): the shapes moved that far first (the derivative is
        taken there; the scene file is not touched).

    Returns
    -------
    RawData, or dict of them (quad-pol: channel name -> RawData)
        The raw data's geometry and axes, ``data`` complex64 [n_pulses, n_samples] the derivative
        per unit of the parameter (no thermal noise: it does not depend on ``p``);
        ``metadata["derivative"]`` names the parameter.

    Raises
    ------
    ParameterError
        An unknown material or parameter, a ``pec`` material (or a half-space's thickness),
        ``split_bounces``, or ``range_kernel = exact``.
    GeometryChange
        A ShapeParameter whose steps to both sides change the lit regions' topology (a
        :class:`GeometryChangeWarning` where one side does: the one-sided derivative from the other).
    """
    _checked(parameter)
    loaded, setup = _setup(source, sensor_overrides, integrator_overrides, at)
    params, settings = loaded.params, loaded.settings
    geometry, window, footprint, effects = setup.geometry, setup.window, setup.footprint, setup.effects
    if isinstance(parameter, ShapeParameter):
        kernel = TangentKernel(loaded.scene, params, window, footprint, settings, setup.table, effects, None, None,
                               parameter.move(loaded))
    else:
        row, material, bsdf = _material(loaded.scene, setup.table, parameter.material, params.frequency)
        tangent = row_tangent(material, bsdf, parameter.name, params.frequency, TABLE_SIZE)
        kernel = TangentKernel(loaded.scene, params, window, footprint, settings, setup.table, effects, row, tangent)

    def run_batches(plan, batches):
        for g0 in batches:
            yield trace_batch(kernel, plan, g0, geometry, window, footprint, settings, params.frequency)

    with evaluated_loops():
        result = trace(loaded.scene, params, geometry, window, footprint, settings, setup.table, effects=effects,
                       run_batches=run_batches)
    if isinstance(parameter, ShapeParameter):
        if kernel.moved.undefined[0]:
            raise GeometryChange(f"{parameter}: {kernel.moved.changes[0]}")
        _warn({parameter: kernel.moved.changes[0]} if kernel.moved.changes[0] else {})
    world = geometry.shifted(loaded.offset) if np.any(loaded.offset) else geometry
    named = ({"material": parameter.material, "parameter": parameter.name} if isinstance(parameter, MaterialParameter)
             else {"shape": parameter.shape, "parameter": parameter.kind, **dataclasses.asdict(parameter)})
    meta = {"scene": str(source), "derivative": {**named, "unit": f"raw data units per {_unit(parameter)}"}}
    if len(params.channels) == 1:
        return binning.to_raw_data(result.contributions(), result, window, params, world, meta)
    return {name: binning.to_raw_data(result.channel(name).contributions(), result.channel(name), window, params, world,
                                      {**meta, "polarization": name}) for name in params.channels}


def _setup(source, sensor_overrides, integrator_overrides, at=None):
    """The loaded scene, its shapes moved by ``at`` (ShapeParameter -> amount), and its trace
    set-up, checked for what derivatives support."""
    loaded = load_scene(source, sensor_overrides, integrator_overrides)
    if loaded.settings.split_bounces:
        raise ParameterError("gradients are taken of the raw data of all bounce orders; set split_bounces = false")
    if loaded.motion is not None:
        raise ParameterError(f"derivatives of a scene with moving shapes ({', '.join(loaded.motion.ids)}) are not "
                             "taken: give the shapes no velocity, or derive at one instant of their motion")
    if loaded.params.bistatic:
        raise ParameterError("derivatives of a bistatic acquisition (receiver_* parameters) are not taken: their "
                             "tracers cut the return legs monostatic; remove the receiver_* parameters")
    # max_depth = auto: the unmoved scene's probe, so that every evaluation traces the same orders
    loaded = choose_depth(loaded)[0]
    moved = {}
    for parameter, amount in dict(at or {}).items():
        if not isinstance(parameter, ShapeParameter) or not np.isfinite(amount):
            raise ParameterError(f"at: {parameter!r}: {amount!r}; give ShapeParameter -> finite amount (its unit)")
        k = parameter.index(loaded)
        start = moved.get(k, scene_meshes(loaded.scene)[k][0])
        moved[k] = parameter.displaced(loaded, start, amount)
    # the fast-time window and the footprint stay the unmoved scene's (the acquisition's
    # sampling does not move with the scene: the derivative is taken on one time grid)
    move_scene(loaded.scene, moved)
    setup = prepare_trace(loaded)       # the raw data of all orders at once: no per-order deposits
    return loaded, dataclasses.replace(setup, effects=dataclasses.replace(setup.effects, order_energy=False))


def _channel_gradients(gradient, channels, shape) -> dict:
    """Channel name -> complex128 gradient [n_pulses, n_samples] (zeros for channels left out);
    ParameterError for a wrong shape or an unknown channel."""
    given = gradient if isinstance(gradient, dict) else {channels[0]: gradient} if len(channels) == 1 else None
    if given is None:
        raise ParameterError(f"a quad-pol trace needs the gradient per channel: a dict over {', '.join(channels)}")
    out = {}
    for name in channels:
        values = np.asarray(given.get(name, np.zeros(shape)), np.complex128)
        if values.shape != shape:
            raise ParameterError(f"gradient shape {values.shape} must be the raw data's {shape} (pulses, samples)")
        out[name] = values
    unknown = set(given) - set(channels)
    if unknown:
        raise ParameterError(f"gradient for channel(s) {', '.join(sorted(unknown))}: the trace holds {', '.join(channels)}")
    return out


def raw_gradient(source: Any, gradient: np.ndarray, parameters, *, sensor_overrides: Mapping[str, Any] | None = None,
                 integrator_overrides: Mapping[str, Any] | None = None, at: Mapping | None = None) -> dict:
    """``dL/dp`` of a real loss ``L`` of the scene's raw data, for every parameter at once.

    Parameters
    ----------
    source : str or Path or Scene
    gradient : complex [n_pulses, n_samples], or dict of them (quad-pol)
        ``dL/d Re(raw) + j dL/d Im(raw)`` at the scene's raw data (for ``L = sum |raw - target|^2``:
        ``2 (raw - target)``); quad-pol: channel name -> that channel's (channels left out: 0).
    parameters : iterable of MaterialParameter and ShapeParameter
    sensor_overrides, integrator_overrides, at : mapping, optional
        As :func:`raw_derivative`.

    Returns
    -------
    dict
        parameter -> float, ``dL/dp`` per unit of the parameter: for a ShapeParameter whose step
        changes the lit regions' topology on one side, the one-sided derivative from the other,
        NaN where both sides change it; each with a :class:`GeometryChangeWarning` saying what
        changed (docs/physics.md (AD4)).

    Raises
    ------
    ParameterError
        As :func:`raw_derivative`; a ``gradient`` whose shape is not the raw data's.
    """
    parameters = [_checked(p) for p in parameters]
    if not parameters:
        return {}                                            # nothing asked: nothing traced
    loaded, setup = _setup(source, sensor_overrides, integrator_overrides, at)
    rows = _material_tangents(loaded, setup, parameters)          # refused before tracing
    kernel = _adjoint_kernel(loaded, setup, parameters, False)
    out, changes = _reverse(loaded, setup, kernel, gradient, parameters, rows)
    _warn(changes)
    return out


def _adjoint_kernel(loaded, setup, parameters, outlines: bool) -> AdjointKernel:
    """The reverse-mode kernel of ``parameters``: their shapes' moves, the derivatives' outlines
    where ``outlines`` or a shape moves."""
    shapes = [p for p in parameters if isinstance(p, ShapeParameter)]
    kernel = AdjointKernel(loaded.scene, loaded.params, setup.window, setup.footprint, loaded.settings, setup.table,
                           setup.effects, [p.move(loaded) for p in shapes], outlines=outlines)
    if kernel.moved is not None:
        kernel.moved.materials = len(shapes) < len(parameters)
    return kernel


def _batches(kernel, loaded, setup, seeds=None):
    """Trace ``kernel`` over the acquisition, its launches seeded batch by batch with ``seeds``
    (channel name -> the raw data's gradient) or, without seeds, depositing values; the trace's
    result."""
    params, settings = loaded.params, loaded.settings
    geometry, window, footprint = setup.geometry, setup.window, setup.footprint

    def run_batches(plan, batches):
        spectra = None if seeds is None else [
            binning.raw_data_adjoint(seeds[name], plan.lref, plan.n_pad, window, params)
            for name in kernel.returns.channels]          # in the histogram's channel order
        if spectra is not None:
            # the seeds scaled by a power of two to magnitudes of at most 1 (exact), so that the
            # adjoints lie in their fixed-point range (docs/physics.md (D7)); scaled back in _reverse
            gain = adjoint_gain(plan.n_pad, window.fs, window.oversample, params.frequency, settings.range_kernel)
            bound = max((float(np.abs(s).sum(axis=1).max(initial=0.0)) for s in spectra), default=0.0) * gain
            kernel.returns.sums.scale = seed_scale(bound)
            spectra = [s / kernel.returns.sums.scale for s in spectra]
        for g0 in batches:
            if spectra is not None:
                p0, p1 = plan.pulses(g0)
                kernel.returns.sums.seed = np.stack(
                    [reduce_deposit_adjoint(spectrum[p0:p1], window.n_fine, window.fs, window.oversample,
                                            params.frequency, settings.range_kernel) for spectrum in spectra], axis=1)
            yield trace_batch(kernel, plan, g0, geometry, window, footprint, settings, params.frequency)

    with evaluated_loops(evaluated=False):          # replayed: symbolic loops, differentiated inside
        if seeds is not None:
            return trace(loaded.scene, params, geometry, window, footprint, settings, setup.table,
                         effects=setup.effects, run_batches=run_batches)
        with dr.suspend_grad():                     # the values: no graph of the tables kept
            return trace(loaded.scene, params, geometry, window, footprint, settings, setup.table,
                         effects=setup.effects, run_batches=run_batches)


def _reverse(loaded, setup, kernel, gradient, parameters, rows) -> dict:
    """The reverse pass of ``kernel`` seeded with the raw data's ``gradient``: parameter -> dL/dp."""
    params = loaded.params
    seeds = _channel_gradients(gradient, params.channels, (setup.geometry.positions.shape[0], setup.window.n_samples))
    _batches(kernel, loaded, setup, seeds)
    scale = kernel.returns.sums.scale
    grads = {name: scale * kernel.table_gradient(name) for name in kernel.leaves}
    out = {}
    for parameter, (row, tangent) in rows.items():
        flat = flat_tangents(kernel.returns.tables, kernel.effects.polarimetric, params.polarization, row, tangent)
        out[parameter] = float(sum(grads[name] @ values for name, values in flat.items()))
    shapes = [p for p in parameters if isinstance(p, ShapeParameter)]
    changes = {}
    for j, parameter in enumerate(shapes):
        moved = kernel.moved
        out[parameter] = math.nan if moved.undefined[j] else scale * float(moved.totals[j])
        if moved.changes[j] is not None:
            changes[parameter] = moved.changes[j]
    return {p: out[p] for p in parameters}, changes


def _warn(changes: dict) -> None:
    """One warning per geometric parameter whose step changed the lit regions' topology."""
    for parameter, change in changes.items():
        warnings.warn(f"{parameter}: {change}", GeometryChangeWarning, stacklevel=3)


@dataclass(frozen=True)
class AmplitudeLoss:
    """``L = sum (|I| - |T|)^2`` over the pixels of the image ``I`` and a target ``T`` (complex or
    magnitudes, [n_az, n_rg], on the same grid). Called on an image, returns ``(L, G)`` with
    ``G = dL/d Re I + j dL/d Im I = 2 (|I| - |T|) I / |I|`` (0 where ``|I| = 0``)."""

    target: np.ndarray

    def __call__(self, image: np.ndarray) -> tuple[float, np.ndarray]:
        image = np.asarray(image, np.complex128)
        target = np.abs(np.asarray(self.target))
        if target.shape != image.shape:
            raise ParameterError(f"AmplitudeLoss target shape {target.shape} must be the image's {image.shape}")
        magnitude = np.abs(image)
        residual = magnitude - target
        unit = np.divide(image, magnitude, out=np.zeros_like(image), where=magnitude > 0)
        return float(np.sum(residual * residual)), 2.0 * residual * unit


@dataclass(frozen=True)
class Gradients:
    """What :func:`gradients` returns: the loss ``L``, ``gradient`` (parameter -> ``dL/dp`` per unit
    of the parameter), the image the loss saw (complex128 [n_az, n_rg], float64 direct
    backprojection, no window), the raw data, and ``changes``: ShapeParameter -> what changed the
    lit regions' topology within its step (docs/physics.md (AD4)): its gradient is then the
    one-sided derivative from the other side, or NaN where both sides change it."""

    loss: float
    gradient: dict
    image: np.ndarray
    raw: RawData
    changes: dict = dataclasses.field(default_factory=dict)


def gradients(source: Any, loss, parameters, *, image_size: tuple[int, int] = (64, 64),
              image_spacing: float | None = None, sensor_overrides: Mapping[str, Any] | None = None,
              integrator_overrides: Mapping[str, Any] | None = None, oversample: int = 8,
              at: Mapping | None = None, focuser: str = "bp") -> Gradients:
    """``dL/dp`` of a loss on the scene's image, for every parameter at once (reverse mode).

    Parameters
    ----------
    source : str or Path or Scene
    loss : callable
        ``loss(image) -> (L, G)``: a real loss of the complex image [n_az, n_rg] and
        ``G = dL/d Re I + j dL/d Im I`` (e.g. :class:`AmplitudeLoss`).
    parameters : iterable of MaterialParameter and ShapeParameter
    image_size, image_spacing
        The ground grid about the scene centre (``simulate``'s), small: the image is formed by the
        float64 backprojection operator, pulse by pulse.
    sensor_overrides, integrator_overrides, at : mapping, optional
        As :func:`raw_derivative` (``at`` moves shapes first: the loss and gradient there).
    oversample : int
        Range upsampling of the backprojection.
    focuser : {"bp", "ffbp"}
        The image's focuser as a float64 linear map: direct backprojection
        (:class:`~sarmitsuba.focus.linear.BackprojectionOperator`), or fast factorised
        backprojection with its default knobs (:class:`~sarmitsuba.focus.ffbp_linear.FFBPOperator`,
        the render's default focuser; docs/physics.md (AD1)).

    Returns
    -------
    Gradients

    Raises
    ------
    ParameterError
        As :func:`raw_gradient`; or ``focuser`` not ``"bp"`` or ``"ffbp"``.
    """
    from .focus.dispatch import azimuth_pattern
    from .focus.ffbp_linear import ffbp_operator
    from .focus.linear import backprojection_operator
    from .focus.scene_grid import sized_grid
    operators = {"bp": backprojection_operator, "ffbp": ffbp_operator}
    if focuser not in operators:
        raise ParameterError(f"focuser = {focuser!r}: sarmitsuba.gradients focuses with 'bp' or 'ffbp' (the "
                             "backprojections as float64 linear maps); for omega-K or range-Doppler, use "
                             "sarmitsuba.focus.linear's operators with raw_gradient")
    parameters = [_checked(p) for p in parameters]
    loaded, setup = _setup(source, sensor_overrides, integrator_overrides, at)
    params = loaded.params
    if len(params.channels) != 1:
        raise ParameterError("sarmitsuba.gradients takes a loss on one channel's image; for quad-pol, set "
                             "polarization to one channel, or use raw_gradient with a gradient per channel")
    grid = sized_grid(params, setup.geometry, image_size, image_spacing)
    if isinstance(loss, AmplitudeLoss) and np.shape(loss.target) != (len(grid.azimuth), len(grid.range)):
        raise ParameterError(f"AmplitudeLoss target shape {np.shape(loss.target)} must be the image's "
                             f"{(len(grid.azimuth), len(grid.range))} (image_size = {tuple(image_size)}, azimuth by "
                             "range pixels): give a target of that shape, or set image_size to the target's")
    rows = _material_tangents(loaded, setup, parameters)      # a pec material refused before the forward render
    shapes = bool(at) or any(isinstance(p, ShapeParameter) for p in parameters)
    # one trace of the geometry: the values pass keeps each launch's lanes and tangents, and the
    # reverse pass replays them (docs/physics.md (AD4))
    kernel = _adjoint_kernel(loaded, setup, parameters, shapes)
    if kernel.moved is not None:
        kernel.moved.kept = {}
    raw = _raw(source, loaded, setup, _batches(kernel, loaded, setup))
    grid = dataclasses.replace(grid, origin=grid.origin + loaded.offset)
    operator = operators[focuser](raw, grid, oversample=oversample,
                                  azimuth_beamwidth=params.traced_beamwidth if params.mode == "stripmap" else None,
                                  squint=params.squint, azimuth_pattern=azimuth_pattern(params))
    image = operator.forward(raw.data)
    value, image_gradient = loss(image)
    if not parameters:
        return Gradients(float(value), {}, image, raw)
    if kernel.moved is not None:
        kernel.moved.replay, kernel.moved.kept = kernel.moved.kept, None
    grads, changes = _reverse(loaded, setup, kernel, operator.adjoint(image_gradient), parameters, rows)
    return Gradients(float(value), grads, image, raw, changes)


def moved_raw(source: Any, at: Mapping | None = None, *, sensor_overrides: Mapping[str, Any] | None = None,
              integrator_overrides: Mapping[str, Any] | None = None) -> RawData:
    """The raw data of the scene with its shapes moved by ``at`` (ShapeParameter -> amount),
    traced with the outlines the geometric derivatives use (docs/physics.md (AD4)): the values
    :func:`raw_derivative` and :func:`raw_gradient` differentiate, for an optimisation's loss
    or a finite difference. One channel (ParameterError for quad-pol); no thermal noise."""
    loaded, setup = _setup(source, sensor_overrides, integrator_overrides, at)
    if len(loaded.params.channels) != 1:
        raise ParameterError("moved_raw traces one channel; set polarization to one channel")
    return _values(source, loaded, setup, True)


def _values(source, loaded, setup, outlines: bool) -> RawData:
    """The raw data of a loaded scene (one channel), with the geometric derivatives' outlines
    where ``outlines``."""
    params, settings = loaded.params, loaded.settings
    geometry, window, footprint, effects = setup.geometry, setup.window, setup.footprint, setup.effects
    kernel = Kernel(loaded.scene, params, window, footprint, settings, setup.table, effects)
    if outlines:
        moved_tracer(kernel, [], always=True)

    def run_batches(plan, batches):
        for g0 in batches:
            yield trace_batch(kernel, plan, g0, geometry, window, footprint, settings, params.frequency)

    return _raw(source, loaded, setup, trace(loaded.scene, params, geometry, window, footprint, settings, setup.table,
                                             effects=effects, run_batches=run_batches))


def _raw(source, loaded, setup, result) -> RawData:
    """The raw data of a trace's ``result`` (one channel), in the world frame."""
    geometry = setup.geometry
    world = geometry.shifted(loaded.offset) if np.any(loaded.offset) else geometry
    return binning.to_raw_data(result.contributions(), result, setup.window, loaded.params, world,
                               {"scene": str(source)})
