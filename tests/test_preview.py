"""Optical preview: written, right size, not blank, fast; overlays land where Mitsuba renders."""
from __future__ import annotations

import math
import time

import matplotlib.image
import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (variant and plugins)
from sarmitsuba.products import groundtruth, preview
from sarmitsuba.scene.loader import load_scene


@pytest.fixture(scope="module")
def urban():
    return load_scene("urban")


def test_preview_written_with_size_and_content(urban, tmp_path):
    start = time.perf_counter()
    path = preview.render_preview(urban, tmp_path / "preview.png")
    seconds = time.perf_counter() - start
    assert path == tmp_path / "preview.png" and path.is_file()
    assert not any(p.name.endswith(".partial") for p in tmp_path.iterdir())
    pixels = matplotlib.image.imread(path)
    assert pixels.shape[:2] == (720, 960)
    grey = pixels[..., :3].mean(axis=2)
    assert grey.std() > 0.05, "blank preview"
    assert seconds < 20.0, f"preview took {seconds:.1f} s"
    # the overlays are drawn: the imaged area (lime green) and the beam (dark orange) are visible
    lime = (np.abs(pixels[..., 0] - 0.196) < 0.08) & (pixels[..., 1] > 0.7) & (pixels[..., 2] < 0.3)
    orange = (pixels[..., 0] > 0.9) & (np.abs(pixels[..., 1] - 0.55) < 0.1) & (pixels[..., 2] < 0.15)
    assert lime.sum() > 200 and orange.sum() > 200, (lime.sum(), orange.sum())


def test_custom_resolution_and_spp(urban, tmp_path):
    path = preview.render_preview(urban, tmp_path / "small.png", spp=4, resolution=(640, 400))
    assert matplotlib.image.imread(path).shape[:2] == (400, 640)
    with pytest.raises(ValueError, match="resolution"):
        preview.render_preview(urban, tmp_path / "bad.png", resolution=(100, 50))
    with pytest.raises(ValueError, match="spp"):
        preview.render_preview(urban, tmp_path / "bad.png", spp=0)


def test_geometry_drawn_matches_the_radar_parameters(urban):
    """Footprint, swath, track and imaged area against the parameters (closed forms)."""
    p = urban.params
    geo = preview.preview_geometry(urban)
    assert geo.track.shape == (p.n_pulses, 3)
    assert math.isclose(np.linalg.norm(geo.track[-1] - geo.track[0]), (p.n_pulses - 1) * p.velocity / p.prf)
    assert np.allclose(geo.antenna, [0.0, p.ground_range, p.altitude])        # heading 0, looking right
    near = np.array([0.0, 120.0, 0.0])                                         # near swath edge y = +120
    r_near = np.linalg.norm(near - geo.antenna)
    width = 2 * r_near * math.tan(math.radians(p.azimuth_beamwidth) / 2)
    assert math.isclose(np.linalg.norm(geo.beam_footprint[1] - geo.beam_footprint[0]), width, rel_tol=1e-9)
    assert np.allclose(geo.beam_footprint[:, 1], [120, 120, -120, -120])       # swath = bbox extent
    assert np.all(geo.beam_footprint[:, 2] == 0.0)
    assert geo.swept_footprint[1, 0] - geo.swept_footprint[0, 0] > (p.n_pulses - 1) * p.velocity / p.prf
    lo, hi = geo.imaged_area.min(axis=0), geo.imaged_area.max(axis=0)
    assert np.all(lo[:2] <= urban.bbox_lo[:2]) and np.all(hi[:2] >= urban.bbox_hi[:2])


def test_spotlight_patch_stays_on_the_scene_centre(tmp_path):
    """Spotlight: the beam is steered at the scene centre, so the illuminated patch is the beam
    footprint there, whatever the track length."""
    loaded = load_scene("urban", sensor_overrides={"mode": "spotlight"})
    geo = preview.preview_geometry(loaded)
    assert geo.mode == "spotlight"
    assert np.allclose(geo.swept_footprint, geo.beam_footprint)
    assert np.allclose(geo.beam_footprint[:, 0].mean(), 0.0)
    path = preview.render_preview(loaded, tmp_path / "spot.png", spp=2, resolution=(400, 300))
    assert matplotlib.image.imread(path).shape[:2] == (300, 400)


def test_projection_is_mitsubas(urban):
    """A projected point lies on the camera ray Mitsuba shoots through that pixel."""
    import mitsuba as mi
    geo = preview.preview_geometry(urban)
    points = np.vstack([geo.bbox_corners, geo.antenna[None], geo.beam_footprint])
    camera = preview._camera(np.zeros(3), np.array([-0.6, 0.5, 0.6]), points, (480, 664), 40.0, 4)
    uv, depth = camera.project(points)
    assert np.all(depth > 0) and np.all((uv >= 0) & (uv <= [480, 664]))
    rays, _ = camera.sensor.sample_ray(0.0, 0.5, mi.Point2f(uv[:, 0] / 480, uv[:, 1] / 664), mi.Point2f(0.5, 0.5))
    o = np.stack([np.array(rays.o.x), np.array(rays.o.y), np.array(rays.o.z)], axis=1)
    d = np.stack([np.array(rays.d.x), np.array(rays.d.y), np.array(rays.d.z)], axis=1)
    rel = points - o
    miss = np.linalg.norm(rel - (rel * d).sum(axis=1, keepdims=True) * d, axis=1)
    assert np.all(miss < 1e-5 * np.linalg.norm(rel, axis=1) + 1e-3), miss


def test_clip_keeps_what_lies_in_front():
    points = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    depth = np.array([-1.0, 1.0, 3.0])
    parts = preview._clip_polygon(points, depth, 0.0, closed=False)
    assert len(parts) == 1 and np.allclose(parts[0], [[0.5, 0, 0], [1, 0, 0], [2, 0, 0]])
    square = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    clipped, = preview._clip_polygon(square, square[:, 0] - 0.5, 0.0, closed=True)
    assert np.allclose(sorted(map(tuple, clipped)), [(0.5, 0, 0), (0.5, 1, 0), (1, 0, 0), (1, 1, 0)])


def test_preview_leaves_the_loaded_scene_usable(tmp_path):
    """Rendering builds its own Mitsuba scene: ray casts on the loaded scene are unchanged. Exact:
    the masks are ray casts and integer counts, no float sums, so the same casts give the same bits
    (no need of docs/physics.md (D7)) and any difference is the bug."""
    from test_groundtruth import grid_image
    loaded = load_scene("dihedral")
    image = grid_image(loaded)
    before = groundtruth.ground_truth(loaded, image)
    preview.render_preview(loaded, tmp_path / "p.png", spp=2, resolution=(400, 300))
    after = groundtruth.ground_truth(loaded, image)
    for name in ("layover", "shadow", "footprint", "double_bounce"):
        assert np.array_equal(getattr(before, name), getattr(after, name)), name


def test_cli_refuses_a_preview_too_small_for_its_panels_before_loading(tmp_path, capsys):
    """preview --resolution below 200x150 (two panels and the header) is a usage error, exit 2 and
    one line, not a ValueError traceback after loading the scene; 200x150 itself parses."""
    from sarmitsuba.cli import build_parser, main
    with pytest.raises(SystemExit) as exc:
        main(["preview", "trihedral", "--resolution", "199x150", "--out", str(tmp_path / "p")])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "at least 200x150" in err and "Traceback" not in err
    assert not (tmp_path / "p").exists()
    assert build_parser().parse_args(["preview", "--resolution", "200x150"]).resolution == (200, 150)
