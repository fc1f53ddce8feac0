"""The fringe coefficients near the shadow and reflection boundaries (docs/physics.md (E3)): where
Keller's and PO's terms are both infinite, the kernel evaluates them a step off the boundary, and
the step must not land on another boundary.

The case that found it: on the generated million-triangle city (benchmarks/city_generator.py), a
wave reflected by the sloping ground reached a roof's eave grazing the wall below it
(``phi' = 0.00994`` rad, ``cos(theta_i) = 0.008``), with the receiver almost in the wall's plane
(``phi = 3.13153``: ``phi + phi' = pi - 1.3e-4``). The untraced reverse path's fringe, stepped
``+2e-2`` rad off ``phi + phi' = pi``, landed within 1e-7 rad of ``phi - phi' = -pi``: its
coefficient was 1.1e6 in float64 and infinite in the kernel's float32, and the whole pulse of the
raw data came out NaN.

Deliberate bugs these tests were run against (each fails at least one):
  * the step always upward (the code before the fix: the captured case's reverse coefficient,
    and the sweep's clearance);
  * the clearance measured from ``+pi`` only, not ``-pi`` (the sweep's clearance);
  * the boundary ``2 N pi - phi - phi'`` of face N left out (the sweep at N = 1.5 and 1.75).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (the Mitsuba variant)
import drjit as dr
import mitsuba as mi

from sarmitsuba.tracing.integration import edge_terms
from sarmitsuba.tracing.integration import edges

#: The captured grazing case (module docstring): the angles of the incidence and of the receiver
#: about the eave [rad], and the right-angle wedge's exterior angle over pi.
GRAZING = (0.00993709939528061, 3.131530627498045, 1.5)


def _distance_to_boundaries(phi, phi_i, n):
    """The distance [rad] from the six boundary lines ``phi - phi' = +-pi``, ``phi + phi' = +-pi``,
    ``phi + phi' = 2 n pi -+ pi``, written out line by line."""
    lines = [phi - phi_i - math.pi, phi - phi_i + math.pi, phi + phi_i - math.pi, phi + phi_i + math.pi,
             phi + phi_i - (2 * n - 1) * math.pi, phi + phi_i - (2 * n + 1) * math.pi]
    return np.min(np.abs(np.stack(lines)), axis=0)


def _kernel(phi, phi_i, n, r=-1.0):
    """The Dr.Jit kernel's coefficients (float32) at arrays of angles, faces of reflection
    coefficient ``r`` for both polarisations."""
    face = (mi.Complex2f(r, 0.0), mi.Complex2f(r, 0.0))
    xs, xh = edge_terms.fringe_coefficients(mi.Float(np.asarray(phi, np.float32)),
                                            mi.Float(np.asarray(phi_i, np.float32)),
                                            mi.Float(np.full(np.shape(phi), n, np.float32)), face, face)
    return (np.asarray(dr.real(xs)) + 1j * np.asarray(dr.imag(xs)),
            np.asarray(dr.real(xh)) + 1j * np.asarray(dr.imag(xh)))


def test_the_captured_grazing_case_stays_finite_both_ways():
    """The captured case: the traced path's and the reverse path's coefficients are finite in the
    kernel and bounded (the reverse one was 1.1e6 with the upward step), and the kernel equals the
    NumPy reference at the point it steps to."""
    phi_i, phi, n = GRAZING
    for a, a_i in ((phi, phi_i), (phi_i, phi)):
        xs, xh = _kernel([a], [a_i], n)
        step = edges.boundary_step(a, a_i, n)
        rs, rh = edges.fringe(a, a_i + step, n, -1.0, -1.0, -1.0, -1.0)
        assert np.all(np.isfinite([xs, xh]))
        assert abs(rs) < 1e3 and abs(rh) < 1e3, (a, a_i, rs, rh)
        # float32 loses about eps / window of the coefficients' size to their cancellation
        scale = max(abs(rs), abs(rh), 1.0)
        assert abs(xs[0] - rs) < 1e-2 * scale and abs(xh[0] - rh) < 1e-2 * scale
    # the reverse path sits next to where the shadow and reflection boundaries cross: stepping up
    # lands on the other one, so it steps down
    assert edges.boundary_step(phi_i, phi, n) == -edges.SINGULAR_STEP
    assert edges.boundary_step(phi, phi_i, n) == edges.SINGULAR_STEP


@pytest.mark.parametrize("n", [1.25, 1.5, 1.75, 2.0])
def test_every_step_clears_every_boundary_by_the_window(n):
    """At grazing incidences on either face and receivers on a fine grid (every pair of boundaries
    that cross, approached from every side), the point the coefficients are evaluated at lies at
    least the window away from all six boundary lines, and the kernel's coefficients are finite
    there, also at float32 angles on the boundaries themselves."""
    grazing = np.concatenate([np.array([0.0, 1e-4, 5e-3, 0.0099, 0.01, 0.015, 0.02, 0.03]),
                              math.pi - np.array([1e-4, 5e-3, 0.0099, 0.015, 0.03])])
    grazing = np.concatenate([grazing, n * math.pi - grazing])          # the same on face N
    phi = np.linspace(0.0, n * math.pi, 4001)
    phi_i, phi = (a.ravel() for a in np.meshgrid(grazing, phi))
    step = edges.boundary_step(phi, phi_i, n)
    before = _distance_to_boundaries(phi, phi_i, n)
    after = _distance_to_boundaries(phi, phi_i + step, n)
    assert np.all(step[before >= edges.SINGULAR_WINDOW] == 0.0)
    assert np.all(after >= edges.SINGULAR_WINDOW - 1e-12), (phi[after.argmin()], phi_i[after.argmin()])
    for a, a_i in ((phi, phi_i), (phi_i, phi)):                         # the traced and reverse paths
        xs, xh = _kernel(a, a_i, n)
        assert np.all(np.isfinite(xs)) and np.all(np.isfinite(xh))


def test_the_kernel_matches_the_reference_off_the_boundaries():
    """Away from the crossings the float32 kernel gives the NumPy reference's coefficients (a
    second implementation of (E2), (E3)) at several wedges and angles, on either side of a
    boundary as well, for a dielectric face too (r = -0.6)."""
    rng = np.random.default_rng(7)
    for n in (1.25, 1.5, 2.0):
        phi_i = rng.uniform(0.05, n * math.pi - 0.05, 400)
        phi = rng.uniform(0.05, n * math.pi - 0.05, 400)
        keep = _distance_to_boundaries(phi, phi_i, n) > 0.05
        for r in (-1.0, -0.6):
            xs, xh = _kernel(phi[keep], phi_i[keep], n, r)
            rs, rh = edges.fringe(phi[keep], phi_i[keep], n, r, r, r, r)
            assert np.allclose(xs, rs, rtol=1e-3, atol=1e-3) and np.allclose(xh, rh, rtol=1e-3, atol=1e-3)
