"""Every pulse's fringe and doubly diffracted terms of the mesh's edges, in Dr.Jit
(docs/physics.md (E1)-(E6)): the kernel side of :mod:`sarmitsuba.tracing.integration.edges`, whose
:func:`~sarmitsuba.tracing.integration.edges.edge_field` and :func:`~sarmitsuba.tracing.integration.edges.double_field`
are its NumPy reference (tests/test_patch_kernel.py compares the two through
:func:`sarmitsuba.tracing.integration.patch_reference.lane_terms`).

:class:`PatchTerms <sarmitsuba.tracing.integration.patch_terms.PatchTerms>` calls :class:`EdgeTerms` for the
lanes whose segment lies on a diffracting edge: their far field per metre of edge, per channel,
and the line integral of the phase along the segment, split or sinc as (M5) splits PO's edges.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from . import ground_wave
from . import jones as pol
from ..device import device_array
from .edges import GRAZING_EDGE, SINGULAR_STEP, SINGULAR_WINDOW, TRANSITION_SERIES

__all__ = ["EdgeTerms", "edge_tangent", "boundary_clearance", "boundary_step", "fringe_coefficients", "sinc", "x_dsinc",
           "end_slope", "MIN_END_ALPHA"]

_SMALL = 1e-4

#: The least ``|alpha| = |k u . a| / 2`` a split segment's end is evaluated with, in its
#: ``1 / (u . a)`` (docs/physics.md (M5), (E4)). The split is decided at the segment's midpoint (or
#: its three views); the end's own ``alpha`` differs from the midpoint's by up to twice the patch's
#: quadratic phase (M1), at most ``pi / 2`` for a valid ``patch_size``, so the end of a split
#: segment (``|alpha| >= 2``) keeps ``|alpha| >= 0.43`` and this floor never acts on a valid render.
#: Beyond that bound ``u . a`` crossed zero at the end and the term reached ``1 / (k 1e-30)``: raw
#: data 1e27 times too strong.
MIN_END_ALPHA = 0.25


def end_slope(ua, a_len, k):
    """``u . a^`` at a split segment's end, its magnitude kept at least ``2 MIN_END_ALPHA / (k |a|)``
    (its sign kept; zero counts as positive)."""
    floor = 2.0 * MIN_END_ALPHA / (k * dr.maximum(a_len, 1e-30))
    return dr.select(ua >= 0.0, dr.maximum(ua, floor), dr.minimum(ua, -floor))


def sinc(x):
    """``sin(x) / x`` in Dr.Jit (its series below 1e-4)."""
    return dr.select(dr.abs(x) < _SMALL, 1.0 - x * x * (1.0 / 6.0), dr.sin(x) / x)


def x_dsinc(x):
    """``x d sinc(x) / dx = cos(x) - sinc(x)``."""
    return dr.select(dr.abs(x) < _SMALL, -x * x * (1.0 / 3.0), dr.cos(x) - dr.sin(x) / x)


def edge_tangent(edge, x0, n0):
    """The unit tangent of each lane's edge (either sense: the edge terms are even in it): its
    segment's direction ``edge``, or where that has no length the wedge's ``x0 x n0`` (zero on a
    lane of no wedge, whose edge terms are not deposited).

    A sub-aperture moves a segment's ends with the antenna, ``x + t x'`` (docs/physics.md (M8)):
    a short segment that a moving line (a mirrored window's, (M3), or a shadow's) cuts shrinks to
    a point at the pulse where that line reaches its other end (a recessed window's pane corner at
    the second bounce: 1.4 mm at ``A``, exactly zero in float32 at the pulse 6.4 m before it,
    tests/test_recess_edges.py). There ``edge`` is zero and ``normalize`` gave NaN, which the
    fringe (E4) and the double term (E6) carried into the deposit (NaN times the segment's zero
    line integral: UnrepresentableSum, (D7)). The wedge's own direction keeps the Keller cone's
    angles, and so the double lane's grazing leg, what they are on a segment of any length; the
    term, ``|a| sinc`` (or a split end's ``1 / (k u . a^)`` at its floor), is zero, the limit of
    the shrinking segment's."""
    length2 = dr.squared_norm(edge)
    some = length2 > 0.0
    frame = dr.cross(x0, n0)
    frame = frame * dr.rsqrt(dr.maximum(dr.squared_norm(frame), 1e-30))
    # dr.normalize's own arithmetic where the segment has a length (the same bits), and no
    # division by zero on either side of the select (whose other side would still carry NaN
    # into a replayed reverse pass)
    return dr.select(some, edge * dr.rsqrt(dr.select(some, length2, 1.0)), frame)


def _cot(x):
    sn, cs = dr.sincos(x)
    return cs / sn


def _fringe(phi, phi_i, nn, face_0, face_n):
    """The fringe coefficients ``(X_s, X_h)`` of eqs. (E2), (E3) in Dr.Jit: Keller's minus the PO
    edge terms of the faces lit and seen; ``face_0``, ``face_n`` the faces' ``(r_te, r_tm)``.
    NumPy reference: :func:`sarmitsuba.tracing.integration.edges.fringe`."""
    (r_te0, r_tm0), (r_ten, r_tmn) = face_0, face_n
    m, p = phi - phi_i, phi + phi_i
    c1, c2 = _cot((math.pi + m) / (2.0 * nn)), _cot((math.pi - m) / (2.0 * nn))
    c3, c4 = _cot((math.pi - p) / (2.0 * nn)), _cot((math.pi + p) / (2.0 * nn))
    inv = -1.0 / (2.0 * nn)
    x_s = (r_te0 * c3 + r_ten * c4 + (c1 + c2)) * inv
    x_h = ((c1 + c2) - r_tm0 * c3 - r_tmn * c4) * inv
    lit0 = (phi_i > 0.0) & (phi_i < math.pi) & (phi > 0.0) & (phi < math.pi)
    pn, pin = nn * math.pi - phi, nn * math.pi - phi_i
    lit_n = (pin > 0.0) & (pin < math.pi) & (pn > 0.0) & (pn < math.pi)
    for lit, a, a_i, r_te, r_tm in ((lit0, phi, phi_i, r_te0, r_tm0), (lit_n, pn, pin, r_ten, r_tmn)):
        den = dr.cos(a) + dr.cos(a_i)
        x_s = dr.select(lit, x_s + r_te * (dr.sin(a_i) / den), x_s)
        x_h = dr.select(lit, x_h - r_tm * (dr.sin(a) / den), x_h)
    return x_s, x_h


def boundary_clearance(phi, phi_i, nn):
    """The distance [rad] of ``(phi, phi_i)`` from the nearest shadow or reflection boundary, in
    Dr.Jit: NumPy reference :func:`sarmitsuba.tracing.integration.edges.boundary_clearance`."""
    out = None
    for x in (phi - phi_i, phi + phi_i, 2.0 * math.pi * nn - phi - phi_i):
        near = dr.minimum(dr.abs(x - math.pi), dr.abs(x + math.pi))
        out = near if out is None else dr.minimum(out, near)
    return out


def boundary_step(phi, phi_i, nn):
    """The step [rad] added to ``phi_i`` before the fringe coefficients are evaluated, eq. (E3):
    0 off every boundary, else up, or down where up lands within the window of another boundary
    (grazing incidence). NumPy reference :func:`sarmitsuba.tracing.integration.edges.boundary_step`."""
    up = boundary_clearance(phi, phi_i + SINGULAR_STEP, nn)
    down = boundary_clearance(phi, phi_i - SINGULAR_STEP, nn)
    step = dr.select((up >= SINGULAR_WINDOW) | (up >= down), SINGULAR_STEP, -SINGULAR_STEP)
    return dr.select(boundary_clearance(phi, phi_i, nn) < SINGULAR_WINDOW, step, 0.0)


def fringe_coefficients(phi, phi_i, nn, face_0, face_n):
    """The fringe coefficients ``(X_s, X_h)`` of eq. (E3) at ``(phi, phi_i)`` (float32, [rad]) of a
    convex wedge of exterior angle ``nn pi``, with ``phi_i`` stepped off the shadow and reflection
    boundaries (:func:`boundary_step`); ``face_0``, ``face_n`` the faces' ``(r_te, r_tm)``
    (mi.Complex2f). Finite wherever the inputs are (tests/test_edge_boundaries.py)."""
    return _fringe(phi, phi_i + boundary_step(phi, phi_i, nn), nn, face_0, face_n)


def _transition(x):
    """Kouyoumjian and Pathak's transition function, the approximation of
    :func:`sarmitsuba.tracing.integration.edges.transition` (its NumPy reference) in Dr.Jit."""
    z = dr.sqrt(x * (2.0 / math.pi))
    f = (1.0 + 0.926 * z) / (2.0 + z * (1.792 + 3.104 * z))
    g = 1.0 / (2.0 + z * (4.142 + z * (3.492 + 6.670 * z)))
    root = dr.sqrt(2.0 * math.pi * x)
    inv = 1.0 / dr.maximum(x, TRANSITION_SERIES)
    inv2 = inv * inv
    near = x < TRANSITION_SERIES
    return mi.Complex2f(dr.select(near, root * f, 1.0 - 0.75 * inv2 + (75.0 / 16.0) * inv2 * inv2),
                        dr.select(near, root * g, inv * (0.5 - (15.0 / 8.0) * inv2)))


def _keller_uniform(phi, phi_i, nn, kl):
    """The hard PEC wedge's uniform coefficient (``R_0 = R_N = +1``) in Dr.Jit: NumPy reference
    :func:`sarmitsuba.tracing.integration.edges.keller_uniform`."""
    def a(beta, sign):
        whole = dr.round((beta + sign * math.pi) / (2.0 * math.pi * nn))
        c = dr.cos((2.0 * math.pi * nn * whole - beta) * 0.5)
        return 2.0 * c * c

    m, p = phi - phi_i, phi + phi_i
    inv = -1.0 / (2.0 * nn)
    total = _transition(kl * a(m, 1.0)) * (_cot((math.pi + m) / (2.0 * nn)) * inv)
    total += _transition(kl * a(m, -1.0)) * (_cot((math.pi - m) / (2.0 * nn)) * inv)
    total += _transition(kl * a(p, -1.0)) * (_cot((math.pi - p) / (2.0 * nn)) * inv)
    total += _transition(kl * a(p, 1.0)) * (_cot((math.pi + p) / (2.0 * nn)) * inv)
    return total


class EdgeTerms:
    """Fringe (E4) and doubly diffracted (E6) terms of a bounce order's edge lanes.

    Parameters
    ----------
    returns : sarmitsuba.tracing.integration.returns.Returns
        The acquisition's per-pulse helpers (reflection tables, channels, track).
    k : float
        Carrier wavenumber [rad/m].
    """

    def __init__(self, returns, k: float):
        self.r, self.k = returns, k

    def mirrored(self, lanes, depth: int):
        """The scalar model's field arriving at an edge after ``depth`` mirrors (its reflection
        coefficients are in ``gamma``): the launch basis reflected by each window's plane (P3')
        with ``r_te = r_tm = 1``."""
        r = self.r
        jones = pol.launch(device_array(mi.Vector3f, lanes.first.T), mi.Vector3f(*r.track))
        one = mi.Complex2f(1.0, 0.0)
        for i in range(depth):
            jones = pol.reflect(jones, device_array(mi.Vector3f, lanes.window_direction[:, i].T),
                                device_array(mi.Vector3f, lanes.window_normal[:, i].T), one, one)
        dr.eval(jones)
        return jones


    def line(self, data, start, u, split):
        """The line integral of ``exp(-j k L)`` along a lane's segment relative to its point, eq. (E4):
        ``-+ j / (k u . a^)`` at a split segment's start and end (spectral order -1), and
        ``|a| sinc(alpha)`` at a midpoint with its first-order change across the band (orders 0
        and 1), as (M5) splits its edges."""
        k = self.k
        a_len = dr.norm(data["edge"])
        ua = dr.dot(u, data["edge"] / dr.maximum(a_len, 1e-30))
        sign = dr.select(start, 1.0, -1.0)
        split_value = mi.Complex2f(0.0, -sign / (k * end_slope(ua, a_len, k)))
        alpha = 0.5 * k * ua * a_len
        s1 = x_dsinc(alpha)
        value = dr.select(split, split_value, mi.Complex2f(a_len * (sinc(alpha) - s1), 0.0))
        return value, mi.Complex2f(a_len * s1, 0.0)

    def fringe(self, data, d, b, n0, cos_i, depth: int):
        """The fringe far field per unit length of each lane's edge, per channel, eq. (E4), with
        whether the lane carries it (not deferred to the wedge's other face): the Dr.Jit form of
        :func:`sarmitsuba.tracing.integration.edges.edge_field` (its NumPy reference)."""
        r = self.r
        x0, xn = data["wedge_x0"], data["wedge_xn"]
        t = edge_tangent(data["edge"], x0, n0)
        two_pi = 2.0 * math.pi

        def angle(v):
            perp = v - t * dr.dot(v, t)
            phi = dr.atan2(dr.dot(perp, n0), dr.dot(perp, x0))
            return dr.select(phi < 0.0, phi + two_pi, phi), dr.norm(perp)

        phi_i, sin_i = angle(-d)
        phi, sin_s = angle(b)
        psi = dr.atan2(dr.dot(xn, n0), dr.dot(xn, x0))
        wedge_n = dr.select(dr.squared_norm(xn) > 0.0, dr.select(psi >= 0.0, psi, psi + two_pi) / math.pi, 2.0)
        convex = wedge_n > 1.0 + 1e-3
        nn = dr.select(convex, wedge_n, 2.0)
        # the shadow and reflection boundaries of either face, where Keller's and PO's terms are
        # both infinite and their difference finite: evaluated a step off them (E3)
        normal_n = dr.sin(nn * math.pi) * x0 - dr.cos(nn * math.pi) * n0    # face N's normal, exterior side

        def reflection(row, cos):
            if r.polarimetric:
                return r.reflection_pair(row, cos, True)
            coefficient = r.reflection_at(row, cos, True)
            return coefficient, coefficient

        unlit_tm = self.unlit_tm(data, sin_i)

        def face_n(cos):
            # face N where the wave does not reach it (cos <= 0) has no incidence of its own: its TM
            # coefficient is the grazing one a wave across the face sees, 1 - 2 F(w), eq. (E2)
            pair = reflection(data["wedge_row"], cos)
            if unlit_tm is None:
                return pair
            hard = dr.select(cos > 0.0, pair[1], unlit_tm)
            return (pair[0], hard) if r.polarimetric else (hard, hard)

        # the traced path: the wave arrives along d, leaves along b
        x_s, x_h = fringe_coefficients(phi, phi_i, nn, reflection(data["row"], cos_i), face_n(-dr.dot(d, normal_n)))
        if depth > 0:
            # and its reverse, not traced (the edge first, the mirrors after it: it arrives along
            # -b and leaves along -d): the same length, the same Keller term, its own PO subtracted
            # (the fringe is not reciprocal where PO is not), eq. (E4)
            back_s, back_h = fringe_coefficients(phi_i, phi, nn, reflection(data["row"], dr.abs(dr.dot(b, n0))),
                                                 face_n(dr.dot(b, normal_n)))
            x_s, x_h = x_s + back_s, x_h + back_h
        # the receiver outside the wedge (face N at phi = N pi; a free edge is seen from every side)
        ok = convex & (sin_i > GRAZING_EDGE) & (sin_s > GRAZING_EDGE) & (phi < nn * math.pi)
        c_e = dr.select(ok, x_s * (1.0 / (two_pi * sin_i * sin_i)), mi.Complex2f(0.0))
        c_m = dr.select(ok, x_h * (-1.0 / (two_pi * sin_i * sin_s)), mi.Complex2f(0.0))
        along = t - b * dr.dot(b, t)
        # face N lit and seen too: the part of lower index carries the edge's term
        lit_n = (phi_i > (nn - 1.0) * math.pi) & (phi > (nn - 1.0) * math.pi)
        carry = ~(data["wedge_defer"] & lit_n)
        return self._channels(data, d, b, t, depth, c_m, (c_e, along)), carry, sin_i

    def _channels(self, data, d, b, t, depth: int, c_m, electric=None) -> list:
        """Per channel, the edge far field of (E4) for the Jones matrix arriving at the lane's edge
        (launched at the first bounce, through the mirrors after it, (P1), (P3')): the magnetic
        current's ``c_m (E . (t x d)) (b x t)``, plus with ``electric = (c_e, along)`` the electric
        current's ``c_e (E . t) along``; received along ``-b`` (P4), reciprocal after a mirror (P8)."""
        r = self.r
        across, normal_t = dr.cross(b, t), dr.cross(t, d)
        if depth == 0:
            jones = pol.launch(d, mi.Vector3f(*r.track))
        else:
            jones = data["jones"] if data["jones"] is not None else data["edge_jones"]

        def column(e_re, e_im):
            f_m = c_m * mi.Complex2f(dr.dot(e_re, normal_t), dr.dot(e_im, normal_t))
            re, im = across * dr.real(f_m), across * dr.imag(f_m)
            if electric is not None:
                c_e, along = electric
                f_e = c_e * mi.Complex2f(dr.dot(e_re, t), dr.dot(e_im, t))
                re, im = re + along * dr.real(f_e), im + along * dr.imag(f_e)
            return re, im

        h_re, h_im = column(jones.h_re, jones.h_im)
        v_re, v_im = column(jones.v_re, jones.v_im)
        field = pol.Jones(h_re=h_re, h_im=h_im, v_re=v_re, v_im=v_im)
        return r.reciprocal(pol.receive(field, -b, mi.Vector3f(*r.track), pol.CHANNELS), depth)

    def grazing_tables(self) -> tuple:
        """The grazing wave's tables (offset, real, imaginary part) for :func:`ground_wave.lookup`."""
        t = self.r.tables
        return t.grazing_offset, t.grazing_re, t.grazing_im

    def grazing_sinks(self) -> tuple:
        """The grazing tables' reverse-mode sinks (None each outside reverse mode), docs/physics.md (D7)."""
        return tuple(self.r.tables.adjoint.get(name) for name in ("grazing_offset", "grazing_re", "grazing_im"))

    def unlit_tm(self, data, sin_i):
        """The TM reflection coefficient at grazing of each lane's face N as a wave grazing it across
        the face sees it, ``1 - 2 F(w)`` (Norton's ``F`` over the distance across, or the lit edge's
        length where no edge lies across, along the Keller cone), eq. (E2): -1 on a conductor as on
        a PEC, toward +1 (the exact-grazing limit) on a dielectric face many wavelengths wide.
        ``None`` where no channel uses a TM coefficient (the scalar HH model) or without tables.
        NumPy reference: :func:`sarmitsuba.tracing.integration.ground_wave.unlit_tm`."""
        r = self.r
        if r.tables.grazing_offset is None or not (r.polarimetric or r.vv_sign):
            return None
        across = dr.norm(data["across"])
        extent = dr.select(across > 0.0, across, dr.norm(data["edge"]))
        weight = ground_wave.lookup(*self.grazing_tables(), data["wedge_row"],
                                    self.k * extent / dr.maximum(sin_i, GRAZING_EDGE), self.grazing_sinks())
        return 1.0 - 2.0 * weight

    def double(self, data, d, b, n0, sin_i, depth: int):
        """The doubly diffracted far field per unit length of each lane's edge (edge 2), per
        channel, eq. (E6): the wave the edge across the face (edge 1) diffracts along the face,
        grazing, diffracted again toward the receiver. Hard polarisation only (a soft wave
        vanishes on the face at grazing). NumPy reference: :func:`sarmitsuba.tracing.integration.edges.double_field`."""
        r, k = self.r, self.k
        x0, across = data["wedge_x0"], data["across"]
        t = edge_tangent(data["edge"], x0, n0)
        two_pi = 2.0 * math.pi

        def angle(v, x):
            perp = v - t * dr.dot(v, t)
            phi = dr.atan2(dr.dot(perp, n0), dr.dot(perp, x))
            return dr.select(phi < 0.0, phi + two_pi, phi), dr.norm(perp)

        def wedge(x, xn):
            psi = dr.atan2(dr.dot(xn, n0), dr.dot(xn, x))
            nn = dr.select(dr.squared_norm(xn) > 0.0, dr.select(psi >= 0.0, psi, psi + two_pi) / math.pi, 2.0)
            return nn

        phi, sin_s = angle(b, x0)
        phi_1, _ = angle(-d, -x0)                        # incidence at edge 1, from its face (-x0)
        n1, n2 = wedge(-x0, data["across_xn"]), wedge(x0, data["wedge_xn"])
        w = dr.norm(across)
        # edge 1 toward the grazing direction phi = 0 (hard, PEC), edge 2 from grazing incidence,
        # half of its coefficient (the grazing incident and reflected waves are one); both uniform
        # over the distance across, L = w sin(beta'), eq. (E6)
        kl = k * w * sin_i
        x_1 = _keller_uniform(0.0, phi_1, n1, kl)
        x_2 = _keller_uniform(phi, 0.0, n2, kl) * 0.5
        spread = dr.rsqrt(dr.maximum(two_pi * k * w * sin_i, 1e-30))
        c = math.sqrt(0.5)
        # a sheet (both edges free, N = 2) carries the grazing wave on both its faces: twice, eq. (E6)
        sheet = dr.select((dr.squared_norm(data["across_xn"]) == 0.0) & (dr.squared_norm(data["wedge_xn"]) == 0.0),
                          2.0, 1.0)
        g = mi.Complex2f(c, -c) * x_1 * (spread * sheet)               # exp(-j pi / 4) X_1 / sqrt(2 pi k w sin)
        # the grazing wave arrives whole on a perfect conductor and as Norton's ground wave F(w)
        # on a face of finite conductivity, over its path w / sin(beta'), eq. (E6): whatever the
        # channel (the wave grazing the face is TM to it)
        if r.tables.grazing_offset is not None:
            g = g * ground_wave.lookup(*self.grazing_tables(), data["row"], k * w / dr.maximum(sin_i, GRAZING_EDGE),
                                       self.grazing_sinks())
        ok = (n1 > 1.0 + 1e-3) & (n2 > 1.0 + 1e-3) & (sin_i > GRAZING_EDGE) & (sin_s > GRAZING_EDGE) & (phi < math.pi)
        # after mirrors, the untraced reverse path (edge 2, edge 1, the mirrors) is the transpose:
        # Keller's coefficients are reciprocal, so twice the reciprocal part, eq. (E6)
        reverse = 2.0 if depth > 0 else 1.0
        c_m = dr.select(ok, g * (-reverse * x_2 / (two_pi * sin_i * sin_s)), mi.Complex2f(0.0))
        return self._channels(data, d, b, t, depth, c_m)

