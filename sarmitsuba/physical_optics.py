"""Ray-tube physical optics in plain NumPy (docs/physics.md (PO1)-(PO3)): the readable reference
of the tracer's PO return, and the closed form it is tested against.

* :func:`tube_terms` -- one tube footprint's PO integral as 1, 2 or 4 point terms, exactly as
  :func:`sarmitsuba.kernel.po_terms` computes it in Dr.Jit;
* :func:`terms_spectrum` -- the terms' sum at any frequency of the band;
* :func:`polygon_integral` -- the PO integral of a planar polygon under a linear phase
  (Gordon, IEEE TAP 23(4), 1975), the closed form that tubes tiling a plate must reproduce
  at every frequency.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["SINC_REGIME", "tube_terms", "terms_spectrum", "polygon_integral"]

#: Footprint edges whose phase half-width ``|alpha| = |k beta| / 2`` is below this keep the
#: carrier's ``sinc(alpha)`` (one term; its relative error across a band B is about
#: ``alpha^2 B / (6 fc)``, -63 dB at X band, 150 MHz); wider ones are split into their two end
#: terms (docs/physics.md (PO2)).
SINC_REGIME = 0.5


def tube_terms(k: float, d: np.ndarray, b: np.ndarray, n: np.ndarray, e1: np.ndarray, e2: np.ndarray,
               prefactor: complex) -> tuple[np.ndarray, np.ndarray, int]:
    """The PO integral of one tube footprint as point terms, eq. (PO2).

    Parameters
    ----------
    k : float, rad/m
        Carrier wavenumber ``2 pi fc / c``.
    d, b, n : float64 [3]
        Unit incoming direction, unit direction to the antenna, unit normal facing the ray.
    e1, e2 : float64 [3], m
        The tube's cross-section edges at the hit (normal to ``d``).
    prefactor : complex
        What multiplies the footprint integral: ``j (2 sqrt(pi) / lambda) A_perp (cos_b + cos_i) / (2 cos_i)``
        times the reflection coefficients (and pattern, spreading).

    Returns
    -------
    offsets : float64 [t], m
        Two-way length of each term relative to the footprint centre's.
    coefficients : complex128 [t]
        Each term's value at the carrier before the propagation phase ``exp(-j k L)``.
    order : int
        Spectral order ``m = 1 - (number of split edges)``: the terms scale as ``(f / fc)^m``.
    """
    cos_i = -float(np.dot(n, d))
    u = d - b
    per_edge = []
    for e in (e1, e2):
        footprint = e + d * np.dot(n, e) / cos_i
        beta = float(np.dot(u, footprint))
        alpha = 0.5 * k * beta
        if abs(alpha) >= SINC_REGIME:     # the two ends: +-exp(+-j alpha) / (2 j alpha)
            per_edge.append(([-0.5 * beta, 0.5 * beta], [1.0 / (1j * k * beta), -1.0 / (1j * k * beta)], 1))
        else:
            per_edge.append(([0.0], [math.sin(alpha) / alpha if alpha else 1.0], 0))
    offsets = np.array([a + c for a in per_edge[0][0] for c in per_edge[1][0]])
    coefficients = prefactor * np.array([a * c for a in per_edge[0][1] for c in per_edge[1][1]])
    return offsets, coefficients, 1 - per_edge[0][2] - per_edge[1][2]


def terms_spectrum(lengths: np.ndarray, coefficients: np.ndarray, orders: np.ndarray, frequencies: np.ndarray,
                   carrier: float) -> np.ndarray:
    """``sum_i c_i (f / fc)^m_i exp(-j 2 pi f L_i / c)`` at each frequency [Hz] (complex128 [n_f]):
    what a set of terms of two-way lengths ``L_i`` [m] returns across the band (eq. (PO3))."""
    from .constants import SPEED_OF_LIGHT
    f = np.asarray(frequencies, float)[:, None]
    return np.sum(coefficients[None, :] * (f / carrier) ** orders[None, :]
                  * np.exp(-2j * np.pi * f * lengths[None, :] / SPEED_OF_LIGHT), axis=1)


def polygon_integral(vertices: np.ndarray, normal: np.ndarray, q: np.ndarray) -> complex:
    """``int_P exp(j q . x) dA`` over a planar polygon, in closed form (Gordon 1975).

    By the divergence theorem in the polygon's plane, with ``q_t`` the part of ``q`` in the
    plane and ``a_n = v_{n+1} - v_n`` the edges (counter-clockwise about ``normal``)::

        I = sum_n  q_t . (a_n x normal) exp(j q . c_n) sinc(q . a_n / 2) / (j |q_t|^2)

    with ``c_n`` the edge midpoints and ``sinc(x) = sin(x) / x``; ``A exp(j q . x_0)`` when
    ``q_t = 0``.

    Parameters
    ----------
    vertices : float64 [n, 3], m
        The polygon's corners in order.
    normal : float64 [3]
        Unit normal (orientation fixes the corner order's sense).
    q : float64 [3], rad/m
        Phase gradient.
    """
    v = np.asarray(vertices, float)
    normal = np.asarray(normal, float)
    q = np.asarray(q, float)
    q_t = q - normal * np.dot(q, normal)
    a = np.roll(v, -1, axis=0) - v
    area_vector = 0.5 * np.sum(np.cross(v, np.roll(v, -1, axis=0)), axis=0)
    sign = 1.0 if np.dot(area_vector, normal) >= 0 else -1.0
    if np.dot(q_t, q_t) < 1e-18:
        return complex(abs(np.dot(area_vector, normal)) * np.exp(1j * np.dot(q, v.mean(axis=0))))
    mid = v + 0.5 * a
    x = 0.5 * (a @ q)
    sinc = np.where(np.abs(x) < 1e-12, 1.0, np.sin(x) / np.where(x == 0, 1.0, x))
    terms = (np.cross(a, normal) @ q_t) * np.exp(1j * (mid @ q)) * sinc
    return complex(sign * terms.sum() / (1j * np.dot(q_t, q_t)))
