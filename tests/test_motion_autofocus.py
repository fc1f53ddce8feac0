"""Motion errors, the nominal track and phase gradient autofocus on a ray-traced trihedral
(issue 30 acceptance; docs/physics.md (J4), (PGA), (PGA2)).

The default airborne X-band sensor flies a 2 cm sinusoidal cross-track deviation of period 40 m
(a 69 m aperture: the phase error ``2 k e sin(theta)`` swings by 5.7 rad over 1.7 periods). Focused
on the true track the trihedral is a clean point response; on the nominal track its azimuth
response breaks up into paired echoes; PGA, given only that image, restores it: azimuth PSLR within
2 dB and IRW within 10 % of the true track's.
"""
from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.raw import RawData
from sarmitsuba.focus import ImageGrid, ffbp
from sarmitsuba.focus.autofocus import pga
from sarmitsuba.pipeline import simulate

MOTION = "0.02, 40"


@pytest.fixture(scope="module")
def images():
    sim = simulate("trihedral", sensor_overrides={"motion_error": MOTION}, focuser="ffbp", image_size=(32, 32))
    frame = sim.image
    n = 256                                                    # 0.1 m pixels: 25.6 m of azimuth
    grid = ImageGrid(origin=frame.origin, azimuth_direction=frame.azimuth_direction,
                     range_direction=frame.range_direction, azimuth=(np.arange(n) - n // 2) * 0.1,
                     range=(np.arange(64) - 32) * 0.2, plane="ground")
    true = ffbp(sim.raw, grid)
    nominal = ffbp(sim.raw.on_track("nominal"), grid)
    with warnings.catch_warnings():
        warnings.simplefilter("error")                           # PGA's assumptions hold here: no warning
        fixed, report = pga(nominal)
    return {"raw": sim.raw, "true": true, "nominal": nominal, "pga": fixed, "report": report}


def _measure(image):
    return analyze_point_target(image, (0.0, 0.0, 0.0), chip=32, search_radius=16)


def test_the_true_track_deviates_by_the_motion_error(images):
    raw: RawData = images["raw"]
    deviation = raw.tx_position - raw.nominal_tx_position
    assert np.max(np.abs(deviation[:, 2])) < 1e-9                        # horizontal
    assert np.max(np.linalg.norm(deviation, axis=1)) == pytest.approx(0.02, rel=1e-3)


def test_the_nominal_track_visibly_degrades_the_azimuth_response(images):
    true, nominal = _measure(images["true"]), _measure(images["nominal"])
    assert nominal.pslr_azimuth_db > true.pslr_azimuth_db + 20.0, (nominal.pslr_azimuth_db, true.pslr_azimuth_db)


def test_pga_restores_the_true_track_response(images):
    true, fixed = _measure(images["true"]), _measure(images["pga"])
    assert abs(fixed.pslr_azimuth_db - true.pslr_azimuth_db) < 2.0, (fixed.pslr_azimuth_db, true.pslr_azimuth_db)
    assert abs(fixed.irw_azimuth / true.irw_azimuth - 1.0) < 0.10, (fixed.irw_azimuth, true.irw_azimuth)
    report = images["report"]
    assert report.deramp and report.converged and report.rms_phase_error > 1.0        # rad: a real error removed
    assert images["pga"].metadata["autofocus"]["method"] == "pga"


def test_the_cli_focuses_on_the_nominal_track_with_pga(images, tmp_path):
    raw_path = images["raw"].save(tmp_path / "raw.npz")
    out = tmp_path / "focused"
    result = subprocess.run([sys.executable, "-m", "sarmitsuba", "focus", str(raw_path), "--algorithm", "ffbp",
                             "--track", "nominal", "--autofocus", "pga", "--pga-reference", "0,0,0", "--out", str(out),
                             "--no-progress"], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "nominal track" in result.stdout and "PGA" in result.stdout, result.stdout
    from sarmitsuba.core.image import SarImage
    linear = SarImage.load(out / "image.npz").metadata["autofocus"]["linear_part"]
    assert linear["estimated"] and linear["reference"] == [0.0, 0.0, 0.0], linear
    bad = subprocess.run([sys.executable, "-m", "sarmitsuba", "focus", str(raw_path), "--autofocus", "pga",
                          "--pga-reference", "0,0", "--out", str(tmp_path / "bad"), "--no-progress"],
                         capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "--pga-reference" in bad.stderr and "X,Y,Z" in bad.stderr, bad.stderr
    assert "Traceback" not in bad.stderr
    alone = subprocess.run([sys.executable, "-m", "sarmitsuba", "focus", str(raw_path), "--pga-reference", "0,0,0",
                            "--out", str(tmp_path / "alone"), "--no-progress"], capture_output=True, text=True, timeout=300)
    assert alone.returncode == 2 and "--autofocus pga" in alone.stderr, alone.stderr      # not silently ignored
    assert "Traceback" not in alone.stderr and not (tmp_path / "alone").exists()
