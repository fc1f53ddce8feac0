"""The patches' Dr.Jit kernel (:class:`sarmitsuba.tracing.integration.patch_terms.PatchTerms`) against its
readable NumPy reference (:func:`sarmitsuba.tracing.integration.patch_reference.lane_terms`), term lane by
term lane, pulse by pulse (docs/physics.md (M5)).

Scene: the PEC ground mirror and the tilted plate of tests/test_kernel_reference.py (paths of one
and two bounces, the plate's not retro-reflecting), a uniform beam, the ``exact`` range kernel
(every term kept with its length and value) and stop-and-hop, so that the reference's plain
float64 formulas apply unchanged. The lanes the host built are captured as the kernel receives
them; the reference evaluates each for every pulse of its sub-aperture from that pulse's own
antenna, with the PO density of physics.md (PO1) written out here: ``j (2 sqrt(pi) / lambda)
(cos_i + cos_b) / 2`` times the PEC chain's sign. Both are compared as spectra across the band
(positions and spectral orders included), per pulse.

Deliberate bugs this test fails: the split term's sign at a segment's end not flipped; the
sinc's band correction (order 1) dropped; the near-specular gate letting a piece's edges through
where its area term stands (the piece counted twice); the area term's quadratic phase dropped;
the unfolded length off by a millimetre. Edge terms (E4), (E6): the split end's sign of the
line integral flipped; the grazing leg of the double diffraction left out of its path; the
fringe gated off with the PO edges of pieces near the specular direction.
"""
from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np
import pytest

from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.planning import AcquisitionWarning
from sarmitsuba.tracing.integration import edges
from sarmitsuba.tracing.integration import patch_terms as integration
from sarmitsuba.tracing.integration.patch_reference import lane_terms
from test_kernel_reference import GROUND_HALF, PLATE_CENTRE, PLATE_SIZE, SCENE, TILT, _spectrum

SCENE_PATCHES = (SCENE.replace('<string name="lit_regions" value="tiles"/>', '<string name="lit_regions" value="patches"/>')
                 .replace('<string name="beam" value="uniform"/>',
                          '<string name="beam" value="uniform"/><boolean name="stop_and_hop" value="true"/>'))


@pytest.mark.parametrize("pulses, tilt, moving", [(1, TILT, False), (6, TILT, False), (6, math.radians(45.0), False),
                                                  (6, TILT, True), (6, math.radians(45.0), True)],
                         ids=["one pulse", "a sub-aperture of six pulses", "plate facing the antenna",
                              "six pulses, boundaries moving", "facing the antenna, boundaries moving"])
def test_patch_kernel_equals_the_numpy_reference(tmp_path, monkeypatch, pulses, tilt, moving):
    """The plate tilted 15 deg (edge terms, split and sinc), and tilted 45 deg, facing the
    antenna at 45 deg incidence: its pieces near the specular direction for some pulses are
    gated per pulse between their area term and their edges. ``moving``: every lane's points,
    midpoints and edges, and every area term's segments, given rates of up to 0.2 m per metre of
    travel (eq. (M8); random, the same for both): each pulse must move them by its own travel
    (deliberate bugs: the travel's sign flipped; the area term's segments left where they were)."""
    a, b, c = PLATE_SIZE[0] / 2, PLATE_SIZE[1] / 2, PLATE_CENTRE
    xml = tmp_path / "mirror_plate.xml"
    xml.write_text(SCENE_PATCHES.format(radar="", gx=GROUND_HALF[0], gy=GROUND_HALF[1], px=a, py=b,
                                        angle=-(90.0 - math.degrees(tilt)), cx=c[0], cy=c[1], cz=c[2], pulses=pulses,
                                        prf=250.0, beam=1.0, spacing=0.2, velocity=100.0))
    captured = []
    real = integration.PatchTerms.__call__

    rng = np.random.default_rng(7)

    def keep(self, ctx, lanes, pieces, depth):
        launch = ctx["launch"]
        if moving:
            m = len(lanes)
            lanes = dataclasses.replace(lanes, origin=launch.reference[lanes.sub],
                                        axis=np.tile(np.float32([0.6, 0.8, 0.0]), (m, 1)),
                                        motion=rng.uniform(-0.2, 0.2, (m, 5, 3)).astype(np.float32))
            s = len(pieces.segment_mid)
            pieces = dataclasses.replace(pieces, segment_mid_rate=rng.uniform(-0.2, 0.2, (s, 3)).astype(np.float32),
                                         segment_edge_rate=rng.uniform(-0.2, 0.2, (s, 3)).astype(np.float32))
        captured.append((lanes, pieces, depth, launch.antenna.copy(), launch.lref.copy(), launch.first.copy(),
                         launch.count.copy(), self.alpha_s))
        return real(self, ctx, lanes, pieces, depth)

    monkeypatch.setattr(integration.PatchTerms, "__call__", keep)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AcquisitionWarning)
        sim = simulate(str(xml), window="rect")
    p = sim.loaded.params
    k = 2 * math.pi * p.frequency / SPEED_OF_LIGHT
    t0, fs, fc = float(sim.raw.fast_time[0]), sim.raw.fs, sim.raw.fc
    positions, values, orders, pulse_of = [], [], [], []
    for lanes, pieces, depth, antenna, lref, first, count, alpha_s in captured:
        # VV, PEC: each bounce -1, a chain of d + 1 bounces in the plane of the look (-1)^(d+1) (P6)
        gamma = -1.0

        def density(m, d, bb, s, r, cos_i, cos_b):
            return 1j * 2 * math.sqrt(math.pi) / p.wavelength * (cos_i + cos_b) / 2 * gamma

        for sub in range(len(first)):
            rows = np.flatnonzero(lanes.sub == sub)
            for q in range(int(count[sub])):
                row = int(first[sub]) + q
                edge = _edge_field_vv(depth, k)
                for m, length, value, order in lane_terms(lanes, pieces, antenna[row], k, alpha_s, depth, density, edge):
                    if m not in rows:
                        continue
                    positions.append((length - SPEED_OF_LIGHT * t0) * fs / SPEED_OF_LIGHT)
                    values.append(value * np.exp(-1j * k * (length - lref[row])))
                    orders.append(order)
                    pulse_of.append(row)
    paths = sim.trace.paths
    diffracting = np.concatenate([lanes.diffracting for lanes, *_ in captured])
    doubles = np.concatenate([lanes.double for lanes, *_ in captured])
    assert diffracting.any() and doubles.any()                    # the plate's rims, and across it
    assert set(np.unique(paths.order)) == ({1, 2} if tilt == TILT else {1})       # facing: no double bounce
    kinds = np.concatenate([lanes.kind for lanes, *_ in captured])
    gated = np.concatenate([~lanes.stable for lanes, *_ in captured])
    assert tilt == TILT or (np.any(kinds == integration.AREA) and np.any(gated & (kinds != integration.AREA)))
    positions, values, orders, pulse_of = map(np.array, (positions, values, orders, pulse_of))
    for pulse in range(pulses):
        mine, theirs = paths.pulse == pulse, pulse_of == pulse
        kernel = _spectrum(paths.position[mine], paths.value[mine].astype(complex), paths.spectral[mine], fs, fc)
        reference = _spectrum(positions[theirs], values[theirs], orders[theirs], fs, fc)
        assert np.abs(reference).max() > 0
        assert np.abs(kernel - reference).max() < 1e-4 * np.abs(reference).max(), \
            (pulse, np.abs(kernel - reference).max() / np.abs(reference).max())


def _basis(look: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """H and V of a line of sight (docs/physics.md (P1))."""
    h = np.cross([0.0, 0.0, 1.0], look)
    h /= np.linalg.norm(h)
    return h, np.cross(look, h)


def _edge_field_vv(depth: int, k: float):
    """The VV edge field per metre of a diffracting lane, PEC, from the NumPy reference
    (:func:`edges.edge_field`, :func:`edges.double_field`): the V field launched along the lane's
    first leg, mirrored by each PEC window (``E -> -(E - 2 (n.E) n)``), received on V; after a
    mirror with the fringe of the untraced reverse path."""
    def field(lanes, m, d, b):
        t = lanes.edge[m].astype(float)
        t /= np.linalg.norm(t)
        n = lanes.normal[m].astype(float)
        n0 = n if n @ d < 0 else -n
        e = _basis(d)[1] if depth == 0 else _basis(lanes.first[m].astype(float))[1]
        for i in range(depth):
            w = lanes.window_normal[m, i].astype(float)
            e = -(e - 2 * (w @ e) * w)
        one = (lambda v: np.asarray(v, float)[None])
        x0, xn = lanes.wedge_x0[m].astype(float), lanes.wedge_xn[m].astype(float)
        if lanes.double[m]:
            f = edges.double_field(one(t), one(x0), one(n0), one(lanes.across[m]), one(lanes.across_xn[m]), one(xn),
                                   one(d), one(b), e.astype(complex)[None], k, reverse=depth > 0)[0]
        else:
            f = edges.edge_field(one(t), one(x0), one(n0), one(xn), one(d), one(b), e.astype(complex)[None],
                                 reverse=depth > 0)[0]
            assert not lanes.wedge_defer[m]                       # free rims: no face N to defer to
        return math.sqrt(4 * math.pi) * (_basis(-b)[1] @ f)
    return field
