"""SAR tomography: a stack of passes on one ground grid, focused in elevation (docs/physics.md (TS1)-(TS7)).

Every pass of a stack is focused by backprojection onto the same ground grid, so pixel ``x`` of
pass ``n`` holds ``y_n(x) = sum_i gamma_i exp(-j phi_n(x, s_i))`` for the scatterers ``i`` that lay
over into ``x`` (docs/physics.md (I2)): each lies on the reference pass's iso-range circle through
``x`` at arc length ``s_i`` (the *elevation*, positive upward) and

    phi_n(x, s) = k [(L_n(x_s) - L_n(x)) - (L_ref(x_s) - L_ref(x))]        (TS2)

with ``L_n`` pass ``n``'s closest-approach two-way length and ``k = 2 pi / lambda``. To first order
``phi_n = 4 pi b_n s / (lambda R)`` (``b_n`` the perpendicular baseline against the reference):
a Fourier pair between baseline and elevation, whence the elevation resolution
``rho_s = lambda R / (2 Delta b)`` and the ambiguity ``lambda R / (2 d_b)`` (TS1).
:func:`phase_model` evaluates (TS2) exactly on a lattice of pixels and elevations, fits a cubic in
``s`` per pass and interpolates across pixels, so the steering vectors carry the curvature of
the wavefronts that the Fourier model drops.

The inversions, per pixel (a vector ``y`` of ``N`` passes, steering ``a(s)``, ``|a_n| = 1``):

* :func:`beamforming`: ``P(s) = |a(s)^H y|^2 / N^2`` (TS3);
* :func:`capon`: ``P(s) = 1 / (a(s)^H R^{-1} a(s))`` with ``R`` the multilooked stack covariance,
  diagonally loaded (TS4);
* :func:`sarmitsuba.stacks.tomo_sparse.sl1mmer`: the compressive-sensing inversion of Zhu and
  Bamler (IEEE TGRS 48(10), 2010) for few scatterers per cell (TS5).

:func:`calibration_phases` calibrates on a surveyed point scatterer and refuses one that does not
stand :data:`MIN_REFERENCE_SCR_DB` over its surroundings (:func:`reference_clutter`, (TS6)).

Sources: G. Fornaro, F. Serafino and F. Soldovieri, "Three-dimensional focusing with
multipass SAR data", IEEE TGRS 41(3), 2003 (beamforming, the steering model);
F. Lombardini and A. Reigber, "Adaptive spectral estimation for multibaseline SAR tomography
with airborne L-band data", IGARSS 2003 (Capon); X. X. Zhu and R. Bamler, "Tomographic SAR
inversion by L1-norm regularization - the compressive sensing approach", IEEE TGRS 48(10), 2010.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from .interferometry import InterferometryError, check_pair, closest_approach_length

__all__ = ["TomographyError", "check_stack", "elevation_points", "PhaseModel", "phase_model", "steering",
           "stack_samples", "calibration_phases", "beamforming", "window_covariance", "capon", "detect_peaks", "elevation_psf",
           "MIN_PASSES", "POLYNOMIAL_DEGREE", "MIN_REFERENCE_SCR_DB", "CLUTTER_BOX", "ReferenceClutter",
           "reference_clutter", "sidelobe_level"]

#: Fewest passes a stack may have.
MIN_PASSES = 3
#: Degree of the per-pixel polynomial in elevation of :class:`PhaseModel`.
POLYNOMIAL_DEGREE = 3
#: Elevation nodes of the exact evaluation (Chebyshev nodes over the elevation interval).
_NODES = 9
#: Signal-to-clutter ratio [dB] a reference point must reach (TS6): its phase error is about
#: 1 / sqrt(2 SCR) = 0.07 rad at 20 dB, whose spread of the profile's power (its square, -23 dB)
#: stays 10 dB under beamforming's -13 dB sidelobes.
MIN_REFERENCE_SCR_DB = 20.0
#: Half-width [pixels] of the box about a reference point whose pixels, less the point's
#: mainlobe, are its surroundings (widened to 3 mainlobes when the mainlobe is wider).
CLUTTER_BOX = 15
#: Pixels per inversion chunk (bounds the steering arrays: chunk x N x S complex128).
_CHUNK = 1024


class TomographyError(ValueError):
    """A stack that cannot be focused in elevation, or a bad tomography parameter."""


def check_stack(images: Sequence[SarImage], raws: Sequence[Any]) -> None:
    """Refuse a stack of fewer than :data:`MIN_PASSES` passes, or passes not on one ground grid
    with one carrier (:func:`sarmitsuba.stacks.interferometry.check_pair` of each against the
    first, naming the pass).

    Raises
    ------
    TomographyError (a ValueError)
    """
    if len(images) < MIN_PASSES or len(images) != len(raws):
        raise TomographyError(f"a stack needs at least {MIN_PASSES} passes (images and raw data alike), got "
                              f"{len(images)} images and {len(raws)} raw data: tomography resolves elevation from 3 "
                              "or more baselines (2 passes: use `interferogram`)")
    for n in range(1, len(images)):
        try:
            check_pair(images[0], images[n], raws[0], raws[n])
        except InterferometryError as exc:
            raise TomographyError(f"pass {n} does not match pass 0: {exc}") from None


# ============================================================================ geometry (TS2)
def _track(raw: Any) -> tuple[np.ndarray, np.ndarray]:
    """(a point, unit direction) of a pass's straight track line (mid phase centres)."""
    mid = 0.5 * (np.asarray(raw.tx_position, np.float64) + np.asarray(raw.rx_position, np.float64))
    direction = mid[-1] - mid[0]
    return mid[0], direction / np.linalg.norm(direction)


def _up(image: SarImage) -> np.ndarray:
    n = np.cross(image.azimuth_direction, image.range_direction)
    n = n / np.linalg.norm(n)
    return -n if n[2] < 0 else n


def elevation_points(image: SarImage, raw: Any, pixels: np.ndarray, s: np.ndarray) -> np.ndarray:
    """World points at elevation ``s`` above pixels: on each pixel's iso-range circle about
    ``raw``'s straight track line, arc length ``s`` from the pixel, upward for ``s > 0`` (TS2).

    Parameters
    ----------
    image : SarImage
        The ground grid.
    raw : RawData
        The reference pass (``tx_position``, ``rx_position`` read).
    pixels : float64 [..., 3], m
        World positions on the grid plane (``image.positions()[rows, cols]``).
    s : float64 [S], m
        Elevations.

    Returns
    -------
    float64 [..., S, 3], m
    """
    start, t = _track(raw)
    x = np.asarray(pixels, np.float64)
    foot = start + ((x - start) @ t)[..., None] * t
    d = x - foot
    r0 = np.linalg.norm(d, axis=-1)
    w = np.cross(t, d)
    w = w / np.linalg.norm(w, axis=-1, keepdims=True)
    w = np.where((w @ _up(image))[..., None] < 0, -w, w) * r0[..., None]
    beta = np.asarray(s, np.float64) / r0[..., None]                      # [..., S]
    return (foot[..., None, :] + np.cos(beta)[..., None] * d[..., None, :]
            + np.sin(beta)[..., None] * w[..., None, :])


@dataclass(frozen=True)
class PhaseModel:
    """The phase (TS2) of every pass at the chosen pixels, a polynomial in elevation.

    Attributes
    ----------
    phase : float64 [N, D + 1, P]
        ``phi_n(s) = sum_k phase[n, k, p] (s / scale)^k`` [rad] for pixel ``p``.
    height : float64 [D + 1, P]
        The height above the grid plane [m] of elevation ``s``, the same polynomial form.
    scale : float, m
        Elevation normalisation of the polynomials.
    interval : (float, float), m
        The elevation interval the polynomials were fitted over.
    fit_error : float, rad
        Largest difference between the exact phase and its polynomial at the fit's nodes.
    """

    phase: np.ndarray
    height: np.ndarray
    scale: float
    interval: tuple[float, float]
    fit_error: float

    def phases(self, s: np.ndarray) -> np.ndarray:
        """``phi_n(s)`` float64 [P, N, S] rad at elevations ``s`` float [S] (or [P, S]) m."""
        u = np.asarray(s, np.float64) / self.scale
        powers = np.stack(np.broadcast_arrays(*[u ** k for k in range(self.phase.shape[1])]), axis=-2)
        if powers.ndim == 2:                                        # [D + 1, S]
            return np.einsum("nkp,ks->pns", self.phase, powers)
        return np.einsum("nkp,pks->pns", self.phase, powers)       # [P, D + 1, S]

    def heights(self, s: np.ndarray) -> np.ndarray:
        """Height [m] above the grid plane of elevation ``s``: float [P] or [P, S] -> same shape."""
        u = np.asarray(s, np.float64) / self.scale
        if u.ndim == 1:
            return sum(self.height[k] * u ** k for k in range(self.height.shape[0]))
        return sum(self.height[k][:, None] * u ** k for k in range(self.height.shape[0]))


def phase_model(images: Sequence[SarImage], raws: Sequence[Any], reference: int, rows: np.ndarray,
                cols: np.ndarray, interval: tuple[float, float], lattice: int = 8) -> PhaseModel:
    """The phase model (TS2) of pixels ``(rows[p], cols[p])``.

    (TS2) is evaluated exactly (closest-approach lengths of each pass,
    :func:`sarmitsuba.stacks.interferometry.closest_approach_length`) at the pixels of a
    lattice every ``lattice`` pixels (and the last row and column), at :data:`_NODES` Chebyshev
    nodes of ``interval``; a least-squares polynomial of degree :data:`POLYNOMIAL_DEGREE` in
    ``s`` is fitted per lattice pixel and pass, and its coefficients are interpolated bilinearly
    to the pixels. Returns :class:`PhaseModel` (``P = len(rows)``).
    """
    from scipy.interpolate import RegularGridInterpolator
    image = images[reference]
    n_az, n_rg = image.data.shape
    lat_az = np.unique(np.r_[np.arange(0, n_az, lattice), n_az - 1])
    lat_rg = np.unique(np.r_[np.arange(0, n_rg, lattice), n_rg - 1])
    lo, hi = float(interval[0]), float(interval[1])
    nodes = 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos(np.pi * (np.arange(_NODES) + 0.5) / _NODES)
    scale = max(abs(lo), abs(hi), 1e-3)
    x = image.positions()[lat_az][:, lat_rg]                               # [La, Lr, 3]
    points = elevation_points(image, raws[reference], x, nodes)            # [La, Lr, M, 3]
    k = 2.0 * math.pi * float(raws[reference].fc) / SPEED_OF_LIGHT

    def delta(raw: Any) -> np.ndarray:
        return closest_approach_length(points, raw) - closest_approach_length(x, raw)[..., None]

    ref = delta(raws[reference])
    exact = np.stack([k * (delta(raw) - ref) for raw in raws])            # [N, La, Lr, M]
    heights = (points - x[:, :, None, :]) @ _up(image)                    # [La, Lr, M]
    vander = np.vander(nodes / scale, POLYNOMIAL_DEGREE + 1, increasing=True)     # [M, D + 1]
    pinv = np.linalg.pinv(vander)
    coef = np.einsum("km,nabm->nkab", pinv, exact)
    coef_h = np.einsum("km,abm->kab", pinv, heights)
    fit_error = float(np.max(np.abs(np.einsum("mk,nkab->nabm", vander, coef) - exact)))
    where = np.column_stack([np.asarray(rows, float), np.asarray(cols, float)])

    def at_pixels(values: np.ndarray) -> np.ndarray:                     # [..., La, Lr] -> [..., P]
        lead = values.shape[:-2]
        flat = values.reshape(-1, *values.shape[-2:])
        out = [RegularGridInterpolator((lat_az, lat_rg), v)(where) for v in flat]
        return np.asarray(out).reshape(*lead, len(where))

    return PhaseModel(phase=at_pixels(coef), height=at_pixels(coef_h), scale=scale, interval=(lo, hi),
                      fit_error=fit_error)


def steering(model: PhaseModel, s: np.ndarray) -> np.ndarray:
    """Steering vectors ``a_n(s) = exp(-j phi_n(s))``, complex128 [P, N, S] (TS2)."""
    return np.exp(-1j * model.phases(s))


# ============================================================================ data and calibration
def stack_samples(images: Sequence[SarImage], rows: np.ndarray, cols: np.ndarray,
                  calibration: np.ndarray | None = None) -> np.ndarray:
    """The stack's complex samples at pixels ``(rows[p], cols[p])``, complex128 [P, N], each pass
    multiplied by ``exp(-j calibration[n])`` (float [N] rad, :func:`calibration_phases`)."""
    y = np.stack([np.asarray(im.data)[rows, cols] for im in images], axis=1).astype(np.complex128)
    return y if calibration is None else y * np.exp(-1j * np.asarray(calibration, np.float64))[None, :]


@dataclass(frozen=True)
class ReferenceClutter:
    """How a reference point's pixel stands over its surroundings (:func:`reference_clutter`).

    Attributes
    ----------
    pixel : (int, int)
        The point's pixel (row, col).
    scr_db : float
        Its mean power over the passes against the mean power of its surroundings, dB
        (``inf`` when they hold none).
    phase_error : float, rad
        ``1 / sqrt(2 SCR)``, capped at ``pi / sqrt(3)`` (a uniformly random phase) (TS6).
    brightest : (int, int)
        The brightest pixel of the box about it.
    brightest_db : float
        That pixel's power against the point's pixel's, dB.
    """

    pixel: tuple[int, int]
    scr_db: float
    phase_error: float
    brightest: tuple[int, int]
    brightest_db: float


def _mainlobe(power: np.ndarray, q: tuple[int, int], axis: int) -> int:
    """Pixels from ``q`` to the first minimum of ``power`` along ``axis``, the farther side."""
    line = power[q[0], :] if axis == 1 else power[:, q[1]]
    i = q[axis]
    reach = 0
    for step in (-1, 1):
        j = i
        while 0 <= j + step < line.size and line[j + step] < line[j]:
            j += step
        reach = max(reach, abs(j - i))
    return reach


def sidelobe_level(image: SarImage) -> float:
    """The peak sidelobe ratio [dB] of the image's focusing windows, the higher of range and
    azimuth (:func:`sarmitsuba.focus.windows.pslr_theory` of the windows its metadata name,
    ``focus.window``; -13.26 dB, the unweighted pulse's, when it names none)."""
    from ..focus.windows import pslr_theory
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    label = str((meta.get("focus") or {}).get("window", ""))
    levels = []
    for name, args in re.findall(r"(?:range|azimuth)=(\w+)(?:\(([^)]*)\))?", label):
        try:
            params = {k.strip(): float(v) for k, v in (kv.split("=") for kv in args.split(",") if "=" in kv)}
            levels.append(pslr_theory(name, **params))
        except (ValueError, TypeError):
            pass
    return max(levels) if levels else pslr_theory("rect")


def reference_clutter(images: Sequence[SarImage], pixel: tuple[int, int]) -> ReferenceClutter:
    """The signal-to-clutter ratio of a reference point's ``pixel`` (TS6).

    Its surroundings are the pixels of a box :data:`CLUTTER_BOX` pixels each way about it (3 times
    its mainlobe when that is wider), less its mainlobe: the pixels to the first minimum of the
    power each way along azimuth and range. The clutter at the pixel is the larger of the speckle
    of the surroundings (their median power over ln 2, the mean of exponential intensity, robust
    to the other scatterers among them) and the peak sidelobe that their brightest pixel puts
    there (its power times :func:`sidelobe_level`). Powers are the passes' means.
    """
    n_az, n_rg = images[0].data.shape
    q = (int(pixel[0]), int(pixel[1]))
    power = np.mean([np.abs(np.asarray(im.data)).astype(np.float64) ** 2 for im in images], axis=0)
    lobe = (_mainlobe(power, q, 0), _mainlobe(power, q, 1))
    half = [max(CLUTTER_BOX, 3 * w) for w in lobe]
    rows = slice(max(0, q[0] - half[0]), min(n_az, q[0] + half[0] + 1))
    cols = slice(max(0, q[1] - half[1]), min(n_rg, q[1] + half[1] + 1))
    box = power[rows, cols]
    around = np.ones(box.shape, bool)
    around[max(0, q[0] - lobe[0] - rows.start):q[0] + lobe[0] + 1 - rows.start,
           max(0, q[1] - lobe[1] - cols.start):q[1] + lobe[1] + 1 - cols.start] = False
    ring = box[around]
    speckle = float(np.median(ring)) / math.log(2.0) if ring.size else 0.0
    sidelobe = float(ring.max()) * 10.0 ** (sidelobe_level(images[0]) / 10.0) if ring.size else 0.0
    clutter, signal = max(speckle, sidelobe), float(power[q])
    if signal <= 0:
        scr = -math.inf
    else:
        scr = math.inf if clutter <= 0 else 10.0 * math.log10(signal / clutter)
    error = math.pi / math.sqrt(3.0) if scr == -math.inf else min(math.pi / math.sqrt(3.0),
                                                                   1.0 / math.sqrt(2.0 * 10.0 ** (scr / 10.0)))
    b = np.unravel_index(int(np.argmax(box)), box.shape)
    brightest = (int(b[0] + rows.start), int(b[1] + cols.start))
    ratio = (10.0 * math.log10(float(power[brightest]) / signal) if signal > 0 else math.inf)
    return ReferenceClutter(pixel=q, scr_db=scr, phase_error=error, brightest=brightest, brightest_db=ratio)


def calibration_phases(images: Sequence[SarImage], raws: Sequence[Any], reference: int,
                       point: Sequence[float] | None = None) -> tuple[np.ndarray, tuple[int, int] | None]:
    """Per-pass phase offsets [rad] that calibrate the stack (TS6).

    ``point`` None, the flat earth: the ground backprojection already removed each pass's
    flat-earth phase exactly (docs/physics.md (I2)), so the offsets are 0 and the grid plane is
    elevation 0. ``point`` (world x, y, z [m]) a stable point-like scatterer at a surveyed
    position: it appears at pixel ``q`` of the reference (:meth:`SarImage.pixel_of`, rounded), and
    pass ``n``'s offset is ``angle(y_n(q) / y_ref(q)) + k [(L_n(P) - L_n(q)) - (L_ref(P) - L_ref(q))]``:
    what the phase there holds beyond the model (orbit or atmospheric errors of a real stack).

    Returns
    -------
    (float64 [N] rad, (row, col) of the reference pixel or None)

    Raises
    ------
    TomographyError
        ``point`` is not 3 finite numbers, or appears outside the image (naming its pixel and the
        image's size), or the reference pixel has no echo in some pass, or stands less than
        :data:`MIN_REFERENCE_SCR_DB` over its surroundings (:func:`reference_clutter`; naming the
        brightest pixel nearby).
    """
    n_pass = len(images)
    if point is None:
        return np.zeros(n_pass), None
    p = np.asarray(point, np.float64).reshape(-1)
    image = images[reference]
    try:
        row, col = image.pixel_of(p)
    except ValueError as exc:
        raise TomographyError(f"reference point {p.tolist()}: {exc}") from None
    n_az, n_rg = image.data.shape
    q = (int(round(row)), int(round(col)))
    if not (0 <= q[0] < n_az and 0 <= q[1] < n_rg):
        raise TomographyError(f"the reference point {p.tolist()} m appears at pixel ({row:.1f}, {col:.1f}), outside "
                              f"the image of {n_az} x {n_rg} pixels [azimuth, range]: give a point inside the imaged "
                              "scene (a corner reflector or another stable point scatterer)")
    y = stack_samples(images, np.array([q[0]]), np.array([q[1]]))[0]
    if np.any(np.abs(y) == 0):
        raise TomographyError(f"the reference point {p.tolist()} m has no echo at pixel {q} in passes "
                              f"{np.flatnonzero(np.abs(y) == 0).tolist()}: choose a point that every pass sees")
    _check_reference(images, q, p)
    x = image.positions()[q]
    k = 2.0 * math.pi * float(raws[reference].fc) / SPEED_OF_LIGHT
    delta = np.array([closest_approach_length(p, raw) - closest_approach_length(x, raw) for raw in raws])
    model = k * (delta - delta[reference])
    return np.angle(y / y[reference]) + model, q


def _check_reference(images: Sequence[SarImage], pixel: tuple[int, int], point: np.ndarray) -> None:
    """Refuse a reference ``point`` (world x, y, z, m) whose ``pixel`` stands less than
    :data:`MIN_REFERENCE_SCR_DB` over its surroundings (:func:`reference_clutter`), naming the
    margin, why, and the brightest pixel nearby with its grid position."""
    found = reference_clutter(images, pixel)
    if found.scr_db >= MIN_REFERENCE_SCR_DB:
        return
    p = [round(float(v), 3) for v in point]
    grid = images[0].positions()[found.brightest]
    scr = "no echo" if found.scr_db == -math.inf else f"{found.scr_db:.1f} dB over its surroundings"
    raise TomographyError(
        f"calibration_point = {p} m appears at pixel {found.pixel}, {scr}: a reference point needs "
        f"{MIN_REFERENCE_SCR_DB:g} dB, its phase being off by about 1/sqrt(2 SCR) rad in every pass (here "
        f"{found.phase_error:.2f} rad; 0.07 rad at {MIN_REFERENCE_SCR_DB:g} dB, docs/physics.md (TS6)). The "
        f"brightest pixel within {CLUTTER_BOX} pixels is {found.brightest}, {found.brightest_db:+.1f} dB against "
        f"it, on the grid at ({grid[0]:.2f}, {grid[1]:.2f}, {grid[2]:.2f}) m: give the surveyed position of a "
        "stable point scatterer (a corner reflector's apex) that images there, or leave the flat earth's "
        "calibration")


# ============================================================================ inversions (TS3), (TS4)
def beamforming(y: np.ndarray, a: np.ndarray) -> np.ndarray:
    """Beamforming profiles ``|a(s)^H y|^2 / N^2`` (TS3): float64 [P, S] from samples ``y``
    complex [P, N] and steering ``a`` complex [P, N, S]; a lone scatterer of amplitude ``gamma``
    peaks at ``|gamma|^2`` [m^2 in normalised radiometry]."""
    n = y.shape[1]
    return np.abs(np.einsum("pns,pn->ps", np.conj(a), y)) ** 2 / n ** 2


def window_covariance(images: Sequence[SarImage], rows: np.ndarray, cols: np.ndarray, looks: tuple[int, int],
                      calibration: np.ndarray | None = None) -> np.ndarray:
    """Sample covariance ``(1 / L) sum y y^H`` of the stack over a ``looks`` window about each pixel
    (centred, clipped at the image's edges), complex128 [P, N, N]."""
    n_az, n_rg = images[0].data.shape
    da = np.arange(looks[0]) - looks[0] // 2
    dr = np.arange(looks[1]) - looks[1] // 2
    ra = np.clip(rows[:, None, None] + da[None, :, None], 0, n_az - 1)
    rc = np.clip(cols[:, None, None] + dr[None, None, :], 0, n_rg - 1)
    ra, rc = np.broadcast_arrays(ra, rc)
    y = stack_samples(images, ra.reshape(-1), rc.reshape(-1), calibration).reshape(len(rows), -1, len(images))
    return np.einsum("pln,plm->pnm", y, np.conj(y)) / y.shape[1]


def capon(covariance: np.ndarray, a: np.ndarray, loading: float = 0.01) -> np.ndarray:
    """Capon profiles ``1 / Re(a^H (R + delta I)^{-1} a)`` (TS4), float64 [P, S].

    ``covariance`` complex [P, N, N] (:func:`window_covariance`), ``a`` complex [P, N, S];
    ``delta = loading tr(R) / N``. A lone scatterer of power ``|gamma|^2`` peaks at
    ``|gamma|^2 + delta / N``.
    """
    n = covariance.shape[1]
    delta = loading * np.real(np.trace(covariance, axis1=1, axis2=2)) / n
    loaded = covariance + (delta + 1e-300)[:, None, None] * np.eye(n)[None]
    solved = np.linalg.solve(loaded, a)                                  # [P, N, S]
    return 1.0 / np.maximum(np.real(np.einsum("pns,pns->ps", np.conj(a), solved)), 1e-300)


def detect_peaks(profiles: np.ndarray, s: np.ndarray, threshold_db: float = -10.0, max_scatterers: int = 3,
                 floor: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Scatterers of elevation profiles: local maxima at least ``threshold_db`` (< 0) below the
    profile's peak and above ``floor``, at most ``max_scatterers`` per pixel (the strongest),
    their elevations refined by the parabola through the maximum and its neighbours (in dB).

    ``profiles`` float [P, S] power, ``s`` float [S] m, evenly spaced. Returns (elevations float64
    [P, K] m, powers float64 [P, K]), NaN-padded, strongest first.
    """
    p = np.asarray(profiles, np.float64)
    left, mid, right = p[:, :-2], p[:, 1:-1], p[:, 2:]
    peak = np.max(p, axis=1, keepdims=True)
    is_max = (mid > left) & (mid >= right) & (mid >= peak * 10.0 ** (threshold_db / 10.0)) & (mid > floor)
    ds = float(s[1] - s[0])
    with np.errstate(divide="ignore", invalid="ignore"):
        lo, c, hi = (10.0 * np.log10(np.maximum(v, 1e-300)) for v in (left, mid, right))
        offset = np.clip(0.5 * (lo - hi) / (lo - 2.0 * c + hi), -0.5, 0.5)
    offset = np.where(np.isfinite(offset), offset, 0.0)
    elev = np.full((p.shape[0], max_scatterers), np.nan)
    power = np.full((p.shape[0], max_scatterers), np.nan)
    for i in np.flatnonzero(is_max.any(axis=1)):
        idx = np.flatnonzero(is_max[i])
        idx = idx[np.argsort(mid[i, idx])[::-1]][:max_scatterers]
        elev[i, :idx.size] = s[idx + 1] + offset[i, idx] * ds
        power[i, :idx.size] = mid[i, idx]
    return elev, power


# ============================================================================ the closed form (TS3)
def elevation_psf(perpendicular: np.ndarray, wavelength: float, slant_range: float, s: np.ndarray) -> np.ndarray:
    """The beamforming profile of a lone unit scatterer at elevation 0 in the Fourier model,
    ``|(1 / N) sum_n exp(j 4 pi b_n s / (lambda R))|^2`` (TS3), float64 like ``s``; for evenly
    spaced baselines ``(sin(N x) / (N sin x))^2`` with ``x = 2 pi d_b s / (lambda R)``."""
    b = np.asarray(perpendicular, np.float64)
    phase = 4.0 * math.pi * np.multiply.outer(np.asarray(s, np.float64), b) / (wavelength * slant_range)
    return np.abs(np.mean(np.exp(1j * phase), axis=-1)) ** 2
