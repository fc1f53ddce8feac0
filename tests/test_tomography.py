"""Tomography's closed forms without rendering: the stack's baselines (TS1), the elevation
response (TS3), Capon's peak (TS4), peak detection, and the planning errors."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (libLLVM, variant)
from sarmitsuba.stacks.tomography import beamforming, capon, detect_peaks, elevation_psf
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.scene.baseline import baseline, perpendicular_direction, stack_baselines
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.stack import plan_stack


@pytest.fixture(scope="module", params=[30.0, 55.0])
def loaded(request):
    return load_scene("trihedral", {"incidence_angle": request.param})


def test_perpendicular_direction_is_normal_to_track_and_line_of_sight(loaded):
    """At incidence theta, flying +x and looking right (toward -y) from y > 0: the line of sight
    from the scene is u = (0, sin, cos) and e, where the look angle grows, is (0, cos, -sin)."""
    theta = math.radians(loaded.params.incidence_angle)
    e = perpendicular_direction(loaded.params)
    assert e == pytest.approx([0.0, math.cos(theta), -math.sin(theta)], abs=1e-6)
    b = baseline(dataclasses.replace(loaded.params, track_offset=tuple(2.5 * e)))
    assert b.perpendicular == pytest.approx(2.5, rel=1e-6) and abs(b.parallel) < 1e-6


def test_stack_resolution_and_ambiguity_are_the_closed_forms(loaded):
    p = loaded.params
    theta = math.radians(p.incidence_angle)
    r = p.altitude / math.cos(theta)                     # flat earth: R = H / cos(theta)
    plan = stack_baselines(p, span=12.0, count=7)
    assert plan.perpendicular == pytest.approx(np.linspace(-6, 6, 7), abs=1e-5)
    assert plan.reference == 3 and plan.mean_spacing == pytest.approx(2.0, rel=1e-6)
    assert plan.elevation_resolution == pytest.approx(p.wavelength * r / 24.0, rel=1e-5)
    assert plan.elevation_ambiguity == pytest.approx(p.wavelength * r / 4.0, rel=1e-5)
    assert plan.height_range() == pytest.approx(p.wavelength * r / 4.0 * math.sin(theta), rel=1e-5)


def test_random_baselines_keep_the_span_and_repeat_with_their_seed(loaded):
    a = stack_baselines(loaded.params, span=10.0, count=9, spacing="random", seed=4)
    b = stack_baselines(loaded.params, span=10.0, count=9, spacing="random", seed=4)
    c = stack_baselines(loaded.params, span=10.0, count=9, spacing="random", seed=5)
    assert np.array_equal(a.perpendicular, b.perpendicular) and not np.allclose(a.perpendicular, c.perpendicular)
    assert a.perpendicular[0] == pytest.approx(-5.0, abs=1e-5) and a.perpendicular[-1] == pytest.approx(5.0, abs=1e-5)
    assert np.all(np.diff(a.perpendicular) > 0)
    assert not np.allclose(np.diff(a.perpendicular), 1.25)


def test_baselines_and_track_offsets_describe_the_same_stack(loaded):
    e = perpendicular_direction(loaded.params)
    from_list = stack_baselines(loaded.params, baselines=[-3.0, 0.0, 1.0, 4.0])
    from_offsets = stack_baselines(loaded.params, track_offsets=[b * e + np.array([5.0, 0, 0]) for b in (-3, 0, 1, 4)])
    assert from_offsets.perpendicular == pytest.approx(from_list.perpendicular, abs=1e-5)   # along track: no baseline
    assert from_list.reference == 1                     # nearest the middle of the span, 0.5 m


@pytest.mark.parametrize("kwargs, words", [
    (dict(span=5.0, count=2), "at least 3 passes"),
    (dict(baselines=[0.0, 1.0]), "at least 3 passes"),
    (dict(baselines=[0.0, 1.0, 1.0]), "share a perpendicular baseline"),
    (dict(baselines=[0.0, 1.0], span=3.0, count=3), "exactly one"),
    (dict(span=float("nan"), count=4), "finite span"),
    (dict(track_offsets=[[0, 0], [1, 1]]), "dx,dy,dz"),
    (dict(span=4.0, count=4, spacing="log"), "spacing"),
])
def test_bad_stack_descriptions_name_the_fix(loaded, kwargs, words):
    with pytest.raises(ParameterError, match=words):
        stack_baselines(loaded.params, **kwargs)


def test_baselines_that_alias_the_scene_are_refused_with_the_spacing_that_would_do(loaded):
    p = loaded.params
    r = p.altitude / math.cos(math.radians(p.incidence_angle))
    height = float(loaded.bbox_hi[2] - p.scene_center[2])
    extent = height / math.sin(math.radians(p.incidence_angle))
    largest = p.wavelength * r / (2 * extent)
    plan_stack(loaded, span=0.9 * largest * 4, count=5)              # spacing 0.9 of the largest: fine
    with pytest.raises(ParameterError, match=f"at most {largest:.3f} m apart"):
        plan_stack(loaded, span=1.1 * largest * 4, count=5)


def test_elevation_psf_of_even_baselines_is_the_dirichlet_kernel():
    n, d, lam, r = 9, 0.8, 0.031, 1200.0
    s = np.linspace(-20, 20, 1001)
    x = 2 * math.pi * d * s / (lam * r)
    with np.errstate(invalid="ignore", divide="ignore"):
        dirichlet = np.where(np.abs(np.sin(x)) > 1e-12, np.sin(n * x) / (n * np.sin(x)), 1.0) ** 2
    psf = elevation_psf(d * (np.arange(n) - 4), lam, r, s)
    assert psf == pytest.approx(dirichlet, abs=1e-9)


def _fourier_steering(b: np.ndarray, s: np.ndarray, lam: float = 0.031, r: float = 1200.0) -> np.ndarray:
    return np.exp(-1j * 4 * math.pi * np.outer(b, s) / (lam * r))[None]


def test_beamforming_and_capon_peak_at_a_lone_scatterers_power():
    b = np.linspace(-5, 5, 11)
    s = np.linspace(-10, 10, 401)
    a = _fourier_steering(b, s)
    gamma = 0.7 * np.exp(0.4j)
    y = gamma * a[0][:, 200]
    bf = beamforming(y[None], a)[0]
    assert bf[200] == pytest.approx(abs(gamma) ** 2, rel=1e-12) and np.argmax(bf) == 200
    cov = np.outer(y, np.conj(y))[None]
    loading = 0.01
    cp = capon(cov, a, loading)[0]
    delta = loading * abs(gamma) ** 2                   # tr(R) / N = |gamma|^2
    assert cp[200] == pytest.approx(abs(gamma) ** 2 + delta / len(b), rel=1e-9) and np.argmax(cp) == 200


def test_detect_peaks_refines_between_samples_and_keeps_the_strongest():
    s = np.arange(0, 20, 0.5)
    centres, powers = (4.3, 11.1, 16.0), (1.0, 0.5, 0.05)
    db = np.max([10 * math.log10(p) - 3 * (s - c) ** 2 for c, p in zip(centres, powers)], axis=0)
    elev, power = detect_peaks(10 ** (db[None] / 10), s, threshold_db=-10.0, max_scatterers=3)
    assert elev[0, :2] == pytest.approx([4.3, 11.1], abs=1e-9)          # a parabola in dB is refined exactly
    assert np.isnan(elev[0, 2])                                         # 13 dB down: below the threshold
    elev, _ = detect_peaks(10 ** (db[None] / 10), s, threshold_db=-20.0, max_scatterers=1)
    assert elev[0, 0] == pytest.approx(4.3, abs=1e-9) and np.all(np.isnan(elev[0, 1:]))


def test_sl1mmer_keeps_one_scatterer_for_one_scatterer_in_noise():
    """The information criterion's penalty: a lone scatterer at -10 dB SNR, 20 noise draws. With
    it, order 1 in 17 of 20 cells; without it (every candidate kept) 7 of 20."""
    from sarmitsuba.stacks.tomo_sparse import sl1mmer
    from sarmitsuba.stacks.tomography import PhaseModel
    n, lam, r, cells = 12, 0.031, 1200.0, 20
    b = np.linspace(-6, 6, n)
    slope = 4 * math.pi * b / (lam * r)
    phase = np.stack([np.zeros(n), slope, np.zeros(n), np.zeros(n)], axis=1)[:, :, None]
    model = PhaseModel(phase=np.repeat(phase, cells, axis=2), height=np.repeat([[0.0], [1.0], [0.0], [0.0]], cells, 1),
                       scale=1.0, interval=(-10.0, 10.0), fit_error=0.0)
    rng = np.random.default_rng(1)
    y = np.array([np.exp(-1j * slope * 2.0) + 0.3 * (rng.normal(size=n) + 1j * rng.normal(size=n)) / math.sqrt(2)
                  for _ in range(cells)])
    found = sl1mmer(y, model, np.linspace(-10, 10, 161))
    assert np.sum(found.orders == 1) >= 15
    ones = found.orders == 1
    assert np.median(np.abs(found.elevations[ones, 0] - 2.0)) < 0.2


def test_the_phase_model_holds_the_wavefront_curvature(loaded):
    """Against the test's own two-way distances to each pass's straight track line, at elevations
    up to 60 m: the linear (Fourier) form is off by 0.04 to 0.15 rad there, the model by milliradians."""
    import types
    from sarmitsuba.core.geometry import acquisition_geometry
    from sarmitsuba.core.image import SarImage
    from sarmitsuba.stacks.tomography import elevation_points, phase_model
    p = loaded.params
    plan = stack_baselines(p, span=20.0, count=5)
    raws = []
    for o in plan.track_offsets:
        g = acquisition_geometry(dataclasses.replace(p, track_offset=tuple(o)))
        raws.append(types.SimpleNamespace(tx_position=g.positions, rx_position=g.positions, fc=p.frequency))
    axis = np.arange(-4, 5) * 2.0
    image = SarImage(data=np.zeros((9, 9), np.complex64), azimuth=axis, range=axis, origin=np.zeros(3),
                     azimuth_direction=np.array([1.0, 0, 0]), range_direction=np.array([0, -1.0, 0]))
    s = np.array([-20.0, 15.0, 60.0])
    model = phase_model([image] * 5, raws, plan.reference, np.array([4, 1]), np.array([4, 7]), (-25.0, 65.0))
    k = 2 * math.pi * p.frequency / 299_792_458.0
    for p_index, (row, col) in enumerate(((4, 4), (1, 7))):
        x = image.positions()[row, col]
        points = elevation_points(image, raws[plan.reference], x, s)

        def two_way(point, raw):
            a, t = raw.tx_position[0], raw.tx_position[-1] - raw.tx_position[0]
            t = t / np.linalg.norm(t)
            d = point - a
            return 2 * np.linalg.norm(d - np.outer(d @ t, t).reshape(d.shape), axis=-1)

        ref = raws[plan.reference]
        exact = np.array([k * ((two_way(points, raw) - two_way(x, raw)) - (two_way(points, ref) - two_way(x, ref)))
                          for raw in raws])
        assert model.phases(s)[p_index] == pytest.approx(exact, abs=5e-3)
        fourier = 4 * math.pi * np.outer(plan.perpendicular - plan.perpendicular[plan.reference], s) / (
            p.wavelength * plan.slant_range)
        assert np.max(np.abs(fourier - exact)) > 0.03


def _fourier_model(b: np.ndarray, cells: int, lam: float = 0.031, r: float = 1200.0):
    """A PhaseModel whose phase is the Fourier form 4 pi b_n s / (lambda R) (TS2), ``cells`` pixels alike."""
    from sarmitsuba.stacks.tomography import PhaseModel
    slope = 4 * math.pi * b / (lam * r)
    phase = np.stack([np.zeros(b.size), slope, np.zeros(b.size), np.zeros(b.size)], axis=1)[:, :, None]
    return PhaseModel(phase=np.repeat(phase, cells, axis=2), height=np.repeat([[0.0], [1.0], [0.0], [0.0]], cells, 1),
                      scale=1.0, interval=(-2.0, 10.0), fit_error=0.0), slope


@pytest.mark.parametrize("n, s0", [(12, 6.0), (16, 3.5)])
def test_sl1mmer_l1_step_is_the_closed_form_lasso_of_one_scatterer(n, s0):
    """One noise-free scatterer of amplitude gamma on the grid point s0, steering a(s0) with
    |a_n| = 1: the L1 problem min 1/2 ||A x - y||^2 + mu ||x||_1 with mu = 0.05 max |A^H y| = 0.05 N |gamma|
    is solved by x = (1 - 0.05) gamma at s0 and 0 elsewhere (the optimality conditions: A^H r = mu
    gamma / |gamma| at s0, |a_k^H r| <= mu elsewhere, for the residual r = 0.05 y). So the L1 profile
    peaks at 0.9025 |gamma|^2 there. The grid (-2 .. 10 m) holds s0 but neither -s0 nor its
    aliases -s0 + k lambda R / (2 d_b): a regularisation computed from A^T y (the conjugate
    dropped), whose peak lies there, is smaller, and the profile's peak larger."""
    from sarmitsuba.stacks.tomo_sparse import sl1mmer
    b = np.linspace(-6, 6, n)
    model, slope = _fourier_model(b, 1)
    s = np.arange(-2.0, 10.0 + 1e-9, 0.125)
    gamma = 0.8 * np.exp(1.1j)
    found = sl1mmer((gamma * np.exp(-1j * slope * s0))[None], model, s)
    j = int(np.argmin(np.abs(s - s0)))
    assert found.profiles[0, j] == pytest.approx(0.95 ** 2 * abs(gamma) ** 2, rel=2e-3)
    others = np.delete(found.profiles[0], j)
    assert others.max() < 1e-4 * abs(gamma) ** 2
    assert found.orders[0] == 1 and found.elevations[0, 0] == pytest.approx(s0, abs=1e-3)


@pytest.mark.parametrize("strong, weak", [((2.0, 1.0), (8.0, 0.4)), ((7.5, 0.9), (1.0, 0.5))])
def test_sl1mmer_lists_the_scatterers_strongest_first(strong, weak):
    """Two noise-free scatterers 6 m apart (4 rho_s: lambda R / (2 Delta b) = 1.55 m), amplitudes
    0.4 to 1.0: both found, the stronger first, at its elevation and with its amplitude (the
    weaker first, ascending order, fails)."""
    from sarmitsuba.stacks.tomo_sparse import sl1mmer
    b = np.linspace(-6, 6, 12)
    model, slope = _fourier_model(b, 1)
    y = strong[1] * np.exp(-1j * slope * strong[0]) + weak[1] * np.exp(0.7j - 1j * slope * weak[0])
    found = sl1mmer(y[None], model, np.arange(-2.0, 10.0 + 1e-9, 0.125))
    assert found.orders[0] == 2
    assert found.elevations[0] == pytest.approx([strong[0], weak[0], np.nan], abs=1e-3, nan_ok=True)
    assert np.abs(found.amplitudes[0, :2]) == pytest.approx([strong[1], weak[1]], abs=1e-3)
