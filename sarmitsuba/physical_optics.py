"""Ray-tube physical optics in plain NumPy (docs/physics.md (PO1)-(PO3)): the readable reference
of the tracer's PO return, and the closed form it is tested against.

* :func:`tube_terms` -- one tube footprint's PO integral as 1, 2 or 4 point terms, each evaluated
  at its own point, as :func:`sarmitsuba.kernel.po_terms` computes it in Dr.Jit;
* :func:`plane_wave`, :func:`point_sources` -- the geometry a term sees at its point;
* :func:`terms_spectrum` -- the terms' sum at any frequency of the band;
* :func:`polygon_integral` -- the PO integral of a planar polygon under a linear phase
  (Gordon, IEEE TAP 23(4), 1975), the closed form that tubes tiling a plate must reproduce
  at every frequency.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["SINC_REGIME", "tube_terms", "plane_wave", "point_sources", "terms_spectrum", "polygon_integral"]

#: Footprint edges whose phase half-width ``|alpha| = |k beta| / 2`` is below this keep the
#: carrier's ``sinc(alpha)`` (one term); wider ones are split into their two end terms
#: (docs/physics.md (PO2)). The sinc's error across a band B is about ``alpha^2 B / (6 fc)`` (1 %
#: at X band, 150 MHz): it matters only where tubes resonate with the band, at ``alpha`` of
#: multiples of pi, which the split avoids. Ends closer than that to a stationary point of the
#: phase (the zero-Doppler line, where the phase is quadratic across the tube) are not well
#: described by their gradient alone, so the split waits for ``alpha`` of 2.
SINC_REGIME = 2.0


def plane_wave(d: np.ndarray, b: np.ndarray, s: float):
    """Geometry of a plane wave arriving along ``d`` and returning along ``b`` (unit vectors): for
    a point ``x`` its ``(d, b, s, L)`` with the tube's unfolded length ``s`` and the two-way length
    ``L = (d - b) . x`` (the far-field limit of :func:`point_sources`)."""
    return lambda x: (d, b, s, float((d - b) @ x))


def point_sources(source: np.ndarray, antenna: np.ndarray):
    """Geometry of a spherical wave from the tube's (image) ``source`` returning to ``antenna``: for a
    point ``x``, ``d = (x - source) / s``, ``b = (antenna - x) / R``, ``s = |x - source|`` and the
    two-way length ``L = s + R``."""
    def geometry(x):
        s, r = np.linalg.norm(x - source), np.linalg.norm(antenna - x)
        return (x - source) / s, (antenna - x) / r, s, s + r
    return geometry


def tube_terms(k: float, centre: np.ndarray, n: np.ndarray, t1: np.ndarray, t2: np.ndarray, geometry,
               density) -> tuple[np.ndarray, np.ndarray, int]:
    """The PO integral of one tube footprint as point terms, eqs. (PO2), (PO4); the readable
    NumPy reference of :func:`sarmitsuba.kernel.po_terms`.

    Parameters
    ----------
    k : float, rad/m
        Carrier wavenumber ``2 pi fc / c``.
    centre : float64 [3], m
        Where the tube's central ray meets the facet.
    n : float64 [3]
        Unit normal of the facet, facing the ray.
    t1, t2 : float64 [3]
        The tube's cross-section edges per metre of unfolded length (at unfolded length ``s`` the
        tube is spanned by ``s t1`` and ``s t2``).
    geometry : callable
        ``x -> (d, b, s, L)`` at a point of the facet (:func:`plane_wave`, :func:`point_sources`).
    density : callable
        ``(cos_i, cos_b, d, b, s, L) -> complex``: the PO amplitude per unit footprint area there
        (``j (2 sqrt(pi) / lambda) (cos_i + cos_b) / 2`` times reflection coefficients, pattern
        and spreading; eq. (PO1)).

    Returns
    -------
    lengths : float64 [t], m
        Two-way length of each term (at its own point).
    coefficients : complex128 [t]
        Each term's value at the carrier before its propagation phase ``exp(-j k L)``.
    order : int
        Spectral order ``m = 1 - (number of split edges)``: the terms scale as ``(f / fc)^m``.

    Notes
    -----
    The footprint edges are ``e_j' = e_j + d (n . e_j) / cos_i`` with ``e_j = s t_j``. An edge
    with ``|alpha_j| = |k (d - b) . e_j'| / 2 >= SINC_REGIME`` at the centre is split into its two
    ends, ``-sigma / (j k g_j)`` at ``x = centre + sigma e_j' / 2`` (``g_j`` the two-way length's
    gradient along the edge); otherwise it contributes ``|e_j'| sinc(alpha_j)`` at the centre line.
    Every term is evaluated at its own point: its geometry, footprint edges and density.
    """
    def edges_at(d, s):
        cos_i = -float(n @ d)
        return [s * t + d * (n @ (s * t)) / cos_i for t in (t1, t2)], cos_i

    d, b, s, _ = geometry(centre)
    centre_edges, _ = edges_at(d, s)
    split = [abs(0.5 * k * float((d - b) @ e)) >= SINC_REGIME for e in centre_edges]
    lengths, coefficients = [], []
    for s1 in ((-1.0, 1.0) if split[0] else (0.0,)):
        for s2 in ((-1.0, 1.0) if split[1] else (0.0,)):
            x = centre + 0.5 * s1 * centre_edges[0] + 0.5 * s2 * centre_edges[1]
            d_x, b_x, s_x, length = geometry(x)
            edges, cos_i = edges_at(d_x, s_x)
            value = density(cos_i, float(n @ b_x), d_x, b_x, s_x, length) * np.linalg.norm(np.cross(*edges))
            for sigma, is_split, e in zip((s1, s2), split, edges):
                grad = float((d_x - b_x) @ e) / np.linalg.norm(e)
                alpha = 0.5 * k * grad * np.linalg.norm(e)
                value *= -sigma / (1j * k * grad * np.linalg.norm(e)) if is_split else \
                    (math.sin(alpha) / alpha if alpha else 1.0)
            lengths.append(length)
            coefficients.append(value)
    return np.array(lengths), np.array(coefficients), 1 - int(split[0]) - int(split[1])


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
