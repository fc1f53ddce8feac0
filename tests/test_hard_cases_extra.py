"""Numerically hard cases, continued (issue 5): 1 km in the long-range series, a one-sample
fast-time window, targets on the window edges and at the scene's edges and centre, amplitudes
far below float32's normal range, Ctrl-C during a render, Fresnel coefficients near vacuum and
toward a perfect conductor.

Every case checks a number against a closed form or an invariant, not only that nothing crashed.
"""
from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

import sarmitsuba  # noqa: F401  (variant and plugins)
from sarmitsuba.signal import binning
from sarmitsuba.scene import planning
from sarmitsuba.scene import canonical as C
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.focus import ImageGrid, backproject
from sarmitsuba.pipeline import image_grid, simulate
from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.scene.loader import builtin_scenes, load_scene, material_table
from sarmitsuba.tracing.driver.trace import trace
from sarmitsuba.scene.trace_inputs import FastTimeWindow

SCENES = Path(__file__).parent / "scenes"
FLOAT32_TINY = float(np.finfo(np.float32).tiny)        # smallest normal float32, 1.18e-38


def _wrap_deg(x: float) -> float:
    return (x + 180.0) % 360.0 - 180.0


def _trihedral_scene(folder: Path, edge: float) -> Path:
    """The built-in trihedral scene (apex at the origin, PEC) with edge length ``edge`` [m]."""
    builtin = builtin_scenes()["trihedral"]
    text = builtin.read_text().replace('<scale value="1.5"/>', f'<scale value="{edge!r}"/>')
    text = text.replace('value="meshes/', f'value="{(builtin.parent / "meshes").resolve()}/')
    path = folder / f"trihedral_{edge:g}.xml"
    path.write_text(text)
    return path


def _pulses_in_beam(raw, point, beamwidth_deg: float) -> np.ndarray:
    """Indices of the pulses whose traced beam (full width ``beamwidth_deg``) contains ``point``
    (the tracer's criterion)."""
    e = np.asarray(point, float) - raw.tx_position
    v = raw.velocity / np.linalg.norm(raw.velocity, axis=1, keepdims=True)
    along = np.abs(np.einsum("ij,ij->i", e, v))
    return np.nonzero(along <= math.sin(math.radians(beamwidth_deg) / 2) * np.linalg.norm(e, axis=1))[0]


# --------------------------------------------------------------------------------------------
# 1. 1 km in the long-range series
# --------------------------------------------------------------------------------------------

def _gated_response(c: float) -> tuple[float, float]:
    """PSLR [dB] and -3 dB half-width (in z) of the beam-limited backprojection of a point
    target, closed form.

    The target is in the beam for the pulses u in [-L/2, L/2] of the track; a pixel x metres
    along track integrates the pulses of its own beam, [x - L/2, x + L/2], so only L - |x| of
    them hold the target's echo, and each column is normalised by L. The azimuth response is
    therefore ``|sin(z (1 - c z))| / z`` with ``z = k x L / R`` and ``c = R / (k L^2)``
    (k = 2 pi / lambda): a sinc whose sidelobes shrink with the overlap. ``c -> 0`` gives
    -13.26 dB and the sinc's IRW; at 1 km (L = 21 m) c = 0.011: the PSLR is 0.47 dB lower
    and the IRW 0.57 % narrower.
    """
    z = np.linspace(1e-6, 40.0, 400_001)
    response = np.abs(np.sin(z * (1.0 - c * z))) / z
    first_null = (1.0 - math.sqrt(1.0 - 4.0 * c * math.pi)) / (2.0 * c) if c > 0 else math.pi
    half_width = float(z[np.argmax(response < math.sqrt(0.5))])
    return 20.0 * math.log10(response[z > first_null].max()), half_width


def test_one_km_joins_the_long_range_series(tmp_path):
    """A 0.2 m trihedral (ray spacing 0.02 m) at 1, 10 and 100 km slant range, same beam and
    resolution, against 100 km (test_hard_cases.py takes 10 km to 100 km with the 1.5 m trihedral,
    benchmarks/long_range.py to 800 km; measured with this one, 800 km matches 100 km to 0.01 %
    in IRW, 0.01 dB in PSLR and 0.001 deg in phase):

    - peak position (1/20 cell), range IRW (1 %), range PSLR (0.2 dB) and peak phase (2 deg;
      measured 0.07 deg) are the same at 1 km;
    - three differences at 1 km are not precision but closed forms, checked here with a
      uniform (hard-edged) beam, whose gated response has the closed form below:

      * the target's near field: the triple-bounce path through a trihedral exit point at
        distance rho from the boresight line is 2 R + rho^2 / R, so the peak phase moves by
        -k <rho^2> / R with <rho^2> = 5 a^2 / 54 over the hexagonal effective aperture
        (0.04 deg here at 1 km; 2.4 deg for the 1.5 m trihedral, next test);
      * the aperture holds a whole number N of pulses d = 0.4 m apart (53 at 1 km: 1.2 % more
        than R beta), and the azimuth IRW is 0.886 lambda R / (2 N d): IRW N d / R is the same
        (0.5 %; measured 0.01 % refocused without the beam gate, 0.16 % with it once its
        closed-form narrowing below is divided out);
      * the beam-limited backprojection gives each pixel its own aperture, so a sidelobe x
        metres from the target integrates L - |x| of its pulses: PSLR and IRW follow
        :func:`_gated_response` (PSLR 0.47 dB lower at 1 km, 0.04 dB at 10 km; measured 0.52
        and 0.03 dB; IRW 0.57 % narrower at 1 km, measured 0.41 %). Refocused without the
        beam gate, the azimuth PSLR is the same at every range (0.2 dB; measured 0.01 dB).
    """
    scene = _trihedral_scene(tmp_path, 0.2)
    edge = 0.2
    k = 2 * math.pi * 9.6e9 / SPEED_OF_LIGHT
    rho2 = 5.0 * edge**2 / 54.0
    results = []
    for slant in (1e3, 10e3, 100e3):
        # direct backprojection: fast factorised backprojection's interpolation moves the peak
        # phase by 0.4 deg at 1 km (its error is measured in test_ffbp.py and benchmarks/ffbp.py)
        sim = simulate(str(scene), sensor_overrides={"altitude": slant * math.cos(math.pi / 4), "beam": "uniform"},
                       integrator_overrides={"ray_spacing": 0.02}, window="rect", focuser="bp")
        assert np.all(np.isfinite(sim.image.data)) and np.all(np.isfinite(sim.raw.data))
        p = sim.loaded.params
        n_beam = _pulses_in_beam(sim.raw, np.zeros(3), p.azimuth_beamwidth).size
        aperture = n_beam * p.velocity / p.prf
        ungated = backproject(sim.raw, image_grid(sim.loaded, acquisition_geometry(p)))
        results.append(dict(slant=slant, gated=analyze_point_target(sim.image, np.zeros(3)),
                            ungated=analyze_point_target(ungated, np.zeros(3)), aperture=aperture,
                            c=slant / (k * aperture**2)))
    ref = results[-1]
    r0, u0 = ref["gated"], ref["ungated"]
    for res in results[:-1]:
        r, u, slant = res["gated"], res["ungated"], res["slant"]
        label = f"{slant / 1e3:g} km"
        for rep in (r, u):
            assert abs(rep.azimuth_error_cells) < 0.05 and abs(rep.range_error_cells) < 0.05, label
        assert abs(r.irw_range / r0.irw_range - 1) < 0.01, label
        assert abs(r.pslr_range_db - r0.pslr_range_db) < 0.2, label
        # peak phase: within 2 deg as measured, within 0.2 deg once the near field is removed
        dphi = _wrap_deg(r.peak_phase_deg - r0.peak_phase_deg)
        near_field = -math.degrees(k * rho2 * (1 / slant - 1 / ref["slant"]))
        assert abs(dphi) < 2.0 and abs(dphi - near_field) < 0.2, (label, dphi, near_field)
        # azimuth: the ungated IRW inversely proportional to the whole-pulse aperture N d, its
        # PSLR identical; the beam-gated IRW and PSLR shifted by the closed form
        (pslr, width), (pslr0, width0) = _gated_response(res["c"]), _gated_response(ref["c"])
        for rep, rep0, gate in ((r, r0, width / width0), (u, u0, 1.0)):
            ratio = (rep.irw_azimuth * res["aperture"] / slant) / (rep0.irw_azimuth * ref["aperture"] / ref["slant"])
            assert abs(ratio / gate - 1) < 0.005, (label, ratio, gate)
        assert abs(u.pslr_azimuth_db - u0.pslr_azimuth_db) < 0.2, (label, u.pslr_azimuth_db, u0.pslr_azimuth_db)
        assert abs((r.pslr_azimuth_db - r0.pslr_azimuth_db) - (pslr - pslr0)) < 0.15, \
            (label, r.pslr_azimuth_db - r0.pslr_azimuth_db, pslr - pslr0)


def test_near_field_phase_of_the_large_trihedral_at_1_km():
    """The built-in 1.5 m trihedral (far-field distance 2 D^2 / lambda = 290 m) at 1 km vs 10 km:
    its peak phase moves by the near-field closed form -k (5 a^2 / 54) (1 / R_1 - 1 / R_2)
    = -2.16 deg (measured -2.21 deg): the "~3 deg at 1 km" of the long-range test is this,
    not float precision."""
    k = 2 * math.pi * 9.6e9 / SPEED_OF_LIGHT
    phases = {}
    for slant in (1e3, 10e3):
        sim = simulate("trihedral", sensor_overrides={"altitude": slant * math.cos(math.pi / 4)})
        phases[slant] = analyze_point_target(sim.image, np.zeros(3)).peak_phase_deg
    expected = -math.degrees(k * 5.0 * 1.5**2 / 54.0 * (1 / 1e3 - 1 / 10e3))
    measured = _wrap_deg(phases[1e3] - phases[10e3])
    assert abs(measured - expected) < 0.2, (measured, expected)


# --------------------------------------------------------------------------------------------
# 2-3. One range sample, one pulse, targets on the window's edges
# --------------------------------------------------------------------------------------------

class _OnePulsePlate:
    """A 0.5 m PEC plate facing the sensor at the scene centre, one broadside pulse, traced with
    a hand-made fast-time window (``pos``: the target's delay in samples from the window start).

    Closed form of its echo: ``a p_r(t - 2R/c) exp(-j k 2R)`` with the unit-peak compressed
    pulse ``p_r(t) = sinc(B t)`` and the PO amplitude of a plate at normal incidence
    ``a = -j (2 sqrt(pi) / lambda) A exp(-j k <rho^2> / R)`` (PEC: r = -1; the spherical
    wavefront adds rho^2 / R of path at distance rho from the axis, <rho^2> = w^2 / 6).
    """

    SIDE = 0.5

    def __init__(self, folder: Path):
        xml = C.scene_xml(folder, C.plate(self.SIDE), C.PEC, 1)
        self.loaded = load_scene(str(xml), {"n_pulses": 1}, {"ray_spacing": 0.02})
        p = self.params = self.loaded.params
        self.geometry = acquisition_geometry(p)
        lo, hi = self.loaded.bbox_lo, self.loaded.bbox_hi
        self.footprint = planning.ray_footprint(p, self.geometry, lo, hi, self.loaded.settings)
        self.table = material_table(self.loaded.scene, p.frequency, p.polarization)
        self.length = 2.0 * float(np.linalg.norm(self.geometry.positions[0]))
        self.k = 2 * math.pi * p.frequency / SPEED_OF_LIGHT
        slant = 0.5 * self.length
        self.amplitude = (-1j * 2 * math.sqrt(math.pi) / p.wavelength * self.SIDE**2
                          * np.exp(-1j * self.k * self.SIDE**2 / 6 / slant))

    def run(self, n_samples: int, pos: float):
        p, st = self.params, self.loaded.settings
        window = FastTimeWindow(t0=self.length / SPEED_OF_LIGHT - pos / p.sampling_rate, fs=p.sampling_rate,
                                n_samples=n_samples, oversample=st.oversample)
        result = trace(self.loaded.scene, p, self.geometry, window, self.footprint, st, self.table)
        raw = binning.to_raw_data(result.contributions(), result, window, p, self.geometry, {})
        return raw, result

    def expected(self, n_samples: int, pos: float) -> np.ndarray:
        """Closed-form range line with the carrier exp(-j k L) removed."""
        p = self.params
        return self.amplitude * np.sinc(p.bandwidth * (np.arange(n_samples) - pos) / p.sampling_rate)

    def baseband(self, raw) -> np.ndarray:
        return raw.data[0].astype(np.complex128) * np.exp(1j * math.fmod(self.k * self.length, 2 * math.pi))


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    return _OnePulsePlate(tmp_path_factory.mktemp("plate"))


def test_one_range_sample_and_one_pulse(plate):
    """The planner's smallest window for a point-like scene is 2 x 64 margin samples (132, a
    fast FFT length, target at sample 64). A hand-made window of ONE sample at the target's
    delay traces and bins: the single raw value is the closed-form echo (1 %: measured 0.45 %),
    finite, with no energy reported outside. Backprojection needs >= 2 samples and says so."""
    lo, hi = plate.loaded.bbox_lo, plate.loaded.bbox_hi
    window = planning.fast_time_window(plate.params, plate.geometry, lo, hi, plate.loaded.settings)
    at = (plate.length / SPEED_OF_LIGHT - window.t0) * window.fs
    assert 2 * planning.WINDOW_MARGIN_SAMPLES <= window.n_samples <= 2 * planning.WINDOW_MARGIN_SAMPLES + 8
    assert abs(at - planning.WINDOW_MARGIN_SAMPLES) < 1.0, at

    raw, result = plate.run(1, 0.0)
    assert raw.data.shape == (1, 1) and np.all(np.isfinite(raw.data))
    value = plate.baseband(raw)[0]
    assert abs(value - plate.amplitude) < 0.01 * abs(plate.amplitude), (value, plate.amplitude)
    assert result.energy_outside_window == 0.0 and result.energy_per_order[0] > 0
    grid = ImageGrid.ground(np.zeros(3), (1, 0, 0), (0, -1, -1), 4.0, 4.0, 0.5)
    with pytest.raises(ValueError, match=">= 2 fast-time samples"):
        backproject(raw, grid)


@pytest.mark.parametrize("where", ["first", "centre", "last"])
def test_target_on_the_first_centre_and_last_sample(plate, where):
    """The plate's delay exactly on sample 0, 64 or 127 of a 128-sample window: the whole range
    line is the closed-form compressed pulse (max error 1 % of the peak: measured 0.45 %), so
    nothing is lost at the edge and nothing of the pulse's sidelobes wraps onto the other edge
    (wrapped, sample 127 of a target on sample 0 would hold its -1 sample sidelobe, 0.2 of the
    peak, instead of 0.0015). The one-pulse backprojected image at the plate's centre is the
    amplitude too (1 %)."""
    n = 128
    pos = {"first": 0.0, "centre": 64.0, "last": float(n - 1)}[where]
    raw, result = plate.run(n, pos)
    line, expected = plate.baseband(raw), plate.expected(n, pos)
    a = abs(plate.amplitude)
    assert np.all(np.isfinite(line)) and result.energy_outside_window == 0.0
    assert int(np.argmax(np.abs(line))) == int(pos)
    assert np.abs(line - expected).max() < 0.01 * a, np.abs(line - expected).max() / a
    grid = ImageGrid.ground(np.zeros(3), (1, 0, 0), (0, -1, -1), 2.0, 2.0, 0.25)
    image = backproject(raw, grid)
    pixel = image.data[grid.shape[0] // 2, grid.shape[1] // 2]              # exactly at the origin
    assert abs(pixel - plate.amplitude) < 0.01 * a, (pixel, plate.amplitude)


def test_target_just_outside_the_window_is_masked_not_clamped(plate):
    """Half a sample before the window: the path is masked (zero line, all its energy reported
    outside), not clamped onto sample 0 (which would hold the full amplitude). Half a sample
    after the last sample the fine deposit grid still holds it (it extends 7/8 sample beyond):
    the last sample holds its true sidelobe p_r(-1/2 fs) = 0.74 of the peak (1 %), not the
    peak. 1.5 samples after: masked."""
    n, a = 128, abs(plate.amplitude)
    for pos in (-0.5, n - 1 + 1.5):
        raw, result = plate.run(n, pos)
        assert np.all(raw.data == 0), pos
        assert result.energy_outside_window == pytest.approx(result.energy_per_order.sum(), rel=1e-6)
        assert result.energy_outside_window > 0
    raw, result = plate.run(n, n - 1 + 0.5)
    line, expected = plate.baseband(raw), plate.expected(n, n - 1 + 0.5)
    assert result.energy_outside_window == 0.0
    assert abs(abs(line[-1]) / a - 0.74) < 0.01
    assert np.abs(line - expected).max() < 0.01 * a


# --------------------------------------------------------------------------------------------
# 3. Targets at the scene's edges and at its centre (planner's window, aperture and footprint)
# --------------------------------------------------------------------------------------------

def _trihedrals(folder: Path, apexes, edge: float = 0.2) -> Path:
    mesh = trimesh.util.concatenate([C.trihedral(edge).apply_translation(a) for a in apexes])
    return C.scene_xml(folder, mesh, C.PEC, 3)


def test_targets_at_the_along_track_ends_image_like_the_centre(tmp_path):
    """Three 0.2 m trihedrals at x = -60, 0, +60 m: the outer ones are at the scene's along-track
    ends, the middle one exactly at the scene centre, farther apart than the traced beam's
    footprint (55 m), so no pulse sees two of them. 60 m is a whole number of pulse spacings
    (0.4 m), sub-apertures (4 m) and ray spacings (0.02 m), so each target sees the same pulses and the same ray
    lattice: the planner (aperture, window, footprint limits) must give the edge targets the
    same echo, pulse for pulse (1e-3 of the peak, the float32 geometry floor 60 m from the
    frame origin, but for a tube on a face edge), and focused on a grid
    centred on each target, the same chip (1e-3). In the render's own image all three peaks sit
    on their apex (1/20 cell).

    (The render's image places the three apexes differently between pixels and between
    pulses; with each pixel integrating its own beam's pulses, that alone moves the peak by up
    to 0.14 dB and the azimuth IRW by 2 %, so peaks are compared on congruent chips.)"""
    d = 60.0
    apexes = [np.array([x, 0.0, 0.0]) for x in (0.0, d, -d)]
    # sub-apertures of 10 pulses (4 m): 60 m is a whole number of them too, so each target also
    # sees the same sub-aperture boundaries (docs/physics.md (T3))
    sim = simulate(str(_trihedrals(tmp_path, apexes)), integrator_overrides={"ray_spacing": 0.02,
                                                                            "pulses_per_trace": 10})
    p = sim.loaded.params
    assert sim.trace.energy_outside_window == 0.0
    assert round(d / (p.velocity / p.prf)) * p.velocity / p.prf == pytest.approx(d)
    pulses = [_pulses_in_beam(sim.raw, a, p.traced_beamwidth) for a in apexes]
    assert len({len(q) for q in pulses}) == 1 and all(np.all(np.diff(q) == 1) for q in pulses)
    centre = sim.raw.data[pulses[0]]
    peak = np.abs(centre).max()
    rows = np.abs(centre).max(axis=1)
    for q in pulses[1:]:        # float32 geometry 60 m from the frame origin: ~4e-6 m, 2e-3 rad
        error = np.abs(sim.raw.data[q] - centre).max(axis=1)
        # a tube whose central ray grazes a face's edge (within the vertices' float32 step, 4e-6 m
        # here) may bounce differently: at most a few pulses lose or gain that one tube, 1/58 of
        # the triple-bounce echo (measured: 2 pulses, 1.7 %)
        flipped = error >= 1e-3 * peak
        assert flipped.sum() <= 3 and np.all(error[flipped] < 0.025 * rows[flipped] + 1e-3 * peak), error[flipped]
    chips = []
    for a in apexes:
        # 8 m chips: their pixels beyond the edge targets still see (almost) their whole beam
        grid = ImageGrid.ground(a, (1, 0, 0), (0, -1, -1), 8.0, 8.0, 0.25)
        chips.append(backproject(sim.raw, grid, azimuth_beamwidth=p.traced_beamwidth).data)
    top = np.abs(chips[0]).max()
    assert top > 1.0
    for chip in chips[1:]:
        assert np.abs(chip - chips[0]).max() < 1e-3 * top
    for a in apexes:
        r = analyze_point_target(sim.image, a)
        assert abs(r.azimuth_error_cells) < 0.05 and abs(r.range_error_cells) < 0.05, a


def _mean_echo(raw, apex: np.ndarray) -> complex:
    """The target's echo at its own delay (band-limited, Whittaker-Shannon interpolation of each
    range line), carrier removed, averaged coherently over all pulses."""
    lengths = 2.0 * np.linalg.norm(raw.tx_position - apex, axis=1)
    k = 2 * math.pi * raw.fc / SPEED_OF_LIGHT
    echoes = [np.sum(raw.data[q] * np.sinc(raw.fs * (lengths[q] / SPEED_OF_LIGHT - raw.fast_time)))
              * np.exp(1j * math.fmod(k * lengths[q], 2 * math.pi)) for q in range(raw.n_pulses)]
    return complex(np.mean(echoes))


def test_targets_at_the_near_and_far_swath_edges(tmp_path):
    """Trihedrals at ground range +40 m, 0 (the scene centre) and -40 m: the outer two are the
    scene's near and far swath edges. The same scene with two more trihedrals at +-120 m has
    them inside the swath (same scene centre, so the same ray lattice; 71 pulses in both).

    No energy falls outside either planned window; the near echo sits the planner's 64 margin
    samples into the window (1 sample), the far one that margin plus (max_depth - 1) x 10 % of
    the box diagonal (room for multi-bounce paths) from its end (up to the FFT-length
    rounding); each target's echo,
    averaged coherently over the pulses, is the same at the edge as inside (1 %, complex;
    measured 0.54 %: the range sidelobes of the targets at +-120 m, 68 samples away, 1 / (pi 68
    B / fs) = 0.6 % of their peak, in phase over the aperture); and in the render's image each peak lies on
    its apex (1/20 cell) with the same magnitude at the edge as inside (0.2 dB; measured
    0.12 dB: each pixel's beam edge is placed with its 16 x 128 tile's centre distance, so a
    different image size can move one pulse in or out of a 61-pulse aperture). (The trihedrals'
    echoes differ among themselves by up to 0.6 dB: 10 rays per edge sample each one
    differently.)"""
    d = 40.0
    apexes = [np.array([0.0, y, 0.0]) for y in (0.0, d, -d)]
    sims = []
    for name, extra in (("edges", []), ("inside", [np.array([0.0, y, 0.0]) for y in (3 * d, -3 * d)])):
        sims.append(simulate(str(_trihedrals(tmp_path / name, apexes + extra)), sensor_overrides={"n_pulses": 71},
                             integrator_overrides={"ray_spacing": 0.02}))
    edge, inside = sims
    margin = planning.WINDOW_MARGIN_SAMPLES
    diagonal = float(np.linalg.norm(edge.loaded.bbox_hi - edge.loaded.bbox_lo))
    for sim in sims:
        assert sim.trace.energy_outside_window == 0.0
        assert np.all(np.isfinite(sim.raw.data)) and np.all(np.isfinite(sim.image.data))
    for apex in apexes:
        raw = edge.raw
        samples = (2.0 * np.linalg.norm(raw.tx_position - apex, axis=1) / SPEED_OF_LIGHT - raw.fast_time[0]) * raw.fs
        assert samples.min() >= margin - 1 and samples.max() <= raw.n_samples - margin + 1
        if apex[1] > 0:
            assert samples.min() < margin + 1                  # the near edge is on the margin
        if apex[1] < 0:       # far edge: the margin plus room for multi-bounce paths (planner)
            extra = (edge.loaded.settings.max_depth - 1) * 0.1 * diagonal / SPEED_OF_LIGHT * raw.fs
            assert margin + extra - 1 < raw.n_samples - 1 - samples.max() < margin + extra + 8
        at_edge, within = _mean_echo(edge.raw, apex), _mean_echo(inside.raw, apex)
        assert abs(at_edge / within - 1) < 0.01, (apex, at_edge, within)
        r, r_inside = analyze_point_target(edge.image, apex), analyze_point_target(inside.image, apex)
        assert abs(r.azimuth_error_cells) < 0.05 and abs(r.range_error_cells) < 0.05, apex
        assert abs(20 * math.log10(r.peak_magnitude / r_inside.peak_magnitude)) < 0.2, apex


# --------------------------------------------------------------------------------------------
# 4. Amplitudes far below float32's normal range: no subnormal values
# --------------------------------------------------------------------------------------------

def _subnormal_count(x) -> int:
    x = np.asarray(x)
    parts = (x.real, x.imag) if np.iscomplexobj(x) else (x,)
    return int(sum(np.count_nonzero((np.abs(v) > 0) & (np.abs(v) < FLOAT32_TINY)) for v in parts))


def test_no_subnormal_values_far_below_the_noise_floor(tmp_path):
    """The 10-bounce canyon of near-vacuum walls (eps_r = 1 + 1e-4, |r| ~ 2.5e-5 at normal
    incidence): the power the rays carry falls by ~1e-9 per order and would cross float32's
    smallest normal value (1.2e-38) after order 4. Dr.Jit's LLVM worker threads run with
    flush-to-zero and denormals-are-zero (nanothread's pool, ftz=1: checked below on a 1024-lane
    kernel; kernels of <= 16 lanes run on the calling thread without it, too small to matter),
    so the tracer never computes with subnormals: the carried power is exactly 0 from the order
    where it would be subnormal on, and the spectra, raw data, image and energies hold no
    subnormal float32 value. (Timing belongs in benchmarks.)"""
    import re

    import mitsuba as mi
    n = 1024
    product = mi.Float(np.full(n, 1e-30, np.float32)) * mi.Float(np.full(n, 1e-10, np.float32))
    assert np.all(product.numpy() == 0), "Dr.Jit's LLVM backend no longer flushes subnormals to zero (FTZ)"

    text = (SCENES / "canyon.xml").read_text()
    vacuum = ('<bsdf type="radar" id="concrete"><float name="relative_permittivity" value="1.0001"/>'
              '<float name="conductivity" value="0"/><string name="model" value="half_space"/></bsdf>')
    text = re.sub(r'<bsdf type="radar" id="concrete">.*?</bsdf>', vacuum, text, flags=re.S)
    xml = tmp_path / "vacuum_canyon.xml"
    xml.write_text(text)
    sim = simulate(str(xml))
    carried = sim.trace.carried_power_per_order
    assert carried.shape == (10,) and carried[0] > 0
    positive = carried[carried > 0]
    assert np.all(positive[1:] < 1e-4 * positive[:-1]), carried          # measured 2e-6, then 1e-11
    assert 0 < positive.size < 10 and np.all(carried[positive.size:] == 0), carried
    assert sim.trace.rays_per_order[positive.size] > 0, "rays do reach the first order carrying 0"
    assert positive[-1] >= FLOAT32_TINY                                  # 0, never subnormal
    for name, values in (("spectrum", sim.trace.spectrum), ("raw", sim.raw.data), ("image", sim.image.data),
                         ("energy", sim.trace.energy_per_order.astype(np.float32)),
                         ("carried", carried.astype(np.float32))):
        assert np.all(np.isfinite(values)), name
        assert _subnormal_count(values) == 0, name
    assert sim.trace.energy_per_order[0] > 0


# --------------------------------------------------------------------------------------------
# 5. Ctrl-C
# --------------------------------------------------------------------------------------------

FINAL_FILES = ("raw.npz", "image.npz", "image.exr", "image.png", "summary.json")


def _assert_final_files_complete(out: Path) -> list[str]:
    """Every final-named output in ``out`` loads completely; returns the names present."""
    import json

    import matplotlib.image
    import OpenEXR

    from sarmitsuba.core.image import SarImage
    from sarmitsuba.core.raw import RawData
    present = [name for name in FINAL_FILES if (out / name).exists()]
    for name in present:
        path = out / name
        if name == "raw.npz":
            assert np.all(np.isfinite(RawData.load(path).data))
        elif name == "image.npz":
            assert np.all(np.isfinite(SarImage.load(path).data))
        elif name == "image.exr":
            assert OpenEXR.File(str(path)).channels()["intensity"].pixels.size > 0
        elif name == "image.png":
            assert matplotlib.image.imread(path).shape[0] > 100
        else:
            assert "timings" in json.loads(path.read_text())
    return present


def test_ctrl_c_while_tracing_exits_130_and_leaves_no_truncated_output(tmp_path):
    """``python -m sarmitsuba render`` gets SIGINT once its trace progress bar is up: exit code
    130, the "interrupted" message, and every final-named output either absent or complete.
    The render is long (the urban scene with ~2 G rays, about a minute when not interrupted),
    so the signal arrives during tracing on any machine; if the run still finished first, it
    is retried with finer rays."""
    for attempt, spacing in enumerate((0.05, 0.02)):
        out = tmp_path / f"run{attempt}"
        proc = subprocess.Popen(
            [sys.executable, "-m", "sarmitsuba", "render", "urban", "--out", str(out),
             "--ray-spacing", str(spacing)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            # a shell's background job (CI runners, nohup ... &) inherits SIGINT ignored, and then
            # Python installs no KeyboardInterrupt handler: give the child the default disposition
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        seen, tracing = [], threading.Event()

        def read(stream=proc.stderr):
            for char in iter(lambda: stream.read(1), ""):
                seen.append(char)
                if char == "|" and "trace" in "".join(seen[-64:]):
                    tracing.set()
        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        try:
            assert tracing.wait(120), "the render never started tracing: " + "".join(seen)[-2000:]
            time.sleep(0.3)
            proc.send_signal(signal.SIGINT)
            code = proc.wait(120)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        reader.join(10)
        stderr = "".join(seen)
        if code == 0:                       # finished before the signal: try a longer run
            continue
        assert code == 130, stderr[-2000:]
        assert "interrupted" in stderr
        _assert_final_files_complete(out)
        return
    pytest.fail("the render finished before SIGINT twice")


@pytest.mark.parametrize("victim", FINAL_FILES)
def test_interrupt_during_each_output_write(tmp_path, monkeypatch, victim):
    """Ctrl-C arriving while ``victim`` is being written (its staged file complete, the move into
    place not yet done): ``render`` exits 130 and the output is all or nothing
    (sarmitsuba/core/outputs.py): no product at all, no staging folder, no ``.partial`` file, and
    the directory the run created is gone; an existing directory keeps only what it held."""
    from sarmitsuba.cli import main
    real_replace = os.replace

    def interrupted(src, dst, *args, **kwargs):
        if Path(dst).name == victim:
            raise KeyboardInterrupt
        return real_replace(src, dst, *args, **kwargs)

    monkeypatch.setattr(os, "replace", interrupted)
    out = tmp_path / "out"
    assert main(["render", "trihedral", "--out", str(out), "--no-progress"]) == 130
    assert not out.exists()
    kept = tmp_path / "kept"
    kept.mkdir()
    (kept / "mine.txt").write_text("a user's file")
    assert main(["render", "trihedral", "--out", str(kept), "--no-progress"]) == 130
    assert sorted(p.name for p in kept.iterdir()) == ["mine.txt"]


def test_interrupt_in_the_middle_of_writing_raw_data(tmp_path, monkeypatch):
    """Ctrl-C while np.savez is half-way through raw.npz: exit 130, nothing left behind."""
    from sarmitsuba.cli import main

    def half_written(file, **arrays):
        file.write(b"PK\x03\x04" + b"\0" * 1000)
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savez", half_written)
    out = tmp_path / "out"
    out.mkdir()
    assert main(["render", "trihedral", "--out", str(out), "--no-progress"]) == 130
    assert sorted(p.name for p in out.iterdir()) == []


# --------------------------------------------------------------------------------------------
# 6. Fresnel: continuous near vacuum and toward a perfect conductor
# --------------------------------------------------------------------------------------------

def test_fresnel_is_continuous_near_vacuum_and_toward_pec():
    """What tests/test_materials.py does not cover (it has |r| <= 1 and finiteness for eta near 1
    and very lossy, the PEC limit at one conductivity, and r(cos = 0) = -1 / +1):

    - eta = 1 + delta -> vacuum: r vanishes linearly, r_TE / delta -> -1 / (4 cos^2) and
      r_TM / delta -> (1 - 2 cos^2) / (4 cos^2), down to delta = 1e-12 (complex delta too);
    - eta = 1 - j X -> PEC: |r_TE + 1| -> 2 cos / sqrt(X) and |r_TM + 1| -> 2 / (cos sqrt(X))
      (1 % for X >= 1e8), i.e. r joins the PEC model's -1 continuously;
    - lossless -> lossy, including eps_r < 1 (total reflection beyond the critical angle,
      where sqrt(eta - sin^2) is imaginary): adding a loss of 1e-9 moves r by < 1e-3
      (measured at most 7e-6; a branch flip of the square root would move it by up to 2);
    - r(cos) has no jump: refining the cos grid 100-fold shrinks the largest step at least
      3-fold (a jump would not shrink it; measured 44-100-fold, 5.6-fold at the critical
      angle of eps_r = 0.05, a square-root edge), for half space and slab.

    r(cos = 0) itself is not continuous in eta at eta = 1 (-1 for any eta != 1, 0 for
    vacuum; documented in fresnel_half_space), so cos >= 1e-3 here."""
    from sarmitsuba.scene.materials import fresnel_half_space, slab_reflection
    cos = np.array([0.1, 0.3, 0.7, 1.0])
    for delta in (1e-4, 1e-8, 1e-12, 1e-8 * (1 - 0.5j)):
        te, tm = fresnel_half_space(cos, 1 + delta)
        te_expected, tm_expected = -1 / (4 * cos**2), (1 - 2 * cos**2) / (4 * cos**2)
        tol = 1e-3 / cos**2 + 10 * abs(delta) / cos**6
        assert np.all(np.abs(te / delta - te_expected) < tol), (delta, te / delta)
        assert np.all(np.abs(tm / delta - tm_expected) < tol), (delta, tm / delta)
    for x in (1e8, 1e12, 1e15):
        te, tm = fresnel_half_space(cos, 1 - 1j * x)
        assert np.allclose(np.abs(te + 1) * math.sqrt(x) / (2 * cos), 1, rtol=0.01)
        assert np.allclose(np.abs(tm + 1) * math.sqrt(x) * cos / 2, 1, rtol=0.01)
    grid = np.linspace(1e-3, 1.0, 20_001)
    models = {"half_space": lambda c, eta: fresnel_half_space(c, eta),
              "slab": lambda c, eta: slab_reflection(c, eta, 0.05, 9.6e9)}
    for eps in (0.05, 0.5, 4.0, 80.0):
        for model, f in models.items():
            for lossless, lossy in zip(f(grid, eps), f(grid, eps - 1e-9j)):
                assert np.abs(lossless - lossy).max() < 1e-3, (eps, model)
    coarse, fine = np.linspace(1e-3, 1.0, 1_001), np.linspace(1e-3, 1.0, 100_001)
    for eta in (1 + 1e-6, 1 - 1e-6j, 0.05, 1 - 1e12j, 3.91 - 0.064j):
        for model, f in models.items():
            for r_coarse, r_fine in zip(f(coarse, eta), f(fine, eta)):
                step_coarse, step_fine = np.abs(np.diff(r_coarse)).max(), np.abs(np.diff(r_fine)).max()
                assert np.all(np.isfinite(r_fine)) and np.abs(r_fine).max() <= 1 + 1e-12
                assert step_fine < step_coarse / 3 or step_coarse < 1e-9, (eta, model, step_coarse, step_fine)


@pytest.mark.parametrize("lit_regions", ["patches", "tiles"])
def test_ctrl_c_inside_the_traced_loop_body_is_an_interrupt(monkeypatch, lit_regions):
    """Dr.Jit wraps an exception raised while it traces a loop's body (the patches' pulse loop,
    the tubes' bounce) in a RuntimeError; a Ctrl-C landing there must still reach the CLI as
    KeyboardInterrupt (exit 130), not as a crash with exit code 1."""
    from sarmitsuba.tracing.integration import patch_terms as integration
    from sarmitsuba.tracing.driver import kernel as kernel_module
    from sarmitsuba.pipeline import simulate

    def interrupted(self, *args):
        raise KeyboardInterrupt

    if lit_regions == "tiles":
        monkeypatch.setattr(kernel_module.Kernel, "_bounce", interrupted)
    else:
        monkeypatch.setattr(integration.PatchTerms, "_pulse", interrupted)
    with pytest.raises(KeyboardInterrupt):
        simulate("trihedral", sensor_overrides={"n_pulses": 4},
                 integrator_overrides={"max_depth": 3, "lit_regions": lit_regions})
