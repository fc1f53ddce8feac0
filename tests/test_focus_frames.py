"""One frame for all focusers (issue 13): a world point is found at the same place by bp, ffbp,
omega-K and RDA, at broadside and squinted, at two incidence angles.

Analytic range-compressed echoes of three point targets (the scene centre, a ground target
off the slant plane, a target 3 m above the ground) in the renderer's geometry: track along
+x at altitude ``H``, looking right (toward -y), the mid-aperture antenna ``R0 tan(squint)``
behind the scene centre (0, 0, 0). The truth is written by hand from that geometry, not
with the code's own mapping:

* ground image (bp, ffbp; origin the scene centre, azimuth along +x, range along -y): a
  ground target ``(x, y, 0)`` at ``(x, -y)``; the elevated target ``(x, y, h)`` lays over
  onto the ground point at the same distance from the track, ``(x, sqrt((G - y)^2 +
  (H - h)^2 - H^2) - G)`` with ``G = H tan(incidence)``;
* slant image (omega-K, RDA): ``(x, sqrt((G - y)^2 + (H - z)^2))``, the along-track distance
  of the target's closest approach from the scene centre's, and its closest-approach range.

The bug this guards against: the FFT focusers' azimuth axis started at the mid-aperture
antenna, so a squinted target read ``R0 tan(squint)`` (514 m at 20 deg and the default
1414 m) away from backprojection's azimuth; and an image without radar metadata mapped a
world point orthogonally onto the slant axes, metres off in range for a point off the slant
plane.
"""
from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from sarmitsuba import pipeline
from sarmitsuba.analysis import synthetic
from sarmitsuba.cli import main
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.core.radar import RadarParameters
from sarmitsuba.core.geometry import acquisition_geometry

FC, BANDWIDTH, FS, PRF, SPEED, ALTITUDE, BEAMWIDTH = 9.6e9, 150e6, 180e6, 250.0, 100.0, 1000.0, 1.2
N_PULSES = 256
#: the scene centre; a ground target off the slant plane; a target 3 m above the ground
TARGETS = ((0.0, 0.0, 0.0), (8.0, -10.0, 0.0), (-8.0, 6.0, 3.0))
CASES = [(0.0, 35.0), (15.0, 55.0), (-25.0, 35.0), (25.0, 55.0)]  # (squint, incidence) deg


def acquisition(squint: float, incidence: float, radar: bool = True):
    """Range-compressed echoes of TARGETS; metadata like a render (``radar`` and scene box), or
    bare (only the generator's own keys) when ``radar`` is False."""
    params = RadarParameters(frequency=FC, bandwidth=BANDWIDTH, sampling_rate=FS, prf=PRF, velocity=SPEED,
                             altitude=ALTITUDE, incidence_angle=incidence, scene_center=(0.0, 0.0, 0.0),
                             n_pulses=N_PULSES, azimuth_beamwidth=BEAMWIDTH, beam="uniform", squint=squint)
    geo = acquisition_geometry(params)
    lengths = np.concatenate([2 * np.linalg.norm(geo.positions - np.array(t), axis=1) for t in TARGETS])
    margin = 48 / FS
    t0 = lengths.min() / C - margin
    n = int(math.ceil((lengths.max() / C + margin - t0) * FS)) + 1
    meta = {"radar": dataclasses.asdict(params),
            "scene_info": {"bbox_min": [-10.0, -12.0, 0.0], "bbox_max": [10.0, 8.0, 3.0]}} if radar else {}
    return synthetic.simulate_point_targets(
        [synthetic.PointTarget(t) for t in TARGETS], geo.positions, FC, BANDWIDTH, FS, t0, n, prf=PRF,
        velocity=geo.velocity, pulse_length=1e-6, beam=synthetic.AzimuthBeam(BEAMWIDTH, squint),
        pulse_time=geo.pulse_time, metadata=meta)


def truth(plane: str, target, incidence: float) -> tuple[float, float]:
    """(azimuth, range) [m] of ``target`` in a ground or slant image, by hand (module docstring)."""
    x, y, z = target
    ground = ALTITUDE * math.tan(math.radians(incidence))
    r0 = math.hypot(ground - y, ALTITUDE - z)
    if plane == "slant":
        return x, r0
    return x, math.sqrt(r0**2 - ALTITUDE**2) - ground


def resolution(plane: str, squint: float, incidence: float) -> tuple[float, float]:
    """(azimuth, range) resolution cells [m]: ``V / B_doppler`` of the beam, ``c / 2B`` (slant)
    or ``c / (2 B sin(incidence))`` (ground)."""
    half, s = math.radians(BEAMWIDTH / 2), math.radians(squint)
    doppler = 2 * SPEED * (math.sin(s + half) - math.sin(s - half)) / (C / FC)
    rg = C / (2 * BANDWIDTH)
    return SPEED / doppler, rg if plane == "slant" else rg / math.sin(math.radians(incidence))


def index(axis: np.ndarray, value: float) -> float:
    return (value - axis[0]) / (axis[1] - axis[0])


def brightest_near(image, row: float, col: float, half: int = 6) -> tuple[int, int]:
    r, c = int(round(row)), int(round(col))
    box = np.abs(image.data[r - half:r + half + 1, c - half:c + half + 1])
    i, j = np.unravel_index(int(np.argmax(box)), box.shape)
    return r - half + int(i), c - half + int(j)


@pytest.fixture(scope="module", params=CASES, ids=lambda c: f"squint{c[0]:+g}-inc{c[1]:g}")
def focused(request):
    squint, incidence = request.param
    raw = acquisition(squint, incidence)
    # unweighted windows: resolution() is the sinc width
    return squint, incidence, {name: pipeline.refocus(raw, name, window="rect") for name in ("bp", "ffbp", "omegak", "rda")}


def test_every_focuser_puts_each_target_at_pixel_of(focused):
    """pixel_of(world point) is the hand-computed pixel, and the response peaks there
    (brightest pixel within half a resolution cell plus half a pixel of it)."""
    squint, incidence, images = focused
    for name, image in images.items():
        assert image.plane == ("ground" if name in ("bp", "ffbp") else "slant"), name
        res_az, res_rg = resolution(image.plane, squint, incidence)
        d_az, d_rg = np.diff(image.azimuth[:2])[0], np.diff(image.range[:2])[0]
        for target in TARGETS:
            az, rg = truth(image.plane, target, incidence)
            row, col = image.pixel_of(np.array(target))
            assert row == pytest.approx(index(image.azimuth, az), abs=1e-6), (name, target)
            assert col == pytest.approx(index(image.range, rg), abs=1e-6), (name, target)
            i, j = brightest_near(image, row, col)
            assert abs(i - row) * d_az <= 0.5 * res_az + 0.5 * d_az, (name, target, i, row)
            assert abs(j - col) * d_rg <= 0.5 * res_rg + 0.5 * d_rg, (name, target, j, col)


def test_azimuth_axes_agree_between_ground_and_slant_images(focused):
    """The same target reads the same azimuth [m] in every image (0 for the scene centre): no
    R0 tan(squint) offset between backprojection and the FFT focusers."""
    _, _, images = focused
    for target in TARGETS:
        rows = {name: np.interp(im.pixel_of(np.array(target))[0], np.arange(im.azimuth.size), im.azimuth)
                for name, im in images.items()}
        assert max(rows.values()) - min(rows.values()) < 1e-6, rows
        assert rows["omegak"] == pytest.approx(target[0], abs=1e-6)


def test_analyze_cli_finds_each_target_in_every_image(focused, tmp_path, capsys):
    """``sarmitsuba analyze IMAGE --target x,y,z``: the refined peak lies within half a
    resolution cell of the hand-computed position, for bp, ffbp, omega-K and RDA images."""
    squint, incidence, images = focused
    for name, image in images.items():
        path = image.save(tmp_path / f"{name}.npz")
        res_az, res_rg = resolution(image.plane, squint, incidence)
        for target in TARGETS:
            code = main(["analyze", str(path), "--chip", "32", f"--target={','.join(map(str, target))}"])
            out, err = capsys.readouterr()
            assert code == 0 and "Traceback" not in err, (name, target, err)
            report = json.loads(out)
            az, rg = truth(image.plane, target, incidence)
            assert abs(report["azimuth"] - az) < 0.5 * res_az, (name, target, report["azimuth"], az)
            assert abs(report["range"] - rg) < 0.5 * res_rg, (name, target, report["range"], rg)


@pytest.mark.parametrize("squint", [0.0, 20.0])
def test_slant_images_without_radar_metadata(squint):
    """Bare synthetic data (no ``radar`` metadata, so no ground grid and no recorded track other
    than the focusers' own): every focuser writes a slant image on the same grid, and each
    world point is found at its closest-approach coordinates, off the slant plane included."""
    incidence = 55.0
    raw = acquisition(squint, incidence, radar=False)
    for name in ("bp", "omegak", "rda"):
        image = pipeline.refocus(raw, name, window="rect")
        assert image.plane == "slant", name
        res_az, res_rg = resolution("slant", squint, incidence)
        for target in TARGETS:
            az, rg = truth("slant", target, incidence)
            az -= image.origin[0]  # origin: the default (flat-earth, mid-swath) scene centre's closest approach
            row, col = image.pixel_of(np.array(target))
            assert row == pytest.approx(index(image.azimuth, az), abs=1e-6), (name, target)
            assert col == pytest.approx(index(image.range, rg), abs=1e-6), (name, target)
            i, j = brightest_near(image, row, col)
            assert abs(i - row) * abs(image.azimuth[1] - image.azimuth[0]) <= 0.5 * res_az + 0.25, (name, target)
            assert abs(j - col) * abs(image.range[1] - image.range[0]) <= 0.5 * res_rg + 0.42, (name, target)
