"""The focused image of a PEC plate against the full-wave method-of-moments tables of
``tests/data/fullwave/`` (bempp-cl, written by ``benchmarks/fullwave.py``; no solver needed here).

The plate is 4 wavelengths square, horizontal, alone; its RCS is integrated from the image
(``analyze``) and compared with the table's monostatic RCS averaged over the pulses and the band as
the image weighs them (the band's frequencies enter as the plate's electrical size, equivalently
``sin(theta) f / f_c`` at the carrier, the phase across the plate that shapes its pattern). With
physical optics alone the plate is 3 dB (HH) and 5 dB (VV) low at 45 deg and 16 to 20 dB low at
60 deg; with the edge currents (docs/physics.md (E1)-(E6)) it must be within the issue's bounds.

Deliberate bugs this was run against: the soft and hard fringe coefficients swapped (VV at 45
deg off by more than 1.5 dB); the double diffraction left out (VV at 45 deg, 60 deg); diffraction
switched off (every case).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.pipeline import simulate

from test_patches import WAVELENGTH, image_weights, rectangle, sensor

TABLES = Path(__file__).parent / "data" / "fullwave"


def _sweep(case: str, phi_deg: float) -> dict:
    table = json.loads((TABLES / f"{case}.json").read_text())
    return next(s for s in table["sweeps"] if abs(s["phi_deg"] - phi_deg) < 1e-6)


def fullwave_rcs_db(sim, sweep: dict, polarization: str) -> float:
    """The table's RCS [dBsm at this wavelength] averaged as the image weighs pulses and band:
    Taylor windows across the processed beam and the band, two-way azimuth pattern."""
    p = sim.loaded.params
    rhat, weight, frequencies, band = image_weights(sim)
    theta = np.asarray(sweep["theta_deg"], float)
    sigma = 10 ** (np.asarray(sweep[f"sigma_{polarization.lower()}_db"], float) / 10)    # sigma / lambda^2
    num = den = 0.0
    for k in np.flatnonzero(weight > 0):
        sin_t = math.hypot(rhat[k][0], rhat[k][1])
        for f, v in zip(frequencies, band):
            t = math.degrees(math.asin(min(sin_t * f / p.frequency, 1.0)))
            s = float(np.interp(t, theta, sigma)) * (SPEED_OF_LIGHT / f) ** 2
            w = (weight[k] * v) ** 2
            num, den = num + w * s, den + w
    return 10 * math.log10(num / den)


@pytest.mark.parametrize("incidence, polarization, bound", [
    (45.0, "HH", 1.5), (45.0, "VV", 1.5), (20.0, "HH", 1.0), (20.0, "VV", 1.0), (60.0, "HH", 2.0), (60.0, "VV", 1.5)])
def test_plate_rcs_from_the_image_matches_full_wave(incidence, polarization, bound):
    """The issue's acceptance: a 4-wavelength square PEC plate, horizontal, edges along and across
    the track, at 45 deg incidence within 1.5 dB of full wave in HH and VV; at 20 deg within 1 dB;
    at 60 deg HH within 2 dB."""
    half = 2 * WAVELENGTH
    plate = rectangle((0, 0, 0), (half, 0, 0), (0, half, 0))
    sim = simulate(sarmitsuba.Scene([(plate, "pec", "plate")],
                                    sensor=sensor(0.0, incidence_angle=incidence, polarization=polarization),
                                    integrator={"max_depth": 1}))
    got = sarmitsuba.analyze(sim.image, (0, 0, 0), raw=sim.raw).rcs_db
    expected = fullwave_rcs_db(sim, _sweep("square", 0.0), polarization)
    assert got == pytest.approx(expected, abs=bound), (got, expected)


@pytest.mark.parametrize("case, phi, ax, by, bounds", [
    ("square", 0.0, 4.0, 4.0, (1.5, 1.5)), ("square_az30", 30.0, 4.0, 4.0, (1.5, 1.5)),
    ("rect", 90.0, 4.0, 2.0, (1.5, 1.6)), ("rect", 0.0, 4.0, 2.0, (3.0, 2.0))])
def test_plate_patterns_follow_full_wave(case, phi, ax, by, bounds):
    """The issue's "across angles": PO plus edge currents (the tracer's terms, by their NumPy
    reference ``edges.plate_scattering``) follow the full-wave pattern from 0 to 60 deg wherever
    it lies within 25 dB of its peak, at the carrier, within ``bounds`` (HH, VV) dB. Measured:
    square 0.92 / 0.92, turned 30 deg 0.39 / 0.85, the 4 x 2 rectangle across its long rims 0.89 /
    1.51 (VV at 55 deg, 2 wavelengths across). Along its long side the 2-wavelength rims leave 2.8
    (HH, 40 deg) and 1.9 dB (VV, 60 deg): the
    full-wave square and rectangle differ there by more than their rims' lengths (their
    difference is the strip's echo width within 0.4 dB in VV, up to 5 dB off in HH), the corners'
    share that edge currents on straight edges do not carry (docs/physics.md (E5)). Catches the
    double diffraction dropped or taken on one face (VV, 3 to 5 dB at 40-60 deg), the fringe's
    sign, swapped polarisations."""
    from sarmitsuba.tracing.integration.edges import plate_scattering
    sweep = _sweep(case, phi)
    theta = np.asarray(sweep["theta_deg"])
    keep = theta <= 60.0
    t, p = np.radians(theta[keep]), math.radians(phi)
    toward = np.stack([np.sin(t) * math.cos(p), np.sin(t) * math.sin(p), np.cos(t)], axis=1)
    corners = np.array([[-ax / 2, -by / 2, 0], [ax / 2, -by / 2, 0], [ax / 2, by / 2, 0], [-ax / 2, by / 2, 0]])
    model = plate_scattering(corners, 2 * math.pi, toward)
    peak = max(max(sweep["sigma_hh_db"]), max(sweep["sigma_vv_db"]))
    for channel, bound in zip(("hh", "vv"), bounds):
        reference = np.asarray(sweep[f"sigma_{channel}_db"])[keep]
        got = 10 * np.log10(4 * math.pi * np.abs(model[channel]) ** 2)
        window = reference >= peak - 25.0
        assert window.sum() >= 8
        assert np.max(np.abs(got - reference)[window]) < bound, (channel, np.round((got - reference)[window], 2))


@pytest.mark.parametrize("incidence, polarization, bound", [(30.0, "HH", 2.0), (45.0, "HH", 2.0), (30.0, "VV", 4.5)])
def test_cube_rcs_from_the_image_near_full_wave(incidence, polarization, bound):
    """A closed 2-wavelength PEC cube, its faces along and across the track: the image's RCS
    against the full-wave table at the carrier (its pattern does not scale with the band as a
    plate's does) within ``bound`` dB. Measured: HH -1.1 / +1.3 dB at 30 / 45 deg (PO alone -8.1
    / -1.6), VV -3.7 dB at 30 (PO alone -5.7: the hard polarisation's corner effects). Catches
    the double diffraction across a face the wave grazes (the side faces here) evaluated with
    Keller's coefficient at its shadow boundary (HH 16 dB high), and a convex corner's fringe
    counted on both faces."""
    import trimesh
    cube = trimesh.creation.box((2 * WAVELENGTH,) * 3)
    sim = simulate(sarmitsuba.Scene([(cube, "pec", "cube")],
                                    sensor=sensor(0.0, incidence_angle=incidence, polarization=polarization)))
    got = sarmitsuba.analyze(sim.image, (0, 0, 0), raw=sim.raw).rcs_db
    sweep = _sweep("box", 0.0)
    expected = float(np.interp(incidence, sweep["theta_deg"], sweep[f"sigma_{polarization.lower()}_db"])) \
        + 20 * math.log10(WAVELENGTH)
    assert got == pytest.approx(expected, abs=bound), (got, expected)
