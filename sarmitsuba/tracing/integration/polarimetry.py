"""Polarimetric ray optics: the NumPy reference of the Jones matrix a ray tube carries.

docs/physics.md, section "Polarimetry", equations (P1)-(P6). Plain NumPy (float64 and
complex128) on the host: readable, not fast. The Dr.Jit tracer's quad-pol kernel is tested
against it.

=========================  ===============================================================
:func:`bsa_basis`          the antenna's H and V unit vectors for a line of sight (P1)
:func:`antenna_jones`      the Jones matrix a ray leaves the antenna with, ``[H V]`` (P1)
:func:`facet_basis`        a facet's s (TE) and p, p' (TM) vectors and the mirror ray (P2)
:func:`reflect_jones`      one specular reflection of a Jones matrix (P3)
:func:`project_bsa`        the 2x2 matrix received at the antenna (P4)
:func:`scattering_matrix`  S of a retro-reflecting mirror chain (P5)
=========================  ===============================================================

Conventions
-----------
* Frame: right-handed, z up (docs/design.md section 4); directions are unit float64 vectors in
  the last axis (``[..., 3]``); leading axes broadcast.
* A **Jones matrix** ``J`` is complex128 ``[..., 3, 2]``: column 0 is the complex field vector
  carried for H transmission, column 1 for V transmission, both transverse to the ray,
  for unit transmitted amplitude. Propagation phase, spreading, antenna pattern and the PO
  factor of (PO1) are scalars common to all four channels and are not part of it.
* Reflection coefficients are those of :mod:`sarmitsuba.scene.fresnel` /
  :mod:`sarmitsuba.scene.materials`, in their **mirror-image convention**: ``r_tm`` is minus
  Born & Wolf's ``r_par`` and P.2040's ``R_TM``, and a perfect conductor has
  ``r_te = r_tm = -1``. Here that means: the TM component is carried to the *mirror image*
  ``p' = M p`` of the incident TM vector (P2), so that a PEC mirror sends ``E`` to
  ``-M E = -E + 2 (n . E) n``, the image-theory field.
* ``S[..., rx, tx]`` with index 0 = H and 1 = V, in the backscatter alignment (the same H, V
  vectors for transmission and reception). A PEC plate at normal incidence gives ``-I``, a PEC
  trihedral ``+I``, a PEC dihedral with its fold along H ``diag(+1, -1)`` (P5).
"""
from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

__all__ = ["PEC", "antenna_jones", "bsa_basis", "facet_basis", "project_bsa", "reflect_jones",
           "scattering_matrix"]

#: ``(r_te, r_tm)`` of a perfect conductor in the mirror-image convention.
PEC = (-1.0 + 0.0j, -1.0 + 0.0j)

#: Below this ``|z x look|`` (sine of the look's angle from the vertical) H is undefined.
NADIR_TOLERANCE = 1e-9
#: Below this ``|n x d|`` (sine of the incidence angle) the incidence counts as normal and s is
#: ``unit(a x d)`` (P2): any s normal to d changes the reflection by at most ``2 |r| 1e-12``.
NORMAL_TOLERANCE = 1e-12

_UP = np.array([0.0, 0.0, 1.0])


def _unit(name: str, v) -> np.ndarray:
    """``v`` (float64 ``[..., 3]``) divided by its length; ValueError if not finite or zero."""
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape [..., 3], got {a.shape}")
    norm = np.linalg.norm(a, axis=-1, keepdims=True)
    if not np.all(np.isfinite(a)) or np.any(norm == 0.0):
        raise ValueError(f"{name} must be finite, non-zero 3-vectors")
    return a / norm


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.sum(a * b, axis=-1)


def bsa_basis(look) -> tuple[np.ndarray, np.ndarray]:
    """The backscatter-alignment H and V unit vectors of a line of sight (P1).

    Parameters
    ----------
    look : array_like of float, shape ``[..., 3]``
        Line of sight from the antenna to the scene (normalised here).

    Returns
    -------
    h, v : ndarray of float64, shape ``[..., 3]``
        ``h = (z x look) / |z x look|``: horizontal, normal to the line of sight (for a
        right-looking radar flying along +x and looking toward -y, ``h = +x``).
        ``v = look x h``: normal to both, **up-ish** (``v . z = sin(theta_inc) > 0`` for a
        look below the horizon at incidence ``theta_inc`` from the vertical), and
        ``(h, v, look)`` is right-handed: ``h x v = look``.

    Raises
    ------
    ValueError
        ``look`` not finite or zero, or within ``NADIR_TOLERANCE`` (sine) of the vertical
        (nadir or zenith), where no direction is horizontal and normal to the line of sight
        in particular and H is undefined.
    """
    k = _unit("look", look)
    z_cross_k = np.cross(_UP, k)
    norm = np.linalg.norm(z_cross_k, axis=-1, keepdims=True)
    if np.any(norm < NADIR_TOLERANCE):
        raise ValueError("look is vertical (nadir or zenith): the BSA basis's H, horizontal and "
                         "normal to the line of sight, is undefined there")
    h = z_cross_k / norm
    return h, np.cross(k, h)


def antenna_jones(look) -> np.ndarray:
    """The Jones matrix a ray leaves the antenna with: columns ``h`` and ``v`` (P1).

    ``look`` float ``[..., 3]``; returns complex128 ``[..., 3, 2]``.
    """
    h, v = bsa_basis(look)
    return np.stack([h, v], axis=-1).astype(np.complex128)


def _least_aligned_axis(v: np.ndarray) -> np.ndarray:
    """The coordinate axis (float64 ``[..., 3]``) with the smallest ``|v_i|`` (first on ties)."""
    return np.eye(3)[np.argmin(np.abs(v), axis=-1)]


def facet_basis(d, n) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A facet's TE and TM unit vectors for incident direction ``d`` and normal ``n`` (P2).

    Parameters
    ----------
    d : array_like of float, shape ``[..., 3]``
        Propagation direction of the incident ray (normalised here).
    n : array_like of float, shape ``[..., 3]``
        Facet normal (normalised here), either orientation: everything below is unchanged
        when ``n`` is negated, apart from the sign of ``s`` and ``p``.

    Returns
    -------
    s, p, p_reflected, d_reflected : ndarray of float64, shape ``broadcast(d, n)``
        ``s = unit(n x d)`` (made normal to ``d`` to rounding by one Gram-Schmidt step, which
        keeps ``s . n`` at rounding level near normal incidence, where ``n x d`` loses its
        relative accuracy), normal to the plane of incidence (TE); ``p = d x s``, so that
        ``(s, p, d)`` is right-handed (TM, incident); ``d' = M d`` and ``p' = M p``, with
        ``M x = x - 2 (n . x) n`` the mirror in the facet plane: ``p'`` is the TM vector of
        the reflected ray, ``p' = s x d'`` (so ``(s, p', d')`` is left-handed, and Born &
        Wolf's right-handed reflected TM vector is ``-p'``: hence ``r_tm = -r_par``).

    Notes
    -----
    Normal incidence (``|n x d| < NORMAL_TOLERANCE``): the plane of incidence is undefined
    and ``s = unit(a x d)`` with ``a`` the coordinate axis least aligned with ``d``. No choice
    of ``s`` is continuous around ``d = -n`` (``unit(n x d)`` takes every direction of the
    facet plane on a small cone about ``n``), but the reflection (P3) is, whatever ``s`` is:
    it equals ``r_tm M + (r_te - r_tm) s s^T`` on fields normal to ``d``, and ``r_te = r_tm``
    at normal incidence for every model of :mod:`sarmitsuba.scene.materials` (P2). Below the
    tolerance, where ``s`` is not quite normal to ``n``, the reflection is off by at most
    ``2 |r| |n x d| < 2e-12 |r|``.
    """
    d = _unit("d", d)
    n = _unit("n", n)
    d, n = np.broadcast_arrays(d, n)
    n_cross_d = np.cross(n, d)
    normal = np.linalg.norm(n_cross_d, axis=-1, keepdims=True) < NORMAL_TOLERANCE
    s = np.where(normal, np.cross(_least_aligned_axis(d), d), n_cross_d)
    s = s - _dot(s, d)[..., None] * d              # normal to d to rounding, even near d = -n
    s = s / np.linalg.norm(s, axis=-1, keepdims=True)
    p = np.cross(d, s)
    d_reflected = d - 2.0 * _dot(d, n)[..., None] * n
    p_reflected = p - 2.0 * _dot(p, n)[..., None] * n
    return s, p, p_reflected, d_reflected


def reflect_jones(J, d, n, r_te, r_tm) -> tuple[np.ndarray, np.ndarray]:
    """One specular reflection of a Jones matrix (P3).

    Parameters
    ----------
    J : array_like of complex, shape ``[..., 3, 2]``
        Field vectors carried for H (column 0) and V (column 1) transmission, normal to ``d``
        (a component along ``d`` is dropped).
    d, n : array_like of float, shape ``[..., 3]``
        Incident direction and facet normal, as in :func:`facet_basis`.
    r_te, r_tm : complex or array_like of complex, broadcast to ``[...]``
        The facet's reflection coefficients at the local incidence ``cos = |d . n|``, in the
        mirror-image convention of :mod:`sarmitsuba.scene.fresnel` (PEC: ``-1, -1``).

    Returns
    -------
    J_reflected : ndarray of complex128, shape ``[..., 3, 2]``
        ``r_te (s . E) s + r_tm (p . E) p'`` for each column ``E``; for a PEC ``-M E``
        ``= -E + 2 (n . E) n``, the image-theory field.
    d_reflected : ndarray of float64, shape ``[..., 3]``
        The mirror ray ``d - 2 (d . n) n``.
    """
    J = np.asarray(J, dtype=np.complex128)
    if J.ndim < 2 or J.shape[-2:] != (3, 2):
        raise ValueError(f"J must have shape [..., 3, 2], got {J.shape}")
    s, p, p_reflected, d_reflected = facet_basis(d, n)
    r_te = np.asarray(r_te, dtype=np.complex128)[..., None, None]
    r_tm = np.asarray(r_tm, dtype=np.complex128)[..., None, None]
    along_s = np.einsum("...i,...ij->...j", s, J)[..., None, :]      # [..., 1, 2]
    along_p = np.einsum("...i,...ij->...j", p, J)[..., None, :]
    J_reflected = r_te * s[..., :, None] * along_s + r_tm * p_reflected[..., :, None] * along_p
    return J_reflected, d_reflected


def project_bsa(J, look) -> np.ndarray:
    """The 2x2 matrix the antenna receives from a returning Jones matrix (P4).

    ``S[..., rx, tx] = b_rx . J[..., :, tx]`` with ``b_0 = h``, ``b_1 = v`` of
    :func:`bsa_basis` (``look`` ``[..., 3]``), the same vectors as on transmission; a plain
    (unconjugated) dot. ``J`` complex ``[..., 3, 2]``; returns complex128 ``[..., 2, 2]``.
    The component of ``J`` along the line of sight, zero for a ray returning along
    ``-look``, is not received.
    """
    h, v = bsa_basis(look)
    basis = np.stack([h, v], axis=-1)                                   # [..., 3, 2]
    return np.einsum("...ir,...it->...rt", basis, np.asarray(J, dtype=np.complex128))


Coefficients = Callable[[np.ndarray], tuple] | tuple


def _coefficients(item: Coefficients, cos_theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(r_te, r_tm)`` of one facet of a chain at ``cos_theta``."""
    if callable(item):
        r_te, r_tm = item(cos_theta)
    else:
        r_te, r_tm = item
    return np.asarray(r_te, dtype=np.complex128), np.asarray(r_tm, dtype=np.complex128)


def scattering_matrix(path_normals, look, r_te_tm: Sequence[Coefficients], *,
                      tol: float = 1e-6) -> np.ndarray:
    """The 2x2 BSA scattering matrix of a specular chain of facets (P5).

    Parameters
    ----------
    path_normals : array_like of float, shape ``[..., k, 3]``
        The normals of the ``k >= 1`` facets the ray meets, in order (either orientation).
    look : array_like of float, shape ``[..., 3]``
        Line of sight, antenna to scene: the ray enters along ``look`` and, after the ``k``
        mirror reflections, must leave along ``-look``.
    r_te_tm : sequence of ``k`` items
        Per facet, either a pair ``(r_te, r_tm)`` (complex, broadcast to ``[...]``;
        :data:`PEC` for a perfect conductor) or a callable ``cos_theta -> (r_te, r_tm)``
        evaluated at the local ``cos_theta = |d . n|`` (float64 ``[...]``), for instance
        ``functools.partial(fresnel_half_space, eta=5 - 0.5j)``. Mirror-image convention.
    tol : float
        Largest accepted ``|d_out + look|``.

    Returns
    -------
    S : ndarray of complex128, shape ``[..., 2, 2]``
        ``S[..., rx, tx]``, 0 = H, 1 = V: (P4) of the Jones matrix after (P3) at every facet,
        starting from :func:`antenna_jones`. A unit-amplitude ray-optics transfer, with the
        absolute sign of image theory: PEC plate at normal incidence ``-I``, PEC trihedral
        ``+I``, PEC dihedral with fold along H ``diag(+1, -1)``; ``S_HH`` is the scalar
        model's product of ``r_te`` whenever every normal lies in the vertical plane of the
        look (P6). A chain and its reverse give transposed matrices (P5).

    Raises
    ------
    ValueError
        Bad shapes, a vertical look (:func:`bsa_basis`), ``len(r_te_tm) != k``, or a chain
        that does not return along ``-look``.
    """
    normals = np.asarray(path_normals, dtype=np.float64)
    if normals.ndim < 2 or normals.shape[-1] != 3 or normals.shape[-2] < 1:
        raise ValueError(f"path_normals must have shape [..., k, 3] with k >= 1, got {normals.shape}")
    k = normals.shape[-2]
    if len(r_te_tm) != k:
        raise ValueError(f"r_te_tm has {len(r_te_tm)} entries for a chain of {k} facets")
    d = _unit("look", look)
    J = antenna_jones(d)
    for i in range(k):
        n = _unit("path_normals", normals[..., i, :])
        r_te, r_tm = _coefficients(r_te_tm[i], np.clip(np.abs(_dot(d, n)), 0.0, 1.0))
        J, d = reflect_jones(J, d, n, r_te, r_tm)
    miss = np.linalg.norm(d + _unit("look", look), axis=-1)
    if np.any(miss > tol):
        raise ValueError(f"the chain does not return along -look (|d_out + look| up to "
                         f"{float(np.max(miss)):.3g} > tol = {tol:g})")
    return project_bsa(J, look)
