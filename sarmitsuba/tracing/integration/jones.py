"""The ray tube's Jones matrix in Dr.Jit: the kernel side of docs/physics.md, section
"Polarimetry".

=======================  ===================================================================
:func:`launch`           the matrix a tube leaves the antenna with, ``[h v]`` (P1)
:func:`reflect`          one specular reflection of both columns (P3') (:func:`reflect_jones`)
:func:`scatter`          the field a facet sends back toward the antenna: the last bounce's
                         PO field (P4')
:func:`scatter_rough`    a rough surface's scatterer in reciprocal bases (P7), (C2)
:func:`receive`          ``S[rx, tx]`` in the BSA basis of the receiving line of sight (P4)
=======================  ===================================================================

The kernel (:mod:`sarmitsuba.tracing.driver.kernel`, :mod:`sarmitsuba.tracing.integration.returns`) compiles these for every
``polarization`` unless the ``sbr`` parameter ``polarimetry = scalar`` asks for the scalar model;
vectorised over lanes in float32 (``llvm_ad_mono``, set by ``import sarmitsuba``). Their NumPy
reference is :mod:`sarmitsuba.tracing.integration.polarimetry`; tests/test_jones.py checks one against the other.
"""
from __future__ import annotations

from dataclasses import dataclass

import drjit as dr
import mitsuba as mi

from ...core.radar import CHANNELS

__all__ = ["NORMAL_TOLERANCE", "CHANNELS", "Jones", "NoJones", "bsa_vectors", "launch", "reflect", "receive", "power",
           "scatter", "scatter_rough", "reflect_jones"]

#: Below this ``|n x d|`` (sine of the incidence angle) the incidence counts as normal and
#: ``s = unit(a x d)``, ``a`` the coordinate axis least aligned with ``d`` (P2). In float32,
#: ``n x d`` carries an absolute rounding error of ~6e-8, so below 1e-6 its direction is mostly
#: rounding anyway; the reflection does not depend on ``s`` there, since ``r_te = r_tm`` at
#: normal incidence (P2) and the ``s``-dependent term of (P3') carries ``r_te - r_tm``.
NORMAL_TOLERANCE = 1e-6


def _te_vector(d: mi.Array3f, n: mi.Array3f) -> mi.Array3f:
    """The TE unit vector ``s`` of (P2): ``unit(n x d)``, made normal to ``d`` by one
    Gram-Schmidt step; ``unit(a x d)`` at normal incidence (``|n x d| < NORMAL_TOLERANCE``)."""
    u = dr.cross(n, d)
    ad = dr.abs(d)
    x_least = (ad.x <= ad.y) & (ad.x <= ad.z)
    y_least = ~x_least & (ad.y <= ad.z)
    a = mi.Array3f(dr.select(x_least, 1.0, 0.0), dr.select(y_least, 1.0, 0.0),
                   dr.select(x_least | y_least, 0.0, 1.0))
    normal = dr.squared_norm(u) < NORMAL_TOLERANCE * NORMAL_TOLERANCE
    u = dr.select(normal, dr.cross(a, d), u)
    u = u - dr.dot(u, d) * d
    return dr.normalize(u)


def reflect_jones(e_re: mi.Array3f, e_im: mi.Array3f, d: mi.Array3f, n: mi.Array3f,
                  r_te: mi.Complex2f, r_tm: mi.Complex2f) -> tuple[mi.Array3f, mi.Array3f, mi.Array3f]:
    """Reflect the complex field ``E = e_re + i e_im`` at a facet by (P3') of docs/physics.md:

        E' = (r_tm M + (r_te - r_tm) s s^T) E,        d' = M d,        M x = x - 2 (n . x) n

    Parameters
    ----------
    e_re, e_im : mi.Array3f
        Real and imaginary parts of the field vector (one column of a Jones matrix), normal to
        ``d``. (P3') equals (P3) only for such fields: a component along ``d`` is mirrored here,
        where the NumPy reference drops it.
    d, n : mi.Array3f
        Unit incident direction and unit facet normal (either orientation; not re-normalised).
    r_te, r_tm : mi.Complex2f
        The facet's reflection coefficients at the local ``cos = |d . n|``, in the mirror-image
        convention of :mod:`sarmitsuba.scene.fresnel` (PEC: ``-1, -1``, giving ``E' = -E + 2 (n.E) n``).

    Returns
    -------
    e_re, e_im, d_reflected : mi.Array3f
        The reflected field's real and imaginary parts and the mirror ray ``d - 2 (d . n) n``.

    Normal incidence is handled as in :func:`sarmitsuba.tracing.integration.polarimetry.facet_basis`: ``s`` falls
    back to ``unit(a x d)``, and the result is continuous there because ``r_te = r_tm``.
    """
    s = _te_vector(d, n)

    def mirror(v):
        return v - 2.0 * dr.dot(v, n) * n

    m_re, m_im = mirror(e_re), mirror(e_im)
    s_re, s_im = dr.dot(s, e_re), dr.dot(s, e_im)                # s . E
    t_re, t_im = dr.real(r_tm), dr.imag(r_tm)
    c_re, c_im = dr.real(r_te) - t_re, dr.imag(r_te) - t_im      # r_te - r_tm
    out_re = t_re * m_re - t_im * m_im + (c_re * s_re - c_im * s_im) * s
    out_im = t_re * m_im + t_im * m_re + (c_re * s_im + c_im * s_re) * s
    return out_re, out_im, mirror(d)


# ============================================================================ the tube's Jones matrix
@dataclass
class Jones:
    """The Jones matrix a ray tube carries (docs/physics.md (P1), (P3')): the complex field vectors
    for unit transmission on H (``h_*``) and on V (``v_*``), real and imaginary parts, float32,
    normal to the tube's direction. A tube of the scalar model carries :class:`NoJones` instead."""

    h_re: mi.Vector3f
    h_im: mi.Vector3f
    v_re: mi.Vector3f
    v_im: mi.Vector3f


@dataclass
class NoJones:
    """The scalar model's placeholder: no field, nothing compiled (docs/design.md section 7)."""


def bsa_vectors(look: mi.Vector3f, fallback: mi.Vector3f) -> tuple[mi.Vector3f, mi.Vector3f]:
    """The H and V unit vectors of a line of sight ``look`` (unit, antenna -> scene), (P1):
    ``h = unit(z x look)``, ``v = look x h`` (up-ish). ``fallback`` (a unit horizontal vector,
    the track direction) replaces ``z x look`` within 1e-6 of the vertical, where H is undefined
    (a SAR never looks there; the check keeps the kernel finite)."""
    zx = mi.Vector3f(-look.y, look.x, 0.0)                 # z x look
    h = dr.select(dr.squared_norm(zx) < 1e-12, fallback, zx)
    h = dr.normalize(h - dr.dot(h, look) * look)
    return h, dr.cross(look, h)


def launch(direction: mi.Vector3f, fallback: mi.Vector3f) -> Jones:
    """The Jones matrix a tube leaves the antenna with along ``direction``: ``[h v]`` (P1)."""
    h, v = bsa_vectors(direction, fallback)
    zero = mi.Vector3f(0.0)
    return Jones(h_re=h, h_im=zero, v_re=v, v_im=zero)


def reflect(jones: Jones, d: mi.Vector3f, n: mi.Vector3f, r_te: mi.Complex2f, r_tm: mi.Complex2f) -> Jones:
    """Both columns of ``jones`` reflected at a facet by (P3') (:func:`reflect_jones`)."""
    h_re, h_im, _ = reflect_jones(jones.h_re, jones.h_im, d, n, r_te, r_tm)
    v_re, v_im, _ = reflect_jones(jones.v_re, jones.v_im, d, n, r_te, r_tm)
    return Jones(h_re=h_re, h_im=h_im, v_re=v_re, v_im=v_im)


def receive(jones: Jones, look: mi.Vector3f, fallback: mi.Vector3f, channels: tuple[str, ...]) -> list:
    """``S[rx, tx] = b_rx . J[:, tx]`` (P4) for each of ``channels`` (names of :data:`CHANNELS`),
    with the H, V vectors of the receiving line of sight ``look`` (antenna -> the last hit).
    Returns one mi.Complex2f per channel; only the products a channel needs are compiled."""
    h, v = bsa_vectors(look, fallback)
    columns = {"H": (jones.h_re, jones.h_im), "V": (jones.v_re, jones.v_im)}
    out = []
    for name in channels:
        b = h if name[0] == "H" else v
        re, im = columns[name[1]]
        out.append(mi.Complex2f(dr.dot(b, re), dr.dot(b, im)))
    return out


def power(jones: Jones) -> mi.Float:
    """``|J|_F^2 / 2``: the power carried, averaged over the two transmit channels (1 at launch)."""
    return 0.5 * (dr.squared_norm(jones.h_re) + dr.squared_norm(jones.h_im)
                  + dr.squared_norm(jones.v_re) + dr.squared_norm(jones.v_im))


def scatter(jones: Jones, d: mi.Vector3f, b: mi.Vector3f, n: mi.Vector3f,
            a_te: mi.Complex2f, a_tm: mi.Complex2f, a_x: mi.Complex2f | None = None) -> Jones:
    """The field a facet sends toward the antenna (along ``b``) for the incoming columns of
    ``jones`` (along ``d``), docs/physics.md (P4'), (P7):

        E' = (a_te (s.E) + a_x (p.E)) s_b + (a_x (s.E) + a_tm (p.E)) p_b

    with ``s = unit(n x d)``, ``p = d x s`` (P2), ``s_b = unit(s - (s.b) b)`` and
    ``p_b = (-b) x s_b``. For the specular direction (``b = d'``) ``s_b = s``, ``p_b = p'`` and,
    with ``a_te, a_tm = r_te, r_tm`` and no ``a_x``, this is the reflection (P3); for
    backscatter (``b = -d``) ``p_b = p``: the Kirchhoff backscatter ``r_te`` on TE and ``r_tm`` on
    TM (PEC: ``E' = -E``, as physical optics gives). ``a_x`` (None: not compiled) couples TE and
    TM symmetrically: a rough surface's cross-polarised scatterer (P7). Where ``s`` is within
    1e-6 of ``b`` (the return leaves along the facet's TE direction), ``s_b = unit(n x (-b))``."""
    s_i = _te_vector(d, n)
    p_i = dr.cross(d, s_i)
    back = -b
    s_b = s_i - dr.dot(s_i, back) * back
    s_b = dr.normalize(dr.select(dr.squared_norm(s_b) < 1e-12, _te_vector(back, n), s_b))
    return _send(jones, (s_i, p_i), (s_b, dr.cross(back, s_b)), a_te, a_tm, a_x)


def scatter_rough(jones: Jones, d: mi.Vector3f, b: mi.Vector3f, n: mi.Vector3f,
                  a_te: mi.Complex2f, a_tm: mi.Complex2f, a_x: mi.Complex2f | None = None) -> Jones:
    """The field a rough surface's scatterer sends along ``b`` (unit, float32) for the incoming
    columns of ``jones`` (along ``d``), docs/physics.md (P7), (C2): the form of :func:`scatter`
    with the outgoing basis that of a wave arriving along ``-b``, ``s_b = unit(n x (-b))``,
    ``p_b = (-b) x s_b``, as the incoming one is ``s = unit(n x d)``, ``p = d x s`` (P2). The
    scatterer's dyadic ``a_te s_b s^T + a_tm p_b p^T + a_x (s_b p^T + p_b s^T)`` is therefore
    transposed by swapping ``d -> -b``, ``b -> -d`` (the reverse ordering of its path; reciprocal
    by construction where the amplitudes are symmetric in the two directions, as (C2)'s are), and
    equals :func:`scatter`'s for backscatter ``b = -d``. Returns the scattered :class:`Jones`."""
    s_i = _te_vector(d, n)
    s_b = _te_vector(-b, n)
    return _send(jones, (s_i, dr.cross(d, s_i)), (s_b, dr.cross(-b, s_b)), a_te, a_tm, a_x)


def _send(jones: Jones, incoming: tuple, outgoing: tuple, a_te, a_tm, a_x) -> Jones:
    """``E' = (a_te (s.E) + a_x (p.E)) s_b + (a_x (s.E) + a_tm (p.E)) p_b`` for both columns of
    ``jones``, ``incoming = (s, p)``, ``outgoing = (s_b, p_b)`` (P4'), (P7)."""
    (s_i, p_i), (s_b, p_b) = incoming, outgoing

    def column(e_re, e_im):
        e_s = mi.Complex2f(dr.dot(s_i, e_re), dr.dot(s_i, e_im))
        e_p = mi.Complex2f(dr.dot(p_i, e_re), dr.dot(p_i, e_im))
        along_s, along_p = a_te * e_s, a_tm * e_p
        if a_x is not None:
            along_s, along_p = along_s + a_x * e_p, along_p + a_x * e_s
        return (s_b * dr.real(along_s) + p_b * dr.real(along_p), s_b * dr.imag(along_s) + p_b * dr.imag(along_p))

    h_re, h_im = column(jones.h_re, jones.h_im)
    v_re, v_im = column(jones.v_re, jones.v_im)
    return Jones(h_re=h_re, h_im=h_im, v_re=v_re, v_im=v_im)
