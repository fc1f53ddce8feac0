"""The sparse tomographic inversion of few scatterers per cell: SL1MMER (docs/physics.md (TS5)).

Zhu and Bamler's "Scale-down by L1 norm Minimization, Model selection, and Estimation
Reconstruction" (IEEE TGRS 48(10), 2010, section III), per pixel of samples ``y`` (``N`` passes)
and steering matrix ``A`` (:func:`sarmitsuba.stacks.tomography.steering` on an elevation grid):

1. **L1-norm minimisation** (basis pursuit denoising, their eq. 9):
   ``min_x 1/2 ||A x - y||^2 + mu ||x||_1`` with ``mu = regularization * max |A^H y|`` (the value
   above which ``x = 0``), solved by cvxpy (Clarabel) as a complex second-order-cone program;
2. **model order selection**: the runs of grid cells where ``|x|`` exceeds a tenth of its peak are
   the candidate scatterers, strongest first; for ``K = 0 ... max_scatterers`` the ``K``
   strongest are refined (step 3) and the order that minimises the Bayesian information
   criterion ``2 N ln(RSS_K / N + floor) + 3 K ln(2 N)`` (three real parameters a scatterer) wins;
3. **parameter estimation**: the ``K`` elevations are refined off the grid by nonlinear least
   squares (``scipy.optimize.least_squares``), the complex amplitudes being the linear
   least-squares fit at each step (variable projection); this debiases the L1 amplitudes.

The solvers are the libraries' (cvxpy, SciPy); this module only poses the problems.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .tomography import PhaseModel, TomographyError, steering

__all__ = ["SparseResult", "sl1mmer", "REGULARIZATION", "NOISE_FLOOR"]

#: Default ``mu / max |A^H y|`` of the L1 step.
REGULARIZATION = 0.05
#: Relative residual power below which the model order selection treats a fit as exact: the
#: information criterion uses ``RSS / N + NOISE_FLOOR |y|^2 / N``.
NOISE_FLOOR = 1e-3
#: A candidate run is where ``|x|`` exceeds this fraction of its peak.
_CANDIDATE = 0.1


@dataclass(frozen=True)
class SparseResult:
    """What :func:`sl1mmer` found, per pixel.

    Attributes
    ----------
    profiles : float64 [P, S]
        ``|x|^2`` of the L1 step on the elevation grid (power, as the beamforming profile).
    elevations : float64 [P, K], m
        The selected scatterers' refined elevations, NaN-padded, strongest first.
    amplitudes : complex128 [P, K]
        Their least-squares complex amplitudes (NaN-padded).
    orders : int [P]
        The selected model order per pixel.
    """

    profiles: np.ndarray
    elevations: np.ndarray
    amplitudes: np.ndarray
    orders: np.ndarray


class _L1Problem:
    """The cvxpy problem of step 1 for ``N`` passes and ``S`` elevations, parameterised (DPP) so
    that it is compiled once and solved per pixel."""

    def __init__(self, n: int, n_s: int) -> None:
        import cvxpy as cp
        self.a = cp.Parameter((n, n_s), complex=True)
        self.y = cp.Parameter(n, complex=True)
        self.mu = cp.Parameter(nonneg=True)
        self.x = cp.Variable(n_s, complex=True)
        self.problem = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(self.a @ self.x - self.y)
                                              + self.mu * cp.norm1(self.x)))

    def solve(self, a: np.ndarray, y: np.ndarray, regularization: float) -> np.ndarray:
        import cvxpy as cp
        self.a.value, self.y.value = a, y
        self.mu.value = regularization * float(np.max(np.abs(np.conj(a).T @ y)))
        try:
            self.problem.solve(solver=cp.CLARABEL)
        except cp.SolverError:
            self.problem.solve(solver=cp.SCS)
        return np.zeros(a.shape[1], complex) if self.x.value is None else np.asarray(self.x.value)


@functools.lru_cache(maxsize=8)
def _problem(n: int, n_s: int) -> _L1Problem:
    """The compiled step-1 problem of ``n`` passes and ``n_s`` elevations, reused across calls."""
    return _L1Problem(n, n_s)


def _candidates(x: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Elevations of the runs of ``|x| > _CANDIDATE max |x|``, power-weighted, strongest run first."""
    power = np.abs(x) ** 2
    if not np.any(power > 0):
        return np.zeros(0)
    on = np.r_[False, np.abs(x) > _CANDIDATE * np.abs(x).max(), False].astype(np.int8)
    starts, ends = np.flatnonzero(np.diff(on) == 1), np.flatnonzero(np.diff(on) == -1)
    runs = [(float(power[a:b].sum()), float(np.sum(power[a:b] * s[a:b]) / power[a:b].sum())) for a, b in zip(starts, ends)]
    return np.array([centre for _, centre in sorted(runs, reverse=True)])


def _one_pixel_model(model: PhaseModel, p: int) -> PhaseModel:
    return PhaseModel(phase=model.phase[:, :, p:p + 1], height=model.height[:, p:p + 1], scale=model.scale,
                      interval=model.interval, fit_error=model.fit_error)


def _refine(y: np.ndarray, model: PhaseModel, start: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Step 3: (elevations [K], amplitudes complex [K], residual power) from ``start`` elevations."""
    from scipy.optimize import least_squares
    lo, hi = model.interval

    def fit(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = steering(model, np.asarray(s))[0]                             # [N, K]
        gamma = np.linalg.lstsq(a, y, rcond=None)[0]
        return gamma, y - a @ gamma

    def residual(s: np.ndarray) -> np.ndarray:
        r = fit(s)[1]
        return np.r_[r.real, r.imag]

    s0 = np.clip(start, lo, hi)
    s = least_squares(residual, s0, bounds=(np.full(s0.size, lo), np.full(s0.size, hi)), x_scale="jac").x
    gamma, r = fit(s)
    return s, gamma, float(np.vdot(r, r).real)


def sl1mmer(y: np.ndarray, model: PhaseModel, s: np.ndarray, *, regularization: float = REGULARIZATION,
            max_scatterers: int = 3, progress: bool = False) -> SparseResult:
    """SL1MMER of pixels' stack samples (module docstring, docs/physics.md (TS5)).

    Parameters
    ----------
    y : complex [P, N]
        Calibrated samples (:func:`sarmitsuba.stacks.tomography.stack_samples`).
    model : PhaseModel
        Of the same ``P`` pixels (:func:`sarmitsuba.stacks.tomography.phase_model`).
    s : float [S], m
        Elevation grid of the L1 step, inside ``model.interval``.
    regularization : float in (0, 1)
        ``mu / max |A^H y|``.
    max_scatterers : int >= 1
        Largest model order tried.
    progress : bool
        A tqdm bar over the pixels.

    Returns
    -------
    SparseResult

    Raises
    ------
    TomographyError
        ``regularization`` outside (0, 1) or ``max_scatterers`` < 1.
    """
    from tqdm.auto import tqdm
    if not (0.0 < regularization < 1.0):
        raise TomographyError(f"regularization = {regularization!r}: give a fraction in (0, 1) of max |A^H y| "
                              f"(default {REGULARIZATION})")
    if int(max_scatterers) != max_scatterers or max_scatterers < 1:
        raise TomographyError(f"max_scatterers = {max_scatterers!r}: give a whole number >= 1 (default 3)")
    y = np.asarray(y, np.complex128)
    n_pix, n = y.shape
    s = np.asarray(s, np.float64)
    problem = _problem(n, s.size)
    profiles = np.zeros((n_pix, s.size))
    elevations = np.full((n_pix, max_scatterers), np.nan)
    amplitudes = np.full((n_pix, max_scatterers), np.nan, complex)
    orders = np.zeros(n_pix, int)
    for p in tqdm(range(n_pix), desc="SL1MMER", unit="px", disable=not progress):
        one = _one_pixel_model(model, p)
        x = problem.solve(steering(one, s)[0], y[p], regularization)
        profiles[p] = np.abs(x) ** 2
        total = float(np.vdot(y[p], y[p]).real)
        best = (2 * n * math.log(total / n + NOISE_FLOOR * total / n + 1e-300), 0, np.zeros(0), np.zeros(0, complex))
        candidates = _candidates(x, s)
        for k in range(1, min(max_scatterers, candidates.size) + 1):
            found, gamma, rss = _refine(y[p], one, candidates[:k])
            bic = 2 * n * math.log(rss / n + NOISE_FLOOR * total / n + 1e-300) + 3 * k * math.log(2 * n)
            if bic < best[0]:
                best = (bic, k, found, gamma)
        _, k, found, gamma = best
        order = np.argsort(-np.abs(gamma))
        elevations[p, :k], amplitudes[p, :k], orders[p] = found[order], gamma[order], k
    return SparseResult(profiles=profiles, elevations=elevations, amplitudes=amplitudes, orders=orders)
