"""Phase gradient autofocus (sarmitsuba.focus.autofocus, docs/physics.md (PGA)) against phase
errors put in by hand: the truth is the error injected into the azimuth spectrum of an image of
band-limited point targets, known up to a constant and a linear phase (a shift), which PGA does not
estimate by design (Wahl et al. 1994)."""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.core.image import SarImage
from sarmitsuba.focus.autofocus import AutofocusWarning, pga

N_AZ, N_RG = 256, 48
FREQ = np.fft.fftshift(np.fft.fftfreq(N_AZ))                     # cycles per sample, centred order
U = np.linspace(-1.0, 1.0, N_AZ)
TARGETS = ((60, 5, 1.0), (140, 17, 0.7), (200, 30, 0.5), (100, 41, 0.8))


def _image(data: np.ndarray, **metadata) -> SarImage:
    return SarImage(data=data.astype(np.complex64), azimuth=np.arange(N_AZ) * 0.5, range=np.arange(N_RG) * 0.5,
                    origin=np.zeros(3), azimuth_direction=np.array([1.0, 0.0, 0.0]),
                    range_direction=np.array([0.0, 1.0, 0.0]), metadata=dict(metadata))


def _targets(band: np.ndarray, seed: int = 1) -> np.ndarray:
    """Point targets whose azimuth spectrum fills ``band`` (a flat, unweighted response), with noise
    60 dB below."""
    rng = np.random.default_rng(seed)
    data = np.zeros((N_AZ, N_RG), complex)
    for a, r, amplitude in TARGETS:
        spectrum = np.where(band, amplitude * np.exp(-2j * np.pi * FREQ * a + 1j * rng.uniform(0, 2 * np.pi)), 0)
        data[:, r] += np.fft.ifft(np.fft.ifftshift(spectrum))
    return data + 1e-3 * (rng.normal(size=data.shape) + 1j * rng.normal(size=data.shape))


def _with_error(data: np.ndarray, error: np.ndarray) -> np.ndarray:
    spectrum = np.fft.fftshift(np.fft.fft(data, axis=0), axes=0) * np.exp(1j * error)[:, None]
    return np.fft.ifft(np.fft.ifftshift(spectrum, axes=0), axis=0)


def _peak(data: np.ndarray, a: int, r: int) -> float:
    """Largest magnitude within 2 samples of azimuth ``a`` in column ``r``, FFT-upsampled 8 times
    (the peak wherever a sub-sample shift puts it)."""
    spectrum = np.fft.fftshift(np.fft.fft(data[:, r]))
    fine = np.fft.ifft(np.fft.ifftshift(np.pad(spectrum, 7 * N_AZ // 2))) * 8
    return float(np.max(np.abs(fine[8 * (a - 2):8 * (a + 2)])))


def _no_trend(phase: np.ndarray, band: np.ndarray) -> np.ndarray:
    k = np.arange(phase.size)
    return phase - np.polyval(np.polyfit(k[band], phase[band], 1), k)


ERRORS = {
    "quadratic + sinusoid": 6.0 * U ** 2 + 1.5 * np.sin(2 * np.pi * 2.3 * U),
    "cubic + fast sinusoid": 15.0 * U ** 3 - 4.0 * U ** 2 + 1.2 * np.cos(2 * np.pi * 5.1 * U),
}
BANDS = {"centred": np.abs(FREQ) < 0.25, "off centre (squint)": (FREQ > -0.1) & (FREQ < 0.35)}


@pytest.mark.parametrize("band", BANDS, ids=list(BANDS))
@pytest.mark.parametrize("shape", ERRORS, ids=list(ERRORS))
def test_pga_recovers_the_injected_phase_error(shape, band):
    support = BANDS[band]
    ideal = _targets(support)
    error = np.where(support, ERRORS[shape], 0.0)
    blurred = _with_error(ideal, error)
    peaks = np.array([_peak(ideal, a, r) for a, r, _ in TARGETS])
    assert np.all(np.array([_peak(blurred, a, r) for a, r, _ in TARGETS]) < 0.7 * peaks)   # visibly defocused
    image, report = pga(_image(blurred))
    residual = _no_trend(report.phase_error, support) - _no_trend(error, support)
    injected = np.sqrt(np.mean(_no_trend(error, support)[support] ** 2))
    assert injected > 0.9                                  # rad rms: a real defocus
    assert np.sqrt(np.mean(residual[support] ** 2)) < 0.1  # a peak loss of exp(-0.1^2): 0.04 dB
    assert report.converged and report.lines == len(TARGETS)
    focused = np.array([_peak(image.data, a, r) for a, r, _ in TARGETS])
    assert np.all(np.abs(20 * np.log10(focused / peaks)) < 0.2)                       # peaks back, in place
    assert image.metadata["autofocus"]["iterations"] == report.iterations
    assert image.metadata["autofocus"]["rms_phase_error_rad"] == pytest.approx(report.rms_phase_error)


def test_a_linear_phase_is_a_shift_and_is_left_alone():
    """A linear phase moves the targets but does not defocus them: PGA has nothing to correct, and
    the targets keep their peaks."""
    support = BANDS["centred"]
    shifted = _with_error(_targets(support), np.where(support, 9.0 * U, 0.0))
    image, report = pga(_image(shifted))
    assert report.rms_phase_error < 0.05                  # against 0.9 rad rms of the linear phase itself
    move = 9.0 / (2 * np.pi) * 2 / (N_AZ - 1) * N_AZ      # samples: the linear phase's shift
    for a, r, _ in TARGETS:
        a_moved = int(round(a - move))
        assert abs(20 * np.log10(_peak(image.data, a_moved, r) / _peak(shifted, a_moved, r))) < 0.1


def test_an_image_of_noise_warns():
    rng = np.random.default_rng(3)
    noise = rng.normal(size=(N_AZ, N_RG)) + 1j * rng.normal(size=(N_AZ, N_RG))
    with pytest.warns(AutofocusWarning):
        pga(_image(noise), max_iterations=3)


def test_one_target_is_refused_and_the_image_left_unchanged():
    """One point-like range line is too few to separate the phase error from the target (PGA4):
    PGA warns and returns the image as it came."""
    support = BANDS["centred"]
    one = np.zeros((N_AZ, N_RG), complex)
    one[:, 5] = _targets(support)[:, 5]
    image = _image(_with_error(one, np.where(support, ERRORS["quadratic + sinusoid"], 0.0)))
    with pytest.warns(AutofocusWarning, match="only 1 range line"):
        out, report = pga(image)
    assert not report.applied and np.array_equal(out.data, image.data)


def test_refusals():
    data = _targets(BANDS["centred"])
    with pytest.raises(ValueError, match="circular track"):
        pga(_image(data, radar={"trajectory": "circular"}))
    with pytest.raises(ValueError, match="max_iterations"):
        pga(_image(data), max_iterations=0)
    with pytest.raises(ValueError, match="tolerance"):
        pga(_image(data), tolerance=-1.0)
    with pytest.raises(ValueError, match="8 azimuth samples"):
        pga(SarImage(data=np.ones((4, 4), np.complex64), azimuth=np.arange(4.0), range=np.arange(4.0),
                     origin=np.zeros(3), azimuth_direction=np.array([1.0, 0, 0]), range_direction=np.array([0, 1.0, 0])))
