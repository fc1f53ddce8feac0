"""Derivatives of the raw data and the image with respect to scene parameters (issue 57).

Forward mode, one parameter at a time: :func:`raw_derivative` traces the scene once with the
parameter's tangent carried through the tracing kernels by Dr.Jit's automatic differentiation
(:mod:`sarmitsuba.tracing.tangents`) and bins it as the raw data are binned, giving
``d raw / d p`` (complex, per range sample and pulse, in the raw data's units per unit of ``p``).
The focusers are linear in the raw data (docs/physics.md (AD1)), so the image's derivative is the
derivative focused as the raw data are (:func:`sarmitsuba.refocus` with the render's options).

Reverse mode, for many parameters at once: :func:`raw_gradient` takes the gradient of a real loss
with respect to the raw data, carries it back through the binning's adjoint
(:func:`sarmitsuba.signal.binning.raw_data_adjoint`,
:func:`sarmitsuba.tracing.deposit.reduce_deposit_adjoint`) to each launch's histogram, and through
the tracing kernels to the reflection tables (Dr.Jit's reverse mode), then to each parameter.

So far: a material's relative permittivity, conductivity or (slabs) thickness, for ``half_space``
and ``slab`` materials (``radar`` and ITU-named), with
the gridded range kernels (``linear``, ``sinc``) and without ``split_bounces``. Pose and vertices
follow (issue 57).

A loss on the image: :func:`gradients` (``sarmitsuba.gradients``) focuses the raw data by direct
backprojection as a float64 linear map (:class:`sarmitsuba.focus.linear.BackprojectionOperator`),
evaluates the loss and its gradient there, carries it to the raw data by the map's adjoint (AD1)
and from there by :func:`raw_gradient`.

Example::

    d = raw_derivative("scene.xml", MaterialParameter("wall", "relative_permittivity"))
    d.data            # complex64 [n_pulses, n_samples]: d raw / d eps_r
    g = sarmitsuba.gradients("scene.xml", AmplitudeLoss(target), [MaterialParameter("wall", "conductivity")])
    g.loss, g.gradient    # L and {parameter: dL/dp}
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import drjit as dr
import numpy as np

from .core.radar import ParameterError
from .core.raw import RawData
from .scene.loader import TABLE_SIZE, load_scene
from .signal import binning
from .tracing.loops import evaluated_loops
from .tracing.deposit import reduce_deposit_adjoint
from .tracing.tangents import MATERIAL_PARAMETERS, AdjointKernel, TangentKernel, flat_tangents, row_tangent
from .tracing.trace import prepare_trace, trace, trace_batch

__all__ = ["MaterialParameter", "raw_derivative", "raw_gradient", "AmplitudeLoss", "Gradients", "gradients"]


@dataclass(frozen=True)
class MaterialParameter:
    """A material's parameter: ``material`` its id in the scene (the BSDF's ``id``), ``name``
    ``"relative_permittivity"`` (the real part ``eps_r`` of ``eta``, 1), ``"conductivity"``
    (``sigma``, S/m; ``eta = eps_r - j sigma / (omega eps_0)``), ``"thickness"`` (a slab's, m) or
    ``"scattering_coefficient"`` (``S`` of an itu-radio-material's Lambertian clutter, 1). For
    ITU-named materials these are the values at the carrier."""

    material: str
    name: str

    def __post_init__(self):
        if self.name not in MATERIAL_PARAMETERS:
            raise ParameterError(f"MaterialParameter name = {self.name!r}; valid: {', '.join(MATERIAL_PARAMETERS)}")


def _material(scene, table, name: str, frequency: float):
    """The table row, the electromagnetic model and the BSDF of the material ``name``; ParameterError
    naming the scene's materials when there is none of that name."""
    if name not in table.names:
        raise ParameterError(f"material {name!r} is not in the scene; its materials: {', '.join(sorted(set(table.names)))}")
    for shape in scene.shapes():
        bsdf = shape.bsdf()
        if getattr(bsdf, "name", None) == name:
            return table.names.index(name), bsdf.material_at(frequency), bsdf
    raise ParameterError(f"material {name!r} is not used by any shape")


def raw_derivative(source: Any, parameter: MaterialParameter, *, sensor_overrides: Mapping[str, Any] | None = None,
                   integrator_overrides: Mapping[str, Any] | None = None) -> "RawData | dict":
    """``d raw / d p``: the derivative of the scene's raw data with respect to ``parameter``.

    Parameters
    ----------
    source : str or Path or Scene
        As :func:`sarmitsuba.simulate` (XML path, built-in name, ``sionna:NAME``).
    parameter : MaterialParameter
    sensor_overrides, integrator_overrides : mapping, optional
        As :func:`sarmitsuba.simulate`.

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
    """
    if not isinstance(parameter, MaterialParameter):
        raise ParameterError(f"parameter must be a MaterialParameter, got {type(parameter).__name__}")
    loaded, setup = _setup(source, sensor_overrides, integrator_overrides)
    params, settings = loaded.params, loaded.settings
    row, material, bsdf = _material(loaded.scene, setup.table, parameter.material, params.frequency)
    tangent = row_tangent(material, bsdf, parameter.name, params.frequency, TABLE_SIZE)
    geometry, window, footprint, effects = setup.geometry, setup.window, setup.footprint, setup.effects
    kernel = TangentKernel(loaded.scene, params, window, footprint, settings, setup.table, effects, row, tangent)

    def run_batches(plan, batches):
        for g0 in batches:
            yield trace_batch(kernel, plan, g0, geometry, window, footprint, settings, params.frequency)

    with evaluated_loops():
        result = trace(loaded.scene, params, geometry, window, footprint, settings, setup.table, effects=effects,
                       run_batches=run_batches)
    world = geometry.shifted(loaded.offset) if np.any(loaded.offset) else geometry
    meta = {"scene": str(source), "derivative": {"material": parameter.material, "parameter": parameter.name,
                                                 "unit": f"raw data units per {MATERIAL_PARAMETERS[parameter.name]}"}}
    if len(params.channels) == 1:
        return binning.to_raw_data(result.contributions(), result, window, params, world, meta)
    return {name: binning.to_raw_data(result.channel(name).contributions(), result.channel(name), window, params, world,
                                      {**meta, "polarization": name}) for name in params.channels}


def _setup(source, sensor_overrides, integrator_overrides):
    """The loaded scene and its trace set-up, checked for what derivatives support."""
    loaded = load_scene(source, sensor_overrides, integrator_overrides)
    if loaded.settings.split_bounces:
        raise ParameterError("gradients are taken of the raw data of all bounce orders; set split_bounces = false")
    return loaded, prepare_trace(loaded)


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
                 integrator_overrides: Mapping[str, Any] | None = None) -> dict:
    """``dL/dp`` of a real loss ``L`` of the scene's raw data, for every parameter at once.

    Parameters
    ----------
    source : str or Path or Scene
    gradient : complex [n_pulses, n_samples], or dict of them (quad-pol)
        ``dL/d Re(raw) + j dL/d Im(raw)`` at the scene's raw data (for ``L = sum |raw - target|^2``:
        ``2 (raw - target)``); quad-pol: channel name -> that channel's (channels left out: 0).
    parameters : iterable of MaterialParameter
    sensor_overrides, integrator_overrides : mapping, optional

    Returns
    -------
    dict
        MaterialParameter -> float, ``dL/dp`` per unit of the parameter.

    Raises
    ------
    ParameterError
        As :func:`raw_derivative`; a ``gradient`` whose shape is not the raw data's.
    """
    parameters = list(parameters)
    for parameter in parameters:
        if not isinstance(parameter, MaterialParameter):
            raise ParameterError(f"parameters must be MaterialParameter, got {type(parameter).__name__}")
    if not parameters:
        return {}                                            # nothing asked: nothing traced
    loaded, setup = _setup(source, sensor_overrides, integrator_overrides)
    params, settings = loaded.params, loaded.settings
    geometry, window, footprint, effects = setup.geometry, setup.window, setup.footprint, setup.effects
    gradients_ = _channel_gradients(gradient, params.channels, (geometry.positions.shape[0], window.n_samples))
    rows = {p: _material(loaded.scene, setup.table, p.material, params.frequency) for p in parameters}
    kernel = AdjointKernel(loaded.scene, params, window, footprint, settings, setup.table, effects)

    def run_batches(plan, batches):
        spectra = [binning.raw_data_adjoint(gradients_[name], plan.lref, plan.n_pad, window, params)
                   for name in kernel.returns.channels]          # in the histogram's channel order
        for g0 in batches:
            p0, p1 = plan.pulses(g0)
            kernel.returns.sums.seed = np.stack(
                [reduce_deposit_adjoint(spectrum[p0:p1], window.n_fine, window.fs, window.oversample, params.frequency,
                                        settings.range_kernel) for spectrum in spectra], axis=1)
            yield trace_batch(kernel, plan, g0, geometry, window, footprint, settings, params.frequency)

    with evaluated_loops():
        trace(loaded.scene, params, geometry, window, footprint, settings, setup.table, effects=effects,
              run_batches=run_batches)
    grads = {name: np.asarray(dr.grad(leaf), np.float64) for name, leaf in kernel.leaves.items()}
    out = {}
    for parameter, (row, material, bsdf) in rows.items():
        flat = flat_tangents(kernel.returns.tables, kernel.effects.polarimetric, params.polarization, row,
                             row_tangent(material, bsdf, parameter.name, params.frequency, TABLE_SIZE))
        out[parameter] = float(sum(grads[name] @ values for name, values in flat.items()))
    return out



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
    """What :func:`gradients` returns: the loss ``L``, ``gradient`` (MaterialParameter -> ``dL/dp``
    per unit of the parameter), the image the loss saw (complex128 [n_az, n_rg], float64 direct
    backprojection, no window) and the raw data."""

    loss: float
    gradient: dict
    image: np.ndarray
    raw: RawData


def gradients(source: Any, loss, parameters, *, image_size: tuple[int, int] = (64, 64),
              image_spacing: float | None = None, sensor_overrides: Mapping[str, Any] | None = None,
              integrator_overrides: Mapping[str, Any] | None = None, oversample: int = 8) -> Gradients:
    """``dL/dp`` of a loss on the scene's image, for every parameter at once (reverse mode).

    Parameters
    ----------
    source : str or Path or Scene
    loss : callable
        ``loss(image) -> (L, G)``: a real loss of the complex image [n_az, n_rg] and
        ``G = dL/d Re I + j dL/d Im I`` (e.g. :class:`AmplitudeLoss`).
    parameters : iterable of MaterialParameter
    image_size, image_spacing
        The ground grid about the scene centre (``simulate``'s), small: the image is formed by the
        float64 backprojection operator, pulse by pulse.
    sensor_overrides, integrator_overrides : mapping, optional
    oversample : int
        Range upsampling of the backprojection.

    Returns
    -------
    Gradients

    Raises
    ------
    ParameterError
        As :func:`raw_gradient`.
    """
    from .pipeline import simulate                           # (the top level's entry point)
    from .focus.dispatch import azimuth_pattern
    from .focus.grid import ImageGrid
    from .focus.linear import backprojection_operator
    sim = simulate(source, sensor_overrides=sensor_overrides, integrator_overrides=integrator_overrides,
                   window="rect", focuser="bp", image_size=image_size, image_spacing=image_spacing)
    params, shown = sim.loaded.params, sim.image
    if len(params.channels) != 1:
        raise ParameterError("sarmitsuba.gradients takes a loss on one channel's image; for quad-pol, set "
                             "polarization to one channel, or use raw_gradient with a gradient per channel")
    grid = ImageGrid(shown.origin, shown.azimuth_direction, shown.range_direction, shown.azimuth, shown.range)
    operator = backprojection_operator(sim.raw, grid, oversample=oversample,
                                       azimuth_beamwidth=params.traced_beamwidth if params.mode == "stripmap" else None,
                                       squint=params.squint, azimuth_pattern=azimuth_pattern(params))
    image = operator.forward(sim.raw.data)
    value, image_gradient = loss(image)
    raw_gradient_ = operator.adjoint(image_gradient)
    grads = raw_gradient(source, raw_gradient_, parameters, sensor_overrides=sensor_overrides,
                         integrator_overrides=integrator_overrides)
    return Gradients(float(value), grads, image, sim.raw)
