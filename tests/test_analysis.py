"""Point-target analysis against closed forms (focusing.md sections 4 and 7).

Two kinds of input:

* a synthetic separable 2-D impulse response ``a p(az / d_az) p(rg / d_rg)`` (``p`` the
  unit-peak compressed pulse of a window, :func:`sarmitsuba.focus.windows.compressed_pulse`)
  with a steep linear phase ramp (aliased by the pixels, as in a ground-plane image), whose
  IRW, PSLR, ISLR, energy and phase are known in closed form;
* a ground-plane backprojected image of analytic raw data (:mod:`sarmitsuba.synthetic`),
  against the resolution formulas of DESIGN.md section 9.

ISLR is the null-bounded 1-D definition of :mod:`sarmitsuba.analysis`: mainlobe between the
first nulls, sidelobes out to ``sidelobes`` null distances beyond them or to the chip edge;
it is compared with :func:`sarmitsuba.focus.windows.islr_theory` at the extent used.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.integrate

from sarmitsuba.analysis import analyze_point_target, carrier_ramp, main
from sarmitsuba.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import ImageGrid, backproject
from sarmitsuba.focus import windows as w
from sarmitsuba.image import SarImage
from sarmitsuba.synthetic import PointTarget, simulate_point_targets, straight_track

SPACING = 0.25  # m, both axes
WIDTH_AZ, WIDTH_RG = 0.37, 0.41  # m, reciprocal bandwidths (1/B) of the synthetic response
AMPLITUDE = 0.8 * np.exp(0.6j)
RAMP = (3.0, 300.0)  # rad/m: 75 rad per range pixel, aliased


def ipr_image(centre=(0.123, -0.311), window="rect", params=None, n=161, plane="slant", noise=0.0, ramp=RAMP):
    params = params or {}
    axis = (np.arange(n) - n // 2) * SPACING
    da, dr = axis[:, None] - centre[0], axis[None, :] - centre[1]
    data = (AMPLITUDE * w.compressed_pulse(da / WIDTH_AZ, 1.0, window, **params)
            * w.compressed_pulse(dr / WIDTH_RG, 1.0, window, **params)
            * np.exp(1j * (ramp[0] * da + ramp[1] * dr)))
    if noise:
        rng = np.random.default_rng(7)
        data = data + np.sqrt(noise / 2) * (rng.standard_normal(data.shape) + 1j * rng.standard_normal(data.shape))
    return SarImage(data.astype(np.complex64), axis, axis.copy(), np.array([10.0, 20.0, 0.0]),
                    np.array([1.0, 0.0, 0.0]), np.array([0.0, -1.0, 0.0]), plane=plane)


def energy_fraction(window, params, extent):
    """int_{-X}^{X} p(u)^2 du / int p^2, X = extent first-null distances (closed form by quadrature)."""
    u1 = w.first_null(window, **params)
    edges = np.arange(0.0, extent * u1, 0.5).tolist() + [extent * u1]
    part = sum(scipy.integrate.quad(lambda u: w.compressed_pulse(u, 1.0, window, **params) ** 2, a, b,
                                    epsabs=1e-14)[0] for a, b in zip(edges[:-1], edges[1:]))
    return 2 * part / w.energy_width(window, **params)


# ============================================================================ synthetic IPR
def test_sinc_ipr_closed_forms():
    centre = (0.123, -0.311)
    report = analyze_point_target(ipr_image(centre), centre, carrier=RAMP, resolution=(WIDTH_AZ, WIDTH_RG))
    irw = w.impulse_response_width("rect")  # 0.8859 / B
    assert report.irw_azimuth == pytest.approx(irw * WIDTH_AZ, rel=1e-3)
    assert report.irw_range == pytest.approx(irw * WIDTH_RG, rel=1e-3)
    assert report.first_null_azimuth == pytest.approx(WIDTH_AZ, rel=0.01)
    for pslr in (report.pslr_azimuth_db, report.pslr_range_db):
        assert pslr == pytest.approx(-13.26, abs=0.1)
    assert report.islr_extent_azimuth == pytest.approx(10.0, abs=0.05)
    for islr in (report.islr_azimuth_nullbounded_db, report.islr_range_nullbounded_db):
        assert islr == pytest.approx(w.islr_theory("rect", sidelobes=10), abs=0.05)  # -10.11 dB
    # position (1e-3 cell), magnitude and phase (true carrier given)
    assert abs(report.azimuth_error_cells) < 1e-3 and abs(report.range_error_cells) < 1e-3
    assert report.azimuth == pytest.approx(centre[0], abs=1e-4) and report.range == pytest.approx(centre[1], abs=1e-4)
    assert report.peak_magnitude == pytest.approx(abs(AMPLITUDE), rel=1e-3)
    assert report.peak_phase_deg == pytest.approx(np.degrees(np.angle(AMPLITUDE)), abs=0.1)
    assert report.predicted_phase_deg == pytest.approx(np.degrees(np.angle(AMPLITUDE)), abs=0.1)
    assert report.carrier == "given" and report.plane == "slant"
    assert np.allclose(report.world_position, [10.0 + centre[0], 20.0 - centre[1], 0.0], atol=1e-4)
    # energy in the +-5-null box: |a|^2 d_az d_rg x (energy fraction)^2; RCS = energy / (d_az d_rg)
    fraction = energy_fraction("rect", {}, 5.0)
    assert report.integrated_energy == pytest.approx(abs(AMPLITUDE) ** 2 * WIDTH_AZ * WIDTH_RG * fraction ** 2,
                                                     rel=0.01)
    assert report.rcs_db == pytest.approx(10 * np.log10(abs(AMPLITUDE) ** 2 * fraction ** 2), abs=0.05)


def test_estimated_ramp_gives_the_phase_at_pixel_centres():
    """An estimated (wrapped) ramp is exact at pixel centres: a target there keeps its phase."""
    centre = (2 * SPACING, -3 * SPACING)
    report = analyze_point_target(ipr_image(centre), centre)
    assert report.carrier == "estimated"
    assert report.phase_ramp_range == pytest.approx(np.angle(np.exp(1j * RAMP[1] * SPACING)), abs=1e-3)
    assert report.peak_phase_deg == pytest.approx(np.degrees(np.angle(AMPLITUDE)), abs=0.1)
    assert report.irw_range == pytest.approx(w.impulse_response_width("rect") * WIDTH_RG, rel=1e-3)


@pytest.mark.parametrize("window, params", [("taylor", {"nbar": 4, "sll": -35}), ("hamming", {}),
                                            ("kaiser", {"beta": 2.5})], ids=["taylor", "hamming", "kaiser"])
def test_windowed_ipr(window, params):
    centre = (-0.07, 0.19)
    report = analyze_point_target(ipr_image(centre, window, params), centre, carrier=RAMP)
    k_w = w.broadening_factor(window, **params)
    assert report.irw_range == pytest.approx(0.886 * k_w * WIDTH_RG, rel=0.01)
    assert report.irw_azimuth == pytest.approx(w.impulse_response_width(window, **params) * WIDTH_AZ, rel=2e-3)
    assert report.pslr_range_db == pytest.approx(w.pslr_theory(window, **params), abs=0.5)
    assert report.islr_range_nullbounded_db == pytest.approx(
        w.islr_theory(window, sidelobes=report.islr_extent_range, **params), abs=0.5)


def test_clutter_is_subtracted_from_the_energy():
    noise = 1e-4  # mean |n|^2 per pixel
    centre = (0.05, 0.02)
    report = analyze_point_target(ipr_image(centre, noise=noise), centre, resolution=(WIDTH_AZ, WIDTH_RG))
    assert report.clutter_level == pytest.approx(noise, rel=0.2)
    expected = abs(AMPLITUDE) ** 2 * energy_fraction("rect", {}, 5.0) ** 2
    assert report.rcs_db == pytest.approx(10 * np.log10(expected), abs=0.1)


def test_report_is_json_and_cli_prints_it(tmp_path, capsys):
    image = ipr_image(plane="ground")
    report = analyze_point_target(image, (10.123, 20.311, 0.0))  # world point -> (0.123, -0.311)
    data = json.loads(json.dumps(report.to_dict()))
    assert data["plane"] == "ground" and data["rcs"] is None and len(data["world_position"]) == 3
    assert data["azimuth"] == pytest.approx(0.123, abs=1e-4)
    path = image.save(tmp_path / "ipr.npz")
    assert main([str(path), "--target", "0.123,-0.311", "--resolution", f"{WIDTH_AZ},{WIDTH_RG}"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["range"] == pytest.approx(-0.311, abs=1e-4) and printed["rcs"] > 0
    assert main([str(tmp_path / "missing.npz"), "--target", "0,0"]) == 2


@pytest.mark.parametrize("kwargs, match", [
    ({"target": (30.0, 0.0)}, "outside the image"),
    ({"target": (0.0, 0.0), "chip": 63}, "even"),
    ({"target": (0.0, 0.0), "chip": 160}, "edge"),
    ({"target": (0.0, 0.0), "oversample": 2}, "oversample"),
    ({"target": (0.0, 0.0, 0.0, 1.0)}, "3 finite numbers"),
    ({"target": (0.0, 0.0), "carrier": (1.0,)}, "carrier"),
    ({"target": (0.0, 0.0), "resolution": (1.0, -1.0)}, "resolution"),
])
def test_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        analyze_point_target(ipr_image(), **kwargs)


# ============================================================================ backprojected target
FC, B = 9.6e9, 150e6
ALT, OFFSET, APERTURE = 3000.0, 4000.0, 140.0
TARGETS = [PointTarget((0.0, 0.0, 0.0), np.exp(0.7j)),  # on a pixel centre
           PointTarget((14.0 + 0.37 * SPACING, -10.0 - 0.21 * SPACING, 0.0), 0.5 * np.exp(-2.1j))]  # sub-pixel


@pytest.fixture(scope="module")
def focused():
    tr = straight_track(int(APERTURE / SPACING) + 1, 400.0, 100.0, center=(0.0, OFFSET, ALT))
    lengths = np.concatenate([2 * np.linalg.norm(tr.position - t.position, axis=1) for t in TARGETS])
    fs = 1.2 * B
    t0 = lengths.min() / C - 64 / B
    raw = simulate_point_targets(TARGETS, tr.position, FC, B, fs, t0, int((np.ptp(lengths) / C + 128 / B) * fs),
                                 prf=tr.prf, velocity=tr.velocity, pulse_length=1e-6)
    grid = ImageGrid(origin=np.zeros(3), azimuth_direction=np.array([1.0, 0.0, 0.0]),
                     range_direction=np.array([0.0, -1.0, 0.0]),
                     azimuth=np.arange(-40, 97) * SPACING, range=np.arange(-40, 81) * SPACING)
    return raw, backproject(raw, grid)


@pytest.mark.parametrize("index", [0, 1], ids=["pixel-centre", "sub-pixel"])
def test_backprojected_point_target(focused, index):
    raw, image = focused
    target = TARGETS[index]
    x, y, _ = target.position
    ground = OFFSET - y
    slant = np.hypot(ALT, ground)
    wavelength = C / FC
    irw_az = 0.886 * wavelength * slant / (2 * APERTURE)  # uniform illumination over the aperture
    irw_rg = 0.886 * C / (2 * B) * slant / ground  # slant IRW / sin(incidence)
    carrier = carrier_ramp(raw, image, target.position)
    report = analyze_point_target(image, target.position, carrier=carrier)
    assert report.irw_azimuth == pytest.approx(irw_az, rel=0.02)
    assert report.irw_range == pytest.approx(irw_rg, rel=0.02)
    assert report.pslr_azimuth_db == pytest.approx(-13.26, abs=0.3)
    assert report.pslr_range_db == pytest.approx(-13.26, abs=0.3)
    assert report.islr_range_nullbounded_db == pytest.approx(
        w.islr_theory("rect", sidelobes=report.islr_extent_range), abs=0.3)
    assert abs(report.azimuth - x) < irw_az / 20 and abs(report.range - (-y)) < irw_rg / 20
    assert abs(report.azimuth_error_cells) < 1 / 20 and abs(report.range_error_cells) < 1 / 20
    assert report.peak_magnitude == pytest.approx(abs(target.amplitude), rel=0.02)
    truth = np.degrees(np.angle(target.amplitude))
    assert abs((report.predicted_phase_deg - truth + 180) % 360 - 180) < 2.0
    if index == 0:  # on a pixel centre the estimated (wrapped) ramp gives the peak phase too
        plain = analyze_point_target(image, target.position)
        assert abs((plain.peak_phase_deg - truth + 180) % 360 - 180) < 2.0
