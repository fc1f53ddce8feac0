"""The tracer core at its defaults (issue 11): physical optics, clutter, planner and beam, end to end.

Each test compares the rendered image with a closed form or a physical invariant:

* a smooth plane returns nothing from its interior (PO: no backscatter off specular), at any ray
  spacing;
* rough ground has sigma0 = gamma cos(theta) in every ground-range bin, with no periodic structure;
* canonical targets at the default spacing read their closed-form RCS (aperture-averaged where
  their pattern is narrower than the beam) and agree with a dense render;
* the tapered default beam leaves no azimuth streak beyond a wall's double-bounce line;
* clutter scatterers belong to the surface: a patch 40 m up focuses like the same patch on the
  ground, two shapes have independent speckle, a seed reproduces it;
* the planner reaches elevated geometry at the scene's edges.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.analysis import point_target as analysis
from sarmitsuba.scene import canonical as C
from sarmitsuba.focus import windows
from sarmitsuba.pipeline import simulate

WAVELENGTH = 299_792_458.0 / 9.6e9
SENSOR = """<sensor type="sar">
        <float name="bandwidth" value="150e6"/>
        <float name="sampling_rate" value="180e6"/>
        <float name="prf" value="250"/>
        <string name="scene_center" value="0, 0, 0"/>
        {extra}
    </sensor>"""


def _scene(tmp_path: Path, body: str, name: str = "scene", depth: int = 1, sensor: str = "",
           integrator: str = "") -> str:
    path = tmp_path / f"{name}.xml"
    path.write_text(f"""<scene version="3.0.0">
    {SENSOR.format(extra=sensor)}
    <integrator type="sbr"><integer name="max_depth" value="{depth}"/>{integrator}</integrator>
    {body}
</scene>""")
    return str(path)


def _rectangle(half_x: float, half_y: float, material: str, centre=(0.0, 0.0, 0.0), rotate: str = "",
               name: str | None = None) -> str:
    ident = f' id="{name}"' if name else ""
    return (f'<shape type="rectangle"{ident}><transform name="to_world"><scale x="{half_x}" y="{half_y}"/>{rotate}'
            f'<translate x="{centre[0]}" y="{centre[1]}" z="{centre[2]}"/></transform><ref id="{material}"/></shape>')


def _sigma0(sim) -> np.ndarray:
    """Calibrated intensity over the weighted impulse response's energy cell (docs/physics.md (K2))."""
    return np.abs(sim.image.data.astype(np.complex128)) ** 2 / float(np.prod(analysis.energy_widths(sim.image)))


def _db(x) -> float:
    return 10.0 * math.log10(x)


# ---------------------------------------------------------------------------------------------
# A smooth plane is dark
# ---------------------------------------------------------------------------------------------

PLATE_MATERIALS = {"metal": '<string name="model" value="pec"/>',
                   "concrete": '<string name="material" value="concrete"/>'}


@pytest.mark.parametrize("material", list(PLATE_MATERIALS))
def test_smooth_plane_interior_is_dark_at_every_ray_spacing(tmp_path, material):
    """A smooth 40 m plate at 45 deg: PO returns nothing from its interior (the phase gradient
    2 k sin(theta) is far outside the band; only the edges return). The old carrier-only tube
    deposit lit it up with -9 dB stripes of constant range.

    * In the default (Taylor) image the interior, more than 8 cells from the edges, is below
      -40 dB at the default spacing and at 0.5, 0.2, 0.1 and 0.05 m (measured -50 to -66 dB):
      what is there is the edges' sidelobes, whose near/far interference moves by a few dB with
      where the lattice puts the edges (within half a tube).
    * Imaged with a -70 dB sidelobe window, which keeps the edges' sidelobes out, the interior's
      own return is below -65 dB at every spacing (measured -75 dB at the default and 0.5 m,
      -86 to -107 dB at 0.2 m and below): nothing of it depends on the ray density above that."""
    body = f'<bsdf type="radar" id="m">{PLATE_MATERIALS[material]}</bsdf>' + _rectangle(20, 20, "m")
    xml = _scene(tmp_path, body, sensor='<integer name="n_pulses" value="48"/>')
    for spacing in (0.0, 0.5, 0.2, 0.1, 0.05):
        for window, limit in (("taylor", -40.0), (("kaiser", {"beta": 9.0}), -65.0)):
            sim = simulate(xml, integrator_overrides={"ray_spacing": spacing}, window=window)
            az, gr = np.meshgrid(sim.image.azimuth, sim.image.range, indexing="ij")
            inside = (np.abs(az) < 4.0) & (np.abs(gr) < 8.0)
            level = _db(_sigma0(sim)[inside].mean())
            assert level < limit, (spacing, window, level)


# ---------------------------------------------------------------------------------------------
# Rough ground: sigma0 in every ground-range bin, no stripes
# ---------------------------------------------------------------------------------------------

def test_rough_ground_sigma0_in_every_range_bin_without_stripes(tmp_path):
    """160 m of concrete, gamma -14 dB, at 35 deg incidence: in 5 m ground-range bins averaged
    over azimuth (20 m clear of the edges), sigma0 is gamma cos(theta) (theta from the
    mid-aperture antenna to each pixel) within 0.3 dB rms, and the bins' deviations hold no
    periodic structure (the largest
    periodogram ordinate below 8x their mean: white deviations exceed it with probability
    ~1e-3). The old tube deposit striped this ground with a 62 m period, +2 dB."""
    body = ('<bsdf type="radar" id="ground"><string name="material" value="concrete"/>'
            '<float name="gamma_db" value="-14"/></bsdf>' + _rectangle(80, 80, "ground"))
    sim = simulate(_scene(tmp_path, body, sensor='<float name="incidence_angle" value="35"/>'))
    im = sim.image
    antenna = sim.raw.tx_position[sim.raw.n_pulses // 2]
    positions = im.positions()
    cos_theta = (antenna[2] - positions[..., 2]) / np.linalg.norm(antenna - positions, axis=-1)
    intensity = np.abs(im.data.astype(np.complex128)) ** 2
    model = 10 ** -1.4 * cos_theta
    az, gr = np.meshgrid(im.azimuth, im.range, indexing="ij")
    deviations = []
    for g0 in np.arange(-60.0, 60.0, 5.0):                   # 20 m clear of the ground's edges
        cell = (np.abs(az) < 60.0) & (gr >= g0) & (gr < g0 + 5.0)
        # the energy cell at the bin's own incidence (rho_gr = c / (2 B sin(theta)) varies across the swath)
        widths = analysis.energy_widths(im, positions[cell][len(positions[cell]) // 2])
        deviations.append(_db(intensity[cell].mean() / float(np.prod(widths)) / model[cell].mean()))
    deviations = np.array(deviations)
    assert math.sqrt(np.mean(deviations**2)) < 0.3, np.round(deviations, 2)
    spectrum = np.abs(np.fft.rfft(deviations - deviations.mean()))[1:] ** 2
    assert spectrum.max() < 8.0 * spectrum.mean(), np.round(spectrum / spectrum.mean(), 1)


def test_lambertian_sigma0_is_absolute(tmp_path):
    """Sionna's itu-radio-material with scattering coefficient S: sigma0 = 4 S^2 |r|^2 cos^2(theta)
    (Lambert's law, docs/physics.md (C)), |r| the slab's coefficient from sarmitsuba.scene.materials at
    each pixel's incidence: the mean calibrated intensity within 0.5 dB."""
    from sarmitsuba.scene import materials
    s = 0.6
    body = (f'<bsdf type="itu-radio-material" id="ground"><string name="type" value="concrete"/>'
            f'<float name="thickness" value="0.2"/><float name="scattering_coefficient" value="{s}"/></bsdf>'
            + _rectangle(30, 30, "ground"))
    sim = simulate(_scene(tmp_path, body, sensor='<float name="incidence_angle" value="30"/>'))
    im = sim.image
    antenna = sim.raw.tx_position[sim.raw.n_pulses // 2]
    az, gr = np.meshgrid(im.azimuth, im.range, indexing="ij")
    inside = (np.abs(az) < 20.0) & (np.abs(gr) < 20.0)
    positions = im.positions()[inside]
    cos_theta = (antenna[2] - positions[:, 2]) / np.linalg.norm(antenna - positions, axis=1)
    slab = materials.Material("concrete", materials.itu_permittivity("concrete", 9.6e9), "slab", 0.2)
    r = np.abs(np.array([complex(materials.reflection_coefficient(slab, c, 9.6e9, "VV")) for c in cos_theta]))
    expected = np.mean(4 * s**2 * r**2 * cos_theta**2)
    measured = _sigma0(sim)[inside].mean()
    assert abs(_db(measured / expected)) < 0.5, (_db(measured), _db(expected))


# ---------------------------------------------------------------------------------------------
# Canonical targets at the default ray spacing
# ---------------------------------------------------------------------------------------------

def _aperture_averaged(sigma: float, length: float, sim) -> float:
    """The closed form averaged over the aperture as the image weights it: sum over the traced
    beam's sines s of (w g^2)^2 sinc^2(2 L s / lambda) / sum (w g^2)^2 (w the azimuth window,
    g^2 the two-way pattern, L the target's length along track; docs/physics.md (K2))."""
    p = sim.loaded.params
    lo, hi = p.beam_sines
    s = np.linspace(lo, hi, 4001)
    spec = sim.image.metadata["focus"]["window_azimuth"]
    name = spec["name"] if isinstance(spec, dict) else spec
    params = {k: v for k, v in spec.items() if k != "name"} if isinstance(spec, dict) else {}
    w = windows.spectral_window(name, s - 0.5 * (lo + hi), hi - lo, **params)
    g2 = np.sinc(p.pattern_length / p.wavelength * s) ** 2
    weight = (w * g2) ** 2
    return sigma * float(np.sum(weight * np.sinc(2 * length / p.wavelength * s) ** 2) / np.sum(weight))


CANONICAL = {
    "plate 1 m": (lambda: C.plate(1.0), 1, C.rcs_plate(1.0, WAVELENGTH), 1.0, 0.5),
    "dihedral 1 m": (lambda: C.dihedral(1.0, 1.0), 2, C.rcs_dihedral(1.0, 1.0, WAVELENGTH), 1.0, 0.5),
    "trihedral 1 m": (lambda: C.trihedral(1.0), 3, C.rcs_trihedral(1.0, WAVELENGTH), 0.0, 0.5),
    "trihedral 0.3 m": (lambda: C.trihedral(0.3), 3, C.rcs_trihedral(0.3, WAVELENGTH), 0.0, 1.0),
}


@pytest.mark.parametrize("name", list(CANONICAL))
def test_canonical_targets_at_the_default_ray_spacing(tmp_path, name):
    """Plate, dihedral and trihedral at the DEFAULT spacing (one tube per resolution cell, finer
    tubes planned around small objects): RCS within 0.5 dB of the closed form (1 dB for the
    0.3 m trihedral) and of a 0.02 m render. The plate's and dihedral's 1 m along track make
    their pattern narrower than the beam: their closed form is averaged over the aperture."""
    make, depth, sigma, length, tolerance = CANONICAL[name]
    xml = str(C.scene_xml(tmp_path, make(), C.PEC, depth))
    default = simulate(xml)
    dense = simulate(xml, integrator_overrides={"ray_spacing": 0.02, "tubes_per_object": 0})
    expected = _aperture_averaged(sigma, length, default) if length else sigma
    rcs_default, rcs_dense = analysis.integrated_rcs(default.image), analysis.integrated_rcs(dense.image)
    assert abs(_db(rcs_default / expected)) < tolerance, (_db(rcs_default), _db(expected))
    assert abs(_db(rcs_default / rcs_dense)) < tolerance, (_db(rcs_default), _db(rcs_dense))


def test_refinement_around_a_small_object_is_what_makes_it_right(tmp_path):
    """Positive control for the tube preview (``lit_regions = tiles``): without the planned
    refinement (``tubes_per_object = 0``) a 0.3 m trihedral at the default spacing (0.7 m tubes)
    is far off or missed. (The default patches need no refinement: test_patches.)"""
    xml = str(C.scene_xml(tmp_path, C.trihedral(0.3), C.PEC, 3))
    coarse = simulate(xml, integrator_overrides={"tubes_per_object": 0, "lit_regions": "tiles"})
    expected = C.rcs_trihedral(0.3, WAVELENGTH)
    rcs = analysis.integrated_rcs(coarse.image)
    assert rcs <= 0 or abs(_db(rcs / expected)) > 2.0


def test_only_objects_smaller_than_eight_tubes_are_refined(tmp_path):
    """Planner rule (T2): a box whose diagonal is 7.5 default tubes is traced with
    ``ceil(48 / 7.5) = 7`` times finer tubes over the cells it covers; one of 8.5 tubes (a
    building, at scale) keeps the default lattice. Bugs caught: refining every shape smaller
    than ``tubes_per_object`` tubes (48: Munich's buildings, 17x the tubes), or none, or sizing
    objects in tubes of an explicit ``ray_spacing`` (a 0.5 m trihedral at 0.1 m spacing: -1.3 dB)."""
    import dataclasses

    from sarmitsuba.scene import planning
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.scene.loader import load_scene
    loaded = load_scene(str(C.scene_xml(tmp_path, C.trihedral(1.0), C.PEC, 3)))
    p, settings = loaded.params, loaded.settings
    geometry = acquisition_geometry(p)
    lo, hi = np.array([-20.0, -20.0, 0.0]), np.array([20.0, 20.0, 5.0])
    plain = planning.ray_footprint(p, geometry, lo, hi, settings)
    tube = max(plain.spacing_azimuth, plain.spacing_range * math.cos(math.radians(p.incidence_angle)))

    def planned(tubes):
        half = tubes * tube / (2.0 * math.sqrt(3.0))            # a cube of that diagonal at the centre
        box = np.array([[[-half, -half, 0.0], [half, half, 2.0 * half]]])
        return planning.ray_footprint(p, geometry, lo, hi, settings, shape_boxes=box).refinements

    small, large = planned(7.5), planned(8.5)
    assert [r.factor for r in small] == [7] and len(small[0].cells) > 0
    assert large == ()
    # the size class is in resolution cells whatever the spacing: at 0.1 m tubes a 0.87 m box
    # (8.7 tubes, 1.1 cells) still gets ceil(48 x 0.1 / 0.87) = 6 x 6 tubes per cell
    fine = dataclasses.replace(settings, ray_spacing=0.1)
    box = np.array([[[-0.25, -0.25, 0.0], [0.25, 0.25, 0.5]]])      # diagonal 0.866 m
    refined = planning.ray_footprint(p, geometry, lo, hi, fine, shape_boxes=box).refinements
    assert [r.factor for r in refined] == [6]


def test_points_the_antenna_cannot_see_return_nothing(tmp_path):
    """Shadowed target (the shadow ray, eq. (PO1)). A smooth metal canopy 5 m above rough
    metal ground, y from -1 to 12 m, with the sensor on +y at 45 deg. Rays that pass under its
    near edge hit the ground at y = 7..15 m, rise to the canopy's underside and come down on
    the ground again at y = -3..5 m. From there the line to the antenna climbs through the
    canopy (it crosses z = 5 m at y = 2..10 m), so the third bounce returns nothing. The first
    bounce, on the ground in the open, does return. Bug caught: no shadow ray, or one that
    starts on the wrong side of the surface."""
    body = ('<bsdf type="radar" id="rough"><string name="model" value="pec"/><float name="gamma_db" value="-10"/></bsdf>'
            '<bsdf type="radar" id="metal"><string name="model" value="pec"/></bsdf>'
            + _rectangle(20.0, 12.5, "rough", centre=(0.0, 2.5, 0.0), name="ground")
            + _rectangle(25.0, 6.5, "metal", centre=(0.0, 5.5, 5.0), name="canopy"))
    sim = simulate(_scene(tmp_path, body, name="canopy", depth=3, sensor='<integer name="n_pulses" value="32"/>'))
    t = sim.trace
    assert t.rays_per_order[2] > 0 and t.scatterers_per_order[0] > 0     # the paths exist; open ground returns
    assert t.scatterers_per_order[2] == 0, t.scatterers_per_order
    assert t.energy_per_order[2] <= 1e-6 * t.energy_per_order[0], t.energy_per_order


# ---------------------------------------------------------------------------------------------
# The default beam has no hard edge
# ---------------------------------------------------------------------------------------------

def _wall_line(tmp_path, sensor: str, window: str):
    body = ('<bsdf type="radar" id="metal"><string name="model" value="pec"/></bsdf>'
            + _rectangle(50, 50, "metal")
            + _rectangle(10, 5, "metal", centre=(0, 0, 5), rotate='<rotate x="1" angle="90"/>'))
    sim = simulate(_scene(tmp_path, body, name=f"wall_{window}", depth=2, sensor=sensor), window=window)
    col = int(np.argmin(np.abs(sim.image.range)))
    line = np.abs(sim.image.data[:, col - 1:col + 2]).max(axis=1) ** 2
    az = sim.image.azimuth
    within = line[np.abs(az) < 8.0].mean()
    beyond = line[(np.abs(az) > 25.0) & (np.abs(az) < 50.0)]
    return _db(beyond.max() / within)


def test_wall_double_bounce_leaves_no_streak_beyond_its_ends(tmp_path):
    """A 20 m metal wall on metal ground (max_depth 2): the double-bounce line's intensity
    15-40 m beyond the wall's ends stays 40 dB below the line itself with the tapered default
    beam and Taylor image. Positive control: a hard-edged uniform beam with rect weighting
    streaks there well above that level."""
    assert _wall_line(tmp_path, "", "taylor") < -40.0
    assert _wall_line(tmp_path, '<string name="beam" value="uniform"/>', "rect") > -40.0


# ---------------------------------------------------------------------------------------------
# Speckle attached to the surface
# ---------------------------------------------------------------------------------------------

def _single_scatterer_sim(tmp_path, incidence: float, height: float, sensor: str = ""):
    """A 2 m Lambertian metal patch with a 2 m scatterer lattice anchored at its corner: exactly
    one scatterer, of RCS ``sigma0 c^2 = 4 |r|^2 cos^2(theta) c^2`` (docs/physics.md (C); Sionna's
    scattering coefficient 1, so no specular part; |r| = 1 within 1e-4 for the ITU metal). The
    patch sits ``height`` up on the line of sight from the mid-aperture antenna to the scene
    centre (the default track looks along -y: the antenna is on +y), so every height sees it at
    the same incidence angle. Returns the simulation and the patch centre."""
    centre = (0.0, height * math.tan(math.radians(incidence)), height)
    body = ('<bsdf type="itu-radio-material" id="rough"><string name="type" value="metal"/>'
            '<float name="scattering_coefficient" value="1"/></bsdf>' + _rectangle(1.0, 1.0, "rough", centre=centre))
    sensor = f'<float name="incidence_angle" value="{incidence}"/>' + sensor
    sim = simulate(_scene(tmp_path, body, name=f"patch{incidence:g}_{height:g}", sensor=sensor),
                   integrator_overrides={"scatterer_spacing": 2.0})
    assert np.abs(sim.image.data).max() > 0, "the patch got no rays"
    return sim, centre


def _single_scatterer(tmp_path, incidence: float, height: float):
    sim, centre = _single_scatterer_sim(tmp_path, incidence, height)
    expected = 4.0 * math.cos(math.radians(incidence)) ** 2 * 2.0 ** 2
    return (sim.image, analysis.analyze_point_target(sim.image, centre),
            analysis.integrated_rcs(sim.image, center=centre), expected)


@pytest.mark.parametrize("incidence", [35.0, 60.0])
def test_one_scatterer_has_its_closed_form_rcs_on_the_ground_and_high_up(tmp_path, incidence):
    """One clutter scatterer, on the ground and 40 m up, at 35 and 60 deg: both get rays (the
    old planner left elevated geometry empty), focus with the Taylor image's sidelobes (azimuth
    PSLR < -30 dB; the old clutter hash slid with the ray and defocused it 40 m up), and
    analyze's integrated RCS equals the closed form ``4 cos^2(theta) c^2`` within 0.25 dB (an
    amplitude, obliquity, spreading or energy-width error at any angle but 45 deg shows here).
    The elevated one appears where the zero-Doppler circle through the ground one's world
    position, raised with the patch, meets the image plane (within 1/10 resolution cell): the
    scatterer is attached to the patch, and the focuser's layover (G2) puts it there."""
    height = 40.0
    (ground_image, ground, rcs_ground, expected), (high_image, high, rcs_high, _) = (
        _single_scatterer(tmp_path, incidence, h) for h in (0.0, height))
    for target, rcs in ((ground, rcs_ground), (high, rcs_high)):
        assert abs(_db(rcs / expected)) < 0.25, (rcs, expected)
        assert target.pslr_azimuth_db < -30.0
    # the scatterer's world position, from where the ground image shows it, raised with the patch
    on_ground = (np.asarray(ground_image.origin) + ground.azimuth * np.asarray(ground_image.azimuth_direction)
                 + ground.range * np.asarray(ground_image.range_direction))
    raised = on_ground + np.array([0.0, height * math.tan(math.radians(incidence)), height])
    az, rg = analysis.layover_position(high_image, raised)
    assert abs(high.azimuth - az) < 0.1 * high.energy_width_azimuth, (high.azimuth, az)
    assert abs(high.range - rg) < 0.1 * high.energy_width_range, (high.range, rg)


@pytest.mark.parametrize("squint", [-6.0, 9.0])
def test_squinted_beam_points_where_the_squint_says(tmp_path, squint):
    """Stripmap squint (the antenna turned about the vertical, its pattern (A) peaking at
    ``sin(phi_az) = sin(squint)``): one scatterer's echo energy over the pulses is centred on
    the pulse whose along-track sine toward it is ``sin(squint)`` (energy-weighted mean sine
    within 0.002; the beam's 3 dB half-width is 0.0087), and peaks as high as at broadside
    (within 1 dB). A pattern turned the wrong way or left at broadside gets the beam's
    sidelobes or nothing."""
    def energy(angle):
        sim, centre = _single_scatterer_sim(tmp_path, 40.0, 0.0, f'<float name="squint" value="{angle}"/>')
        per_pulse = np.sum(np.abs(sim.trace.spectrum) ** 2, axis=1)
        to_target = np.asarray(centre) - sim.raw.tx_position
        sines = (to_target @ np.array([1.0, 0.0, 0.0])) / np.linalg.norm(to_target, axis=1)
        return per_pulse, sines
    broadside, _ = energy(0.0)
    per_pulse, sines = energy(squint)
    centroid = float(np.sum(per_pulse * sines) / np.sum(per_pulse))
    assert abs(centroid - math.sin(math.radians(squint))) < 0.002, (centroid, math.sin(math.radians(squint)))
    assert abs(_db(per_pulse.max() / broadside.max())) < 1.0


def test_specular_part_of_a_lambertian_surface_keeps_sqrt_1_minus_s2_per_bounce(tmp_path):
    """Sionna's Lambertian surface with scattering coefficient S reflects the field specularly
    with ``sqrt(1 - S^2)`` (docs/physics.md (C)): a metal dihedral's double bounce, S = 0.6 against
    S = 0, loses ``(1 - S^2)^2`` in RCS (-3.9 dB; 1 - S^2 per bounce in field would give -7.8 dB,
    a factor on the last bounce only -1.9 dB). The clutter the rough facets add is 40 dB below."""
    def dihedral_rcs(scattering: float) -> float:
        folder = tmp_path / f"s{scattering:g}"
        folder.mkdir()
        C.dihedral(1.0, 1.0).export(folder / "dihedral.ply")
        xml = folder / "dihedral.xml"
        xml.write_text(f"""<scene version="3.0.0">
    {C.SENSOR}
    <integrator type="sbr"><integer name="max_depth" value="2"/></integrator>
    <bsdf type="itu-radio-material" id="mat"><string name="type" value="metal"/>
        <float name="scattering_coefficient" value="{scattering}"/></bsdf>
    <shape type="ply"><string name="filename" value="dihedral.ply"/>
        <boolean name="face_normals" value="true"/><ref id="mat"/></shape>
</scene>""")
        return analysis.integrated_rcs(simulate(str(xml)).image)
    s = 0.6
    assert abs(_db(dihedral_rcs(s) / dihedral_rcs(0.0)) - _db((1.0 - s * s) ** 2)) < 0.2


@pytest.mark.parametrize("names", [("left", "right"), (None, None)], ids=["named", "id-less"])
def test_two_shapes_have_independent_speckle_and_a_seed_reproduces_it(tmp_path, names):
    """Two identical rough plates side by side (their own scatterer lattices, the same local
    coordinates), with ids or without (the hash then keys on their place in the file): their
    speckle chips are uncorrelated (|coherence| < 0.2); the same seed gives the same image,
    another seed independent speckle. Relies on the bit-for-bit guarantee (docs/physics.md (D7)):
    the two renders with the default seed differ only in repetition, so any difference is the bug."""
    body = ('<bsdf type="radar" id="rough"><string name="material" value="concrete"/>'
            '<float name="gamma_db" value="-10"/></bsdf>'
            + _rectangle(8, 8, "rough", centre=(-12, 0, 0), name=names[0])
            + _rectangle(8, 8, "rough", centre=(12, 0, 0), name=names[1]))
    xml = _scene(tmp_path, body)
    sim = simulate(xml, window="rect")
    im = sim.image

    def chip(centre):
        rows = np.flatnonzero(np.abs(im.azimuth - centre) < 5.0)
        cols = np.flatnonzero(np.abs(im.range) < 5.0)
        return im.data[np.ix_(rows, cols)].ravel()

    left, right = chip(-12.0), chip(12.0)
    n = min(left.size, right.size)
    coherence = abs(np.vdot(left[:n], right[:n])) / (np.linalg.norm(left[:n]) * np.linalg.norm(right[:n]))
    assert coherence < 0.2, coherence
    if names[0] is None:
        return
    again = simulate(xml, window="rect")
    assert np.array_equal(again.image.data, im.data)
    other = simulate(xml, window="rect", integrator_overrides={"seed": 9})
    a, b = im.data.ravel(), other.image.data.ravel()
    assert abs(np.vdot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)) < 0.2


# ---------------------------------------------------------------------------------------------
# The planner reaches everything in view
# ---------------------------------------------------------------------------------------------

def test_roof_at_the_far_edge_gets_all_its_scatterers(tmp_path):
    """A rough 20 m x 20 m roof 100 m up at the far edge of the scene, seen from 1 km at 45 deg:
    while the beam covers it, each pulse finds every scatterer of its lattice on it, area / c^2
    within 3 % (jittered one per cell). The old planner widened the aim grid by h (G + a) / H
    instead of h (G + a) / (H - h) and left 9 m of this roof without rays."""
    c = 0.5
    body = ('<bsdf type="radar" id="smooth"><string name="model" value="pec"/></bsdf>'
            '<bsdf type="radar" id="rough"><string name="material" value="concrete"/>'
            '<float name="gamma_db" value="-10"/></bsdf>'
            + _rectangle(40, 40, "smooth") + _rectangle(10, 10, "rough", centre=(0, -30, 100)))
    xml = _scene(tmp_path, body, sensor='<float name="azimuth_beamwidth" value="3"/><integer name="n_pulses" value="1"/>',
                 integrator=f'<float name="scatterer_spacing" value="{c}"/>')
    sim = simulate(xml)
    found = int(sim.trace.scatterers_per_order[0])
    assert abs(found / (400.0 / c**2) - 1.0) < 0.03, found
