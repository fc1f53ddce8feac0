"""Forward-mode derivatives of a trace with respect to a material's reflection table (issue 57).

The kernels read each material's reflection coefficient ``r(cos_i)`` from a table (eq. (R)),
in Dr.Jit. :class:`TangentKernel` is the tracing kernel with that table made a differentiable
leaf: Dr.Jit records how every deposited term depends on it while the launch runs (its loops
evaluated, :mod:`.loops`), and :class:`TangentSums` then propagates a tangent of the table,
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

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from ..core.constants import SPEED_OF_LIGHT, VACUUM_PERMITTIVITY
from ..core.radar import ParameterError
from .accumulate import Accumulator
from .kernel import Kernel

__all__ = ["MATERIAL_PARAMETERS", "reflection_table_ad", "material_tangent", "TangentKernel", "TangentSums",
           "AdjointKernel", "AdjointSums", "TABLES"]

#: The kernel's reflection tables: (real, imaginary) of r_te or the channel's r, and of r_tm (Jones model).
TABLES = (("re", "im"), ("re_tm", "im_tm"))

#: The material parameters a derivative can be taken with respect to, and their units.
MATERIAL_PARAMETERS = {"relative_permittivity": "1", "conductivity": "S/m", "thickness": "m"}


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


class TangentSums(Accumulator):
    """The histogram of a launch replaced by its derivative: before collecting, the table's tangent
    is set on the kernel's differentiable table and propagated forward to the histogram."""

    def __init__(self, base: Accumulator, leaves: tuple, tangent: tuple):
        super().__init__(base.settings, base.window, base.groups, base.n_channels)
        if self.exact:
            raise ParameterError("range_kernel = 'exact' keeps path lists, which derivatives do not flow through; "
                                 "use range_kernel linear or sinc")
        self.leaves, self.tangent = leaves, tangent

    def collect(self, ctx: dict) -> dict:
        for leaf, tangent in zip(self.leaves, self.tangent):
            dr.set_grad(leaf, tangent)
        dr.forward_to(ctx["hist"], flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)
        ctx["hist"] = dr.grad(ctx["hist"])
        dr.eval(ctx["hist"])
        return super().collect(ctx)


class TangentKernel(Kernel):
    """:class:`~sarmitsuba.tracing.kernel.Kernel` whose launches return ``d hist / dp``: the
    reflection tables' row ``row`` moves by ``tangent_te`` and ``tangent_tm`` (complex [n_cos],
    ``dr_te/dp`` and ``dr_tm/dp``) per unit of ``p``; every other row stays. The scalar model's
    one table is the channel's (``r_tm`` for VV, else ``r_te``), the Jones model's both (P3')."""

    def __init__(self, scene, params, window, footprint, settings, material_table, effects, row: int,
                 tangent_te: np.ndarray, tangent_tm: np.ndarray):
        super().__init__(scene, params, window, footprint, settings, material_table, effects)
        t = self.returns.tables
        if self.effects.polarimetric:
            pairs = (("re", "im", tangent_te), ("re_tm", "im_tm", tangent_tm))
        else:
            pairs = (("re", "im", tangent_tm if params.polarization == "VV" else tangent_te),)
        leaves, tangents = [], []
        for re_name, im_name, tangent in pairs:
            full = np.zeros(dr.width(getattr(t, re_name)), np.complex128)
            full[row * t.n_cos:(row + 1) * t.n_cos] = tangent
            for name, part in ((re_name, full.real), (im_name, full.imag)):
                leaf = mi.Float(dr.detach(getattr(t, name)))
                dr.enable_grad(leaf)
                setattr(t, name, leaf)
                leaves.append(leaf)
                tangents.append(mi.Float(part.astype(np.float32)))
        self.returns.sums = TangentSums(self.returns.sums, tuple(leaves), tuple(tangents))


class AdjointSums(Accumulator):
    """Reverse mode: each launch's histogram gets the loss's gradient with respect to it
    (:attr:`seed`, complex [orders, groups, n_b, n_fine], set per batch by the caller), which
    Dr.Jit carries back to the reflection tables' leaves, where it adds up over the launches.
    The launch's own histogram (the values) is returned as usual."""

    def __init__(self, base: Accumulator):
        super().__init__(base.settings, base.window, base.groups, base.n_channels)
        if self.exact:
            raise ParameterError("range_kernel = 'exact' keeps path lists, which gradients do not flow through; "
                                 "use range_kernel linear or sinc")
        self.seed = None

    def collect(self, ctx: dict) -> dict:
        floats = np.zeros(dr.width(ctx["hist"]), np.float32)
        flat = np.ascontiguousarray(self.seed, np.complex64).reshape(-1).view(np.float32)
        floats[:flat.size] = flat
        dr.set_grad(ctx["hist"], mi.Float(floats))
        dr.enqueue(dr.ADMode.Backward, ctx["hist"])
        dr.traverse(dr.ADMode.Backward, flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)
        return super().collect(ctx)


class AdjointKernel(Kernel):
    """:class:`~sarmitsuba.tracing.kernel.Kernel` for reverse mode: every reflection table a
    differentiable leaf (:attr:`leaves`, name -> mi.Float), its launches' histograms seeded by
    :class:`AdjointSums`; after the trace, ``dr.grad`` of a leaf is the loss's gradient with
    respect to that table (float32 [n_rows * n_cos])."""

    def __init__(self, scene, params, window, footprint, settings, material_table, effects):
        super().__init__(scene, params, window, footprint, settings, material_table, effects)
        t = self.returns.tables
        self.leaves = {}
        for pair in TABLES[:2 if self.effects.polarimetric else 1]:
            for name in pair:
                leaf = mi.Float(dr.detach(getattr(t, name)))
                dr.enable_grad(leaf)
                setattr(t, name, leaf)
                self.leaves[name] = leaf
        self.returns.sums = AdjointSums(self.returns.sums)
