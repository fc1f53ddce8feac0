"""The phase of PGA's output against the true-track focus (sarmitsuba.focus.autofocus,
docs/physics.md (PGA2)), for interferometry and the SICD, which read the complex image.

Four trihedrals away from the scene centre (along-track -10 to +8 m), a Gaussian cross-track
motion error (1 cm rms, 8 m correlation): backprojected on the nominal track, then PGA, and
compared with the same data backprojected on the true track. PGA does not estimate a linear
phase in the deramped spectrum, so its image is the true one shifted by ``D`` along track and
re-ramped: at a target ``x_t`` (``x_ref`` the mid-aperture antenna, ``R0`` the target's
closest-approach range, ``k = 2 pi fc / c``)

    arg O(x_t + D) - arg I(x_t) = k (2 (x_t - x_ref) D + D^2) / R0 + const,

derived from (PGA2): ``O(x) = I(x - D) exp(j k ((x - x_ref)^2 - (x - D - x_ref)^2) / R0)``. The
test measures ``D`` and the phases at every target (sub-pixel, by point-target analysis) and
checks every pair's phase difference against that closed form.
"""
from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.focus import ImageGrid, ffbp
from sarmitsuba.focus.autofocus import pga
from sarmitsuba.pipeline import simulate

FC = 9.6e9
TARGETS = ((-10.0, -2.0), (-4.0, 1.0), (3.0, -1.0), (8.0, 2.0))      # (along-track, ground range) [m]


@pytest.fixture(scope="module")
def focused():
    reflector = trimesh.load("scenes/meshes/trihedral.obj")
    meshes = [(reflector.copy().apply_translation((a, -g, 0.0)), "pec", f"trihedral{i}")
              for i, (a, g) in enumerate(TARGETS)]                      # the radar looks toward -y
    scene = sarmitsuba.Scene(meshes=meshes, integrator={"max_depth": 3},
                             sensor={"frequency": FC, "bandwidth": 150e6, "incidence_angle": 45,
                                     "scene_center": (0, 0, 0), "motion_error": "random, 0.01, 8, 3"})
    sim = simulate(scene, focuser="ffbp", image_size=(32, 32))
    frame = sim.image
    assert np.allclose(frame.azimuth_direction, [1, 0, 0]) and np.allclose(frame.range_direction, [0, -1, 0])
    grid = ImageGrid(origin=frame.origin, azimuth_direction=frame.azimuth_direction,
                     range_direction=frame.range_direction, azimuth=(np.arange(256) - 128) * 0.1,
                     range=(np.arange(64) - 32) * 0.2, plane="ground")
    true, nominal = ffbp(sim.raw, grid), ffbp(sim.raw.on_track("nominal"), grid)
    fixed, report = pga(nominal)
    return sim.raw, true, nominal, fixed, report


def _found(image, along: float, ground: float):
    """Point-target analysis of the peak nearest ``(along, ground)`` within 2.5 m along track."""
    rows = np.flatnonzero(np.abs(image.azimuth - along) <= 2.5)
    col = int(np.argmin(np.abs(image.range - ground)))
    peak = float(image.azimuth[rows[np.argmax(np.abs(image.data[rows, col]))]])
    return analyze_point_target(image, (peak, -ground, 0.0), chip=32, search_radius=3)


def test_pga_restores_each_target(focused):
    _, true, nominal, fixed, report = focused
    assert report.applied and report.deramp and report.rms_phase_error > 1.0
    for along, ground in TARGETS:
        t, f = _found(true, along, ground), _found(fixed, along, ground)
        near = (np.abs(nominal.azimuth - along) <= 2.5)[:, None] & (np.abs(nominal.range - ground) <= 1.0)[None, :]
        assert np.abs(nominal.data[near]).max() < 0.8 * t.peak_magnitude     # defocused: -2.6 to -5.8 dB
        assert abs(20 * math.log10(f.peak_magnitude / t.peak_magnitude)) < 0.5


def test_pga_output_phase_matches_the_true_track_focus(focused):
    """Catches a re-ramp of the wrong sign (``exp(-j phase)`` for ``exp(+j phase)``): magnitudes
    are unchanged, but every pixel carries an extra ``2 k x^2 / R0`` (0.28 rad x^2 [m] here: 18
    rad at 8 m), which the pairs below see as up to 2.0 rad against 0.05 with the right sign."""
    raw, true, _, fixed, _ = focused
    k = 2 * math.pi * FC / SPEED_OF_LIGHT
    mid = raw.nominal_tx_position[raw.n_pulses // 2]
    x_ref = float(mid @ true.azimuth_direction)
    measured = []
    for along, ground in TARGETS:
        t, f = _found(true, along, ground), _found(fixed, along, ground)
        point = np.array([along, -ground, 0.0])
        r0 = float(np.min(np.linalg.norm(raw.nominal_tx_position - point, axis=1)))   # closest approach
        shift = f.azimuth - t.azimuth
        assert 0.3 < abs(shift) < 2.0                       # PGA's unestimated linear phase: a shift
        expected = k * (2 * (t.azimuth - x_ref) * shift + shift ** 2) / r0
        measured.append((math.radians(f.peak_phase_deg - t.peak_phase_deg), expected))
    for (ma, ea), (mb, eb) in itertools.combinations(measured, 2):
        error = np.angle(np.exp(1j * ((ma - mb) - (ea - eb))))
        assert abs(error) < 0.25, (ma - mb, ea - eb)
