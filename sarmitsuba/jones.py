"""One specular reflection of a complex field vector in Dr.Jit: the kernel side of (P3').

docs/physics.md, section "Polarimetry", (P2), (P3'). Groundwork for the quad-pol tracer (not
wired into :mod:`sarmitsuba.kernel` yet); vectorised over lanes in float32 (``llvm_ad_mono``,
set by ``import sarmitsuba``). Its NumPy reference is
:func:`sarmitsuba.polarimetry.reflect_jones`, applied per column of a Jones matrix;
tests/test_jones.py checks one against the other.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi

__all__ = ["NORMAL_TOLERANCE", "reflect_jones"]

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
        convention of :mod:`sarmitsuba.fresnel` (PEC: ``-1, -1``, giving ``E' = -E + 2 (n.E) n``).

    Returns
    -------
    e_re, e_im, d_reflected : mi.Array3f
        The reflected field's real and imaginary parts and the mirror ray ``d - 2 (d . n) n``.

    Normal incidence is handled as in :func:`sarmitsuba.polarimetry.facet_basis`: ``s`` falls
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
