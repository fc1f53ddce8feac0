"""Tangents of a rough surface's material row (docs/physics.md (RS6)): its reflection tables carry
the coherent factor ``exp(-2 (k s cos)^2)``, and its sigma nought tables depend on the surface's
``rms_height`` and ``correlation_length`` and on the permittivity. Used by
:func:`sarmitsuba.tracing.derivatives.tangents.row_tangent`.

The sigma nought tables' tangents are central differences of the model
(:func:`sarmitsuba.scene.rough_tables.rough_tables`) at a relative step of ``STEP``: the model is a
series of smooth terms, so their truncation error is of the step's square, below the float32
tables' rounding.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ...core.constants import SPEED_OF_LIGHT, VACUUM_PERMITTIVITY
from ...core.radar import ParameterError
from ...scene.materials import reflection_coefficient
from ...scene.rough_tables import coherent_factor, rough_tables

__all__ = ["ROUGH_PARAMETERS", "STEP", "rough_row_tangent"]

#: The rough surface's own parameters a derivative can be taken with respect to, and their units.
ROUGH_PARAMETERS = {"rms_height": "m", "correlation_length": "m"}
#: Relative step of the sigma nought tables' central differences.
STEP = 1e-3


def _tables(surface, eta, wavenumber: float) -> tuple[np.ndarray, np.ndarray]:
    t = rough_tables([surface], [eta], wavenumber, cross=True)
    return t.mono[0].astype(np.float64), t.bistatic[0].astype(np.float64)


def rough_row_tangent(material, surface, parameter: str, frequency: float, n_cos: int, smooth: tuple):
    """``(d r_te, d r_tm, (d mono, d bistatic))`` of a rough material's row for ``parameter``.

    Parameters
    ----------
    material : sarmitsuba.scene.materials.Material
    surface : sarmitsuba.scene.roughness.RoughSurface
    parameter : str
        ``rms_height``, ``correlation_length`` (m), ``relative_permittivity``, ``conductivity``
        (S/m) or ``thickness`` (m, slabs: the reflection tables only; the rough surface scatters
        as its half-space).
    frequency : float, Hz
    n_cos : int
        The reflection tables' size.
    smooth : tuple
        ``(d r_te, d r_tm)`` of the smooth material for ``parameter`` (complex128 [n_cos]), or
        ``(None, None)`` for the surface's own parameters.

    Returns
    -------
    te, tm : complex128 [n_cos]
    rough : (float64 [3, MONO_SIZE], float64 [2, COS_SIZE, COS_SIZE, PHI_SIZE])

    Raises
    ------
    ParameterError
        For a perfect conductor's permittivity (it has none).
    """
    k = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    cos = np.linspace(0.0, 1.0, n_cos)
    factor = coherent_factor(surface, k, cos)
    eta = material.relative_permittivity
    if parameter in ROUGH_PARAMETERS:
        value = getattr(surface, parameter)
        h = STEP * value
        pair = [_tables(dataclasses.replace(surface, **{parameter: value + sign * h}), eta, k) for sign in (1, -1)]
        if parameter == "rms_height":     # d exp(-2 k^2 s^2 c^2) / ds = -4 k^2 s c^2 exp(...)
            d_factor = -4.0 * k * k * surface.rms_height * cos * cos * factor
            te, tm = (reflection_coefficient(material, cos, frequency, p) * d_factor for p in ("HH", "VV"))
        else:
            te = tm = np.zeros(n_cos, np.complex128)
    else:
        if eta is None:
            raise ParameterError(f"material {material.name!r} is a perfect conductor: it has no {parameter}")
        te, tm = (d * factor for d in smooth)
        if parameter == "thickness":
            shape = _tables(surface, eta, k)
            return te, tm, (np.zeros_like(shape[0]), np.zeros_like(shape[1]))
        # d eta: 1 per unit of relative_permittivity, -j / (omega eps_0) per S/m of conductivity
        d_eta = 1.0 if parameter == "relative_permittivity" else -1j / (2.0 * math.pi * frequency * VACUUM_PERMITTIVITY)
        h = STEP * abs(eta) / abs(d_eta)
        pair = [_tables(surface, complex(eta) + sign * h * d_eta, k) for sign in (1, -1)]
    d_mono, d_bi = ((a - b) / (2.0 * h) for a, b in zip(*pair))
    return te, tm, (d_mono, d_bi)
