"""The Dr.Jit kernel against a second, NumPy implementation of the same model (docs/physics.md (T1), (PO1)-(PO3), (R1)).

Scene: a PEC ground mirror and a PEC plate above it, tilted by 15 deg, one broadside pulse,
two bounce orders. The reference traces each tube of the planner's lattice through the two
rectangles with plain vector algebra (plane intersections, the law of reflection, shadow
segments), writes each footprint's PO integral with the textbook scalar obliquity
``(cos_i + cos_b) / 2`` per unit area (Knott, Shaeffer and Tuley, *Radar Cross Section*, ch. 5)
and :func:`sarmitsuba.physical_optics.tube_terms`, and the bistatic radar equation's spreading
``1 / (s R_rx)`` with ``s`` the unfolded length from the antenna (image theory). The mirror
makes the plate's paths non-retro-reflecting (cos_i = 0.5, cos_b = 0.87 on the plate), so an
obliquity factor of 1, a spreading over the first leg or a wrong term all change the comparison
by far more than its 1e-4 tolerance. No term of this scene is shadowed: the shadow ray is
tested in test_tracer_core.py (a ground under a canopy).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba import planning
from sarmitsuba.constants import SPEED_OF_LIGHT
from sarmitsuba.physical_optics import point_sources, tube_terms
from sarmitsuba.pipeline import simulate
from sarmitsuba.radar import acquisition_geometry

TILT = math.radians(15.0)
PLATE_CENTRE = np.array([0.173, -3.512, 3.061])
PLATE_SIZE = (3.07, 2.03)
GROUND_HALF = (4.113, 4.371)

SCENE = """<scene version="3.0.0">
    <sensor type="sar">
        <float name="bandwidth" value="150e6"/>
        <float name="prf" value="250"/>
        <string name="scene_center" value="0, 0, 0"/>
        <string name="beam" value="uniform"/>
        <integer name="n_pulses" value="1"/>
        {radar}
    </sensor>
    <integrator type="sbr">
        <integer name="max_depth" value="2"/>
        <float name="ray_spacing" value="0.2"/>
        <integer name="tubes_per_object" value="0"/>
        <string name="range_kernel" value="exact"/>
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


def _rectangles():
    """(centre, unit normal, half-edge vectors) of the ground and the plate, as the XML places them."""
    ground = (np.zeros(3), np.array([0.0, 0.0, 1.0]),
              (np.array([GROUND_HALF[0], 0, 0]), np.array([0, GROUND_HALF[1], 0])))
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


def _reference_terms(sim, radiometry: bool):
    """Every term of the pulse, from the planner's lattice, traced in NumPy."""
    p = sim.loaded.params
    geometry = acquisition_geometry(p)
    fp = planning.ray_footprint(p, geometry, sim.loaded.bbox_lo, sim.loaded.bbox_hi, sim.loaded.settings)
    antenna = geometry.positions[0]
    lref = 2 * np.linalg.norm(antenna - geometry.scene_center)
    k = 2 * math.pi * p.frequency / SPEED_OF_LIGHT
    t0, fs = float(sim.raw.fast_time[0]), sim.raw.fs
    rects = _rectangles()
    lo_sine, hi_sine = p.beam_sines
    positions, values, orders = [], [], []
    for ii in range(fp.n_azimuth):
        i = fp.k0[0] + ii
        along = (i + 0.5) * fp.spacing_azimuth
        if not fp.along_limits[0, 0] <= along <= fp.along_limits[0, 1]:
            continue
        for j in range(fp.n_range):
            aim = fp.origin + along * fp.track + (fp.range_min + (j + 0.5) * fp.spacing_range) * fp.look
            r = np.linalg.norm(aim - antenna)
            d = (aim - antenna) / r
            if not lo_sine <= d @ fp.track <= hi_sine:
                continue
            t1 = fp.track * fp.spacing_azimuth / r
            t2 = fp.look * fp.spacing_range / r
            t1, t2 = t1 - d * (d @ t1), t2 - d * (d @ t2)
            origin, s, gamma = antenna, 0.0, 1.0 + 0j
            for depth in range(2):
                hits = [(h, q) for q, rect in enumerate(rects) if (h := _hit(origin, d, rect)) is not None]
                if not hits:
                    break
                (t, point), q = min(hits, key=lambda x: x[0][0])
                s += t
                n = rects[q][1] if rects[q][1] @ d < 0 else -rects[q][1]
                gamma *= -1.0                                                # PEC
                to_ant = antenna - point
                dist = np.linalg.norm(to_ant)
                b = to_ant / dist
                cos_i, cos_b = -(n @ d), n @ b
                shadowed = any(_hit(point, b, rects[o]) is not None for o in range(2) if o != q)
                if cos_b > 0 and not shadowed:
                    def density(cos_i, cos_b, d_x, b_x, s_x, length, gamma=gamma):
                        value = 1j * 2 * math.sqrt(math.pi) / p.wavelength * (cos_i + cos_b) / 2 * gamma
                        if radiometry:                                   # bistatic radar equation
                            value *= (0.5 * lref) ** 2 / (s_x * (length - s_x))
                        return value
                    source = point - d * s                               # the tube's image source
                    lengths, coefficients, order = tube_terms(k, point, n, t1, t2, point_sources(source, antenna),
                                                              density)
                    positions.extend((lengths - SPEED_OF_LIGHT * t0) * fs / SPEED_OF_LIGHT)
                    values.extend(coefficients * np.exp(-1j * k * (lengths - lref)))
                    orders.extend([order] * len(coefficients))
                d = d - 2 * (d @ n) * n
                t1, t2 = t1 - 2 * (t1 @ n) * n, t2 - 2 * (t2 @ n) * n
                origin = point
    return np.array(positions), np.array(values), np.array(orders)


def _spectrum(positions, values, orders, fs, fc):
    """sum v (1 + f / fc)^m exp(-j 2 pi f x / fs) at baseband frequencies across the band."""
    f = np.linspace(-75e6, 75e6, 21)[:, None]
    return np.sum(values * (1 + f / fc) ** orders * np.exp(-2j * math.pi * f * positions / fs), axis=1)


@pytest.mark.parametrize("radiometry", [False, True], ids=["normalised", "absolute"])
def test_kernel_terms_equal_the_numpy_reference(tmp_path: Path, radiometry):
    radar = ('<float name="transmit_power" value="100"/><float name="antenna_gain_db" value="30"/>'
             if radiometry else "")
    a, b, c = PLATE_SIZE[0] / 2, PLATE_SIZE[1] / 2, PLATE_CENTRE
    xml = tmp_path / "mirror_plate.xml"
    xml.write_text(SCENE.format(radar=radar, gx=GROUND_HALF[0], gy=GROUND_HALF[1], px=a, py=b,
                                angle=-(90.0 - math.degrees(TILT)), cx=c[0], cy=c[1], cz=c[2]))
    sim = simulate(str(xml), window="rect")
    paths = sim.trace.paths
    assert set(np.unique(paths.order)) == {1, 2} and np.all(paths.pulse == 0)
    ref = _reference_terms(sim, radiometry)
    assert len(ref[0]) == len(paths.position)                           # the same tubes and terms
    fs, fc = sim.raw.fs, sim.raw.fc
    kernel = _spectrum(paths.position, paths.value.astype(complex), paths.spectral, fs, fc)
    reference = _spectrum(*ref, fs, fc)
    assert np.abs(kernel - reference).max() < 1e-4 * np.abs(reference).max(), \
        np.abs(kernel - reference).max() / np.abs(reference).max()
    # the plate's non-retro-reflecting returns are a real part of it (obliquity 1.37 there)
    assert np.abs(reference).max() > 0
