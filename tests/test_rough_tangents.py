"""Derivatives of a rough material's sigma nought tables with respect to its conductivity
(docs/physics.md (RS6), (AD2)): against central differences of the model evaluated directly (no
table) at the permittivity the conductivity gives, ``eta = eps_r - j sigma / (omega eps_0)``
(ITU-R P.2040 eq. 9a), written out here with eps_0 = 8.8541878128e-12 F/m (CODATA 2018).

Planted bug: the conductivity's ``d eta`` with its sign flipped (``+1j`` for ``-1j`` in
``rough_tangents``): every derivative changes sign and the test fails."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sarmitsuba.scene.materials import Material
from sarmitsuba.scene.rough_tables import COS_SIZE, MONO_SIZE, PHI_SIZE
from sarmitsuba.scene.roughness import RoughSurface, sigma0_backscatter, sigma0_bistatic
from sarmitsuba.tracing.derivatives.rough_tangents import rough_row_tangent

FREQUENCY = 9.6e9
K = 2 * math.pi * FREQUENCY / 299792458.0
EPS_0 = 8.8541878128e-12
EPS_R, SIGMA = 6.0, 0.8                  # S/m: a wet soil's loss, eta = 6 - 1.5j at 9.6 GHz
SURFACE = RoughSurface(0.004, 0.02)      # k s = 0.80, s / l = 0.2


def _eta(sigma: float) -> complex:
    return complex(EPS_R, -sigma / (2 * math.pi * FREQUENCY * EPS_0))


def _tangents():
    material = Material("soil", _eta(SIGMA))
    zero = np.zeros(MONO_SIZE, np.complex128)
    return rough_row_tangent(material, SURFACE, "conductivity", FREQUENCY, MONO_SIZE, (zero, zero))[2]


@pytest.mark.parametrize("node", [96, 160, 224])              # incidence 68, 51 and 29 deg
def test_monostatic_conductivity_derivative_is_the_models_central_difference(node):
    """``d sigma0 / d sigma`` of HH, VV and HV at a node of the monostatic table within 1 % of
    ``(sigma0(sigma + h) - sigma0(sigma - h)) / 2h`` (h = 0.01 S/m) of :func:`sigma0_backscatter`."""
    d_mono, _ = _tangents()
    cos = node / (MONO_SIZE - 1)
    h = 0.01
    up, down = (sigma0_backscatter(SURFACE, _eta(SIGMA + s * h), K, cos) for s in (1, -1))
    for p, name in enumerate(("HH", "VV", "HV")):
        expected = (float(up[name]) - float(down[name])) / (2 * h)
        assert abs(expected) > 0, name
        assert d_mono[p, node] == pytest.approx(expected, rel=1e-2), name


@pytest.mark.parametrize("a, b, m", [(10, 25, 4), (28, 12, 12)])
def test_bistatic_conductivity_derivative_is_the_models_central_difference(a, b, m):
    """The bistatic table's ``d sigma0 / d sigma`` of HH and VV at a node (incidence and scattering
    cosines ``a / 32``, ``b / 32``, azimuth cosine ``-1 + m / 8``) within 1 % of the central
    difference of :func:`sigma0_bistatic`."""
    _, d_bi = _tangents()
    ci, cs, cp = a / (COS_SIZE - 1), b / (COS_SIZE - 1), -1.0 + 2.0 * m / (PHI_SIZE - 1)
    h = 0.01
    up, down = (sigma0_bistatic(SURFACE, _eta(SIGMA + s * h), K, ci, cs, math.acos(cp)) for s in (1, -1))
    for p, name in enumerate(("HH", "VV")):
        expected = (float(up[name]) - float(down[name])) / (2 * h)
        assert abs(expected) > 0, name
        assert d_bi[p, a, b, m] == pytest.approx(expected, rel=1e-2), name
