"""Distributed clutter and speckle (docs/physics.md (C)) against the material model and speckle theory.

A homogeneous rough ground of constant gamma (sigma0 = gamma cos(theta)): the mean of the
calibrated image intensity over rho_az rho_gr is sigma0 (within 0.5 dB), with rho the energy
widths of the image's unit-peak impulse response (window and antenna pattern included;
sarmitsuba.analysis.energy_widths, docs/physics.md (K2)), the intensity is
fully developed speckle (std / mean within 10 % of 1: exponential statistics, Goodman 1976),
the same seed reproduces it, another seed gives independent speckle (|coherence| < 0.1).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.analysis import energy_widths
from sarmitsuba.pipeline import simulate

SCENE = str(Path(__file__).parent / "scenes" / "rough_ground.xml")
GAMMA = 0.1                          # -10 dB in the scene file
SPACING = 0.2                        # m: ~25 scatterers per resolution cell


def _interior(sim):
    im = sim.image
    az, gr = np.meshgrid(im.azimuth, im.range, indexing="ij")
    box = (np.abs(az) < 30.0) & (np.abs(gr) < 30.0)
    return im.data[box], im.positions()[box]


@pytest.fixture(scope="module")
def seed0():
    return simulate(SCENE, integrator_overrides={"ray_spacing": SPACING, "seed": 0})


def test_mean_sigma_nought_matches_model(seed0):
    values, positions = _interior(seed0)
    antenna = seed0.raw.tx_position.mean(axis=0)
    cos_theta = (antenna[2] - positions[:, 2]) / np.linalg.norm(antenna - positions, axis=1)
    measured = np.mean(np.abs(values) ** 2) / np.prod(energy_widths(seed0.image))
    expected = np.mean(GAMMA * cos_theta)
    assert abs(10 * math.log10(measured / expected)) < 0.5, \
        f"sigma0 {10 * math.log10(measured):.2f} dB, model {10 * math.log10(expected):.2f} dB"


def test_fully_developed_speckle(seed0):
    intensity = np.abs(_interior(seed0)[0]) ** 2
    contrast = intensity.std() / intensity.mean()
    assert abs(contrast - 1.0) < 0.1, f"speckle contrast {contrast:.3f}"


def test_same_seed_reproduces_other_seed_decorrelates(seed0):
    again = simulate(SCENE, integrator_overrides={"ray_spacing": SPACING, "seed": 0})
    other = simulate(SCENE, integrator_overrides={"ray_spacing": SPACING, "seed": 7})
    a, b, c = (_interior(s)[0] for s in (seed0, again, other))
    # equal up to the order of float32 atomic additions
    assert np.abs(a - b).max() <= 1e-5 * np.abs(a).max()
    coherence = abs(np.vdot(a, c)) / (np.linalg.norm(a) * np.linalg.norm(c))
    assert coherence < 0.1, f"|coherence| between seeds {coherence:.3f}"


def test_speckle_is_coherent_across_the_aperture(seed0):
    """Fixed scatterers focus: the image's energy is in focused speckle, not spread. The mean
    intensity with the full aperture equals the model, which fails if phases were redrawn per
    pulse (the sum over pulses would then average down by the number of pulses)."""
    values, _ = _interior(seed0)
    ratio = np.mean(np.abs(values) ** 2) / (GAMMA * 0.7 * np.prod(energy_widths(seed0.image)))
    assert ratio > 0.5


def test_smooth_scene_has_no_clutter_term():
    """A scene with no rough material compiles no clutter term: its table reports none."""
    from sarmitsuba.scene import load_scene, material_table
    loaded = load_scene("dihedral")
    table = material_table(loaded.scene, loaded.params.frequency, loaded.params.polarization)
    assert not table.has_clutter
    rough = load_scene(SCENE)
    assert material_table(rough.scene, rough.params.frequency, rough.params.polarization).has_clutter


def test_material_override_makes_a_smooth_scene_rough():
    """--material-set gamma_db=-10 turns the smooth plane into the rough ground's statistics."""
    smooth = str(Path(__file__).parent / "scenes" / "plane.xml")
    sim = simulate(smooth, material_overrides={"gamma_db": -10}, integrator_overrides={"ray_spacing": SPACING})
    p = sim.loaded.params
    values, positions = _interior(sim)
    measured = np.mean(np.abs(values) ** 2) / np.prod(energy_widths(sim.image))
    assert abs(10 * math.log10(measured / (GAMMA * math.cos(math.radians(p.incidence_angle))))) < 0.7
    with pytest.raises(Exception, match="unknown material override"):
        simulate(smooth, material_overrides={"roughness": 1})


def test_sigma_nought_at_grazing_incidence():
    """At 87 deg incidence (cos 0.052, below kernel.CLUTTER_COS_MIN = 0.1) every tube's clutter
    footprint is shortened to 10 tube widths and its sigma0 raised by the same factor: the
    calibrated mean intensity is still gamma cos(theta) (within 0.5 dB). Bug caught: shortening
    without the raise (-2.8 dB), or the raise applied where the footprint is not shortened."""
    sim = simulate(SCENE, sensor_overrides={"incidence_angle": 87.0}, integrator_overrides={"seed": 0})
    values, positions = _interior(sim)
    antenna = sim.raw.tx_position.mean(axis=0)
    cos_theta = (antenna[2] - positions[:, 2]) / np.linalg.norm(antenna - positions, axis=1)
    assert cos_theta.max() < 0.1                                # the shortened regime everywhere
    measured = np.mean(np.abs(values) ** 2) / np.prod(energy_widths(sim.image))
    expected = np.mean(GAMMA * cos_theta)
    assert abs(10 * math.log10(measured / expected)) < 0.5, \
        f"sigma0 {10 * math.log10(measured):.2f} dB, model {10 * math.log10(expected):.2f} dB"
