"""The fringe kernel's face N (docs/physics.md (E2)-(E4)): what the Dr.Jit edge terms
(:class:`sarmitsuba.tracing.integration.edge_terms.EdgeTerms`) take for the wedge's other face,
against the NumPy reference :func:`sarmitsuba.tracing.integration.edges.edge_field` fed with the
closed forms of (E2): a lit face N's Fresnel ``(r_TE, r_TM)`` at its own incidence (a dielectric
half space, written out here), and an unlit face N's ``r_TE = -1``, ``r_TM = 1 - 2 F(w)`` with
Norton's ``F`` (through the Faddeeva function) over the distance across the face along the
Keller cone, ``w = -j k (|across| / sin(beta')) Delta^2 / 2``, ``Delta = sqrt(eps - 1) / eps``.

The lone plates the rest of the suite renders never light face N (it is their back), and their
squares make the distance across equal to the lit edge's length. Here: the roof-wall edge of a
dielectric box at 30 deg incidence, both faces lit (N = 3/2), and the free rim of a plate 1 m
along its edge and 3 m across it. All four channels, polarimetric.

Deliberate bugs these were run against (each fails a test here): the lit face N's TM
coefficient read as its TE one (``pair[1]`` -> ``pair[0]`` in ``EdgeTerms.fringe``); the unlit
face's Norton distance taken as the lit edge's length (``extent = |edge|`` in ``unlit_tm``).
"""
from __future__ import annotations

import math
import types

import numpy as np
import pytest
from scipy.special import wofz

import sarmitsuba  # noqa: F401  (its libLLVM before drjit's)
import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

from sarmitsuba.tracing.integration import edges, ground_wave  # noqa: E402
from sarmitsuba.tracing.integration import jones as pol  # noqa: E402
from sarmitsuba.tracing.integration.edge_terms import EdgeTerms  # noqa: E402
from sarmitsuba.tracing.integration.returns import Returns  # noqa: E402

EPS = 5.0                       # a lossless dielectric (concrete's order): real Fresnel coefficients
K = 2.0 * math.pi / 0.3         # 1 GHz: |w| of a few over metres, where Norton's F changes fastest
DELTA = math.sqrt(EPS - 1.0) / EPS
TRACK = (0.0, 1.0, 0.0)


def fresnel(cos):
    """``(r_te, r_tm)`` of the half space ``EPS`` at ``cos`` (clipped to [0, 1]), the mirror-image
    convention of (R) (a perfect conductor -1, -1): NumPy or Dr.Jit alike."""
    clip = np.clip(cos, 0.0, 1.0) if isinstance(cos, (float, np.ndarray)) else dr.clip(cos, 0.0, 1.0)
    root = (EPS - 1.0 + clip * clip) ** 0.5
    return (clip - root) / (clip + root), (root - EPS * clip) / (root + EPS * clip)


def norton_unlit_tm(k_distance: float) -> complex:
    """``1 - 2 F(w)``: ``F(w) = 1 - j sqrt(pi w) exp(-w) erfc(j sqrt w)``, ``exp(-w) erfc(j sqrt w) =
    wofz(-sqrt w)`` (Norton, Proc. IRE 25(9), 1937), ``w = -j k d Delta^2 / 2``."""
    w = -1j * k_distance * DELTA ** 2 / 2.0
    root = np.sqrt(w)
    return 1.0 - 2.0 * (1.0 - 1j * np.sqrt(np.pi * w) * wofz(-root))


def _returns():
    """What :class:`EdgeTerms` reads of :class:`Returns`: the closed-form Fresnel pair for every
    row, the grazing tables of ``DELTA``, all four channels."""
    def pair(row, cos, active):
        r_te, r_tm = fresnel(cos)
        return mi.Complex2f(r_te, 0.0), mi.Complex2f(r_tm, 0.0)

    offset, table = ground_wave.grazing_table([DELTA])
    tables = types.SimpleNamespace(grazing_offset=mi.Float(offset), grazing_re=mi.Float(table.real.ravel()),
                                   grazing_im=mi.Float(table.imag.ravel()), adjoint={})
    r = types.SimpleNamespace(polarimetric=True, vv_sign=False, channels=pol.CHANNELS, track=list(TRACK),
                              tables=tables, reflection_pair=pair)
    r.reciprocal = lambda entries, depth: Returns.reciprocal(r, entries, depth)
    return r


def _kernel_channels(edge, x0, n0, xn, across, d) -> np.ndarray:
    """The kernel's fringe of one lane, monostatic (``b = -d``), depth 0: complex [4] in
    ``pol.CHANNELS`` order."""
    v = lambda a: mi.Vector3f(*[float(c) for c in a])      # noqa: E731
    data = {"edge": v(edge), "wedge_x0": v(x0), "wedge_xn": v(xn), "across": v(across), "row": mi.UInt32(0),
            "wedge_row": mi.UInt32(0), "wedge_defer": mi.Bool(False)}
    d_ = v(d)
    cos_i = -dr.dot(d_, v(n0))
    channels, carry, _ = EdgeTerms(_returns(), K).fringe(data, d_, -d_, v(n0), cos_i, 0)
    dr.eval(channels)
    return np.array([complex(dr.real(c).numpy()[0], dr.imag(c).numpy()[0]) for c in channels])


def _reference_channels(edge, x0, n0, xn, d, rn) -> np.ndarray:
    """``edges.edge_field`` for the H and V columns launched along ``d`` (P1), received on the H
    and V of the line of sight (P4), face 0 at its Fresnel pair and face N at ``rn``."""
    t = np.asarray(edge, float) / np.linalg.norm(edge)

    def hv(look):
        h = np.cross([0.0, 0.0, 1.0], look)
        h /= np.linalg.norm(h)
        return h, np.cross(look, h)

    one = lambda a: np.asarray(a, float)[None]             # noqa: E731
    h, v = hv(np.asarray(d, float))
    r0 = fresnel(float(-np.dot(d, n0)))
    out = {}
    for tx, e in (("H", h), ("V", v)):
        f = edges.edge_field(one(t), one(x0), one(n0), one(xn), one(d), one(-np.asarray(d, float)),
                             e.astype(complex)[None], r0=r0, rn=rn)[0]
        for rx, b in (("H", h), ("V", v)):
            out[rx + tx] = b @ f
    return np.array([out[c] for c in pol.CHANNELS])


def test_a_lit_face_n_takes_its_own_tm_coefficient():
    """The roof-wall edge of a dielectric box (along y; the roof at x < 0 is face 0, the wall
    below the edge faces +x), seen at 30 deg incidence from +x: both faces lit, N = 3/2, the wall
    at cos 0.5 where Fresnel's ``r_TM`` (-0.10) is far from ``r_TE`` (-0.61). All four channels
    within 1e-3 of the reference's largest (float32). Catches face N's TM read as its TE: VV
    off by 12 % of the largest channel (the audit's 6 m box: -26 dB NRMSE, +0.19 dB)."""
    theta = math.radians(30.0)
    d = np.array([-math.sin(theta), 0.0, -math.cos(theta)])
    edge, x0, n0, xn = (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, -1.0)
    got = _kernel_channels(edge, x0, n0, xn, (0.0, 0.0, 0.0), d)
    expected = _reference_channels(edge, x0, n0, xn, d, fresnel(math.sin(theta)))
    assert np.abs(expected[3]) > 0.1 * np.abs(expected).max()                      # VV is there
    assert np.abs(got - expected).max() < 1e-3 * np.abs(expected).max(), (got, expected)


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_an_unlit_face_n_takes_nortons_coefficient_over_the_distance_across(incidence):
    """The free rim of a dielectric plate 1 m along its edge and 3 m across (the rim at x = 0,
    the plate at x < 0; face N its unlit back), seen broadside to the rim (``sin(beta') = 1``)
    from +x: face N's ``r_TM = 1 - 2 F(w)`` over ``k 3 m`` (``|w|`` 5.0; over the edge's 1 m, 1.7:
    ``r_TM`` 0.95 + 0.18j against 0.78 + 0.38j), ``r_TE = -1``. All four channels within 1e-3 of
    the reference's largest plus what the grazing table's own error (2e-3 in ``F``) moves them
    (5e-4 to 8e-4). Catches the Norton distance taken as the edge's length (1 m): VV off by 3 %
    to 5 % of the largest channel."""
    theta = math.radians(incidence)
    d = np.array([-math.sin(theta), 0.0, -math.cos(theta)])
    edge, x0, n0, xn, across = (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (-3.0, 0.0, 0.0)
    got = _kernel_channels(edge, x0, n0, xn, across, d)
    expected = _reference_channels(edge, x0, n0, xn, d, (-1.0, norton_unlit_tm(K * 3.0)))
    table = _reference_channels(edge, x0, n0, xn, d, (-1.0, norton_unlit_tm(K * 3.0) + 4e-3)) - expected
    assert np.abs(got - expected).max() < 1e-3 * np.abs(expected).max() + np.abs(table).max(), (got, expected)
