"""The ray tubes' Dr.Jit kernel (``lit_regions = tiles``, the fast preview) against a second, NumPy
implementation of the same model (docs/physics.md (T1), (PO1)-(PO3), (R1)); the patches' kernel has
its own in tests/test_patch_kernel.py.

Scene: a PEC ground mirror and a PEC plate above it, tilted by 15 deg, one broadside pulse,
two bounce orders. The reference traces each tube of the planner's lattice through the two
rectangles with plain vector algebra (plane intersections, the law of reflection, shadow
segments), finds each aim cell's tile by tracing the rays through the cell's corners along the
same mirrors and differentiating them by finite differences, writes the tile's PO integral with
the textbook scalar obliquity ``(cos_i + cos_b) / 2`` per unit area (Knott, Shaeffer and Tuley,
*Radar Cross Section*, ch. 5) and :func:`sarmitsuba.tracing.integration.physical_optics.cell_terms`, and the bistatic
radar equation's spreading ``1 / (s R_rx)`` with ``s`` the unfolded length from the antenna
(image theory). Every term is kept (``cancel_interior`` off), so the two lists match one to one. The mirror
makes the plate's paths non-retro-reflecting (cos_i = 0.5, cos_b = 0.87 on the plate), so an
obliquity factor of 1, a spreading over the first leg or a wrong term all change the comparison
by far more than its 1e-4 tolerance. Each echo is received where the straight track has carried
the antenna (docs/physics.md (J3), solved in NumPy by ``trajectory.receive_time``). No term of this scene is shadowed: the shadow ray is
tested in test_tracer_core.py (a ground under a canopy).
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.scene import planning
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.tracing.integration.physical_optics import SINC_REGIME, cell_alphas, cell_terms, split_threshold
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.planning import AcquisitionWarning
from sarmitsuba.core.geometry import acquisition_geometry, trajectory_of
from sarmitsuba.core.trajectory import receive_time

TILT = math.radians(15.0)
PLATE_CENTRE = np.array([0.173, -3.512, 3.061])
PLATE_SIZE = (3.07, 2.03)
GROUND_HALF = (4.113, 4.371)

SCENE = """<scene version="3.0.0">
    <sensor type="sar">
        <float name="bandwidth" value="150e6"/>
        <float name="prf" value="{prf}"/>
        <float name="velocity" value="{velocity}"/>
        <float name="azimuth_beamwidth" value="{beam}"/>
        <string name="scene_center" value="0, 0, 0"/>
        <string name="beam" value="uniform"/>
        <integer name="n_pulses" value="{pulses}"/>
        {radar}
    </sensor>
    <integrator type="sbr">
        <integer name="max_depth" value="2"/>
        <float name="ray_spacing" value="{spacing}"/>
        <integer name="tubes_per_object" value="0"/>
        <string name="range_kernel" value="exact"/>
        <boolean name="cancel_interior" value="false"/>
        <string name="lit_regions" value="tiles"/>
        <integer name="pulses_per_trace" value="{pulses}"/>
    </integrator>
    <bsdf type="radar" id="metal"><string name="model" value="pec"/></bsdf>
    <shape type="rectangle" id="ground">
        <transform name="to_world"><scale x="{gx}" y="{gy}"/></transform>
        <ref id="metal"/>
    </shape>
    <shape type="rectangle" id="plate">
        <transform name="to_world">
            <scale x="{px}" y="{py}"/>
            <rotate x="1" angle="{angle}"/>
            <translate x="{cx}" y="{cy}" z="{cz}"/>
        </transform>
        <ref id="metal"/>
    </shape>
</scene>"""


def _rectangles(ground_half=GROUND_HALF):
    """(centre, unit normal, half-edge vectors) of the ground and the plate, as the XML places them."""
    ground = (np.zeros(3), np.array([0.0, 0.0, 1.0]),
              (np.array([ground_half[0], 0, 0]), np.array([0, ground_half[1], 0])))
    # the rectangle's normal +z, rotated about x by -(90 - 15) deg: (0, -sin a, cos a) = (0, cos 15, sin 15),
    # facing the sensor (+y) and tilted up by 15 deg
    a = -math.radians(90.0 - math.degrees(TILT))
    rot = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    plate = (PLATE_CENTRE, rot @ np.array([0.0, 0.0, 1.0]),
             (rot @ np.array([PLATE_SIZE[0] / 2, 0, 0]), rot @ np.array([0, PLATE_SIZE[1] / 2, 0])))
    return [ground, plate]


def _hit(origin, direction, rect, eps=1e-9):
    centre, n, (ha, hb) = rect
    denominator = direction @ n
    if abs(denominator) < 1e-12:
        return None
    t = ((centre - origin) @ n) / denominator
    if t <= eps:
        return None
    p = origin + t * direction
    rel = p - centre
    if abs(rel @ ha) <= ha @ ha and abs(rel @ hb) <= hb @ hb:
        return t, p
    return None


def _through_planes(antenna, point, planes):
    """The ray from ``antenna`` toward ``point``, reflected in each plane ``(centre, normal)`` of the
    list but the last and met by the last: ``(x, d, s, n)`` with ``n`` facing the ray."""
    origin, d, s = antenna, (point - antenna) / np.linalg.norm(point - antenna), 0.0
    for q, (centre, normal) in enumerate(planes):
        t = ((centre - origin) @ normal) / (d @ normal)
        origin, s = origin + t * d, s + t
        n = normal if normal @ d < 0 else -normal
        if q < len(planes) - 1:
            d = d - 2 * (d @ n) * n
    return origin, d, s, n


def _tile_point(reference, antenna, point, planes):
    """The tile's point where the ray from the sub-aperture's ``reference`` toward ``point`` meets
    the last plane after the mirrors, and how the pulse at ``antenna`` reaches it (image theory:
    the point reflected back through the mirrors, last first, lies straight ahead of the antenna):
    ``(x, d, s, n)``, ``d`` the arriving direction and ``s`` the unfolded length."""
    x, _, _, n = _through_planes(reference, point, planes)
    image = x
    for centre, normal in reversed(planes[:-1]):
        image = image - 2 * ((image - centre) @ normal) * normal
    s = float(np.linalg.norm(image - antenna))
    d = (image - antenna) / s
    for _, normal in planes[:-1]:
        d = d - 2 * (d @ normal) * normal
    return x, d, s, n


def _split(alphas: np.ndarray, split_at: float) -> np.ndarray:
    """docs/physics.md (T3): per edge, from ``alpha`` at the reference, first and last pulse
    (rows): True (split), False (sinc) or None (each pulse decides)."""
    low, high = np.abs(alphas).min(axis=0), np.abs(alphas).max(axis=0)
    same = np.all(alphas * alphas[:1] > 0, axis=0)
    return [False if h < split_at else (True if (lo >= SINC_REGIME and ok) else None)
            for lo, h, ok in zip(low, high, same)]


def _reference_terms(sim, radiometry: bool, ground_half=GROUND_HALF):
    """Every term of every pulse, from the planner's lattice, traced in NumPy (docs/physics.md (T3)):
    each sub-aperture's tubes are traced from its reference position (the midpoint of its first
    and last antenna), which decides their facets and visibility and puts each aim cell's tile
    on them (the rays from the reference through the cell, after the same mirrors); each pulse
    then takes the tile's terms with its own lengths and directions (:func:`cell_terms`)."""
    p, settings = sim.loaded.params, sim.loaded.settings
    geometry = acquisition_geometry(p)
    track = trajectory_of(p)            # each echo received where the track has carried the antenna (J3)
    fp = planning.ray_footprint(p, geometry, sim.loaded.bbox_lo, sim.loaded.bbox_hi, settings)
    k = 2 * math.pi * p.frequency / SPEED_OF_LIGHT
    t0, fs = float(sim.raw.fast_time[0]), sim.raw.fs
    rects = _rectangles(ground_half)
    lo_sine, hi_sine = p.beam_sines
    cell = (fp.track * fp.spacing_azimuth, fp.look * fp.spacing_range)
    split_at = split_threshold(p.bandwidth, p.frequency)
    size = settings.pulses_per_trace
    positions, values, orders, pulses = [], [], [], []
    for first in range(0, geometry.positions.shape[0], size):
        group = np.arange(first, min(first + size, geometry.positions.shape[0]))
        antennas = geometry.positions[group]
        reference = 0.5 * (antennas[0] + antennas[-1])
        lrefs = 2 * np.linalg.norm(antennas - geometry.scene_center, axis=1)
        limits = (fp.along_limits[group, 0].min(), fp.along_limits[group, 1].max())
        for i in range(fp.k0[group].min(), fp.k0[group].max() + fp.n_azimuth):
            along = (i + 0.5) * fp.spacing_azimuth
            if not limits[0] <= along <= limits[1]:
                continue
            for j in range(fp.n_range):
                aim = fp.origin + along * fp.track + (fp.range_min + (j + 0.5) * fp.spacing_range) * fp.look
                sines = [((aim - a) @ fp.track) / np.linalg.norm(aim - a) for a in antennas[[0, -1]]]
                if max(sines) < lo_sine or min(sines) > hi_sine:
                    continue                                     # no pulse of the sub-aperture casts it
                d = (aim - reference) / np.linalg.norm(aim - reference)
                origin, gamma, planes = reference, 1.0 + 0j, []
                for depth in range(2):
                    hits = [(h, q) for q, rect in enumerate(rects) if (h := _hit(origin, d, rect)) is not None]
                    if not hits:
                        break
                    (t, point), q = min(hits, key=lambda x: x[0][0])
                    planes.append((rects[q][0], rects[q][1]))
                    n = rects[q][1] if rects[q][1] @ d < 0 else -rects[q][1]
                    gamma *= -1.0                                            # PEC
                    b = (reference - point) / np.linalg.norm(reference - point)
                    shadowed = any(_hit(point, b, rects[o]) is not None for o in range(2) if o != q)
                    if n @ b > 0 and not shadowed:
                        path = (lambda x, a, planes=tuple(planes): _tile_point(reference, a, x, planes))
                        ends = (reference, antennas[0], antennas[-1])
                        split = _split(np.array([cell_alphas(k, a, aim, cell, lambda x, a=a: path(x, a))
                                                 for a in ends]), split_at)
                        for antenna, lref, pulse, t_tx in zip(antennas, lrefs, group, geometry.pulse_time[group]):
                            sine = ((aim - antenna) @ fp.track) / np.linalg.norm(aim - antenna)
                            if not lo_sine <= sine <= hi_sine:
                                continue                         # uniform beam: cut per pulse at the aim
                            # VV (the default): a k-bounce chain in the plane of the look takes (-1)^(k+1) (P6)
                            def density(cos_i, cos_b, d_x, b_x, s_x, length, gamma=gamma * (-1) ** depth, lref=lref):
                                value = 1j * 2 * math.sqrt(math.pi) / p.wavelength * (cos_i + cos_b) / 2 * gamma
                                if radiometry:                               # bistatic radar equation
                                    value *= (0.5 * lref) ** 2 / (s_x * (length - s_x))
                                return value
                            mine = lambda x, antenna=antenna: path(x, antenna)      # noqa: E731
                            own = [bool(abs(a) >= split_at) if s_ is None else s_
                                   for s_, a in zip(split, cell_alphas(k, antenna, aim, cell, mine))]
                            receiver = (lambda x, s, t_tx=t_tx: receive_time(track, t_tx, x, first_leg=s)[1])  # noqa: E731
                            lengths, coefficients, order = cell_terms(k, antenna, aim, cell, mine, density, split=own,
                                                                      receiver=receiver)
                            positions.extend((lengths - SPEED_OF_LIGHT * t0) * fs / SPEED_OF_LIGHT)
                            values.extend(coefficients * np.exp(-1j * k * (lengths - lref)))
                            orders.extend([order] * len(coefficients))
                            pulses.extend([pulse] * len(coefficients))
                    d = d - 2 * (d @ n) * n
                    origin = point
    return np.array(positions), np.array(values), np.array(orders), np.array(pulses)


def _spectrum(positions, values, orders, fs, fc):
    """sum v (1 + f / fc)^m exp(-j 2 pi f x / fs) at baseband frequencies across the band."""
    f = np.linspace(-75e6, 75e6, 21)[:, None]
    return np.sum(values * (1 + f / fc) ** orders * np.exp(-2j * math.pi * f * positions / fs), axis=1)


@pytest.mark.parametrize("radiometry,pulses,prf,beam,spacing,velocity", [
    (False, 1, 250.0, 1.0, 0.2, 100.0), (True, 1, 250.0, 1.0, 0.2, 100.0), (False, 6, 250.0, 1.0, 0.2, 100.0),
    (False, 6, 50.0, 3.0, 1.0, 100.0), (False, 3, 17500.0, 1.0, 0.2, 7000.0)],
    ids=["normalised", "absolute", "sub-aperture of 6 pulses", "splits decided per pulse", "fast platform"])
def test_kernel_terms_equal_the_numpy_reference(tmp_path: Path, radiometry, pulses, prf, beam, spacing, velocity):
    """One pulse: the kernel's terms are the reference's. Six pulses in one sub-aperture (2.4 m of
    track; the plate is traced once): every pulse's terms are the reference's for that pulse's
    own antenna (lengths and phase gradients) on the tiles, facets and visibility of the
    reference position; tiles projected from each pulse's own antenna instead fail it (the plate
    stands 3 m above the aim plane). With 0.5 m tubes, a 3 deg beam, a 72 m long mirror and 12 m of track, the
    edges' phase half-width sweeps through the split threshold within the sub-aperture: those
    edges are split or not pulse by pulse (docs/physics.md (T3)). At 7 km/s the antenna moves 6.6 cm
    during an echo: a kernel receiving at the transmit position (stop-and-hop), or moving the
    antenna the wrong way, is 8 rad off the reference there (docs/physics.md (J3))."""
    radar = ('<float name="transmit_power" value="100"/><float name="antenna_gain_db" value="30"/>'
             if radiometry else "")
    a, b, c = PLATE_SIZE[0] / 2, PLATE_SIZE[1] / 2, PLATE_CENTRE
    xml = tmp_path / "mirror_plate.xml"
    ground = GROUND_HALF if beam == 1.0 else (36.0, GROUND_HALF[1])   # reaching 2.5 deg off broadside
    xml.write_text(SCENE.format(radar=radar, gx=ground[0], gy=ground[1], px=a, py=b,
                                angle=-(90.0 - math.degrees(TILT)), cx=c[0], cy=c[1], cz=c[2], pulses=pulses,
                                prf=prf, beam=beam, spacing=spacing, velocity=velocity))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AcquisitionWarning)          # 3 deg at 50 Hz: azimuth ambiguities
        sim = simulate(str(xml), window="rect")
    paths = sim.trace.paths
    assert set(np.unique(paths.order)) == {1, 2} and set(np.unique(paths.pulse)) == set(range(pulses))
    ref = _reference_terms(sim, radiometry, ground)
    assert len(ref[0]) == len(paths.position)                           # the same tubes and terms
    fs, fc = sim.raw.fs, sim.raw.fc
    for pulse in range(pulses):
        mine, theirs = paths.pulse == pulse, ref[3] == pulse
        kernel = _spectrum(paths.position[mine], paths.value[mine].astype(complex), paths.spectral[mine], fs, fc)
        reference = _spectrum(ref[0][theirs], ref[1][theirs], ref[2][theirs], fs, fc)
        assert np.abs(kernel - reference).max() < 1e-4 * np.abs(reference).max(), \
            (pulse, np.abs(kernel - reference).max() / np.abs(reference).max())
    # the plate's non-retro-reflecting returns are a real part of it (obliquity 1.37 there)
    assert np.abs(reference).max() > 0
