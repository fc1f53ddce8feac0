"""The phase gradient kernel of phase gradient autofocus on the point-like range lines
(docs/physics.md (PGA)): centre, window, estimate, integrate, iterate.

Every function works on the azimuth spectra of the lines PGA learns from, ``[n, m]`` complex (``n``
spectral samples in centred order, ``m`` lines), or on those lines in the image domain. The image
domain of an ``n``-sample spectrum is periodic: the lines are circularly shifted to put their
brightest sample at index 0 (:func:`centre_lines`), so that a response split across the ends of
the image stays in one piece about that index, and every distance from it is circular
(:func:`circular_distance`): the window keeps the samples on both sides of the centre.

References
----------
.. [1] D. E. Wahl, P. H. Eichel, D. C. Ghiglia and C. V. Jakowatz, "Phase gradient autofocus: a
   robust tool for high resolution SAR phase correction", IEEE Trans. Aerosp. Electron. Syst.
   30(3), 827-835, 1994.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

__all__ = ["circular_distance", "centre_lines", "smear_width", "apply_phase", "estimate_phase", "extend_phase",
           "detrend_phase", "spectral_power", "weighted_rms", "iterate", "Iteration"]


def circular_distance(n: int) -> np.ndarray:
    """int [n]: the circular distance [samples] of each index from index 0, ``min(k, n - k)``."""
    k = np.arange(n)
    return np.minimum(k, n - k)


def centre_lines(lines: np.ndarray) -> np.ndarray:
    """Step 1 of (PGA): every column of ``lines`` [n, m] circularly shifted so that its brightest
    sample sits at index 0 (the origin of the FFT: no linear phase is left in its spectrum)."""
    n = lines.shape[0]
    rows = (np.arange(n)[:, None] + np.argmax(np.abs(lines), axis=0)[None, :]) % n
    return np.take_along_axis(lines, rows, axis=0)


def smear_width(centred: np.ndarray, level_db: float, widen: float, background: float | None = None) -> int:
    """The first window [samples]: ``widen`` times the circular extent, about index 0, of the
    centred lines' summed intensity above ``-level_db`` of its peak (Wahl et al. section III-C:
    -10 dB) and, where ``background`` is given, above ``background`` times its median (the level
    of what surrounds the response); every sample above counts, so that paired echoes split by a
    gap stay inside. At least 1, at most ``n``."""
    intensity = np.sum(np.abs(centred) ** 2, axis=1)
    level = intensity.max() * 10.0 ** (-level_db / 10.0)
    if background is not None:
        level = max(level, background * float(np.median(intensity)))
    above = intensity >= level
    width = int(np.ceil(widen * (2 * np.max(circular_distance(centred.shape[0])[above]) + 1)))
    return int(np.clip(width, 1, centred.shape[0]))


def apply_phase(spectrum: np.ndarray, phase: np.ndarray) -> np.ndarray:
    """The image domain of the centred-order azimuth ``spectrum`` [n, m] with ``exp(-j phase)``
    removed: ``phase`` float [n] (one for every line) or [n, m]."""
    phase = phase if phase.ndim == 2 else phase[:, None]
    return np.fft.ifft(np.fft.ifftshift(spectrum * np.exp(-1j * phase), axes=0), axis=0)


def spectral_power(centred: np.ndarray) -> np.ndarray:
    """float64 [n]: the summed spectral power of the centred lines [n, m], centred order."""
    return np.fft.fftshift(np.sum(np.abs(np.fft.fft(centred, axis=0)) ** 2, axis=1))


def estimate_phase(centred: np.ndarray, width: int, support_db: float,
                   band: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Steps 2-3 of (PGA) on the centred lines [n, m]: the lines windowed to the samples within
    ``width // 2`` (circularly) of index 0, their spectra ``G_n(u)`` and the maximum-likelihood
    gradient ``arg sum_n G_n(u) G_n*(u - 1)``, integrated over the supported samples (within
    ``support_db`` of the summed power's peak, and within ``band``, bool [n], where given; no
    gradient across a gap) and less its power-weighted mean and linear trend.

    Returns
    -------
    phase : float64 [n], rad
        Centred order; held at the support's end values beyond it, interpolated across its gaps.
    support : bool [n]
    power : float64 [n]
        The windowed lines' summed spectral power.
    """
    keep = circular_distance(centred.shape[0]) <= width // 2
    spectra = np.fft.fftshift(np.fft.fft(np.where(keep[:, None], centred, 0.0), axis=0), axes=0)
    power = np.sum(np.abs(spectra) ** 2, axis=1)
    support = power >= power.max() * 10.0 ** (-support_db / 10.0)
    if band is not None:
        support &= band
    gradient = np.angle(np.sum(spectra[1:] * np.conj(spectra[:-1]), axis=1))
    gradient = np.where(support[1:] & support[:-1], gradient, 0.0)
    phase = np.concatenate([[0.0], np.cumsum(gradient)])
    return extend_phase(detrend_phase(phase, support, power), support), support, power


def extend_phase(phase: np.ndarray, support: np.ndarray) -> np.ndarray:
    """``phase`` on ``support``, interpolated linearly across its gaps and held constant beyond its
    ends (the weak spectral samples just outside still get the error of their neighbours)."""
    k = np.arange(phase.size)
    return np.interp(k, k[support], phase[support]) if support.any() else np.zeros_like(phase)


def detrend_phase(phase: np.ndarray, support: np.ndarray, power: np.ndarray) -> np.ndarray:
    """``phase`` less its power-weighted mean and linear trend over ``support`` (centred order)."""
    k = np.arange(phase.size, dtype=float)
    w = np.where(support, power, 0.0)
    if not w.sum() > 0:
        return np.zeros_like(phase)
    slope, offset = np.polyfit(k[support], phase[support], 1, w=np.sqrt(w[support]))
    return phase - (slope * k + offset)


def weighted_rms(phase: np.ndarray, support: np.ndarray, power: np.ndarray, level_db: float) -> float:
    """Power-weighted rms [rad] of ``phase`` over the samples of ``support`` within ``level_db`` of the
    peak ``power`` (the weak samples carry too little signal to say whether it converged)."""
    w = np.where(support & (power >= power.max() * 10.0 ** (-level_db / 10.0)), power, 0.0)
    return float(np.sqrt(np.sum(w * phase ** 2) / w.sum())) if w.sum() > 0 else 0.0


@dataclasses.dataclass(frozen=True)
class Iteration:
    """What :func:`iterate` found: the summed correction (float64 [n], rad, centred order), its
    support (bool [n]), the last centred lines ([n, m]), the window of every iteration [samples] and
    whether the last correction fell below the tolerance."""

    total: np.ndarray
    support: np.ndarray
    centred: np.ndarray
    widths: list[int]
    converged: bool


def _next_width(width: int | None, first: int | None, floor: int, centred: np.ndarray,
                options: dict[str, Any]) -> tuple[int, int]:
    """The window of the next iteration and the first one: the smear's width (:func:`smear_width`),
    no wider than ``options["max_window"]`` where given, at first; then ``shrink`` times the last,
    never below ``floor``, nor below ``first / first_floor`` (a window narrower than the error's
    paired echoes cuts them off)."""
    n = centred.shape[0]
    if width is None:
        first = smear_width(centred, options["window_db"], options["widen"], options.get("background"))
        width = first = min(first, options.get("max_window") or n)
    else:
        width = max(options["min_window"], first // options["first_floor"], int(width * options["shrink"]))
    return min(max(width, floor, options["min_window"]), n), first


def _cells_floor(n: int, support: np.ndarray, cells: int) -> int:
    """Eq. (PGA6): the narrowest window, whose smoothing of the spectrum (``n / W`` samples) is the
    estimate's ``support`` over ``cells``."""
    return int(np.ceil(n * cells / max(int(support.sum()), 1)))


def _floor(spectrum: np.ndarray, options: dict[str, Any]) -> int:
    """The first iteration's narrowest window: :func:`_cells_floor` of the unwindowed lines' support
    where ``options["cells"]`` is given, else ``min_window``."""
    if not options.get("cells"):
        return options["min_window"]
    power = np.sum(np.abs(spectrum) ** 2, axis=1)
    support = power >= power.max() * 10.0 ** (-options["support_db"] / 10.0)
    if options.get("band") is not None:
        support &= options["band"]
    return max(options["min_window"], _cells_floor(spectrum.shape[0], support, options["cells"]))


def iterate(spectrum: np.ndarray, options: dict[str, Any], progress: bool = False) -> Iteration:
    """Steps 1-4 of (PGA), iterated on the point-like lines' spectra [n, m] (centred order).

    ``options``: ``max_iterations``, ``min_iterations``, ``tolerance`` [rad], ``window_db``, ``widen``,
    ``shrink``, ``min_window``, ``first_floor``, ``support_db``, ``rms_db``, and optionally
    ``max_window`` (the widest first window [samples]), ``band`` (bool [n]: the samples that may carry
    an estimate) and ``cells`` (eq. (PGA6): the narrowest window is ``n cells / support``)."""
    from tqdm.auto import tqdm
    total = np.zeros(spectrum.shape[0])
    widths: list[int] = []
    converged = False
    width = first = None
    floor = _floor(spectrum, options)
    bar = tqdm(total=options["max_iterations"], desc="PGA", unit="iteration", disable=not progress)
    try:
        for _ in range(options["max_iterations"]):
            centred = centre_lines(apply_phase(spectrum, total))
            width, first = _next_width(width, first, floor, centred, options)
            widths.append(width)
            step, support, power = estimate_phase(centred, width, options["support_db"], options.get("band"))
            if options.get("cells"):
                floor = _cells_floor(centred.shape[0], support, options["cells"])
            total = total + step
            bar.update(1)
            if len(widths) >= options["min_iterations"] and \
                    weighted_rms(step, support, spectral_power(centred), options["rms_db"]) < options["tolerance"]:
                converged = True
                break
    finally:
        bar.close()
    return Iteration(total, support, centred, widths, converged)
