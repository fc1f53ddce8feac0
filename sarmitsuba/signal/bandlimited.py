"""Exact band-limited (periodic DFT) interpolation of uniformly sampled signals.

A signal of ``n`` samples ``x[m]`` whose DFT is ``X[k]`` has the periodic band-limited
interpolant (Oppenheim and Schafer, *Discrete-Time Signal Processing*, 3rd ed., section 8.6)

    x(u) = (1/n) sum_k X[k] exp(2 pi j k u / n),   k in fftfreq order,

which passes through every sample. For even ``n`` the Nyquist bin ``k = n/2`` is split evenly
between ``+n/2`` and ``-n/2``, so its term is ``X[n/2] cos(pi u) / n`` and the interpolant of
a real signal stays real. Point-target analysis and its figure evaluate chips with it.

======================  ==========================================================
:func:`dft_rows`        matrix ``E`` [len(u), n] with ``x(u) = E @ X``
:class:`Interpolant2D`  ``x(u, v)`` of a 2-D array on a grid of rows x columns
======================  ==========================================================
"""
from __future__ import annotations

import numpy as np

__all__ = ["Interpolant2D", "dft_rows"]


def dft_rows(n: int, u: np.ndarray | float) -> np.ndarray:
    """Rows evaluating the periodic band-limited interpolant of ``n`` samples at ``u``.

    Parameters
    ----------
    n : int
        Number of samples (>= 1).
    u : float or array_like
        Positions in sample units (sample ``m`` is at ``u = m``), any real values.

    Returns
    -------
    complex128 [len(u), n]
        ``E`` with ``x(u) = E @ numpy.fft.fft(x)``.
    """
    u = np.atleast_1d(np.asarray(u, dtype=np.float64))
    e = np.exp(2j * np.pi * np.outer(u, np.fft.fftfreq(n))) / n
    if n % 2 == 0:
        e[:, n // 2] = np.cos(np.pi * u) / n          # Nyquist bin split symmetrically
    return e


class Interpolant2D:
    """The band-limited interpolant of a 2-D array (complex or real), separable in rows and columns.

    Parameters
    ----------
    samples : array_like [n_rows, n_columns]
        The samples; ``Interpolant2D(a)(i, j) == a[i, j]`` for integer ``i, j``.
    """

    def __init__(self, samples: np.ndarray) -> None:
        samples = np.asarray(samples)
        self.spectrum = np.fft.fft2(samples)
        self.shape = samples.shape

    def __call__(self, u: np.ndarray | float, v: np.ndarray | float) -> np.ndarray:
        """Values at rows ``u`` x columns ``v`` (sample units): complex128 [len(u), len(v)]."""
        return dft_rows(self.shape[0], u) @ self.spectrum @ dft_rows(self.shape[1], v).T
