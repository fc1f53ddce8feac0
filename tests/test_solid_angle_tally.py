"""The carried-power tally of ray tubes seen from orbit (:data:`sarmitsuba.tracing.deposit.fixed_point.SOLID_ANGLE`,
docs/physics.md (D7)).

A tube cast from a satellite 700 km up subtends ``a^2 cos(theta) / R^2``: 0.25 m tubes at 800 to
1300 km of slant range are 2e-14 to 1e-13 sr each, so the fixed-point quantum that sums them must
lie far below that. Truth: Python's exact rationals for the sums of the words, and the solid
angle of a plate seen from the antenna, ``A cos(theta) / R^2`` per pulse (its tubes tile it).

Deliberate bug these tests were run against: the solid angle summed with the energy tallies'
quantum ``2^-40`` (9.1e-13 sr), as ``fraction_bits=40``: every spaceborne tube rounds to 0, the
carried power of the plate reads 0.
"""
from __future__ import annotations

import math
import warnings
from fractions import Fraction

import numpy as np
import pytest

import sarmitsuba  # noqa: I001  (the variant and Dr.Jit's libLLVM before mitsuba)
import mitsuba as mi
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.planning import AcquisitionWarning
from sarmitsuba.tracing.deposit.accumulate import TALLIES
from sarmitsuba.tracing.deposit.fixed_point import SOLID_ANGLE

from test_patches import rectangle


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_spaceborne_tubes_sum_to_their_exact_total(incidence):
    """4096 tubes of 0.25 m at the slant range of a 700 km orbit at ``incidence`` (spherical-earth
    range, each tube's size jittered by up to 10 %), their float32 solid angles added on the device
    into one slot: the slot reads their exact sum within the quantum's rounding, ``N 2^-81`` sr
    (Python's rationals), and every tube alone reads itself within half a quantum, none zero."""
    earth, height, theta = 6_371_000.0, 700e3, math.radians(incidence)
    slant = math.sqrt((earth + height) ** 2 - (earth * math.sin(theta)) ** 2) - earth * math.cos(theta)
    rng = np.random.default_rng(5)
    sizes = 0.25 * (1.0 + 0.1 * rng.uniform(-1.0, 1.0, 4096))
    omega = (sizes ** 2 * math.cos(math.radians(incidence)) / slant ** 2).astype(np.float32)
    assert 1e-14 < omega.min() and omega.max() < 2e-13
    assert TALLIES["carried"] is SOLID_ANGLE
    total = SOLID_ANGLE.zeros(1)
    SOLID_ANGLE.add(total, mi.Float(omega), mi.UInt32(np.zeros(omega.size, np.uint32)), True)
    exact = sum(Fraction(float(w)) for w in omega)
    assert abs(Fraction(SOLID_ANGLE.read(total)[0]) - exact) <= omega.size * Fraction(1, 2 ** 81) + exact / 2 ** 52
    each = SOLID_ANGLE.zeros(omega.size)
    SOLID_ANGLE.add(each, mi.Float(omega), mi.UInt32(np.arange(omega.size, dtype=np.uint32)), True)
    read = SOLID_ANGLE.read(each)
    assert np.all(read > 0) and np.all(np.abs(read - omega.astype(np.float64)) <= 2.0 ** -81)


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_a_plate_seen_from_orbit_carries_its_solid_angle(incidence):
    """A 20 m square plate at the scene centre, traced with 0.25 m ray tubes (``lit_regions =
    tiles``) from a 693 km orbit over 8 pulses (tubes of 7e-14 and 3e-14 sr): the first order's
    carried power is the plate's solid angle from each pulse's antenna, ``sum_p A cos(theta_p) /
    R_p^2`` (about 5.6e-10 and 1.3e-10 sr a pulse), within 0.5 % (the tubes cut by its rims;
    measured 0.03 and 0.06 %)."""
    plate = rectangle((0.0, 0.0, 0.0), (10.0, 0.0, 0.0), (0.0, 10.0, 0.0))
    sensor = {"trajectory": "orbit", "altitude": 693e3, "incidence_angle": incidence, "n_pulses": 8,
              "beam": "uniform", "scene_center": (0.0, 0.0, 0.0)}
    integrator = {"max_depth": 1, "lit_regions": "tiles", "diffraction": False, "ray_spacing": 0.25}
    with warnings.catch_warnings():                 # the scene's 150 Hz PRF: ghosts, not the point here
        warnings.simplefilter("ignore", AcquisitionWarning)
        sim = simulate(sarmitsuba.Scene([(plate, "concrete", "plate")], sensor=sensor, integrator=integrator))
    antenna = sim.raw.tx_position
    distance = np.linalg.norm(antenna, axis=1)
    expected = float(np.sum(400.0 * antenna[:, 2] / distance / distance ** 2))     # cos(theta_p) = z_p / R_p
    carried = float(sim.trace.carried_power_per_order[0])
    assert carried == pytest.approx(expected, rel=5e-3), (carried, expected)
