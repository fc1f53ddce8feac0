"""The stored full-wave (method-of-moments, bempp-cl EFIE) RCS tables, tests/data/fullwave/*.json.

They are written by ``benchmarks/fullwave.py --write`` (slow, needs the ``validation`` extra); these
tests only read them (no bempp-cl needed) and check what an independent truth fixes: closed forms
at the points where they are exact to the table's accuracy (flat plate at normal incidence, dihedral
at boresight), reciprocity, the symmetries of the geometry, the physical-optics phase, the known
polarisation behaviour of a plate near grazing incidence, and the provenance. Each test names the
bug of the table writer it would catch.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data" / "fullwave"
CASES = ["square", "square_az30", "rect", "dihedral", "box"]
CHANNELS = ("hh", "hv", "vh", "vv")


def load(case: str) -> dict:
    path = DATA / f"{case}.json"
    assert path.exists(), f"{path} missing: run python benchmarks/fullwave.py --write"
    return json.loads(path.read_text())


def complex_s(sweep: dict, channel: str) -> np.ndarray:
    return np.asarray(sweep[f"S_{channel}_re"]) + 1j * np.asarray(sweep[f"S_{channel}_im"])


def sweep_at(doc: dict, phi: float) -> dict:
    return next(s for s in doc["sweeps"] if abs(s["phi_deg"] - phi) < 1e-9)


def value_at(sweep: dict, key: str, theta: float):
    i = int(np.argmin(np.abs(np.asarray(sweep["theta_deg"]) - theta)))
    assert abs(sweep["theta_deg"][i] - theta) < 1e-9
    return sweep[key][i]


def db(x: float) -> float:
    return 10.0 * math.log10(x)


@pytest.mark.parametrize("case", CASES)
def test_provenance_keys(case):
    """Catches a writer that drops provenance (solver, version, mesh, Mie check, convergence, command)
    or that labels a file with the wrong case."""
    doc = load(case)
    for key in ("case", "geometry", "conventions", "solver", "mie_check_db", "convergence_db", "created",
                "command", "sweeps"):
        assert key in doc, key
    assert doc["case"] == case
    solver = doc["solver"]
    for key in ("version", "formulation", "quadrature", "stored_density_cells_per_lambda", "unknowns"):
        assert key in solver, key
    assert "EFIE" in solver["formulation"]
    assert doc["mie_check_db"] is not None and doc["mie_check_db"]["max_abs_db"] < 0.2
    assert "max" in doc["convergence_db"]["max_abs_db_diff"]
    assert "exp(+j omega t)" in doc["conventions"]
    assert "benchmarks/fullwave.py" in doc["command"]
    for sweep in doc["sweeps"]:
        n = len(sweep["theta_deg"])
        for c in CHANNELS:
            assert len(sweep[f"S_{c}_re"]) == len(sweep[f"S_{c}_im"]) == len(sweep[f"sigma_{c}_db"]) == n


@pytest.mark.parametrize("case", CASES)
def test_sigma_db_is_4pi_abs_s_squared(case):
    """Catches dB columns inconsistent with the complex S (20 log10 |S| without the 4 pi, 10 log10 |S|,
    a column written from another channel or another angle)."""
    for sweep in load(case)["sweeps"]:
        for c in CHANNELS:
            s = complex_s(sweep, c)
            expected = 10 * np.log10(np.maximum(4 * np.pi * np.abs(s) ** 2, 1e-30))
            got = np.asarray(sweep[f"sigma_{c}_db"])
            strong = expected > -60  # tiny cross-pol values: rounding of S dominates
            assert np.allclose(got[strong], expected[strong], atol=2e-3)


@pytest.mark.parametrize("case", ["square", "square_az30"])
def test_square_plate_normal_incidence_is_4pi_area_squared(case):
    """Flat plate at normal incidence: sigma = 4 pi A^2 / lambda^2 = 35.07 dB for A = 16 lambda^2
    (edge effects of a 4 lambda plate are well under 0.5 dB). Catches a wrong normalisation (a missing
    4 pi, sigma in units of pi a^2 or of lambda^2 at another lambda, |S| for |S|^2)."""
    sweep = load(case)["sweeps"][0]
    expected = db(4 * math.pi * 16.0**2)
    for c in ("hh", "vv"):
        assert abs(value_at(sweep, f"sigma_{c}_db", 0.0) - expected) < 0.5


def test_rect_plate_normal_incidence_is_4pi_area_squared():
    """The 4 x 2 plate at normal incidence, both observation planes: 4 pi (8)^2 = 28.05 dB. Catches a
    geometry written with the wrong size or a sweep filled from the other case."""
    expected = db(4 * math.pi * 8.0**2)
    for sweep in load("rect")["sweeps"]:
        for c in ("hh", "vv"):
            assert abs(value_at(sweep, f"sigma_{c}_db", 0.0) - expected) < 0.6


@pytest.mark.parametrize("case", ["square", "square_az30"])
def test_plate_hh_equals_vv_at_normal_incidence(case):
    """At normal incidence a square plate (unchanged by a quarter turn) cannot tell h from v in any
    basis: a reciprocal scattering matrix that a quarter turn leaves alone is a multiple of the
    identity, so in the backscatter alignment both co-polar returns are the same complex number.
    (The 4 x 2 rectangle can: its HH and VV differ by 0.5 dB there.) Catches a forward-scatter-
    alignment receive basis (S_hh = -S_vv), a conjugate on one channel, or co-polar columns from
    different angles."""
    for sweep in load(case)["sweeps"]:
        hh, vv = complex_s(sweep, "hh")[0], complex_s(sweep, "vv")[0]
        assert abs(hh - vv) < 0.01 * abs(hh)


def test_square_plate_normal_incidence_has_the_physical_optics_phase():
    """exp(+j omega t): the physical-optics return of a flat plate at normal incidence, phase referenced
    to its centre, is S = -j A / lambda (PO current 2 n x H_inc radiating exp(-j k R)/R). Catches the
    exp(-i omega t) solver output stored without conjugation (phase +90 deg) or a sign error of S."""
    sweep = load("square")["sweeps"][0]
    hh = complex_s(sweep, "hh")[0]
    assert abs(np.degrees(np.angle(hh)) - (-90.0)) < 10.0


@pytest.mark.parametrize("case", CASES)
def test_reciprocity_hv_equals_vh(case):
    """Monostatic reciprocity: S_hv = S_vh (complex). Catches cross-polar columns taken from different
    angles or transmit/receive, a sign flip of one antenna basis vector between transmit and receive,
    a conjugate on one channel."""
    for sweep in load(case)["sweeps"]:
        hv, vh = complex_s(sweep, "hv"), complex_s(sweep, "vh")
        co = max(np.max(np.abs(complex_s(sweep, "hh"))), np.max(np.abs(complex_s(sweep, "vv"))))
        assert np.max(np.abs(hv - vh)) < 1e-3 * co


@pytest.mark.parametrize("case,phi", [("square", 0.0), ("rect", 0.0), ("rect", 90.0), ("box", 0.0)])
def test_cross_pol_vanishes_in_a_symmetry_plane(case, phi):
    """The observation plane is a mirror plane of the scene (and of the mesh): no cross-polarised return.
    Catches an antenna basis built with the wrong azimuth (degrees taken as radians, phi from another
    sweep) or h/v not perpendicular/parallel to the plane of incidence."""
    sweep = sweep_at(load(case), phi)
    co = max(np.max(np.abs(complex_s(sweep, "hh"))), np.max(np.abs(complex_s(sweep, "vv"))))
    for c in ("hv", "vh"):
        assert np.max(np.abs(complex_s(sweep, c))) < 10 ** (-40 / 20) * co


def test_oblique_plane_has_cross_pol():
    """phi = 30 deg is not a symmetry plane of the square: cross-pol must appear off normal incidence.
    Catches the phi = 30 sweep computed (or written) in the phi = 0 plane."""
    sweep = load("square_az30")["sweeps"][0]
    assert sweep["phi_deg"] == 30.0
    hv = np.asarray(sweep["sigma_hv_db"])
    theta = np.asarray(sweep["theta_deg"])
    in_plane = np.asarray(load("square")["sweeps"][0]["sigma_hv_db"])      # rounding only: about -125 dB
    assert np.max(hv[(theta > 10) & (theta < 60)]) > np.max(in_plane) + 100.0


def test_dihedral_boresight_is_near_8pi_a2b2():
    """90 deg dihedral at boresight (theta = 45 in the plane phi = 90, normal to the fold): physical
    optics' sigma = 8 pi a^2 b^2 / lambda^2, a = 3 (fold length), b = 2 (face width), 29.57 dB, is
    the large-dihedral limit: faces of 2 wavelengths lose to their edges, full wave lies 1.0 dB
    (HH) and 3.2 dB (VV, E across the rims) below it. Both within 4 dB below and 0.5 dB above, and
    HH's sweep peaks at boresight. Catches the wrong observation plane (phi = 0 looks along the
    fold: no double bounce), theta indexing off by the step, or the faces' widths swapped with the
    fold length (a 2 x 3 dihedral seen along its 3-wavelength faces)."""
    sweep = sweep_at(load("dihedral"), 90.0)
    expected = db(8 * math.pi * 3.0**2 * 2.0**2)
    for c in ("hh", "vv"):
        assert -4.0 < value_at(sweep, f"sigma_{c}_db", 45.0) - expected < 0.5
    assert sweep["theta_deg"][int(np.argmax(sweep["sigma_hh_db"]))] == 45.0


def test_dihedral_is_symmetric_about_its_bisector():
    """Mirroring through the bisector plane (y = z) swaps the two faces: sigma(theta) =
    sigma(90 - theta) in both co-polar channels, to the mesh's rounding. Catches a sweep written
    with a theta offset or faces of unequal size."""
    sweep = sweep_at(load("dihedral"), 90.0)
    for c in ("hh", "vv"):
        values = np.asarray(sweep[f"sigma_{c}_db"])
        assert np.max(np.abs(values - values[::-1])) < 0.05


def test_cube_face_on_is_4pi_area_squared():
    """The 2-wavelength cube seen along a face normal: a square plate's 4 pi A^2 / lambda^2 =
    23.03 dB, within 0.5 dB, and the same at 90 deg (the next face), both channels. Catches a cube
    of the wrong size or sweeps of another plane."""
    sweep = load("box")["sweeps"][0]
    expected = db(4 * math.pi * 4.0**2)
    for c in ("hh", "vv"):
        for theta in (0.0, 90.0):
            assert abs(value_at(sweep, f"sigma_{c}_db", theta) - expected) < 0.5


def test_dihedral_boresight_flips_one_polarisation():
    """Two reflections in a 90 deg dihedral, plane of incidence normal to the fold: a PEC face reverses the
    tangential field and keeps the normal one, so the field along the fold (h = x here) is reversed
    twice (+1, against -1 for a plate's single reflection) while the one in the plane of incidence
    comes back as from a plate: S_hh = -S_vv at boresight in phase (a plate gives S_hh = S_vv); the
    magnitudes differ by the rims' effects (1.1 dB here), less than a factor 2. Catches a receive
    basis with a flipped v (or h) between transmit and receive, which turns this ratio into +1."""
    sweep = sweep_at(load("dihedral"), 90.0)
    hh, vv = (complex_s(sweep, c)[int(np.argmin(np.abs(np.asarray(sweep["theta_deg"]) - 45)))] for c in ("hh", "vv"))
    ratio = hh / vv
    assert 0.5 < abs(ratio) < 2.0 and abs(np.angle(ratio, deg=True)) > 150


def test_plate_near_grazing_vv_exceeds_hh():
    """Square plate, phi = 0: h = -y is parallel to the leading and trailing edges, v lies in the plane of
    incidence. Near grazing (60-80 deg) the polarisation with E normal to the leading edge (VV here)
    returns far more than the one with E along it (HH), which stays near physical optics (Ross, IEEE
    TAP 14, 1966, and every moment-method result since). Catches HH and VV swapped by the writer."""
    sweep = load("square")["sweeps"][0]
    theta = np.asarray(sweep["theta_deg"])
    band = (theta >= 60) & (theta <= 80)
    hh = np.max(np.asarray(sweep["sigma_hh_db"])[band])
    vv = np.max(np.asarray(sweep["sigma_vv_db"])[band])
    assert vv > hh + 3.0


@pytest.mark.parametrize("case", CASES)
def test_convergence_recorded_and_small(case):
    """The table's mesh-convergence figure (max dB difference between two densities where sigma is within
    25 dB of the peak) is recorded and small. Catches a table written from an unconverged (too coarse)
    mesh, or a convergence figure that compares a run with itself (exactly 0)."""
    conv = load(case)["convergence_db"]
    dens = conv["densities_cells_per_lambda"]
    assert len(dens) == 2 and dens[0] != dens[1]
    worst = conv["max_abs_db_diff"]["max"]
    assert 0.0 < worst < 1.5
