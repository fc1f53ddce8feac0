"""Repeat-pass interferometry (sarmitsuba.stacks.interferometry, ``interferogram`` CLI) against closed forms.

Synthetic ground grids and straight tracks, no tracer: a primary track at slant range ``R`` and
incidence ``theta`` from the scene centre, flying +y with the scene at +x (right-looking), and a
secondary track shifted by ``b`` along ``e = -(cos theta, 0, sin theta)``, the unit vector normal
to the track and to the line of sight in which the look angle grows (outward and down,
sarmitsuba.scene.baseline's convention): a purely perpendicular baseline
``B_perp = b`` (Hanssen, Radar Interferometry, 2001, sections 2.4-2.5).
"""
from __future__ import annotations

import math
import re

import numpy as np
import pytest

from sarmitsuba.stacks import interferometry as ifm
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.core.image import SarImage
from sarmitsuba.core.raw import RawData

FC = 10e9
WAVELENGTH = SPEED_OF_LIGHT / FC
SLANT_RANGE = 1000.0


def ground_image(data=None, n_az=33, n_rg=65, spacing=0.5, origin=(0.0, 0.0, 0.0), plane="ground"):
    """A SarImage on a ground grid centred on ``origin``: azimuth +y, range +x (away from the sensor)."""
    if data is None:
        data = np.ones((n_az, n_rg), np.complex64)
    n_az, n_rg = data.shape
    return SarImage(data=np.asarray(data, np.complex64), azimuth=(np.arange(n_az) - n_az // 2) * spacing,
                    range=(np.arange(n_rg) - n_rg // 2) * spacing, origin=np.asarray(origin, float),
                    azimuth_direction=np.array([0.0, 1.0, 0.0]), range_direction=np.array([1.0, 0.0, 0.0]),
                    plane=plane)


def track(positions, rx_positions=None, fc=FC):
    """RawData holding only a track (the samples are never read by the geometry)."""
    n = len(positions)
    rx = positions.copy() if rx_positions is None else rx_positions
    return RawData(data=np.zeros((n, 2), np.complex64), fast_time=np.array([0.0, 1e-9]),
                   pulse_time=np.arange(n) * 1e-3, tx_position=positions, rx_position=rx,
                   velocity=np.tile([0.0, 100.0, 0.0], (n, 1)), fc=fc, bandwidth=1.5e8, chirp_rate=1.5e13,
                   pulse_length=1e-5, fs=2e8, prf=1e3)


def pair(theta_deg, b_perp, spacing=0.3, b_par=0.0):
    """(primary, secondary) RawData of straight tracks along +y over +-30 m at ``spacing``."""
    theta = math.radians(theta_deg)
    y = np.arange(-30.0, 30.0 + 1e-9, spacing)
    p1 = np.stack([np.full_like(y, -SLANT_RANGE * math.sin(theta)), y,
                   np.full_like(y, SLANT_RANGE * math.cos(theta))], axis=1)
    e = np.array([-math.cos(theta), 0.0, -math.sin(theta)])           # normal to the LOS, outward and down
    u = np.array([-math.sin(theta), 0.0, math.cos(theta)])            # toward the sensor
    return track(p1), track(p1 + b_perp * e + b_par * u)


def speckle(shape, seed):
    """Circular complex Gaussian samples of unit mean power, complex128."""
    rng = np.random.default_rng(seed)
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) / math.sqrt(2.0)


# ============================================================================ geometry
@pytest.mark.parametrize("bistatic", [False, True])
def test_closest_approach_length_is_exact_between_pulses(bistatic):
    """Pixels fall between pulses (0.5 m grid, 0.3 m pulses); catches an unrefined minimum over
    pulses (errors ~ spacing^2 / R ~ 0.1 mm... 20 um) and an ignored receiver."""
    primary, _ = pair(30, 0.0)
    if bistatic:                       # tx and rx 2 m either side along track: L = 2 sqrt(r^2 + 2^2)
        tx = primary.tx_position + [0.0, 2.0, 0.0]
        primary = track(tx, primary.tx_position - [0.0, 2.0, 0.0])
    x = ground_image().positions()
    sensor = primary.tx_position[0]
    r = np.hypot(x[..., 0] - sensor[0], x[..., 2] - sensor[2])
    exact = 2.0 * np.sqrt(r ** 2 + (4.0 if bistatic else 0.0))
    assert np.max(np.abs(ifm.closest_approach_length(x, primary) - exact)) < 1e-6


@pytest.mark.parametrize("offset", [100.0, -300.0])
def test_closest_approach_lies_many_pulses_from_the_tracks_mid_point(offset):
    """A bistatic pair whose transmitter flies ``offset`` m ahead at 1 km from the scene and whose
    receiver trails at 300 m height, as far aside: the least ``|tx - x| + |rx - x|`` lies tens of
    metres (hundreds of pulses) from the projection of the mid-point track. Against the exact
    minimum over the continuous track, found here by a bounded scalar search; catches a search
    that stops near that projection or after a step, whose parabola is then extrapolated from
    metres away (1.4e-4 m off at 100 m, 8e-3 m at 300 m, against 1e-9 m)."""
    from scipy.optimize import minimize_scalar

    def tx_at(s):
        return np.array([-700.0, s + offset, 700.0])

    def rx_at(s):
        return np.array([-700.0, s - offset, 300.0])

    y = np.arange(-400.0, 400.0 + 1e-9, 0.3)
    x = ground_image(n_az=5, n_rg=3, spacing=20.0).positions().reshape(-1, 3)
    exact = [minimize_scalar(lambda s: np.linalg.norm(tx_at(s) - p) + np.linalg.norm(rx_at(s) - p), bounds=(-400, 400),
                             method="bounded", options={"xatol": 1e-9}).fun for p in x]
    found = ifm.closest_approach_length(x, track(np.stack([tx_at(v) for v in y]), np.stack([rx_at(v) for v in y])))
    assert np.max(np.abs(found - exact)) < 1e-6


@pytest.mark.parametrize("theta_deg", [30, 60])
def test_flat_earth_fringe_rate_matches_closed_form(theta_deg):
    """d phi / d y = 4 pi B_perp cos(theta) / (lambda R) per metre of ground range, i.e.
    4 pi B_perp / (lambda R tan(theta)) per metre of slant range (Hanssen 2001, eq. 2.4.x):
    catches one-way lengths (half), a sign flip, and cos/sin swapped (30 and 60 deg differ)."""
    b = 3.0
    primary, secondary = pair(theta_deg, b)
    image = ground_image()
    phase = ifm.flat_earth_phase(image, primary, secondary)
    i, j = image.data.shape[0] // 2, image.data.shape[1] // 2
    rate = (phase[i, j + 2] - phase[i, j - 2]) / (image.range[j + 2] - image.range[j - 2])
    theta = math.radians(theta_deg)
    assert rate == pytest.approx(4 * math.pi * b * math.cos(theta) / (WAVELENGTH * SLANT_RANGE), rel=0.01)
    per_slant_metre = rate / math.sin(theta)
    assert per_slant_metre == pytest.approx(4 * math.pi * b / (WAVELENGTH * SLANT_RANGE * math.tan(theta)),
                                            rel=0.01)
    assert np.all(ifm.flat_earth_phase(image, primary, primary) == 0.0)


@pytest.mark.parametrize("theta_deg", [30, 60])
def test_height_sensitivity_matches_closed_form_and_an_elevated_point(theta_deg):
    """k_z = 4 pi B_perp / (lambda R sin(theta)) (Hanssen 2001, eq. 2.5.13), and k_z h is the
    phase of a point at height h on the centre pixel's iso-range circle, computed here from the
    two antenna distances: catches moving the point vertically instead of along the circle."""
    b = 3.0
    primary, secondary = pair(theta_deg, b)
    image = ground_image()
    k_z = ifm.height_sensitivity(image, primary, secondary)
    theta = math.radians(theta_deg)
    centre = k_z[image.data.shape[0] // 2, image.data.shape[1] // 2]
    assert centre == pytest.approx(4 * math.pi * b / (WAVELENGTH * SLANT_RANGE * math.sin(theta)), rel=0.01)
    h = 2.0
    a1, a2 = primary.tx_position[100], secondary.tx_position[100]        # both at y = 0
    up = math.acos((SLANT_RANGE * math.cos(theta) - h) / SLANT_RANGE)     # look angle to the raised point
    raised = a1 + SLANT_RANGE * np.array([math.sin(up), 0.0, -math.cos(up)])
    k = 2 * math.pi / WAVELENGTH
    phase = k * 2.0 * (np.linalg.norm(raised - a2) - np.linalg.norm(-a2))     # L1 unchanged on the circle
    assert centre * h == pytest.approx(phase, rel=0.01)
    assert np.all(np.abs(ifm.height_sensitivity(image, primary, primary)) < 1e-6)


def test_pair_baseline_splits_perpendicular_and_parallel():
    """An offset of 2 m along e and 1 m along the line of sight: B_perp 2, B_par 1, and the height
    of ambiguity lambda R sin(theta) / (2 B_perp) is 2 pi / |k_z| (k_z from the geometry)."""
    primary, secondary = pair(40, 2.0, b_par=1.0)
    image = ground_image()
    baseline = ifm.pair_baseline(image, primary, secondary)
    assert baseline.perpendicular == pytest.approx(2.0, abs=1e-9)
    assert baseline.parallel == pytest.approx(1.0, abs=1e-9)
    assert baseline.along_track == pytest.approx(0.0, abs=1e-9)
    assert baseline.slant_range == pytest.approx(SLANT_RANGE)
    k_z = ifm.height_sensitivity(image, primary, secondary)[16, 32]
    assert baseline.height_of_ambiguity == pytest.approx(2 * math.pi / abs(k_z), rel=0.01)
    assert math.isinf(ifm.pair_baseline(image, primary, primary).height_of_ambiguity)


# ============================================================================ interferogram and coherence
def test_focused_interferogram_has_no_flat_earth_fringes_until_restored():
    """Identical speckle from both passes (ground scatterers, flat earth removed by ground
    backprojection): phase 0; remove_flat_earth=False restores exp(j phi_fe)."""
    primary, secondary = pair(30, 3.0)
    s = speckle((33, 65), 1)
    a, b = ground_image(s), ground_image(s)
    assert np.max(np.abs(np.angle(ifm.interferogram(a, b)))) < 1e-6
    restored = ifm.interferogram(a, b, primary, secondary, remove_flat_earth=False)
    expected = np.abs(s) ** 2 * np.exp(1j * ifm.flat_earth_phase(a, primary, secondary))
    assert np.allclose(restored, expected, atol=1e-5)
    with pytest.raises(ValueError, match="primary_raw and secondary_raw"):
        ifm.interferogram(a, b, remove_flat_earth=False)


def test_coherence_of_identical_images_is_one_and_of_empty_ones_zero():
    s = speckle((40, 40), 2)
    gamma = ifm.coherence(ground_image(s), ground_image(s), looks=(4, 5))
    assert gamma.dtype == np.float32 and gamma.shape == (40, 40)
    assert np.all(np.abs(gamma - 1.0) < 1e-5)
    zero = ifm.coherence(np.zeros((40, 40), np.complex64), s, looks=(3, 3))
    assert np.all(zero == 0.0) and not np.any(np.isnan(zero))


def test_coherence_beside_a_bright_block_is_quiet_and_exact():
    """A bright block beside an empty region: the running-sum means of the powers round below zero
    next to it (about -1e-8 at 1e4 amplitudes); the coherence is 1 where the window holds the block,
    0 where it holds nothing, and no warning is raised (a bare sqrt gave NaN and a RuntimeWarning)."""
    import warnings
    s = np.zeros((64, 64), np.complex64)
    s[:, :20] = speckle((64, 20), 5) * 1e4
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gamma = ifm.coherence(ground_image(s), ground_image(s * np.exp(0.7j)), looks=(5, 5))
    assert np.all(np.abs(gamma[:, :18] - 1.0) < 1e-5) and np.all(gamma[:, 23:] == 0.0)


def test_coherence_of_independent_speckle_is_the_estimator_bias():
    """gamma = 0: E|gamma_hat| = Gamma(N) Gamma(3/2) / Gamma(N + 1/2) ~ sqrt(pi / (4 N)) for N
    looks (Touzi et al., IEEE TGRS 37(1), 1999); catches a missing |.| or a wrong normalisation."""
    n = 8 * 8
    gamma = ifm.coherence(speckle((256, 256), 3), speckle((256, 256), 4), looks=(8, 8))[8:-8, 8:-8]
    expected = math.exp(math.lgamma(n) + math.lgamma(1.5) - math.lgamma(n + 0.5))
    assert float(gamma.mean()) == pytest.approx(expected, rel=0.08)


@pytest.mark.parametrize("true_gamma", [0.3, 0.6, 0.9])
def test_coherence_of_partially_correlated_speckle(true_gamma):
    """I2 = gamma I1 + sqrt(1 - gamma^2) n: the estimate with 15 x 15 looks is gamma within 0.03."""
    s, noise = speckle((150, 150), 5), speckle((150, 150), 6)
    mixed = true_gamma * s + math.sqrt(1 - true_gamma ** 2) * noise
    gamma = ifm.coherence(s, mixed, looks=(15, 15))
    assert float(gamma.mean()) == pytest.approx(true_gamma, abs=0.03)


def test_multilooked_interferogram_is_the_boxcar_mean():
    """A hand-made 3 x 3 window over an interferogram that is 9 at one pixel and 0 elsewhere."""
    a = np.zeros((7, 7), np.complex64)
    a[3, 3] = 3.0
    ml = ifm.multilooked_interferogram(a, a, looks=(3, 3))
    assert np.allclose(ml[2:5, 2:5], 1.0) and np.allclose(ml[0, :], 0.0) and np.allclose(ml[:, 6], 0.0)


# ============================================================================ height
def test_height_recovers_a_wrapped_hill_and_reads_zero_on_the_ground():
    """A Gaussian hill 25 m high at a height of ambiguity of 4.3 m (about 6 fringes): the
    wrapped phase k_z h is unwrapped and referenced to the ground; catches a missing unwrap
    (errors of metres), a missing 2 pi reference, and dividing by the wrong k_z."""
    primary, secondary = pair(35, 2.0)
    image = ground_image(n_az=96, n_rg=96, spacing=0.5)
    n_az, n_rg = image.data.shape
    ii, jj = np.meshgrid(np.arange(n_az), np.arange(n_rg), indexing="ij")
    h_true = 25.0 * np.exp(-((ii - 48) ** 2 + (jj - 48) ** 2) / (2 * 14.0 ** 2))
    k_z = ifm.height_sensitivity(image, primary, secondary)
    assert 2 * math.pi / abs(k_z[48, 48]) < 5.0
    s = np.exp(2j * math.pi * np.random.default_rng(7).random((n_az, n_rg)))      # unit-amplitude speckle
    first, second = ground_image(s), ground_image(s * np.exp(-1j * k_z * h_true))
    h = ifm.height(first, second, primary, secondary, looks=(3, 3))
    assert h.dtype == np.float64 and h.shape == (n_az, n_rg)
    assert np.max(np.abs(h - h_true)) < 0.01 * 25.0
    ground = h_true < 0.05
    assert np.max(np.abs(h[ground])) < 0.01 * 25.0


def test_height_is_nan_without_baseline():
    primary, _ = pair(30, 0.0)
    s = speckle((33, 65), 8)
    assert np.all(np.isnan(ifm.height(ground_image(s), ground_image(s), primary, primary, looks=(3, 3))))


# ============================================================================ refusals
@pytest.mark.parametrize("change, word", [
    ({"origin": (0.001, 0.0, 0.0)}, "origin"),
    ({"spacing": 0.5001}, "azimuth"),
    ({"n_rg": 64}, "shape"),
    ({"plane": "slant"}, "ground"),
])
def test_check_pair_names_what_differs(change, word):
    primary = ground_image()
    with pytest.raises(ValueError, match=word):
        ifm.check_pair(primary, ground_image(**change))
    with pytest.raises(ValueError, match=word):
        ifm.check_pair(ground_image(**change), primary) if word == "ground" else ifm.coherence(
            primary, ground_image(**change))


def test_check_pair_refuses_different_carriers_and_bad_looks():
    primary, _ = pair(30, 1.0)
    other = track(primary.tx_position, fc=FC * 1.01)
    with pytest.raises(ValueError, match="carrier frequencies"):
        ifm.check_pair(ground_image(), ground_image(), primary, other)
    for looks in ((0, 3), (3, 66), (2.5, 2), "4"):
        with pytest.raises(ValueError, match="looks must be two whole numbers"):
            ifm.coherence(ground_image(), ground_image(), looks=looks)


# ============================================================================ files and CLI
def _render_dir(folder, data, raw):
    folder.mkdir()
    ground_image(data).save(folder / "image.npz")
    raw.save(folder / "raw.npz")
    return folder


def test_cli_writes_products_and_summary(tmp_path, capsys):
    from sarmitsuba.cli import main
    primary, secondary = pair(30, 2.0)
    s = speckle((33, 65), 9)
    one, two = _render_dir(tmp_path / "p", s, primary), _render_dir(tmp_path / "s", s, secondary)
    assert main(["interferogram", str(one), str(two), "--out", str(tmp_path / "insar"), "--looks", "3,5"]) == 0
    captured = capsys.readouterr()
    line = captured.out.strip()
    assert "mean coherence 1.000" in line and "B_perp 2.000 m" in line and re.search(r"looks: \d+\.\d s, ", line)
    assert "interferogram" in captured.err and "4/4" in captured.err             # the progress bar's last state
    assert main(["interferogram", str(one), str(two), "--out", str(tmp_path / "quiet"), "--no-progress"]) == 0
    assert capsys.readouterr().err == ""
    written = sorted(p.name for p in (tmp_path / "insar").iterdir())
    assert written == sorted(ifm.PRODUCT_FILES.values())
    with np.load(tmp_path / "insar" / "height.npz") as f:
        assert np.max(np.abs(f["height"])) < 1e-3 and np.array_equal(f["range"], ground_image().range)
    with np.load(tmp_path / "insar" / "coherence.npz") as f:
        assert f["coherence"].dtype == np.float32 and '"looks": [3, 5]' in str(f["metadata"])
    with np.load(tmp_path / "insar" / "interferogram.npz") as f:
        assert f["interferogram"].dtype == np.complex64 and f["multilooked"].shape == (33, 65)


@pytest.mark.parametrize("problem", ["missing", "no_raw", "damaged", "grid", "looks"])
def test_cli_bad_input_exits_2_and_writes_nothing(tmp_path, capsys, problem):
    from sarmitsuba.cli import main
    primary, secondary = pair(30, 2.0)
    s = speckle((33, 65), 10)
    one = _render_dir(tmp_path / "p", s, primary)
    two = tmp_path / "missing"
    expected = "does not exist"
    if problem == "no_raw":
        two.mkdir()
        ground_image(s).save(two / "image.npz")
        expected = "has no raw.npz"
    elif problem == "damaged":
        two = _render_dir(tmp_path / "s", s, secondary)
        (two / "image.npz").write_bytes((two / "image.npz").read_bytes()[:300])
        expected = "cannot read SarImage"
    elif problem in ("grid", "looks"):
        two = _render_dir(tmp_path / "s", s[:, :64] if problem == "grid" else s, secondary)
        expected = "differ in shape" if problem == "grid" else "looks must be"
    out = tmp_path / "insar"
    looks = ["--looks", "40,4"] if problem == "looks" else []
    argv = ["interferogram", str(one), str(two), "--out", str(out), *looks]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert expected in err and "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()


def test_cli_refuses_malformed_looks(tmp_path, capsys):
    from sarmitsuba.cli import main
    with pytest.raises(SystemExit) as exit_info:
        main(["interferogram", str(tmp_path), str(tmp_path), "--out", str(tmp_path / "o"), "--looks", "4x4"])
    assert exit_info.value.code == 2 and "expected AZ,RG" in capsys.readouterr().err


def test_unwrapped_phase_is_referenced_to_the_ground(monkeypatch):
    """unwrap_phase may return the phase offset by any multiple of 2 pi (here forced to +3 cycles):
    the ground, the commonest cycle among the coherent pixels, is brought back to 0, even where
    it is under half of them (a median reference would fail here); less coherent ground is not
    used as the reference."""
    import skimage.restoration
    unwrap = skimage.restoration.unwrap_phase
    monkeypatch.setattr(skimage.restoration, "unwrap_phase", lambda phase: unwrap(phase) + 6 * math.pi)
    jj = np.arange(80)[None, :].repeat(40, axis=0)
    phase = 15.0 * np.clip((jj - 30) / 40.0, 0.0, 1.0)             # ground (38 % of columns), slope, plateau
    assert np.median(phase) > math.pi
    gamma = np.ones(phase.shape)
    assert np.allclose(ifm.unwrapped_phase(np.exp(1j * phase), gamma), phase, atol=1e-9)
    gamma[:, :30] = 0.5
    assert not np.allclose(ifm.unwrapped_phase(np.exp(1j * phase), gamma), phase, atol=1e-9)
