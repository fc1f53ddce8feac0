"""Backprojection against closed forms (docs/design.md section 9).

Raw data are synthesised analytically here, never by the tracer: for a point target of
complex amplitude ``a`` at ``X`` and a monostatic antenna at ``S_p``, range-compressed
sample ``i`` of pulse ``p`` is

    a * sinc(B (t_i - L / c)) * exp(-j 2 pi frac(fc L / c)),   L = 2 |S_p - X|,

with ``L`` and the carrier phase in float64 (numpy's unit-peak ``sinc``). The track runs
along +x, the sensor sits on the +y side and looks toward -y (docs/design.md section 4). The
point-target analysis follows ISCE3 and Aresys practice (:mod:`sarmitsuba.analysis.point_target`): chip,
remove the linear phase ramp, FFT-oversample (32x), peak, cuts, -3 dB widths, peak phase with
the ramp restored.
"""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus import ImageGrid, backproject, backproject_reference
from sarmitsuba.core.raw import RawData

FC = 9.6e9  # Hz, X band
B = 150e6  # Hz
WAVELENGTH = C / FC
SLANT_IRW = 0.886 * C / (2 * B)  # m, rect spectrum


# ============================================================================ synthesis
@dataclasses.dataclass(frozen=True)
class Geometry:
    """Straight track along +x at ``altitude``, offset ``ground_offset`` toward +y."""

    altitude: float
    ground_offset: float
    aperture: float  # m, track length (uniform illumination over it)
    pulse_spacing: float  # m
    fs_factor: float = 1.2

    @property
    def closest_range(self) -> float:
        return float(np.hypot(self.altitude, self.ground_offset))

    @property
    def sin_incidence(self) -> float:
        return self.ground_offset / self.closest_range

    def azimuth_irw(self) -> float:
        """0.886 lambda R / (2 L) for a uniformly illuminated aperture of length L."""
        return 0.886 * WAVELENGTH * self.closest_range / (2 * self.aperture)

    def ground_range_irw(self) -> float:
        return SLANT_IRW / self.sin_incidence


AIRBORNE = Geometry(altitude=3000.0, ground_offset=4000.0, aperture=140.0, pulse_spacing=0.25)
ORBIT_800KM = Geometry(altitude=800e3 * np.cos(np.deg2rad(30.0)), ground_offset=800e3 * np.sin(np.deg2rad(30.0)),
                       aperture=5500.0, pulse_spacing=5.0)


def simulate(geometry: Geometry, targets: list[tuple[tuple[float, float, float], complex]], *,
             rx_offset: tuple[float, float, float] | None = None, margin: float = 30.0,
             window: tuple[float, float] | None = None) -> RawData:
    """Analytic range-compressed RawData for point ``targets`` [(xyz, amplitude)].

    ``rx_offset`` makes the data bistatic (receiver = transmitter + offset). ``window``
    overrides the fast-time window ``(t_first, t_last)`` in seconds.
    """
    fs = geometry.fs_factor * B
    xs = np.arange(-geometry.aperture / 2, geometry.aperture / 2 + 1e-9, geometry.pulse_spacing)
    tx = np.stack([xs, np.full_like(xs, geometry.ground_offset), np.full_like(xs, geometry.altitude)], axis=1)
    rx = tx + np.asarray(rx_offset, float) if rx_offset is not None else tx.copy()
    points = np.array([t[0] for t in targets], float)
    lengths = (np.linalg.norm(tx[:, None, :] - points[None], axis=-1)
               + np.linalg.norm(points[None] - rx[:, None, :], axis=-1))  # float64 [P, T]
    if window is None:
        window = ((lengths.min() - 2 * margin) / C, (lengths.max() + 2 * margin) / C)
    n_samples = int(np.ceil((window[1] - window[0]) * fs)) + 1
    fast_time = window[0] + np.arange(n_samples) / fs
    data = np.zeros((xs.size, n_samples), np.complex128)
    for k, (_, amplitude) in enumerate(targets):
        carrier = np.exp(-2j * np.pi * np.mod(FC * lengths[:, k] / C, 1.0))
        data += amplitude * np.sinc(B * (fast_time[None, :] - lengths[:, k, None] / C)) * carrier[:, None]
    speed = 100.0
    return RawData(data=data.astype(np.complex64), fast_time=fast_time, pulse_time=xs / speed,
                   tx_position=tx, rx_position=rx, velocity=np.tile([speed, 0.0, 0.0], (xs.size, 1)),
                   fc=FC, bandwidth=B, chirp_rate=B / 10e-6, pulse_length=10e-6, fs=fs,
                   prf=speed / geometry.pulse_spacing, range_compressed=True,
                   metadata={"scene": "analytic point targets", "units": "sqrt(m^2)"})


def ground_grid(half_extent: float, spacing: float, **kw) -> ImageGrid:
    return ImageGrid.ground((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, -1.0, -1.0),
                            2 * half_extent, 2 * half_extent, spacing, **kw)


# ============================================================================ point-target analysis
def _upsample_axis(x: np.ndarray, factor: int, axis: int) -> np.ndarray:
    """Periodic FFT interpolation along ``axis`` (Nyquist bin split), amplitude preserved."""
    n = x.shape[axis]
    spec = np.moveaxis(np.fft.fft(x, axis=axis), axis, -1)
    big = np.zeros(spec.shape[:-1] + (n * factor,), complex)
    h = (n + 1) // 2
    big[..., :h] = spec[..., :h]
    if n % 2 == 0:
        big[..., h] = big[..., -h] = 0.5 * spec[..., h]
        big[..., n * factor - h + 1:] = spec[..., h + 1:]
    else:
        big[..., n * factor - (n - h):] = spec[..., h:]
    return np.moveaxis(np.fft.ifft(big, axis=-1) * factor, -1, axis)


def _width(cut: np.ndarray, peak: int) -> float:
    """-3 dB width (samples) of a power cut around index ``peak``, linear interpolation."""
    half = cut[peak] / 2.0
    lo = peak
    while cut[lo - 1] > half:
        lo -= 1
    hi = peak
    while cut[hi + 1] > half:
        hi += 1
    left = lo - (cut[lo] - half) / (cut[lo] - cut[lo - 1])
    right = hi + (cut[hi] - half) / (cut[hi] - cut[hi + 1])
    return right - left


def analyse(image, point, *, half: int = 16, factor: int = 32) -> dict[str, float]:
    """Peak position (m, grid axes), IRWs (m) and peak magnitude of the target near ``point``.

    The peak *phase* is not taken from the oversampled chip: a ground-range BP image keeps
    the carrier ramp ``exp(j 4 pi sin(theta) x / lambda)`` (about 80 rad per 0.25 m pixel
    at X band), which the pixels alias, so the phase between pixels is only defined once
    that ramp is removed with the geometry (the peak phase is defined after removing the
    two-way carrier 4 pi R0 / lambda, docs/physics.md (S1), (S3)). :func:`value_at` evaluates
    the image exactly at a point instead.
    """
    row, col = (int(round(v)) for v in image.pixel_of(np.asarray(point, float)))
    chip = image.data[row - half:row + half, col - half:col + half].astype(np.complex128)
    assert chip.shape == (2 * half, 2 * half), "target too close to the image edge"
    ramp_a = np.angle(np.sum(chip[1:] * np.conj(chip[:-1])))
    ramp_r = np.angle(np.sum(chip[:, 1:] * np.conj(chip[:, :-1])))
    n = np.arange(2 * half)
    base = chip * np.exp(-1j * (ramp_a * n[:, None] + ramp_r * n[None, :]))
    up = _upsample_axis(_upsample_axis(base, factor, 0), factor, 1)
    power = np.abs(up) ** 2
    pi, pj = np.unravel_index(np.argmax(power), power.shape)

    def vertex(y0, y1, y2):  # parabolic refinement of the maximum
        return 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)

    fi = pi + vertex(*np.log(power[pi - 1:pi + 2, pj]))
    fj = pj + vertex(*np.log(power[pi, pj - 1:pj + 2]))
    d_az = image.azimuth[1] - image.azimuth[0]
    d_rg = image.range[1] - image.range[0]
    return {
        "azimuth": image.azimuth[row - half] + fi / factor * d_az,
        "range": image.range[col - half] + fj / factor * d_rg,
        "irw_azimuth": _width(power[:, pj], pi) / factor * d_az,
        "irw_range": _width(power[pi, :], pj) / factor * d_rg,
        "peak_magnitude": float(np.abs(up[pi, pj])),
    }


def value_at(raw: RawData, image, point) -> complex:
    """The focused image at ``point`` exactly: backprojection onto a one-pixel grid there."""
    grid = ImageGrid(origin=np.asarray(point, float), azimuth_direction=image.azimuth_direction,
                     range_direction=image.range_direction, azimuth=np.zeros(1), range=np.zeros(1))
    return complex(backproject(raw, grid).data[0, 0])


def grid_coordinates(grid: ImageGrid, point) -> tuple[float, float]:
    rel = np.asarray(point, float) - grid.origin
    return float(rel @ grid.azimuth_direction), float(rel @ grid.range_direction)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a.astype(np.complex128).ravel(), b.astype(np.complex128).ravel()
    return float(abs(np.vdot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)))


def phase_error_deg(measured: complex, expected: complex) -> float:
    return float(np.rad2deg(abs(np.angle(measured * np.conj(expected)))))


# ============================================================================ closed-form tests
TARGET_A = ((0.37 * 0.25, -0.21 * 0.25, 0.0), 1.0 * np.exp(0.7j))  # sub-pixel offset
TARGET_B = ((-5.03, -5.58, 0.0), 0.5 * np.exp(-2.1j))  # 10 azimuth / 5 range cells away


@pytest.fixture(scope="module", params=[1.2, 2.0], ids=["fs=1.2B", "fs=2B"])
def airborne(request):
    geometry = dataclasses.replace(AIRBORNE, fs_factor=request.param)
    raw = simulate(geometry, [TARGET_A, TARGET_B])
    grid = ground_grid(10.0, 0.25)
    return geometry, raw, grid, backproject(raw, grid)


@pytest.mark.parametrize("target", [TARGET_A, TARGET_B], ids=["A", "B"])
def test_point_target_closed_forms(airborne, target):
    geometry, raw, grid, image = airborne
    (point, amplitude) = target
    pta = analyse(image, point)
    true_az, true_rg = grid_coordinates(grid, point)
    res_az, res_rg = geometry.azimuth_irw(), geometry.ground_range_irw()
    assert abs(pta["azimuth"] - true_az) < res_az / 20
    assert abs(pta["range"] - true_rg) < res_rg / 20
    assert pta["irw_azimuth"] == pytest.approx(res_az, rel=0.05)
    assert pta["irw_range"] == pytest.approx(res_rg, rel=0.05)
    assert pta["peak_magnitude"] == pytest.approx(abs(amplitude), rel=0.02)  # 1/n_pulses normalisation
    peak = value_at(raw, image, point)
    assert phase_error_deg(peak, amplitude) < 2.0
    assert abs(peak) == pytest.approx(abs(amplitude), rel=0.02)


def test_agrees_with_reference(airborne):
    _, raw, grid, image = airborne
    reference = backproject_reference(raw, grid)
    assert correlation(image.data, reference.data) > 0.999
    assert np.linalg.norm(image.data - reference.data) / np.linalg.norm(reference.data) < 1e-3


def test_800km_slant_range_focuses():
    """Hybrid precision: float32 absolute ranges would be off by 6 cm (12 rad) here."""
    amplitude = 1.0 * np.exp(-1.3j)
    point = (0.41 * 0.5, 0.17 * 0.5, 0.0)
    raw = simulate(ORBIT_800KM, [(point, amplitude)])
    grid = ground_grid(12.0, 0.5)
    image = backproject(raw, grid)
    pta = analyse(image, point)
    true_az, true_rg = grid_coordinates(grid, point)
    assert abs(pta["azimuth"] - true_az) < ORBIT_800KM.azimuth_irw() / 20
    assert abs(pta["range"] - true_rg) < ORBIT_800KM.ground_range_irw() / 20
    assert pta["irw_azimuth"] == pytest.approx(ORBIT_800KM.azimuth_irw(), rel=0.05)
    assert pta["irw_range"] == pytest.approx(ORBIT_800KM.ground_range_irw(), rel=0.05)
    peak = value_at(raw, image, point)
    assert phase_error_deg(peak, amplitude) < 2.0 and abs(peak) == pytest.approx(abs(amplitude), rel=0.02)
    reference = backproject_reference(raw, grid)
    assert correlation(image.data, reference.data) > 0.9999
    row, col = (int(round(v)) for v in image.pixel_of(np.asarray(point)))
    # hybrid precision matches float64 (docs/design.md section 8)
    assert phase_error_deg(image.data[row, col], reference.data[row, col]) < 0.1


# ============================================================================ agreement across paths
SKEWED = ImageGrid(origin=np.array([1.0, -2.0, 0.5]), azimuth_direction=np.array([1.0, 0.0, 0.0]),
                   range_direction=np.array([np.sin(0.35), -np.cos(0.35), 0.0]),
                   azimuth=np.arange(-20, 21) * 0.3, range=np.arange(-25, 26) * 0.3, plane="ground")


@pytest.mark.parametrize("case", ["bistatic", "skewed-grid", "window-edge", "small-blocks", "coarse-grid"])
def test_fast_path_matches_reference(case):
    targets = [TARGET_A, ((2.0, -3.0, 0.0), 0.8j)]
    geometry = dataclasses.replace(AIRBORNE, aperture=60.0, pulse_spacing=0.3)
    grid, kwargs, raw_kw = ground_grid(6.0, 0.25), {}, {}
    if case == "coarse-grid":  # 20 m pixels: tiles shrink to keep float32 residuals small
        targets = [TARGET_A, ((100.0, -120.0, 0.0), 0.8j)]
        grid, raw_kw = ground_grid(300.0, 20.0), {"margin": 400.0}
    elif case == "bistatic":
        raw_kw["rx_offset"] = (0.0, 35.0, -20.0)
    elif case == "skewed-grid":
        grid = SKEWED
    elif case == "window-edge":  # the window ends inside the grid: far pixels are masked
        length = 2 * np.hypot(AIRBORNE.altitude, AIRBORNE.ground_offset)
        raw_kw["window"] = ((length - 40.0) / C, (length + 3.0) / C)
    else:
        kwargs = {"pulse_block": 7, "workers": 2, "oversample": 4}
    raw = simulate(geometry, targets, **raw_kw)
    fast = backproject(raw, grid, **kwargs)
    reference = backproject_reference(raw, grid, oversample=kwargs.get("oversample", 8))
    assert correlation(fast.data, reference.data) > 0.999
    assert np.max(np.abs(fast.data - reference.data)) < 2e-3 * np.max(np.abs(reference.data))
    if case == "window-edge":
        far = grid.range > 1.5 / AIRBORNE.sin_incidence + 0.5  # two-way delay past the window end
        assert np.all(fast.data[:, far] == 0) and np.any(fast.data[:, ~far])


def test_threads_and_blocks_do_not_change_the_result():
    raw = simulate(dataclasses.replace(AIRBORNE, aperture=40.0), [TARGET_A])
    grid = ground_grid(4.0, 0.25)
    one = backproject(raw, grid, workers=1, pulse_block=1000)
    two = backproject(raw, grid, workers=2, pulse_block=13)
    assert np.allclose(one.data, two.data, rtol=0, atol=1e-5 * np.abs(one.data).max())


def test_fft_upsample_is_band_limited_interpolation():
    from sarmitsuba.focus.backprojection import _fft_upsample

    fs, factor = 1.2 * B, 8
    t = np.arange(200) / fs
    delay = 100.37 / fs
    lines = np.stack([np.sinc(B * (t - delay)), 0.5j * np.sinc(B * (t - delay - 7.1 / fs))]).astype(np.complex64)
    fine = _fft_upsample(lines, factor)
    assert fine.shape == (2, 199 * factor + 1) and fine.dtype == np.complex64
    assert np.allclose(fine[:, ::factor], lines, atol=1e-5)
    t_fine = np.arange(fine.shape[1]) / (fs * factor)
    exact = np.stack([np.sinc(B * (t_fine - delay)), 0.5j * np.sinc(B * (t_fine - delay - 7.1 / fs))])
    middle = slice(60 * factor, 140 * factor)  # away from the window edges (truncated sinc tails)
    assert np.max(np.abs(fine[:, middle] - exact[:, middle])) < 5e-3


# ============================================================================ contract and errors
def test_zero_data_gives_zero_image():
    raw = simulate(dataclasses.replace(AIRBORNE, aperture=20.0), [TARGET_A])
    raw = dataclasses.replace(raw, data=np.zeros_like(raw.data))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        image = backproject(raw, ground_grid(3.0, 0.25))
    assert image.data.dtype == np.complex64
    assert np.all(np.isfinite(image.data)) and not np.any(image.data)


def test_image_contract_and_metadata():
    raw = simulate(dataclasses.replace(AIRBORNE, aperture=20.0), [TARGET_A])
    grid = ground_grid(3.0, 0.25)
    image = backproject(raw, grid, oversample=4)
    assert image.data.shape == grid.shape and image.data.dtype == np.complex64
    assert image.plane == "ground" and image.algorithm == "backprojection" and image.window == "rect"
    assert np.array_equal(image.azimuth, grid.azimuth) and np.array_equal(image.range, grid.range)
    assert image.metadata["scene"] == "analytic point targets"
    focus = image.metadata["focus"]
    assert focus["oversample"] == 4 and focus["normalisation"] == "1/n_pulses"
    assert focus["n_pulses"] == raw.n_pulses and focus["seconds"] > 0
    assert "focus" not in raw.metadata  # the input is not mutated


def test_rejects_uncompressed_data():
    raw = simulate(dataclasses.replace(AIRBORNE, aperture=10.0), [TARGET_A])
    raw = dataclasses.replace(raw, range_compressed=False)
    with pytest.raises(ValueError, match="range-compressed"):
        backproject(raw, ground_grid(2.0, 0.25))
    with pytest.raises(ValueError, match="range-compressed"):
        backproject_reference(raw, ground_grid(2.0, 0.25))


@pytest.mark.parametrize("kwargs, match", [({"oversample": 0}, "oversample"), ({"oversample": 2.5}, "oversample"),
                                           ({"pulse_block": 0}, "pulse_block"), ({"workers": 0}, "workers")])
def test_rejects_bad_options(kwargs, match):
    raw = simulate(dataclasses.replace(AIRBORNE, aperture=10.0), [TARGET_A])
    with pytest.raises(ValueError, match=match):
        backproject(raw, ground_grid(2.0, 0.25), **kwargs)


def test_rejects_non_uniform_fast_time():
    raw = simulate(dataclasses.replace(AIRBORNE, aperture=10.0), [TARGET_A])
    fast_time = raw.fast_time.copy()
    fast_time[5:] += 0.3 / raw.fs
    with pytest.raises(ValueError, match="fast_time"):
        backproject(dataclasses.replace(raw, fast_time=fast_time), ground_grid(2.0, 0.25))


# ============================================================================ ImageGrid
def test_ground_grid_geometry():
    grid = ImageGrid.ground((10.0, 20.0, 3.0), (2.0, 0.0, 0.5), (0.3, -1.0, -1.0), 10.0, 6.0, (0.5, 1.0))
    assert grid.shape == (21, 7) and grid.plane == "ground"
    assert np.allclose(grid.azimuth_direction, [1, 0, 0]) and np.allclose(grid.range_direction, [0, -1, 0])
    assert grid.azimuth[10] == 0.0 and grid.range[3] == 0.0
    assert np.allclose(np.diff(grid.azimuth), 0.5) and np.allclose(np.diff(grid.range), 1.0)
    positions = grid.positions()
    assert positions.shape == (21, 7, 3) and positions.dtype == np.float64
    assert np.allclose(positions[10, 3], [10.0, 20.0, 3.0])
    assert np.allclose(positions[10, 4] - positions[10, 3], [0.0, -1.0, 0.0])
    with pytest.raises(ValueError):
        grid.azimuth[0] = 1.0  # read-only arrays: the grid is immutable


@pytest.mark.parametrize("args, match", [
    (((0, 0), (1, 0, 0), (0, -1, -1), 1, 1, 0.1), "origin"),
    (((0, 0, 0), (0, 0, 1), (0, -1, -1), 1, 1, 0.1), "track_direction"),
    (((0, 0, 0), (1, 0, 0), (0, 0, -1), 1, 1, 0.1), "look_direction"),
    (((0, 0, 0), (1, 0, 0), (1, 0, -1), 1, 1, 0.1), "look_direction"),
    (((0, 0, 0), (1, 0, 0), (0, -1, -1), -1, 1, 0.1), "azimuth_extent"),
    (((0, 0, 0), (1, 0, 0), (0, -1, -1), 1, np.nan, 0.1), "range_extent"),
    (((0, 0, 0), (1, 0, 0), (0, -1, -1), 1, 1, 0.0), "spacing"),
])
def test_ground_grid_rejects_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        ImageGrid.ground(*args)


@settings(max_examples=60, deadline=None)
@given(track=st.tuples(*[st.floats(-1, 1)] * 3), look=st.tuples(*[st.floats(-1, 1)] * 3),
       extent=st.floats(0, 50), spacing=st.floats(0.05, 5))
def test_ground_grid_properties(track, look, extent, spacing):
    track_h, look_h = np.array([*track[:2], 0.0]), np.array([*look[:2], 0.0])
    assume(np.linalg.norm(track_h) > 1e-3)
    across = look_h - (look_h @ track_h) / (track_h @ track_h) * track_h
    assume(np.linalg.norm(across) > 1e-3)
    grid = ImageGrid.ground((1.0, 2.0, 3.0), track, look, extent, 0.5 * extent, spacing)
    e_a, e_r = grid.azimuth_direction, grid.range_direction
    assert np.isclose(np.linalg.norm(e_a), 1) and np.isclose(np.linalg.norm(e_r), 1)
    assert abs(e_a @ e_r) < 1e-9 and e_a[2] == 0 and e_r[2] == 0
    assert e_a @ track_h > 0 and e_r @ look_h > 0  # along track, away from the sensor
    for axis, full in ((grid.azimuth, extent), (grid.range, 0.5 * extent)):
        assert axis.size % 2 == 1 and axis[axis.size // 2] == 0 and np.allclose(axis, -axis[::-1])
        assert axis[-1] - axis[0] <= full + 1e-9 and (axis.size == 1 or np.allclose(np.diff(axis), spacing))


def test_grid_validation():
    good = dict(origin=np.zeros(3), azimuth_direction=np.array([1.0, 0, 0]),
                range_direction=np.array([0, -1.0, 0]), azimuth=np.arange(3.0), range=np.arange(4.0))
    ImageGrid(**good)
    for key, value, match in [("azimuth_direction", np.array([2.0, 0, 0]), "unit"),
                              ("range", np.array([0.0, 0.0, 1.0]), "increasing"),
                              ("azimuth", np.array([]), "non-empty"),
                              ("plane", "oblique", "plane")]:
        with pytest.raises(ValueError, match=match):
            ImageGrid(**{**good, key: value})


def _float32_absolute_backprojection(raw, grid, oversample: int = 8) -> np.ndarray:
    """A deliberately naive backprojector: absolute ranges and the carrier phase in float32
    (what the hybrid scheme exists to avoid: the float32 ulp at 800 km is 6.25 cm, up to 12.6 rad
    of two-way phase at X band; docs/design.md section 5)."""
    from scipy.signal import resample
    n = raw.n_samples * oversample
    lines = resample(raw.data, n, axis=1).astype(np.complex64)
    t_up = (raw.fast_time[0] + np.arange(n) / (raw.fs * oversample)).astype(np.float32)
    pixels = grid.positions().reshape(-1, 3).astype(np.float32)
    k = np.float32(2 * np.pi * raw.fc / 299_792_458.0)
    image = np.zeros(len(pixels), np.complex64)
    for p in range(raw.n_pulses):
        two_way = np.float32(2.0) * np.linalg.norm(pixels - raw.tx_position[p].astype(np.float32), axis=1)
        sample = np.interp(two_way / np.float32(299_792_458.0), t_up, lines[p].real) \
            + 1j * np.interp(two_way / np.float32(299_792_458.0), t_up, lines[p].imag)
        image += (sample * np.exp(1j * (k * two_way))).astype(np.complex64)
    return (image / raw.n_pulses).reshape(grid.shape)


def test_float32_absolute_backprojection_fails_at_800km_while_hybrid_passes():
    """Guards the design (issue 4): at 800 km a float32 absolute range is quantised to 6 cm
    (12 rad of X-band two-way phase): the naive image loses its focus (peak > 10 dB down),
    while the hybrid backprojector keeps the full peak."""
    amplitude = 1.0 + 0.0j
    point = (0.0, 0.0, 0.0)
    raw = simulate(ORBIT_800KM, [(point, amplitude)])
    grid = ground_grid(4.0, 0.5)
    hybrid = np.abs(backproject(raw, grid).data).max()
    naive = np.abs(_float32_absolute_backprojection(raw, grid)).max()
    assert hybrid == pytest.approx(abs(amplitude), rel=0.05)
    assert 20 * np.log10(naive / hybrid) < -10.0, f"naive float32 peak only {20 * np.log10(naive / hybrid):.1f} dB down"


# ============================================================================ azimuth weighting
# A target seen through a beam of along-track sines [sin_lo, sin_hi] whose echoes carry the
# two-way pattern g^2 = sinc^2(L / lambda * sin(phi - squint)), focused with a window w(u).
# Second method: the azimuth cut as a 1-D sum over the pulses, I(x) = sum_p [p in the beam
# of the target and of pixel x] g_p^2 w(u_x(p)) exp(j 4 pi (R_p(x) - R_p(0)) / lambda) along a
# line at the closest-approach range, evaluated directly. Without a pattern the -3 dB width is
# also the window's closed form over the Doppler band 2 (sin_hi - sin_lo) / lambda
# (sarmitsuba.focus.windows); its sidelobes are not, because a beam-limited pixel integrates
# only the pulses of its own beam (the window's pedestal is cut off-peak).
BEAM = 0.6  # deg, full width of the traced beam
WEIGHTED = dataclasses.replace(AIRBORNE, aperture=100.0)  # footprint 52 m: the target sees the whole beam


def simulate_beam(geometry: Geometry, target, *, beamwidth: float, pattern: float | None = None,
                  squint: float = 0.0) -> RawData:
    """``simulate`` with every echo gated by the beam and weighted by the two-way pattern."""
    raw = simulate(geometry, [target])
    los = np.asarray(target[0], float) - raw.tx_position
    s = los[:, 0] / np.linalg.norm(los, axis=1)  # track along +x
    phi = np.arcsin(s) - np.radians(squint)
    gain = (np.abs(phi) <= np.radians(beamwidth) / 2).astype(float)
    if pattern is not None:
        gain *= np.sinc(pattern * np.sin(phi)) ** 2
    return dataclasses.replace(raw, data=(raw.data * gain[:, None]).astype(np.complex64))


def azimuth_cut_model(geometry: Geometry, window: str, pattern: float | None, null: float, extent: float,
                      beamwidth: float = BEAM) -> tuple[float, float]:
    """(-3 dB width [m], PSLR [dB]: the highest power between ``null`` and ``extent`` metres
    from the peak) of the 1-D pulse sum above (the second method). The sum changes by a step
    whenever a pulse leaves a pixel's beam, so its shoulders ripple: the first null is taken
    from the measurement rather than searched here."""
    from sarmitsuba.focus.windows import spectral_window
    r0 = geometry.closest_range
    xa = np.arange(-geometry.aperture / 2, geometry.aperture / 2 + 1e-9, geometry.pulse_spacing)
    half = np.sin(np.radians(beamwidth) / 2)
    x = np.arange(-4000, 4001) * 0.003  # pixel offsets along track [m]
    x = x[np.abs(x) <= extent]
    dx = x[:, None] - xa[None, :]
    s_pixel = dx / np.hypot(dx, r0)
    s_target = -xa / np.hypot(xa, r0)
    weight = spectral_window(window, s_pixel / (2 * half), 1.0) * (np.abs(s_target) <= half)
    if pattern is not None:
        weight = weight * np.sinc(pattern * s_target) ** 2
    phase = 4 * np.pi / WAVELENGTH * (np.hypot(dx, r0) - np.hypot(xa, r0))
    power = np.abs((weight * np.exp(1j * phase)).sum(axis=1)) ** 2
    power /= power.max()
    above = np.flatnonzero(power >= 0.5)
    irw = (above.max() - above.min()) * 0.003  # contiguous mainlobe (sidelobes < -3 dB)
    return irw, float(10 * np.log10(power[np.abs(x) >= null].max()))


@pytest.mark.parametrize("window, pattern", [("rect", None), ("taylor", None), ("hamming", None),
                                             ("rect", "nulls"), ("taylor", "nulls")])
def test_weighted_point_target_peaks_at_its_amplitude(window, pattern):
    from sarmitsuba.analysis.point_target import analyze_point_target
    from sarmitsuba.focus import windows

    point, amplitude = (0.3, -0.2, 0.0), 0.7 * np.exp(0.4j)
    length = 1 / np.sin(np.radians(BEAM) / 2) if pattern else None  # first nulls on the traced beam's edges
    raw = simulate_beam(WEIGHTED, (point, amplitude), beamwidth=BEAM, pattern=length)
    image = backproject(raw, ground_grid(8.0, 0.25), azimuth_beamwidth=BEAM, azimuth_pattern=length,
                        window_azimuth=window)
    report = analyze_point_target(image, point, chip=48)
    assert report.peak_magnitude == pytest.approx(abs(amplitude), rel=0.01)
    assert abs(report.azimuth_error) < 0.02 and abs(report.range_error) < 0.02
    extent = report.first_null_azimuth * (1 + report.islr_extent_azimuth)  # where the PSLR was sought
    irw, pslr = azimuth_cut_model(WEIGHTED, window, length, report.first_null_azimuth, extent)
    assert report.irw_azimuth == pytest.approx(irw, rel=0.02)
    assert report.pslr_azimuth_db == pytest.approx(pslr, abs=1.0 if pslr > -45 else 1.5)
    if pattern is None:  # the window's closed form over the Doppler band
        band = 2 * 2 * np.sin(np.radians(BEAM) / 2) / WAVELENGTH
        assert report.irw_azimuth == pytest.approx(windows.impulse_response_width(window) / band, rel=0.02)
    assert report.irw_range == pytest.approx(WEIGHTED.ground_range_irw(), rel=0.03)  # range untouched


@pytest.mark.parametrize("case", ["uniform-rect", "uniform-taylor", "pattern-taylor", "squint-kaiser",
                                  "spotlight-hamming"])
def test_weighted_fast_path_matches_reference(case):
    """The fast path's per (pulse, tile row) weights against the reference's exact per-pixel ones."""
    targets = [TARGET_A, ((2.0, -3.0, 0.0), 0.8j)]
    geometry = dataclasses.replace(AIRBORNE, aperture=100.0, pulse_spacing=0.3)
    kwargs = {"uniform-rect": dict(azimuth_beamwidth=0.5),
              "uniform-taylor": dict(azimuth_beamwidth=0.5, window_azimuth="taylor"),
              "pattern-taylor": dict(azimuth_beamwidth=0.5, window_azimuth="taylor",
                                     azimuth_pattern=1 / np.sin(np.radians(0.25))),
              "squint-kaiser": dict(azimuth_beamwidth=0.5, squint=0.2, window_azimuth=("kaiser", {"beta": 3.0})),
              "spotlight-hamming": dict(window_azimuth="hamming")}[case]
    raw = simulate(geometry, targets)
    grid = ground_grid(6.0, 0.25)
    fast = backproject(raw, grid, **kwargs)
    reference = backproject_reference(raw, grid, **kwargs)
    assert correlation(fast.data, reference.data) > 0.9999
    assert np.max(np.abs(fast.data - reference.data)) < 2e-3 * np.max(np.abs(reference.data))
    assert fast.metadata["focus"]["window_azimuth"] == reference.metadata["focus"]["window_azimuth"]


def test_spotlight_window_keeps_the_peak():
    """Without a beam the window runs over the aperture's pulses; the peak stays a."""
    raw = simulate(dataclasses.replace(AIRBORNE, aperture=40.0), [TARGET_A])
    grid = ground_grid(4.0, 0.25)
    plain, tapered = backproject(raw, grid), backproject(raw, grid, window_azimuth="taylor")
    point, amplitude = TARGET_A
    assert abs(value_at(raw, plain, point)) == pytest.approx(abs(amplitude), rel=0.02)
    one_pixel = ImageGrid(origin=np.asarray(point, float), azimuth_direction=grid.azimuth_direction,
                          range_direction=grid.range_direction, azimuth=np.zeros(1), range=np.zeros(1))
    peak = complex(backproject(raw, one_pixel, window_azimuth="taylor").data[0, 0])
    assert abs(peak) == pytest.approx(abs(amplitude), rel=0.02) and phase_error_deg(peak, amplitude) < 2.0
    # the Taylor mainlobe is wider: less of the energy leaves the peak row's neighbours
    assert analyse(tapered, point)["irw_azimuth"] > 1.2 * analyse(plain, point)["irw_azimuth"]


def test_rect_window_without_pattern_is_the_beam_mask():
    """window rect and no pattern: the same image as before weighting existed (0/1 mask, pulse counts)."""
    from sarmitsuba.focus.backprojection import illumination_count
    raw = simulate(WEIGHTED, [TARGET_A])
    grid = ground_grid(4.0, 0.25)
    image = backproject(raw, grid, azimuth_beamwidth=BEAM)
    explicit = backproject(raw, grid, azimuth_beamwidth=BEAM, window_azimuth="rect", azimuth_pattern=None)
    assert np.array_equal(image.data, explicit.data)
    counts = illumination_count(raw, grid, BEAM, step=1)
    assert image.metadata["focus"]["max_pulses_per_pixel"] == pytest.approx(counts.max(), abs=1.0)
    assert image.window == "rect" and image.metadata["focus"]["window_azimuth"] == {"name": "rect"}


def test_weighting_metadata():
    raw = simulate(WEIGHTED, [TARGET_A])
    image = backproject(raw, ground_grid(2.0, 0.25), azimuth_beamwidth=BEAM, azimuth_pattern=100.0,
                        window_azimuth="taylor", squint=0.1)
    focus = image.metadata["focus"]
    assert focus["window_azimuth"] == {"name": "taylor", "nbar": 4, "sll": -35.0}
    assert focus["window_range"] == {"name": "rect"}
    assert image.window == "range=rect, azimuth=taylor(nbar=4, sll=-35)" == focus["window"]
    assert focus["azimuth_pattern"] == 100.0
    assert focus["beam_sines"] == pytest.approx([np.sin(np.radians(0.1 - BEAM / 2)),
                                                 np.sin(np.radians(0.1 + BEAM / 2))])
    mid = raw.n_pulses // 2
    assert focus["track"]["position"] == pytest.approx(raw.tx_position[mid].tolist())
    assert focus["track"]["direction"] == pytest.approx([1.0, 0.0, 0.0])


@pytest.mark.parametrize("kwargs, match", [
    ({"window_azimuth": "triangle"}, "unknown window"),
    ({"window_azimuth": ("taylor", {"sll": -10})}, "sll"),
    ({"window_azimuth": 3}, "window"),
    ({"azimuth_pattern": 50.0}, "azimuth_pattern needs azimuth_beamwidth"),
    ({"azimuth_pattern": -1.0, "azimuth_beamwidth": 1.0}, "azimuth_pattern"),
    ({"azimuth_pattern": "wide", "azimuth_beamwidth": 1.0}, "azimuth_pattern"),
])
def test_rejects_bad_weighting(kwargs, match):
    raw = simulate(dataclasses.replace(AIRBORNE, aperture=10.0), [TARGET_A])
    for focus in (backproject, backproject_reference):
        with pytest.raises(ValueError, match=match):
            focus(raw, ground_grid(1.0, 0.25), **kwargs)
