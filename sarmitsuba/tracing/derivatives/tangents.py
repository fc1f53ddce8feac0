"""Derivatives of a trace with respect to a material's reflection table, and the
kernels that carry a shape's geometric tangents too (:func:`moved_tracer`, docs/physics.md (AD4)).

The kernels read each material's reflection coefficient ``r(cos_i)`` from a table (eq. (R)),
in Dr.Jit. :class:`TangentKernel` is the tracing kernel with that table made a differentiable
leaf: Dr.Jit records how every deposited term depends on it while the launch runs (its loops
evaluated, :mod:`..loops`), and :class:`TangentSums` then propagates a tangent of the table,
``dT = dT/dp`` for one parameter ``p``, forward to the launch's histogram (``dr.forward_to``).
The histogram a launch hands back is that derivative, ``d hist / dp``; everything after the
histogram (range compression, radiometry) is linear, so the same binning turns it into
``d raw / dp``.

:func:`material_tangent` gives ``dT/dp`` of a half-space's or a slab's table by Dr.Jit's own AD
through the Fresnel and slab coefficients (docs/physics.md (R), (AD2)); :func:`reflection_table_ad`'s
values equal :func:`sarmitsuba.scene.fresnel.fresnel_half_space` and
:func:`~sarmitsuba.scene.fresnel.slab_reflection`, the readable NumPy references
(tests/test_gradients.py).
"""
from __future__ import annotations

import dataclasses
import math

import drjit as dr
import mitsuba as mi
import numpy as np

from ...core.constants import SPEED_OF_LIGHT, VACUUM_PERMITTIVITY
from ...core.radar import ParameterError
from ...scene.materials import grazing_impedance
from ..deposit.accumulate import Accumulator
from ..deposit.adjoint import AdjointSink
from ..device import device_array
from .geometry_tangents import MovedTracer
from ..driver.kernel import Kernel
from ..integration import ground_wave
from .rough_tangents import ROUGH_PARAMETERS, rough_row_tangent

__all__ = ["MATERIAL_PARAMETERS", "DIFFERENTIABLE", "reflection_table_ad", "material_tangent", "RowTangent",
           "row_tangent", "flat_tangents", "TangentKernel", "TangentSums", "AdjointKernel", "AdjointSums",
           "moved_tracer"]

#: The material parameters a derivative can be taken with respect to, and their units.
MATERIAL_PARAMETERS = {"relative_permittivity": "1", "conductivity": "S/m", "thickness": "m",
                       "scattering_coefficient": "1", "gamma": "1", **ROUGH_PARAMETERS}
#: The kernel's per-material tables a derivative can flow from (attributes of its ``tables``).
DIFFERENTIABLE = ("re", "im", "re_tm", "im_tm", "specular", "clutter_value", "rough_mono", "rough_bi", "grazing_offset", "grazing_re",
                  "grazing_im")


def reflection_table_ad(eta_re, eta_im, n_cos: int, polarization: str, thickness=None,
                        frequency: float = 0.0) -> mi.Complex2f64:
    """``r(cos_i)`` at ``cos_i = i / (n_cos - 1)`` of a half-space (``thickness`` None) or a slab of
    ``thickness`` [m] at ``frequency`` [Hz], of relative permittivity ``eta = eta_re + j eta_im``
    (``mi.Float64``, differentiable, as ``thickness``): ``r_te`` for HH, ``r_tm`` for VV, in
    :mod:`sarmitsuba.scene.fresnel`'s conventions. Half-space: ``s = sqrt(eta - sin^2)``,
    ``r_te = (c - s) / (c + s)``, ``r_tm = (s / eta - c) / (s / eta + c)``. Slab (ITU-R P.2040
    eqs. (43a), (44)): ``R = R' D / (D + (1 - R'^2) E)``, ``E = exp(-2 j q)``, ``D = 1 - E``,
    ``q = 2 pi f d s / c``. Complex2f64 [n_cos]."""
    c = mi.Complex2f64(dr.linspace(mi.Float64, 0.0, 1.0, n_cos), 0.0)
    eta = mi.Complex2f64(eta_re, eta_im)
    s = dr.sqrt(eta - 1.0 + c * c)        # principal root: Im s <= 0 where Im eta <= 0
    p = s if polarization == "HH" else s / eta
    r = (c - p) / (c + p)
    r = r if polarization == "HH" else -r
    if thickness is None:
        return r
    q = (2.0 * math.pi * frequency / SPEED_OF_LIGHT) * thickness * s
    e = dr.exp(mi.Complex2f64(0.0, -2.0) * q)
    d = 1.0 - e
    return r * d / (d + (1.0 - r) * (1.0 + r) * e)


def material_tangent(material, parameter: str, frequency: float, polarization: str, n_cos: int) -> np.ndarray:
    """``dT/dp`` complex128 [n_cos] of a material's table for ``parameter`` by forward-mode AD:
    ``relative_permittivity`` (``d/d Re eta``), ``conductivity`` (``d/d sigma`` per S/m, with
    ``eta = eps_r - j sigma / (omega eps_0)``, ITU-R P.2040 eq. (9b)) or ``thickness`` (slabs,
    per m). Raises ParameterError for another parameter, a ``pec`` material, or the thickness
    of a half-space."""
    if parameter not in MATERIAL_PARAMETERS:
        raise ParameterError(f"parameter = {parameter!r}; valid: {', '.join(MATERIAL_PARAMETERS)}")
    if material.model not in ("half_space", "slab"):
        raise ParameterError(f"material {material.name!r} is a {material.model!r}: it has no {parameter} "
                             "(derivatives are taken for half_space and slab materials)")
    if parameter == "thickness" and material.model != "slab":
        raise ParameterError(f"material {material.name!r} is a half_space: it has no thickness (model slab has)")
    omega_eps0 = 2.0 * math.pi * frequency * VACUUM_PERMITTIVITY
    eta = complex(material.relative_permittivity)
    leaves = {"relative_permittivity": mi.Float64(eta.real), "conductivity": mi.Float64(-eta.imag * omega_eps0),
              "thickness": mi.Float64(material.thickness or 0.0)}
    dr.enable_grad(leaves[parameter])
    r = reflection_table_ad(leaves["relative_permittivity"], -leaves["conductivity"] / omega_eps0, n_cos, polarization,
                            leaves["thickness"] if material.model == "slab" else None, frequency)
    dr.forward_from(leaves[parameter])
    grad = dr.grad(r)
    return np.asarray(grad.real, np.float64) + 1j * np.asarray(grad.imag, np.float64)


@dataclasses.dataclass(frozen=True)
class RowTangent:
    """``dT/dp`` of one material's row of the kernel's tables: ``te`` and ``tm`` complex [n_cos]
    (None: unchanged), the specular factor's and the clutter value's (floats)."""

    te: np.ndarray | None = None
    tm: np.ndarray | None = None
    specular: float = 0.0
    clutter_value: float = 0.0
    grazing: tuple | None = None      # (d offset, d table) of the grazing wave's row, (E6')
    rough: tuple | None = None        # (d mono, d bistatic) of a rough surface's sigma0 tables, (RS6)


def row_tangent(material, bsdf, parameter: str, frequency: float, n_cos: int) -> RowTangent:
    """The :class:`RowTangent` of ``parameter`` of ``material`` (its BSDF ``bsdf``). For
    ``scattering_coefficient`` ``S`` (Sionna's Lambertian clutter, docs/physics.md (C)): the
    specular factor ``sqrt(1 - S^2)`` moves by ``-S / sqrt(1 - S^2)`` and the clutter value
    ``4 S^2`` by ``8 S``. For ``gamma`` (a ``radar`` material's constant-gamma clutter, linear,
    docs/physics.md (C)): the clutter value is ``gamma`` itself, its tangent 1. Raises
    ParameterError where the material has no such parameter. A rough surface's material
    (``rms_height``, docs/physics.md (RS6)) also moves its sigma nought tables and carries its
    coherent factor (:func:`sarmitsuba.tracing.derivatives.rough_tangents.rough_row_tangent`)."""
    surface = getattr(bsdf, "surface", None)
    if parameter in ROUGH_PARAMETERS or surface is not None:
        if surface is None or parameter in ("gamma", "scattering_coefficient"):
            raise ParameterError(f"material {material.name!r} has no {parameter} (a radar material with rms_height "
                                 f"and correlation_length has {', '.join(ROUGH_PARAMETERS)}; one with gamma_db, gamma)")
        smooth = (None, None) if parameter in ROUGH_PARAMETERS else \
            tuple(material_tangent(material, parameter, frequency, pol, n_cos) for pol in ("HH", "VV"))
        te, tm, rough = rough_row_tangent(material, surface, parameter, frequency, n_cos, smooth)
        return RowTangent(te, tm, grazing=None if parameter in ROUGH_PARAMETERS else
                          grazing_row_tangent(material, parameter, frequency), rough=rough)
    if parameter == "gamma":
        if bsdf.clutter[0] != 1:
            raise ParameterError(f"material {material.name!r} has no gamma (a radar material with gamma_db has)")
        return RowTangent(clutter_value=1.0)
    if parameter == "scattering_coefficient":
        kind, value = bsdf.clutter
        if kind != 2:
            raise ParameterError(f"material {material.name!r} has no scattering_coefficient (an itu-radio-material with "
                                 "scattering_coefficient > 0 has)")
        s = math.sqrt(value / 4.0)
        if s >= 1.0:
            raise ParameterError(f"material {material.name!r}: scattering_coefficient 1 has no derivative (the "
                                 "specular factor sqrt(1 - S^2) is not differentiable there)")
        return RowTangent(specular=-s / math.sqrt(1.0 - s * s), clutter_value=8.0 * s)
    te, tm = (material_tangent(material, parameter, frequency, pol, n_cos) for pol in ("HH", "VV"))
    return RowTangent(te, tm, grazing=grazing_row_tangent(material, parameter, frequency))


def grazing_row_tangent(material, parameter: str, frequency: float) -> tuple | None:
    """The grazing-wave table's tangent (:func:`ground_wave.table_tangent`) for ``parameter``:
    ``Delta = sqrt(eta - 1) / eta`` (E6') moves as ``d ln Delta = (1 / (2 (eta - 1)) - 1 / eta)
    d eta``, ``d eta = 1`` per unit of ``relative_permittivity`` and ``-j / (omega eps_0)`` per S/m
    of ``conductivity``; None for ``thickness`` (a slab's grazing wave is its half space's)."""
    if parameter == "thickness":
        return None
    eta = complex(material.relative_permittivity)
    d_eta = 1.0 if parameter == "relative_permittivity" else -1j / (2.0 * math.pi * frequency * VACUUM_PERMITTIVITY)
    return ground_wave.table_tangent(grazing_impedance(material, frequency),
                                     (0.5 / (eta - 1.0) - 1.0 / eta) * d_eta)


def flat_tangents(tables, polarimetric: bool, polarization: str, row: int, tangent: RowTangent) -> dict:
    """The kernel tables' tangents, float64 arrays of their widths by attribute name, zero outside
    ``row``. The scalar model's one reflection table is the channel's (``r_tm`` for VV, else
    ``r_te``), the Jones model's both (P3')."""
    out, n_cos = {}, tables.n_cos
    pairs = ((("re", "im"), tangent.te), (("re_tm", "im_tm"), tangent.tm)) if polarimetric else \
        ((("re", "im"), tangent.tm if polarization == "VV" else tangent.te),)
    for (re_name, im_name), values in pairs:
        if values is not None:
            full = np.zeros(dr.width(getattr(tables, re_name)), np.complex128)
            full[row * n_cos:(row + 1) * n_cos] = values
            out[re_name], out[im_name] = full.real, full.imag
    for name in ("specular", "clutter_value"):
        if getattr(tangent, name) and getattr(tables, name) is not None:
            full = np.zeros(dr.width(getattr(tables, name)))
            full[row] = getattr(tangent, name)
            out[name] = full
    if tangent.rough is not None and getattr(tables, "rough_mono", None) is not None:
        for name, values in zip(("rough_mono", "rough_bi"), tangent.rough):
            full = np.zeros(dr.width(getattr(tables, name)))
            full[row * values.size:(row + 1) * values.size] = values.ravel()
            out[name] = full
    if tangent.grazing is not None and getattr(tables, "grazing_offset", None) is not None:
        d_offset, d_table = tangent.grazing
        out["grazing_offset"] = np.zeros(dr.width(tables.grazing_offset))
        out["grazing_offset"][row] = d_offset
        full = np.zeros(dr.width(tables.grazing_re), np.complex128)
        full[row * d_table.size:(row + 1) * d_table.size] = d_table
        out["grazing_re"], out["grazing_im"] = full.real, full.imag
    return out


def _leaves(tables, names) -> dict:
    """Each table of ``names`` replaced by a differentiable copy (a leaf); name -> leaf."""
    leaves = {}
    for name in names:
        if getattr(tables, name, None) is not None:
            leaf = mi.Float(dr.detach(getattr(tables, name)))
            dr.enable_grad(leaf)
            setattr(tables, name, leaf)
            leaves[name] = leaf
    return leaves


class TangentSums(Accumulator):
    """The histogram of a launch replaced by its derivative: each deposit's values are kept with
    their entries; before collecting, the tables' tangents are set on the kernel's differentiable
    tables (the geometric leaves carry theirs from when they were made), propagated forward to
    those values in one traversal, and the values' tangents deposited as values are, in fixed
    point (docs/physics.md (D7)): the derivative's sums do not depend on the order of the
    additions either."""

    def __init__(self, base: Accumulator, leaves: tuple, tangent: tuple):
        super().__init__(base.settings, base.window, base.groups, base.n_channels)
        if self.exact:
            raise ParameterError("range_kernel = 'exact' keeps path lists, which derivatives do not flow through; "
                                 "use range_kernel linear or sinc")
        self.leaves, self.tangent = leaves, tangent

    def open(self, ctx: dict) -> None:
        """Open the launch's histogram and the list of its deposits, kept differentiable:
        ``(re, im, entry, active)`` each."""
        super().open(ctx)
        ctx["deposits"] = []

    def add(self, ctx, re, im, index, active) -> None:
        """Keep the deposit: its tangent is added in :meth:`collect`."""
        ctx["deposits"].append((re, im, index, active))

    def collect(self, ctx: dict) -> dict:
        """Set the leaves' tangents, propagate them forward to every kept deposit, deposit those
        tangents and collect them as the base accumulator collects values."""
        for leaf, tangent in zip(self.leaves, self.tangent):
            dr.set_grad(leaf, tangent)
        deposits = ctx.pop("deposits")
        values = [x for re, im, _, _ in deposits for x in (re, im) if dr.grad_enabled(x)]
        if values:
            dr.forward_to(*values, flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)
        for re, im, index, active in deposits:
            super().add(ctx, dr.grad(re), dr.grad(im), index, active)
        dr.eval(ctx["hist"])
        return super().collect(ctx)


class TangentKernel(Kernel):
    """:class:`~sarmitsuba.tracing.driver.kernel.Kernel` whose launches return ``d hist / dp``: the
    material tables' row ``row`` moves by ``tangent`` (a :class:`RowTangent`) per unit of ``p``;
    every other row stays."""

    def __init__(self, scene, params, window, footprint, settings, material_table, effects, row: int | None,
                 tangent: RowTangent | None, move=None):
        super().__init__(scene, params, window, footprint, settings, material_table, effects)
        flat = {} if row is None else flat_tangents(self.returns.tables, self.effects.polarimetric,
                                                    params.polarization, row, tangent)
        leaves = _leaves(self.returns.tables, flat)
        self.moved = moved_tracer(self, [] if move is None else [move])
        self.returns.sums = TangentSums(self.returns.sums, tuple(leaves.values()),
                                        tuple(device_array(mi.Float, flat[name]) for name in leaves))
        if self.moved is not None:
            self.moved.forward = True


class AdjointSums(Accumulator):
    """Reverse mode: each launch's histogram's gradient (:attr:`seed`, the loss's gradient with
    respect to it, complex [orders, groups, n_b, n_fine], set per batch by the caller) is put in
    the launch's context, and the term kernels replay the launch against it
    (:mod:`sarmitsuba.tracing.deposit.replay`): each pulse's terms are differentiated where they
    are evaluated and their share of ``dL`` carried back to the differentiable leaves (the
    material tables, the geometric lanes), where it adds up over the launches. Nothing is
    deposited: the histogram a replayed launch hands back is zero."""

    def __init__(self, base: Accumulator):
        super().__init__(base.settings, base.window, base.groups, base.n_channels)
        if self.exact:
            raise ParameterError("range_kernel = 'exact' keeps path lists, which gradients do not flow through; "
                                 "use range_kernel linear or sinc")
        self.seed = None
        #: The power of two the seeds were divided by (:func:`~..deposit.adjoint.seed_scale`): the
        #: gradients are multiplied by it.
        self.scale = 1.0

    def open(self, ctx: dict) -> None:
        """Open the launch's histogram, and put :attr:`seed` beside it as its (re, im) floats
        (without a seed, the launch deposits its values as any other)."""
        super().open(ctx)
        if self.seed is None:
            return
        floats = np.zeros(dr.width(ctx["hist"]), np.float32)           # the low words: one per real value
        flat = np.ascontiguousarray(self.seed, np.complex64).reshape(-1).view(np.float32)
        floats[:flat.size] = flat
        ctx["seed"] = device_array(mi.Float, floats)     # aligned: the kernels' packet gathers


class AdjointKernel(Kernel):
    """:class:`~sarmitsuba.tracing.driver.kernel.Kernel` for reverse mode: every material table of
    :data:`DIFFERENTIABLE` a differentiable leaf (:attr:`leaves`, name -> mi.Float), its launches'
    histograms seeded by :class:`AdjointSums`; after the trace, ``dr.grad`` of a leaf is the
    loss's gradient with respect to that table. With ``moves`` (or ``outlines``), the mesh
    tracer is a :class:`~.geometry_tangents.MovedTracer`: the geometric derivatives' outlines
    (docs/physics.md (AD4)) and the moves' tangents."""

    def __init__(self, scene, params, window, footprint, settings, material_table, effects, moves=(),
                 outlines: bool = False):
        super().__init__(scene, params, window, footprint, settings, material_table, effects)
        self.leaves = _leaves(self.returns.tables, DIFFERENTIABLE)
        # every read of a table adds its adjoint in fixed point (docs/physics.md (D7))
        self.returns.tables.adjoint = {name: AdjointSink(leaf) for name, leaf in self.leaves.items()}
        self.returns.sums = AdjointSums(self.returns.sums)
        self.serial = True                  # one launch at a time: Dr.Jit's reverse passes from one thread
        self.moved = moved_tracer(self, list(moves), always=outlines)

    def __call__(self, launch, capacity: int = 0) -> dict:
        out = super().__call__(launch, capacity)
        if self.moved is not None:
            self.moved.accumulate()
        return out

    def table_gradient(self, name: str) -> np.ndarray:
        """``dL/d table`` (float64, the table's width) of differentiable table ``name`` after the
        reverse pass, for the seeds as scaled (:attr:`AdjointSums.scale`): its sink's fixed-point
        sums, plus anything read without a sink."""
        return self.returns.tables.adjoint[name].sums()[0] + np.asarray(dr.grad(self.leaves[name]), np.float64)


def moved_tracer(kernel: Kernel, moves: list, always: bool = False):
    """The kernel's mesh tracer made a :class:`~.geometry_tangents.MovedTracer` of ``moves``
    (without moves: None and unchanged, unless ``always``: the geometric derivatives' own
    outlines, docs/physics.md (AD4), for the values they are taken at); ParameterError where
    the kernel has no mesh tracer."""
    if not moves and not always:
        return None
    if kernel.mesh is None or kernel.tubes:
        raise ParameterError("geometric derivatives are taken with lit_regions = patches (the default) on scenes of "
                             "meshes only (no spheres or other analytic shapes)")
    kernel.mesh = MovedTracer(kernel, moves)
    kernel.serial = True                    # one launch at a time: the tracer keeps each launch's leaves
    return kernel.mesh
