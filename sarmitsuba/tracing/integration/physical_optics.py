"""Ray-tube physical optics in plain NumPy (docs/physics.md (PO1)-(PO3)): the readable reference
of the tracer's PO return, and the closed form it is tested against.

* :func:`tube_terms` -- one tube footprint's PO integral as 1, 2 or 4 point terms, each evaluated
  at its own point, on the parallelogram tangent to the tube at its centre;
* :func:`cell_terms` -- the same for the tile of an aim cell as one pulse sees it (the images of
  the cell's corners), as :meth:`sarmitsuba.tracing.integration.returns.Returns.po` computes it in Dr.Jit;
* :func:`plane_wave`, :func:`point_sources` -- the geometry a term sees at its point;
* :func:`terms_spectrum` -- the terms' sum at any frequency of the band;
* :func:`polygon_integral` -- the PO integral of a planar polygon under a linear phase
  (Gordon, IEEE TAP 23(4), 1975), the closed form that tubes tiling a plate must reproduce
  at every frequency.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["SINC_REGIME", "split_threshold", "tube_terms", "cell_terms", "cell_alphas", "plane_wave", "point_sources", "terms_spectrum", "polygon_integral"]

#: Footprint edges whose phase half-width ``|alpha| = |k beta| / 2`` is below this always keep the
#: carrier's ``sinc(alpha)`` (one term); wider ones may be split into their two end terms
#: (docs/physics.md (PO2)). Ends closer than that to a stationary point of the phase (the
#: zero-Doppler line, where the phase is quadratic across the tube) are not well described by
#: their gradient alone. A pulse splits an edge at :func:`split_threshold`; a sub-aperture whose
#: pulses all see ``|alpha| >= SINC_REGIME`` may split it for all of them (docs/physics.md (T3)).
SINC_REGIME = 2.0


def split_threshold(bandwidth: float, frequency: float) -> float:
    """``|alpha|`` [rad] at which a pulse splits a footprint edge: ``0.95 pi / (1 + B / (2 fc))``.

    Below it the edge keeps ``sinc(alpha)``, whose error across the band is about
    ``alpha^2 B / (6 fc)`` (2 % at ``alpha`` = 2.9, X band, 150 MHz); the sinc must not reach its
    first zero anywhere in the band (``alpha (1 + B / (2 fc)) < pi``), where a lattice of equal tubes
    resonates with the band (docs/physics.md (PO2)). Between :data:`SINC_REGIME` and this value
    both forms hold. 2.92 at X band (9.6 GHz) and 150 MHz.
    """
    return 0.95 * math.pi / (1.0 + bandwidth / (2.0 * frequency))


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
               density, split_at: float = SINC_REGIME) -> tuple[np.ndarray, np.ndarray, int]:
    """The PO integral of one tube footprint as point terms, eqs. (PO2), (PO4); the readable
    NumPy reference of :func:`sarmitsuba.tracing.driver.kernel.po_terms`.

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
    split_at : float
        ``|alpha|`` from which an edge is split (the tracer uses :func:`split_threshold`).

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
    with ``|alpha_j| = |k (d - b) . e_j'| / 2 >= split_at`` at the centre is split into its two
    ends, ``-sigma / (j k g_j)`` at ``x = centre + sigma e_j' / 2`` (``g_j`` the two-way length's
    gradient along the edge); otherwise it contributes ``|e_j'| sinc(alpha_j)`` at the centre line.
    Every term is evaluated at its own point: its geometry, footprint edges and density.
    """
    def edges_at(d, s):
        cos_i = -float(n @ d)
        return [s * t + d * (n @ (s * t)) / cos_i for t in (t1, t2)], cos_i

    d, b, s, _ = geometry(centre)
    centre_edges, _ = edges_at(d, s)
    split = [abs(0.5 * k * float((d - b) @ e)) >= split_at for e in centre_edges]
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


def cell_terms(k: float, antenna: np.ndarray, aim: np.ndarray, cell: tuple, path, density,
               split_at: float = SINC_REGIME, step: float = 1e-4, split=None,
               receiver=None) -> tuple[np.ndarray, np.ndarray, int]:
    """The PO integral of one aim cell's tile as one pulse sees it, as point terms, eqs. (T3),
    (PO2), (PO4): the readable NumPy reference of :meth:`sarmitsuba.tracing.integration.returns.Returns.po`.

    Every point of the tile is where the ray from the sub-aperture's reference position (the
    pulse's antenna with one pulse per trace) through a point of the aim cell meets the facet
    after its mirrors; the pulse reaches it along its own unfolded leg. A term belongs to a corner, edge midpoint or the centre of
    the cell; its tile edges there are the images of the cell's edges, taken here by central
    finite differences of ``path`` (the kernel differentiates the projection analytically).

    Parameters
    ----------
    k : float, rad/m
        Carrier wavenumber.
    antenna : float64 [3], m
        The pulse's antenna position.
    aim : float64 [3], m
        Centre of the aim cell (on the aim plane).
    cell : (float64 [3], float64 [3]), m
        The aim cell's edge vectors (along track, ground range).
    path : callable
        ``point -> (x, d, s, n)``: the ray from the reference position toward ``point`` (on the
        aim plane) meets the facet at ``x`` (float64 [3]), which the pulse's ray reaches along
        ``d`` after an unfolded length ``s`` [m]; ``n`` is the facet's unit normal facing the ray.
    density : callable
        ``(cos_i, cos_b, d, b, s, L) -> complex``, as for :func:`tube_terms`.
    split_at : float
        ``|alpha|`` from which an edge is split, decided at the cell's centre.
    step : float
        Finite-difference step, in cell edges.
    split : (bool, bool), optional
        Which edges are split, when decided elsewhere (a sub-aperture, docs/physics.md (T3));
        ``split_at`` is then unused.
    receiver : callable, optional
        ``(x, s) -> float64 [3]``: where the antenna receives the echo of ``x`` reached after the
        unfolded length ``s`` (docs/physics.md (J3)); default ``antenna`` (stop-and-hop).

    Returns
    -------
    lengths : float64 [t], m
        Two-way length ``s + |A_rx - x|`` of each term.
    coefficients : complex128 [t]
        Values at the carrier before the propagation phase.
    order : int
        Spectral order ``1 - (number of split edges)``.
    """
    def at(point):
        x, d, s, n = path(point)
        edges = [(path(point + step * v)[0] - path(point - step * v)[0]) / (2.0 * step) for v in cell]
        to_antenna = (antenna if receiver is None else receiver(x, s)) - x
        dist = float(np.linalg.norm(to_antenna))
        return x, d, s, n, to_antenna / dist, dist, edges

    if split is None:
        split = np.abs(cell_alphas(k, antenna, aim, cell, path, step)) >= split_at
    lengths, coefficients = [], []
    for s1 in ((-1.0, 1.0) if split[0] else (0.0,)):
        for s2 in ((-1.0, 1.0) if split[1] else (0.0,)):
            x, d, s, n, b, dist, edges = at(aim + 0.5 * s1 * cell[0] + 0.5 * s2 * cell[1])
            value = density(-float(n @ d), float(n @ b), d, b, s, s + dist) * np.linalg.norm(np.cross(*edges))
            for sigma, is_split, e in zip((s1, s2), split, edges):
                g = float((d - b) @ e)
                value *= -sigma / (1j * k * g) if is_split else (math.sin(0.5 * k * g) / (0.5 * k * g) if g else 1.0)
            lengths.append(s + dist)
            coefficients.append(value)
    return np.array(lengths), np.array(coefficients), 1 - int(split[0]) - int(split[1])


def cell_alphas(k: float, antenna: np.ndarray, aim: np.ndarray, cell: tuple, path, step: float = 1e-4) -> np.ndarray:
    """``alpha_j = k (d - b) . e_j / 2`` at the centre of an aim cell's tile (float64 [2]): half the
    phase across each of its edges as the pulse at ``antenna`` sees it (arguments as
    :func:`cell_terms`), eq. (PO2)."""
    x, d, _, _ = path(aim)
    b = (antenna - x) / np.linalg.norm(antenna - x)
    edges = [(path(aim + step * v)[0] - path(aim - step * v)[0]) / (2.0 * step) for v in cell]
    return np.array([0.5 * k * float((d - b) @ e) for e in edges])


def terms_spectrum(lengths: np.ndarray, coefficients: np.ndarray, orders: np.ndarray, frequencies: np.ndarray,
                   carrier: float) -> np.ndarray:
    """``sum_i c_i (f / fc)^m_i exp(-j 2 pi f L_i / c)`` at each frequency [Hz] (complex128 [n_f]):
    what a set of terms of two-way lengths ``L_i`` [m] returns across the band (eq. (PO3))."""
    from ...core.constants import SPEED_OF_LIGHT
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
