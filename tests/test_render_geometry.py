"""End-to-end geometry: where dihedral, trihedral and elevated returns land in the focused image.

Each expectation is a closed form of docs/design.md section 9 / docs/physics.md (G1)-(G2), not
an earlier output: the double bounce focuses on the fold line, a trihedral at its apex, a
point at height h lays over toward the sensor by h / tan(theta_inc).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (variant and plugins)
from sarmitsuba.pipeline import simulate

SCENES = Path(__file__).parent / "scenes"


def _peak(image) -> tuple[float, float, float]:
    """Azimuth [m], ground range [m] and amplitude of the image's brightest pixel."""
    mag = np.abs(image.data)
    i, j = np.unravel_index(np.argmax(mag), mag.shape)
    return float(image.azimuth[i]), float(image.range[j]), float(mag[i, j])


def _cells(sim):
    p = sim.loaded.params
    return p.azimuth_resolution, p.ground_range_resolution


@pytest.fixture(scope="module")
def dihedral_depth2():
    return simulate("dihedral", integrator_overrides={"max_depth": 2})


@pytest.fixture(scope="module")
def dihedral_depth1():
    return simulate("dihedral", integrator_overrides={"max_depth": 1})


def test_dihedral_double_bounce_on_fold_line(dihedral_depth2):
    """(G1): the brightest return lies on the fold line (ground range 0) within one cell."""
    sim = dihedral_depth2
    az, gr, _ = _peak(sim.image)
    _, cell_gr = _cells(sim)
    assert abs(gr) <= cell_gr, f"double bounce at ground range {gr:.2f} m, fold line at 0 (cell {cell_gr:.2f} m)"
    assert abs(az) <= 10.0, "peak must lie on the 20 m long fold line"


def test_dihedral_line_spans_the_wall(dihedral_depth2):
    """The double-bounce line is bright along the whole 20 m fold, dark beyond its ends (where
    only the rect-window edge response remains: sinc-integral tail ~ 1 / (pi n) at n cells)."""
    sim = dihedral_depth2
    col = np.argmin(np.abs(sim.image.range))
    line = np.abs(sim.image.data[:, col - 1:col + 2]).max(axis=1)
    az = sim.image.azimuth
    inside = line[np.abs(az) < 8.0]
    outside = line[np.abs(az) > 13.0]
    assert inside.min() > 0.2 * line.max(), "the line must be continuous along the fold"
    assert outside.max() < 0.2 * line.max() and outside.mean() < 0.1 * line.max(), "no line beyond the wall's ends"


def test_max_depth_1_has_no_double_bounce(dihedral_depth1, dihedral_depth2):
    """With max_depth 1 the fold line is absent (> 20 dB weaker); with 2 it is present."""
    def fold_power(sim):
        col = np.argmin(np.abs(sim.image.range))
        return float(np.max(np.abs(sim.image.data[:, col - 1:col + 2]) ** 2))

    ratio_db = 10 * math.log10(fold_power(dihedral_depth1) / fold_power(dihedral_depth2))
    assert ratio_db < -20.0, f"fold line with max_depth 1 only {ratio_db:.1f} dB below max_depth 2"
    e1 = dihedral_depth1.trace.energy_per_order
    assert e1.shape == (1,) and dihedral_depth2.trace.energy_per_order[1] > 100 * e1[0]


def test_trihedral_peaks_at_apex():
    """The triple bounce focuses at the apex (0, 0, 0) within one cell in both directions."""
    sim = simulate("trihedral")
    az, gr, _ = _peak(sim.image)
    cell_az, cell_gr = _cells(sim)
    assert abs(az) <= cell_az and abs(gr) <= cell_gr, f"peak at az {az:.2f} m, gr {gr:.2f} m; apex at 0, 0"
    energy = sim.trace.energy_per_order
    assert energy[2] > 10 * energy[:2].sum(), "the trihedral's energy is triple bounce"


def test_elevated_point_lays_over_toward_sensor():
    """(G2): a trihedral on a 30 m tower roof appears 30 m / tan(45 deg) closer in ground range."""
    sim = simulate(str(SCENES / "tower.xml"))
    p = sim.loaded.params
    az, gr, _ = _peak(sim.image)
    expected = -30.0 / math.tan(math.radians(p.incidence_angle))   # toward the sensor = negative
    cell_az, cell_gr = _cells(sim)
    assert abs(gr - expected) <= cell_gr, f"roof reflector at {gr:.2f} m, expected {expected:.2f} m"
    assert abs(az) <= cell_az


def _azimuth_model(p) -> tuple[float, float]:
    """IRW [m] and PSLR [dB] of the azimuth response ``h(x) = int W(s) exp(j 4 pi s x / lambda) ds``
    over the traced beam's sines s, W the two-way pattern ``sinc^2(L s / lambda)`` of the tapered
    beam (1 for a uniform one): direct quadrature, independent of the focuser."""
    lo, hi = p.beam_sines
    s = np.linspace(lo, hi, 4001)
    weight = np.sinc(p.pattern_length / p.wavelength * s) ** 2 if p.pattern_length else np.ones_like(s)
    x = np.linspace(0.0, 12.0 * p.azimuth_resolution, 24001)
    h = np.abs(np.trapezoid(weight[None, :] * np.cos(4 * np.pi * s[None, :] * x[:, None] / p.wavelength), s, axis=1))
    h /= h[0]
    half = x[np.argmax(h < math.sqrt(0.5))]
    null = np.argmax(np.diff(h) > 0)                     # first minimum
    return 2.0 * half, 20.0 * math.log10(h[null:].max())


@pytest.mark.parametrize("beam", ["tapered", "uniform"])
def test_traced_trihedral_point_target_quality(beam):
    """End to end through the tracer: the trihedral's impulse response has the theoretical IRW
    (azimuth: the tapered beam's sinc^2-weighted response by quadrature, or 0.886 lambda / (2 beta)
    for a uniform beam; 0.886 c / (2 B sin(theta)) in ground range) within 3 %, the rect-window
    PSLR (-13.26 dB in range within 0.5 dB; in azimuth the quadrature's, -13.26 dB for a uniform
    beam and -40 dB for the tapered one, the sidelobe's amplitude within 0.01 of the peak's),
    the apex position within 1/20 cell and the PEC triple-bounce phase j S_VV = +90 deg (S = +I,
    docs/physics.md (P5))
    within 2 deg. At 10 km slant range: at the scene's own 1.4 km the 2 m reflector's near
    field adds ~2 deg of quadratic phase."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    sim = simulate("trihedral", sensor_overrides={"altitude": 10e3 * math.cos(math.pi / 4), "beam": beam},
                   window="rect")
    p = sim.loaded.params
    r = analyze_point_target(sim.image, np.zeros(3))
    irw, pslr = _azimuth_model(p)
    if beam == "uniform":
        assert irw == pytest.approx(0.886 * p.azimuth_resolution, rel=0.01) and pslr == pytest.approx(-13.26, abs=0.1)
    assert abs(r.irw_azimuth / irw - 1) < 0.03, (r.irw_azimuth, irw)
    assert abs(r.irw_range / (0.886 * p.ground_range_resolution) - 1) < 0.03
    # the peak sidelobe's amplitude within 0.01 of the peak's (0.4 dB of a -13 dB sidelobe)
    assert abs(10 ** (r.pslr_azimuth_db / 20) - 10 ** (pslr / 20)) < 0.01, (r.pslr_azimuth_db, pslr)
    assert abs(r.pslr_range_db + 13.26) < 0.5
    assert abs(r.azimuth_error_cells) < 0.05 and abs(r.range_error_cells) < 0.05
    assert abs((r.peak_phase_deg - 90.0 + 180.0) % 360.0 - 180.0) < 2.0


@pytest.mark.parametrize("n_pulses", [0, 160])
def test_spotlight_resolution_follows_the_integration_angle(n_pulses):
    """Spotlight: the beam stays on the scene centre; azimuth IRW = 0.886 lambda / (2 dtheta) with
    dtheta = n_pulses v / (prf R) (Carrara, Goodman and Majewski, *Spotlight SAR*, eq. 2.9),
    within 3 %, whatever the aperture; the apex stays put."""
    from sarmitsuba.analysis.point_target import analyze_point_target
    sim = simulate("trihedral", sensor_overrides={"mode": "spotlight", "n_pulses": n_pulses}, window="rect")
    p = sim.loaded.params
    r = analyze_point_target(sim.image, np.zeros(3))
    expected = 0.886 * p.wavelength / (2 * p.integration_angle)
    assert abs(r.irw_azimuth / expected - 1) < 0.03, f"IRW {r.irw_azimuth:.3f} m, theory {expected:.3f} m"
    assert abs(r.azimuth_error_cells) < 0.05 and abs(r.range_error_cells) < 0.05
    assert any("spotlight" in e for e in sim.raw.metadata["effects"])


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_ground_layover_of_raised_points_is_the_closed_form(incidence):
    """(G2): a point ``h`` up at ground distance ``Y`` from the track (height ``H``) images at
    ground distance ``sqrt(Y^2 - 2 H h + h^2)``, at its own along-track position; a point on
    the ground maps to itself, and one nearer the track than ``R0 < H`` allows maps nowhere
    (NaN). At 30 deg the layover is about 1.73 h, at 60 deg 0.58 h."""
    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.core.geometry import acquisition_geometry, ground_layover
    p = RadarParameters(scene_center=(0.0, 0.0, 0.0), n_pulses=5, incidence_angle=incidence, heading=20.0)
    g = acquisition_geometry(p)
    H, Y0 = p.altitude, p.ground_range
    along, across, h = np.array([-7.0, 3.0, 12.0]), np.array([4.0, -9.0, 0.0]), np.array([25.0, 0.0, 60.0])
    points = (along[:, None] * g.track_direction + across[:, None] * g.look_direction
              + h[:, None] * np.array([0.0, 0.0, 1.0]))
    laid = ground_layover(g, points)
    y = Y0 + across                                   # ground distance of each point from the track
    expected = np.sqrt(y**2 - 2.0 * H * h + h**2) - Y0
    np.testing.assert_allclose(laid[:, 0], along, atol=1e-9)
    np.testing.assert_allclose(laid[:, 1], expected, atol=1e-9)
    assert laid[1, 1] == pytest.approx(across[1], abs=1e-9)
    assert across[0] - laid[0, 1] == pytest.approx(25.0 / math.tan(math.radians(incidence)), rel=0.05)
    beyond = ground_layover(g, np.array([[0.0, 0.0, 0.9 * H]]) - 0.8 * Y0 * g.look_direction)
    assert np.all(np.isnan(beyond[:, 1]))
