"""Range-Doppler algorithm against closed forms, and where it is expected to fail (Cumming and
Wong 2005, ch. 6 and Table 6.1).

Cases and helpers: ``test_stripmap.py``; quality assertions: ``test_omegak.assert_quality``
(range IRW 2 %, azimuth IRW 3 %, PSLR 0.3 dB, ISLR 0.5 dB, position 1/20 cell, phase 2 deg).
Cross-algorithm agreement with omega-K and backprojection is in ``test_omegak.py``.

Where RDA is valid: broadside airborne and spaceborne without SRC; C&W 3.5 deg with SRC
(option 3, range frequency domain) for phase preservation; C&W 21.9 deg only with SRC.
Expected failures, tested as such: C&W 3.5 deg without SRC focuses well but biases the
peak phase by the band-mean of the uncompensated quadratic phase (about 3.5 deg); C&W
21.9 deg without SRC defocuses in range (quadratic phase error about 460 deg at the band
edge).
"""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus.omegak import omega_k
from sarmitsuba.focus.rda import range_doppler

from test_omegak import KAISER, TAYLOR, assert_quality
from test_stripmap import (AIRBORNE_X, CASES, CW_HIGH, CW_LOW, SPACEBORNE_C, analyse, chip, correlation, deskew,
                           geometry, phase_error_deg, simulate)

VALID = [(AIRBORNE_X, False), (SPACEBORNE_C, False), (CW_LOW, "range"), (CW_HIGH, "2d"), (CW_HIGH, "range")]


@pytest.mark.parametrize("case,src", VALID, ids=[f"{c.name}-src={s}" for c, s in VALID])
def test_rda_point_targets(case, src):
    """The 3 x 3 grid meets every tolerance where RDA is valid."""
    geo = geometry(case.name)
    image = range_doppler(simulate(case.name), geometry=geo, src=src, doppler_bandwidth=case.doppler_processed)
    assert image.algorithm == "rda" and image.plane == "slant"
    assert image.metadata["focus"]["src"] == src or (src is False and image.metadata["focus"]["src"] == "none")
    assert_quality(image, case, geo, case.doppler_processed)


def test_rda_windows():
    """Weighting: Taylor (4, -35 dB) in range, Kaiser 2.5 in azimuth (airborne, broadside)."""
    case = AIRBORNE_X
    geo = geometry(case.name)
    image = range_doppler(simulate(case.name), geometry=geo, doppler_bandwidth=case.doppler_processed,
                          window_range=TAYLOR, window_azimuth=KAISER)
    assert_quality(image, case, geo, case.doppler_processed, TAYLOR, KAISER)


def test_rda_low_squint_without_src_focuses_but_biases_phase():
    """C&W 3.5 deg without SRC: IRW/PSLR/ISLR/position within tolerance, but the peak phase is
    off by the band-mean of the uncompensated coupling, (2 pi R0 / c) (alpha^2 / Q0^3) B^2 / 12."""
    case = CW_LOW
    geo = geometry(case.name)
    image = range_doppler(simulate(case.name), geometry=geo, src=False, doppler_bandwidth=case.doppler_processed)
    assert_quality(image, case, geo, case.doppler_processed, phase_tol=10.0)
    alpha = C * geo.doppler_centroid / (2 * geo.velocity)
    q0 = np.sqrt(case.fc**2 - alpha**2)
    for target in case.targets():
        rep, (_, r0) = analyse(image, geo, case.fc, target)
        bias = np.degrees(2 * np.pi * r0 / C * alpha**2 / q0**3 * case.bandwidth**2 / 12)
        assert bias == pytest.approx(3.5, abs=0.3)
        assert phase_error_deg(rep, target) == pytest.approx(bias, abs=0.5)


def test_rda_high_squint_without_src_fails():
    """C&W 21.9 deg without SRC (discriminating test; Cumming and Wong 2005, ch. 6, SRC): the
    range response is defocused far beyond tolerance, while omega-K and RDA with SRC pass on the same data."""
    case = CW_HIGH
    geo = geometry(case.name)
    raw = simulate(case.name)
    bad = range_doppler(raw, geometry=geo, src=False, doppler_bandwidth=case.doppler_processed)
    good = omega_k(raw, geometry=geo, doppler_bandwidth=case.doppler_processed)
    for target in case.targets():
        az, rg = geo.zero_doppler(target.position)
        a, b = chip(bad, az, rg, 16), chip(good, az, rg, 16)
        assert correlation(a, b) < 0.6
        assert np.abs(a).max() < 0.6 * np.abs(b).max()  # peak loss > 4.4 dB
        # the range cut has no -3 dB point inside its first null, or is > 1.5x too wide
        try:
            rep = analyze_point_target(deskew(bad, geo, rg), (az, rg))
        except ValueError as exc:
            assert "null" in str(exc)
        else:
            assert rep.irw_range / np.cos(geo.squint) > 1.5 * case.range_irw() or rep.pslr_range_db > -10.0


def test_rda_src_options_and_errors():
    case = AIRBORNE_X
    raw = simulate(case.name)
    geo = geometry(case.name)
    a = range_doppler(raw, geometry=geo, src="none")
    b = range_doppler(raw, geometry=geo, src=True)
    assert b.metadata["focus"]["src"] == "2d" and a.metadata["focus"]["src"] == "none"
    # broadside airborne: the coupling is negligible, SRC changes almost nothing
    for target in case.targets()[::4]:
        az, rg = geo.zero_doppler(target.position)
        assert correlation(chip(a, az, rg), chip(b, az, rg)) > 0.9999
    with pytest.raises(ValueError, match="src"):
        range_doppler(raw, geometry=geo, src="option1")
    with pytest.raises(ValueError, match="upsample"):
        range_doppler(raw, geometry=geo, upsample=0)
    with pytest.raises(ValueError, match="taps"):
        range_doppler(raw, geometry=geo, taps=7)
