"""PGA learns from point-like range lines only, refuses where too few remain, and removes the
linear part of the phase error from a known point (sarmitsuba.focus.autofocus,
sarmitsuba.focus.pga_lines, docs/physics.md (PGA4), (PGA5)).

The truths: closed forms of the point-likeness on lines of known intensity; a phase error
injected by hand (as in tests/test_autofocus.py) with extended scatterers beside the points; and,
on ray-traced scenes other than those of tests/test_pga_guard.py and tests/test_motion_autofocus.py
(a trihedral off the scene centre at 40 and 55 deg incidence in weaker clutter, walls on ground
filling the image or a third of it), the same raw data focused on the true track: a second method.
"""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.focus import ImageGrid, ffbp
from sarmitsuba.focus.autofocus import DOMINANCE_DB, AutofocusWarning, pga
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.focus.pga_lines import POINT_EXTENT, point_likeness
from test_autofocus import BANDS, ERRORS, N_AZ, TARGETS, U, _image, _no_trend, _targets, _with_error

MOTION = "0.02, 40"                   # 2 cm sinusoidal cross-track sway of period 40 m


def test_point_likeness_closed_forms():
    """A line of constant intensity over its lit half: the window of ``POINT_EXTENT`` of the lit
    extent (128 samples: 2 x 16 + 1 of them) about its middle holds 33 / 128 of its energy; a
    lone sample holds all of its line's but the dark samples'. Catches a window relative to the whole line (65 / 128 = 0.51, point-like) and a
    share over the whole line's energy instead of the lit part's."""
    n = 256
    intensity = np.full((n, 3), 1e-6)
    signal = np.zeros((n, 3), bool)
    intensity[64:192, 0] = 4.0                    # a wall along half the line, its brightest sample mid-way
    intensity[128, 0] = 4.0001
    signal[64:192, :] = True
    intensity[100, 1] = 9.0                       # a point
    intensity[64:192:2, 2] = 1.0                  # half the samples lit at 1
    intensity[130, 2] = 1000.0
    share, level_db = point_likeness(intensity, signal)
    half = int(POINT_EXTENT * 128 / 2)
    assert half == 16
    assert share[0] == pytest.approx(33 / 128, rel=1e-4)
    assert share[1] == pytest.approx((9.0 + 32e-6) / (9.0 + 127e-6), rel=1e-9)   # 32 dark samples near it
    background = np.median(intensity[signal])     # (PGA3)'s background: median over the signal pixels
    assert level_db[1] == pytest.approx(10 * np.log10(9.0 / background))
    assert level_db[2] == pytest.approx(10 * np.log10(1000.0 / background))
    energy = 1000.0 + 63 * 1.0 + 1e-6 * 64        # lit samples of line 2
    near = 1000.0 + 1.0 * np.sum(np.arange(130 - 16, 130 + 17) % 2 == 0) - 1.0 + 1e-6 * 16
    assert share[2] == pytest.approx(near / energy, rel=1e-4)


def test_pga_learns_only_from_the_points_beside_extended_lines():
    """Four band-limited points and two extended lines (speckle of the same band along the whole
    azimuth axis, a wall's double bounce seen edge-on) under an injected phase error: PGA on the
    point-like lines recovers it within 0.1 rad rms. Catches every bright line used (measured: 2.9
    rad rms, the extended lines' random phase gradients swamp the points')."""
    support = BANDS["centred"]
    rng = np.random.default_rng(7)
    data = _targets(support)
    for column in (10, 25):
        speckle = np.fft.fftshift(np.fft.fft(0.1 * np.exp(2j * np.pi * rng.uniform(size=N_AZ))))
        data[:, column] += np.fft.ifft(np.fft.ifftshift(np.where(support, speckle, 0.0)))
    error = np.where(support, ERRORS["quadratic + sinusoid"], 0.0)
    share, level_db = point_likeness(np.abs(_with_error(data, error)) ** 2)
    assert np.all(level_db[[10, 25]] > 40.0) and np.all(share[[10, 25]] < 0.35)   # bright, but extended
    _, report = pga(_image(_with_error(data, error)))
    residual = _no_trend(report.phase_error, support) - _no_trend(error, support)
    assert report.applied and report.lines == 4
    assert np.sqrt(np.mean(residual[support] ** 2)) < 0.1


@pytest.mark.parametrize("kept", [1, 2, 3])
def test_too_few_point_lines_refuses(kept):
    """The targets' range lines 5, 17, 30 kept, the first ``kept`` of them: with 1 or 2 point-like
    lines PGA refuses and returns the image unchanged (docs/physics.md (PGA4): it needs 3); with 3
    it runs. (Caught: the bound taken as 2, which one line alone did not show.)"""
    support = BANDS["centred"]
    few = np.zeros_like(_targets(support))
    for column in (5, 17, 30)[:kept]:
        few[:, column] = _targets(support)[:, column]
    blurred = _with_error(few, np.where(support, ERRORS["quadratic + sinusoid"], 0.0))
    if kept == 3:
        _, report = pga(_image(blurred))
        assert report.applied and report.lines == 3
        return
    with pytest.warns(AutofocusWarning, match=f"not applied: only {kept} range line"):
        out, report = pga(_image(blurred))
    assert not report.applied and np.array_equal(out.data, _image(blurred).data)
    assert out.metadata["autofocus"]["refusal"] == f"{kept} point-like range line(s)"      # for the CLI's note


def test_a_reference_puts_the_targets_back():
    """An image without a track record (no deramp): an even defocusing error (no linear part of its
    own) plus a linear phase that moves every target by 9 / (2 pi) * 2 / 255 * 256 = 2.87 samples. With the first target's true
    position as the reference, PGA removes both and every target peaks where it was put, within a
    twentieth of a sample (sub-sample peak of the 16-times upsampled magnitude). Catches the
    linear phase removed with the wrong sign (5.7 samples off); a shift measured on the
    uncorrected image passes here and fails the rendered tests below."""
    support = BANDS["centred"]
    error = np.where(support, 6.0 * U ** 2 + 1.2 * np.cos(2 * np.pi * 5.1 * U) + 9.0 * U, 0.0)
    blurred = _image(_with_error(_targets(support), error))
    a0, r0, _ = TARGETS[0]
    out, report = pga(blurred, reference=(a0 * 0.5, r0 * 0.5, 0.0))   # 0.5 m samples, the axes along x and y
    assert report.linear_shift_m == pytest.approx(-9.0 / (2 * np.pi) * 2 / (N_AZ - 1) * N_AZ * 0.5, abs=0.1)
    for a, r, _ in TARGETS:
        spectrum = np.fft.fftshift(np.fft.fft(out.data[:, r]))
        peak = np.argmax(np.abs(np.fft.ifft(np.fft.ifftshift(np.pad(spectrum, 15 * N_AZ // 2))))) / 16.0
        assert abs(peak - a) < 0.05, (a, peak)
    assert out.metadata["autofocus"]["linear_part"]["shift_m"] == pytest.approx(report.linear_shift_m, abs=1e-4)


def _scene(incidence: float, *, trihedral=None, wall: bool = False, plate: float = 40.0, gamma_db: float = -20.0,
           pixels=((256, 0.1), (64, 0.2)), window: str = "taylor") -> tuple:
    """True-track and nominal-track ffbp images (``pixels``: count and spacing [m] along track and in
    range) of rough ground ``2 plate`` m square, a trihedral at ``trihedral`` (x, y) [m] and a PEC
    wall 20 m x 0.3 m x 6 m on the scene centre; the radar looks toward -y."""
    ground = trimesh.Trimesh([[-plate, -plate, 0], [plate, -plate, 0], [plate, plate, 0], [-plate, plate, 0]],
                             [[0, 1, 2], [0, 2, 3]])
    meshes = [(ground, {"material": "medium_dry_ground", "gamma_db": gamma_db}, "ground")]
    if trihedral is not None:
        meshes.append((trimesh.load("scenes/meshes/trihedral.obj").apply_translation((*trihedral, 0.0)), "pec",
                       "trihedral"))
    if wall:
        meshes.append((trimesh.creation.box((20.0, 0.3, 6.0)).apply_translation((0, 0, 3.0)), "pec", "wall"))
    scene = sarmitsuba.Scene(meshes=meshes, integrator={"max_depth": 3},
                             sensor={"frequency": 9.6e9, "bandwidth": 150e6, "incidence_angle": incidence,
                                     "scene_center": (0, 0, 0), "motion_error": MOTION})
    sim = simulate_quiet(scene)
    frame = sim.image
    (n_az, d_az), (n_rg, d_rg) = pixels
    grid = ImageGrid(origin=frame.origin, azimuth_direction=frame.azimuth_direction,
                     range_direction=frame.range_direction, azimuth=(np.arange(n_az) - n_az // 2) * d_az,
                     range=(np.arange(n_rg) - n_rg // 2) * d_rg, plane="ground")
    return (ffbp(sim.raw, grid, window_azimuth=window),
            ffbp(sim.raw.on_track("nominal"), grid, window_azimuth=window))


def simulate_quiet(scene, **options):
    from sarmitsuba.pipeline import simulate
    return simulate(scene, focuser="ffbp", image_size=(32, 32), **options)


#: (incidence [deg], trihedral (x, y) [m]): along track x, ground range -y.
POINTS = {"40 deg, (4, -2) m": (40.0, (4.0, -2.0)), "55 deg, (-3, 1) m": (55.0, (-3.0, 1.0))}


@pytest.fixture(scope="module", params=list(POINTS), ids=list(POINTS))
def point_in_clutter(request):
    incidence, (x, y) = POINTS[request.param]
    true, nominal = _scene(incidence, trihedral=(x, y))
    with warnings.catch_warnings():
        warnings.simplefilter("error", AutofocusWarning)           # it runs and converges
        fixed, report = pga(nominal, reference=(x, y, 0.0))
        shifted, plain = pga(nominal)
    return (x, y), true, nominal, fixed, report, shifted, plain


def _analyse(image, x: float, y: float):
    return analyze_point_target(image, (x, y, 0.0), chip=32, search_radius=4)


def test_pga_with_a_reference_reaches_the_true_track(point_in_clutter):
    """The acceptance of docs/physics.md (PGA4): azimuth PSLR within 3 dB and IRW within 5 % of the
    true track's, measured where the trihedral is; with the reference the image is in place (its
    peak within 3 cm of the true track's) and its complex pixels about the trihedral are the true
    track's (coherence > 0.99). Catches the linear phase applied with the wrong sign (the image
    moves 2 shifts away, the analysis finds no trihedral there)."""
    (x, y), true, nominal, fixed, report, _, _ = point_in_clutter
    t, f = _analyse(true, x, y), _analyse(fixed, x, y)
    assert _analyse(nominal, x, y).pslr_azimuth_db > t.pslr_azimuth_db + 20.0          # visibly defocused
    assert abs(f.pslr_azimuth_db - t.pslr_azimuth_db) < 3.0, (f.pslr_azimuth_db, t.pslr_azimuth_db)
    assert abs(f.irw_azimuth / t.irw_azimuth - 1.0) < 0.05, (f.irw_azimuth, t.irw_azimuth)
    assert abs(f.azimuth - t.azimuth) < 0.03
    rows, cols = np.abs(true.azimuth - x) <= 2.0, np.abs(true.range + y) <= 2.0
    a, b = true.data[np.ix_(rows, cols)], fixed.data[np.ix_(rows, cols)]
    assert abs(np.vdot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)) > 0.99
    assert fixed.metadata["autofocus"]["linear_part"]["estimated"] is True


def test_without_a_reference_the_shift_is_reported_and_bounded(point_in_clutter):
    """Without a reference PGA leaves the linear part: its image is shifted along track by what the
    reference run removed (measured independently, by point-target analysis of both images), by
    more than a resolution cell here, and by no more than the bound in its metadata (eq. (PGA5))."""
    (x, y), true, _, fixed, report, shifted, plain = point_in_clutter
    moved = analyze_point_target(shifted, (x + report.linear_shift_m, y, 0.0), chip=32, search_radius=4)
    assert moved.azimuth - _analyse(true, x, y).azimuth == pytest.approx(report.linear_shift_m, abs=0.03)
    assert abs(report.linear_shift_m) > _analyse(true, x, y).irw_azimuth
    record = shifted.metadata["autofocus"]["linear_part"]
    assert record["estimated"] is False and plain.linear_shift_m is None
    assert abs(report.linear_shift_m) <= record["bound_m"]
    assert np.allclose(plain.phase_error, report.phase_error)          # the reference only adds the linear part


def test_a_reference_outside_the_image_is_refused(point_in_clutter):
    _, _, nominal, *_ = point_in_clutter
    with pytest.raises(ValueError, match="reference .* outside the image") as refused:
        pga(nominal, reference=(40.0, 0.0, 0.0))
    assert "reference (40, 0, 0) appears" in str(refused.value)           # numbers, not np.float64(...)
    with pytest.raises(ValueError, match="reference must be"):
        pga(nominal, reference=(1.0, 2.0))


CLUTTER = {
    "wall on ground filling the image, 50 deg": dict(incidence=50.0, wall=True, gamma_db=-30.0),
    "wall on a 16 m plate, a third of the image, 45 deg": dict(incidence=45.0, wall=True, plate=8.0, gamma_db=-14.0,
                                                               pixels=((160, 0.1), (120, 0.5))),
}


@pytest.mark.parametrize("name", list(CLUTTER), ids=list(CLUTTER))
def test_pga_refuses_walls_and_rims_without_a_point(name):
    """No point in the scene: PGA warns and hands the nominal-track image back unchanged, and no
    range line is point-like. The wall on the small plate stands 34.9 dB above its clutter
    (measured), above (PGA3)'s 25 dB: only (PGA4) refuses it. Catches the point-like test left
    out (PGA then ran on it and changed it by +2.6 dB NRMSE)."""
    _, nominal = _scene(**CLUTTER[name])
    with pytest.warns(AutofocusWarning, match="not applied"):
        out, report = pga(nominal)
    assert np.array_equal(out.data, nominal.data) and not report.applied and report.lines == 0
    if "third" in name:
        assert report.dominance_db > DOMINANCE_DB


def exact_phase_focus(raw, grid: ImageGrid, point, window: str = "taylor"):
    """The nominal-track focus of ``raw`` after every pulse is multiplied by ``exp(j k dL)``, ``dL`` the
    true minus the nominal two-way path to ``point`` [m], from the recorded tracks: the exact
    correction of a phase error common to the image, the model PGA estimates (docs/physics.md (PGA))."""
    nominal = raw.on_track("nominal")
    p = np.asarray(point, float)
    extra = (np.linalg.norm(raw.tx_position - p, axis=1) + np.linalg.norm(raw.rx_position - p, axis=1)
             - np.linalg.norm(raw.nominal_tx_position - p, axis=1) - np.linalg.norm(raw.nominal_rx_position - p, axis=1))
    k = 2 * np.pi * raw.fc / SPEED_OF_LIGHT
    data = (nominal.data * np.exp(1j * k * extra)[:, None]).astype(np.complex64)
    return ffbp(dataclasses.replace(nominal, data=data), grid, window_azimuth=window)


def trihedral_alone(window: str = "taylor") -> tuple:
    """The built-in trihedral (no clutter) with the 2 cm, 40 m sway: true-track, nominal-track and
    exactly phase-corrected (:func:`exact_phase_focus`) images, 0.1 m x 0.2 m pixels."""
    sim = simulate_quiet("trihedral", sensor_overrides={"motion_error": MOTION})
    frame = sim.image
    grid = ImageGrid(origin=frame.origin, azimuth_direction=frame.azimuth_direction,
                     range_direction=frame.range_direction, azimuth=(np.arange(256) - 128) * 0.1,
                     range=(np.arange(64) - 32) * 0.2, plane="ground")
    return (ffbp(sim.raw, grid, window_azimuth=window), ffbp(sim.raw.on_track("nominal"), grid, window_azimuth=window),
            exact_phase_focus(sim.raw, grid, (0.0, 0.0, 0.0), window))


def test_where_pga_falls_short_it_is_the_spectral_support(monkeypatch):
    """The built-in trihedral without clutter, Taylor-weighted: the true track gives sidelobes near
    -58 dB, and so does the exact phase correction of every pulse (from the recorded tracks: the
    common phase error PGA models, measured -57.5 dB against -57.8). PGA misses them by more than
    3 dB (-54.2 dB): the Taylor spectrum's edges lie more than SUPPORT_DB = 40 dB below its peak, carry no estimate
    and keep the phase of their neighbours. Estimated down to 60 dB, PGA comes within 1.5 dB of the
    exact correction (-56.8 dB); in clutter that support takes in samples the clutter outweighs
    (docs/physics.md (PGA5)). Catches a PGA stopped early or on too narrow a window (several dB
    further), and an explanation of the shortfall that does not hold."""
    import sarmitsuba.focus.autofocus as autofocus
    true, nominal, exact = trihedral_alone()
    t, e = _analyse(true, 0.0, 0.0), _analyse(exact, 0.0, 0.0)
    assert abs(e.pslr_azimuth_db - t.pslr_azimuth_db) < 1.0                # the model holds
    with warnings.catch_warnings():
        warnings.simplefilter("error", AutofocusWarning)
        narrow = _analyse(pga(nominal, reference=(0.0, 0.0, 0.0))[0], 0.0, 0.0)
        monkeypatch.setattr(autofocus, "SUPPORT_DB", 60.0)
        wide = _analyse(pga(nominal, reference=(0.0, 0.0, 0.0))[0], 0.0, 0.0)
    assert e.pslr_azimuth_db + 2.0 < narrow.pslr_azimuth_db < t.pslr_azimuth_db + 4.0
    assert wide.pslr_azimuth_db < e.pslr_azimuth_db + 1.5
    assert abs(narrow.irw_azimuth / t.irw_azimuth - 1.0) < 0.01
