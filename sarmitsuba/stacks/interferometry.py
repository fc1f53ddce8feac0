"""Repeat-pass interferometry of two renders on one ground grid: interferogram, coherence, height.

Both passes are focused by backprojection onto the same ground grid. Pixel ``x`` of image ``i``
sums the range-compressed echoes at the two-way length ``L_i(x) = |tx - x| + |rx - x|`` times
``exp(+j k L_i(x))``, ``k = 2 pi fc / c``, while a scatterer at ``x_s`` carries the carrier phase
``exp(-j k L_i(x_s))`` (docs/physics.md (S2)). So:

* a scatterer on the grid plane at pixel ``x`` keeps only its own phase in either image: the
  focused interferogram ``I1 I2*`` has the flat-earth phase removed *exactly*, with no orbit
  model (:func:`flat_earth_phase` gives the phase that ground backprojection took away);
* a scatterer at height ``h`` appears at its layover pixel ``x'`` (the point of the grid plane on
  its iso-range circle about the primary track) and ``I1 I2*`` keeps
  ``phi = -k [(L1(x_s) - L1(x')) - (L2(x_s) - L2(x'))] ~ k_z h`` (:func:`height_sensitivity`),
  from which :func:`height` recovers ``h`` after phase unwrapping.

Sign conventions: the baseline is ``B = secondary - primary`` (mid-aperture antenna phase
centres); ``B_perp = B_n . e`` with ``B_n`` its part normal to the primary track and ``e`` the
unit vector normal to the track and to the line of sight ``u`` (scene centre to primary) that
points away from the scene and down (``e . n < 0`` for the grid normal ``n``): the direction in
which the look angle grows (as :mod:`sarmitsuba.scene.baseline`); ``B_par = B_n . u``. Then, to first order in ``B / R``, the
flat-earth fringe rate in ground range is ``d phi / d y = 4 pi B_perp cos(theta) / (lambda R)``
(``4 pi B_perp / (lambda R tan(theta))`` per metre of slant range) and
``k_z = 4 pi B_perp / (lambda R sin(theta))``; the height of ambiguity is ``2 pi / |k_z|``.

No coregistration beyond the common grid: an elevated point lays over to pixels about
``h B_perp / (R sin^2 theta)`` apart in the two passes, negligible well below the critical baseline.

The product files and figure of a pair of render directories: :mod:`sarmitsuba.stacks.insar_products`.

Sources: R. Bamler and P. Hartl, "Synthetic aperture radar interferometry", Inverse Problems 14
(1998) R1-R54 (flat-earth phase, eqs. 12-16; coherence, section 4); H. A. Zebker and
J. Villasenor, "Decorrelation in interferometric radar echoes", IEEE TGRS 30(5), 1992
(geometric decorrelation); R. F. Hanssen, *Radar Interferometry*, Kluwer, 2001 (sections 2.4-2.5:
flat-earth phase, height of ambiguity; section 4.2: the coherence estimator and its bias).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..scene.baseline import Baseline
from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.raw import RawData

__all__ = ["InterferometryError", "check_pair", "check_looks", "closest_approach_length",
           "flat_earth_phase", "height_sensitivity", "pair_baseline", "interferogram", "multilooked_interferogram",
           "coherence", "unwrapped_phase", "height", "height_from_phase", "PRODUCT_FILES",
           "GRID_TOLERANCE_M", "MAX_HEIGHT_OF_AMBIGUITY_M"]

#: Largest difference [m] between two grids' origins and axes (and [1] between directions) that
#: :func:`check_pair` accepts as "the same grid".
GRID_TOLERANCE_M = 1e-6
#: Pixels whose height of ambiguity ``2 pi / |k_z|`` exceeds this [m] get no height (NaN): the
#: baseline gives them no height sensitivity (a zero-baseline pair).
MAX_HEIGHT_OF_AMBIGUITY_M = 1e5
#: Files :func:`~sarmitsuba.stacks.insar_products.write_products` writes.
PRODUCT_FILES = {"interferogram": "interferogram.npz", "coherence": "coherence.npz", "height": "height.npz",
                 "figure": "interferogram.png"}
#: Steps of one pulse the closest-approach descent takes at most before it searches every pulse.
_WINDOW = 8
#: Points handled at once by the closest-approach search (bounds the temporaries).
_CHUNK = 8192


class InterferometryError(ValueError):
    """Two renders that do not form an interferometric pair, or a bad product parameter."""


# ============================================================================ the pair
def check_pair(primary: SarImage, secondary: SarImage, primary_raw: RawData | None = None,
               secondary_raw: RawData | None = None) -> None:
    """Refuse two images (SarImage) that are not on one ground grid and, when both raw data
    (RawData) are given, passes whose carrier frequencies ``fc`` differ (by over 1e-9 relative).

    Raises
    ------
    InterferometryError (a ValueError)
        Naming what differs: a plane other than ``"ground"``, the shape, the origin, the
        azimuth or range direction, the azimuth or range axis (beyond :data:`GRID_TOLERANCE_M`),
        or the carrier frequency.
    """
    for name, image in (("primary", primary), ("secondary", secondary)):
        if image.plane != "ground":
            raise InterferometryError(f"the {name} image is on a {image.plane!r} grid: interferometry needs both "
                                      "passes focused on the ground grid (sarmitsuba render)")
    if primary.data.shape != secondary.data.shape:
        raise InterferometryError(f"the images differ in shape: primary {list(primary.data.shape)}, secondary "
                                  f"{list(secondary.data.shape)} [n_azimuth, n_range]: render both passes of the "
                                  "same scene with the same grid parameters, only track_offset changed")
    for field in ("origin", "azimuth_direction", "range_direction", "azimuth", "range"):
        a, b = getattr(primary, field), getattr(secondary, field)
        worst = float(np.max(np.abs(a - b)))
        if worst > GRID_TOLERANCE_M:
            raise InterferometryError(
                f"the images' grids differ in {field} (by up to {worst:.3g} m, tolerance {GRID_TOLERANCE_M:g} m): "
                "the two passes must be focused on one ground grid; render both with the same scene and grid "
                "parameters, only track_offset changed")
    if primary_raw is not None and secondary_raw is not None:
        f1, f2 = float(primary_raw.fc), float(secondary_raw.fc)
        if abs(f1 - f2) > 1e-9 * max(f1, f2):
            raise InterferometryError(f"the passes have different carrier frequencies (primary fc = {f1:.9g} Hz, "
                                      f"secondary fc = {f2:.9g} Hz): render both with the same frequency")


def _wavenumber(raw: RawData) -> float:
    """``k = 2 pi fc / c`` [rad/m] of a pass."""
    return 2.0 * math.pi * float(raw.fc) / SPEED_OF_LIGHT


# ============================================================================ geometry
def _track_line(raw: RawData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mid positions float64 [n, 3], first mid position, unit direction first-to-last) of a track."""
    mid = 0.5 * (np.asarray(raw.tx_position, np.float64) + np.asarray(raw.rx_position, np.float64))
    direction = mid[-1] - mid[0]
    norm = float(np.linalg.norm(direction))
    if mid.shape[0] < 3 or norm == 0.0:
        raise InterferometryError(f"a track of {mid.shape[0]} pulses spanning {norm:.3g} m has no closest approach "
                                  "to refine: interferometry needs a moving track of at least 3 pulses")
    return mid, mid[0], direction / norm


def _two_way(points: np.ndarray, tx: np.ndarray, rx: np.ndarray) -> np.ndarray:
    """``|tx - x| + |rx - x|`` [m], broadcast over leading axes (last axis xyz)."""
    return np.linalg.norm(tx - points, axis=-1) + np.linalg.norm(rx - points, axis=-1)


def _nearest_pulse(points: np.ndarray, raw: RawData) -> np.ndarray:
    """Index of the pulse of least two-way length to each point [P, 3]: a descent from the pulse
    nearest the point's along-track projection, one pulse a step, for at most :data:`_WINDOW`
    steps (the two-way length along a straight track has one minimum; there the projection lies
    within a pulse of it); over all pulses for a point still descending after them (a curved
    track) or a track that is not monotonic."""
    mid, start, t = _track_line(raw)
    tx, rx = raw.tx_position, raw.rx_position
    s = (mid - start) @ t
    n = s.size
    if np.all(np.diff(s) > 0):
        along = (points - start) @ t
        after = np.clip(np.searchsorted(s, along), 1, n - 1)
        best = np.where(along - s[after - 1] < s[after] - along, after - 1, after)
        here = _two_way(points, tx[best], rx[best])
        redo = np.ones(len(points), bool)
        for _ in range(_WINDOW):
            rows = np.flatnonzero(redo)
            if not rows.size:
                break
            b, p, length = best[rows], points[rows], here[rows]
            left = np.where(b > 0, _two_way(p, tx[b - 1], rx[b - 1]), np.inf)
            right = np.where(b < n - 1, _two_way(p, tx[np.minimum(b + 1, n - 1)], rx[np.minimum(b + 1, n - 1)]), np.inf)
            step = np.where((left < length) & (left <= right), -1, np.where(right < length, 1, 0))
            best[rows], here[rows] = b + step, np.minimum(length, np.minimum(left, right))
            redo[rows] = step != 0
    else:
        best, redo = np.zeros(len(points), np.int64), np.ones(len(points), bool)
    rows, step = np.flatnonzero(redo), max(1, 500_000 // n)
    for r0 in range(0, rows.size, step):
        r = rows[r0:r0 + step]
        best[r] = np.argmin(_two_way(points[r, None, :], tx[None], rx[None]), axis=1)
    return best


def closest_approach_length(points: np.ndarray, raw: RawData) -> np.ndarray:
    """Closest-approach two-way length of a track to each point: ``min |tx - x| + |rx - x|``.

    The least over the pulses, refined by the parabola through that pulse and its two
    neighbours in along-track distance (exact to ~``d^4 / R^3`` for pulse spacing ``d`` and range
    ``R``: far below a micrometre for a decimetre spacing at 1 km). A point whose closest
    approach lies beyond the recorded track gets the end pulse's length.

    ``points`` float64 [..., 3] m; ``raw`` the pass (only ``tx_position``, ``rx_position`` are read).
    Returns float64 [...] m. Raises InterferometryError for a track of fewer than 3 pulses or one
    that does not move.
    """
    pts = np.asarray(points, np.float64)
    flat = pts.reshape(-1, 3)
    mid, start, t = _track_line(raw)
    s = (mid - start) @ t
    out = np.empty(flat.shape[0])
    for c0 in range(0, flat.shape[0], _CHUNK):
        p = flat[c0:c0 + _CHUNK]
        best = _nearest_pulse(p, raw)
        i = np.clip(best, 1, s.size - 2)
        lengths = [_two_way(p, raw.tx_position[i + o], raw.rx_position[i + o]) for o in (-1, 0, 1)]
        h1, h2 = s[i] - s[i - 1], s[i + 1] - s[i]
        f_left, f_right = (lengths[1] - lengths[0]) / h1, (lengths[2] - lengths[1]) / h2
        curvature = (f_right - f_left) / (h1 + h2)
        slope = f_right - curvature * h2
        interior = (best == i) & (curvature > 0)
        vertex = lengths[1] - slope ** 2 / (4.0 * np.where(interior, curvature, 1.0))
        end = _two_way(p, raw.tx_position[best], raw.rx_position[best])
        out[c0:c0 + _CHUNK] = np.where(interior, np.minimum(vertex, lengths[1]), end)
    return out.reshape(pts.shape[:-1])


def flat_earth_phase(image: SarImage, primary_raw: RawData, secondary_raw: RawData) -> np.ndarray:
    """Flat-earth phase of each pixel: the interferometric phase a scatterer on the grid plane at
    that pixel has in a raw (not ground-backprojected) interferogram, ``-k (L1(x) - L2(x))``.

    ``L_i(x)`` is pass ``i``'s closest-approach two-way length to the pixel's world position
    (:func:`closest_approach_length`) and ``k = 2 pi fc / c`` the primary's wavenumber (Bamler and
    Hartl 1998, eq. 14; Hanssen 2001, section 2.4). Backprojection onto the ground grid has
    already removed this phase from the focused images, so the focused interferogram has no
    flat-earth fringes; ``interferogram(..., remove_flat_earth=False)`` puts them back,
    ``I1 I2* exp(j phi_fe)``, to inspect them or to check their rate: to first order
    ``d phi_fe / d y = 4 pi B_perp cos(theta) / (lambda R)`` per metre of ground range.

    Returns float64 [n_az, n_rg] rad, not wrapped. Raises InterferometryError for an unusable
    track (:func:`closest_approach_length`).
    """
    x = image.positions()
    return -_wavenumber(primary_raw) * (closest_approach_length(x, primary_raw)
                                        - closest_approach_length(x, secondary_raw))


def _up(image: SarImage) -> np.ndarray:
    """Unit normal of the grid plane pointing up (world ``z >= 0``), float64 [3]."""
    n = np.cross(image.azimuth_direction, image.range_direction)
    n = n / np.linalg.norm(n)
    return -n if n[2] < 0 else n


def _iso_range_points(image: SarImage, raw: RawData, dh: float) -> np.ndarray:
    """Points ``dh`` [m] above (below for ``dh < 0``) the grid plane on each pixel's iso-range
    circle about the primary's straight track line, float64 [n_az, n_rg, 3]: the circle about the
    line through the pixel, in the plane normal to the track, on the pixel's side."""
    _, start, t = _track_line(raw)
    x = image.positions()
    foot = start + ((x - start) @ t)[..., None] * t
    d = x - foot
    r0 = np.linalg.norm(d, axis=-1)
    n = _up(image)
    w = np.cross(t, d)
    w = w / np.linalg.norm(w, axis=-1, keepdims=True)
    w = np.where((w @ n)[..., None] < 0, -w, w)
    a, b = d @ n, r0 * (w @ n)                       # height of F + cos(beta) d + r0 sin(beta) w above x
    radius, phase = np.hypot(a, b), np.arctan2(b, a)
    beta = phase - np.arccos(np.clip((dh + a) / radius, -1.0, 1.0))
    return foot + np.cos(beta)[..., None] * d + (r0 * np.sin(beta))[..., None] * w


def height_sensitivity(image: SarImage, primary_raw: RawData, secondary_raw: RawData,
                       dh: float = 1.0) -> np.ndarray:
    """Vertical wavenumber ``k_z = d phi / d h`` of each pixel, from the exact geometry.

    A scatterer at height ``h`` that appears at pixel ``x'`` lies on ``x'``'s iso-range circle
    about the primary track, where it adds ``phi(h) = -k [(L1(x_s) - L1(x')) - (L2(x_s) - L2(x'))]``
    to the focused interferogram (``L_i`` closest-approach two-way lengths). ``k_z`` is the
    central difference ``(phi(dh) - phi(-dh)) / (2 dh)`` along that circle (error ``O(dh^2 / R^2)``
    relative). To first order ``k_z = 4 pi B_perp / (lambda R sin(theta))`` (module docstring's
    sign convention; Hanssen 2001, eq. 2.5.13; Bamler and Hartl 1998, eq. 16).

    ``image``: the ground grid (either pass's); ``primary_raw``, ``secondary_raw``: the passes
    (``tx_position``, ``rx_position``, ``fc`` are read); ``dh``: height step [m], > 0.
    Returns float64 [n_az, n_rg] rad/m. Raises InterferometryError for a ``dh`` that is not a
    finite number > 0 or an unusable track.
    """
    if not (math.isfinite(dh) and dh > 0):
        raise InterferometryError(f"dh must be a finite height step > 0 (m), got {dh!r}")
    k = _wavenumber(primary_raw)

    def phase(points: np.ndarray) -> np.ndarray:
        return -k * (closest_approach_length(points, primary_raw) - closest_approach_length(points, secondary_raw))

    return (phase(_iso_range_points(image, primary_raw, dh))
            - phase(_iso_range_points(image, primary_raw, -dh))) / (2.0 * dh)


def pair_baseline(image: SarImage, primary_raw: RawData, secondary_raw: RawData) -> Baseline:
    """The pair's baseline at the scene centre (``image.origin``), mid-aperture positions.

    ``B = secondary - primary`` at pulse ``n // 2`` (antenna phase centres ``(tx + rx) / 2``),
    split as in the module docstring; ``R = |A1 - C|`` and the incidence ``theta`` between the
    line of sight and the grid normal give the critical baseline ``lambda R tan(theta) B_w / c``
    (``B_w`` the primary's bandwidth) and the height of ambiguity ``lambda R sin(theta) / (2 |B_perp|)``
    (infinite for ``B_perp = 0``; Hanssen 2001, eq. 2.5.13).

    Returns
    -------
    sarmitsuba.scene.baseline.Baseline
    """
    mid1, _, t = _track_line(primary_raw)
    mid2, _, _ = _track_line(secondary_raw)
    a1, a2 = mid1[len(mid1) // 2], mid2[min(len(mid2) - 1, len(mid1) // 2)]
    to_sensor = a1 - image.origin
    r = float(np.linalg.norm(to_sensor))
    u, up = to_sensor / r, _up(image)
    e = np.cross(t, u)
    e = -e if e @ up > 0 else e                  # outward and down: the look angle grows
    b = a2 - a1
    normal = b - (b @ t) * t
    perpendicular, theta = float(normal @ e), math.acos(min(1.0, float(u @ up)))
    wavelength = SPEED_OF_LIGHT / float(primary_raw.fc)
    critical = wavelength * r * math.tan(theta) * float(primary_raw.bandwidth) / SPEED_OF_LIGHT
    ambiguity = wavelength * r * math.sin(theta) / (2.0 * abs(perpendicular)) if perpendicular else math.inf
    return Baseline(vector=b, along_track=float(b @ t), parallel=float(normal @ u), perpendicular=perpendicular,
                    critical=critical, height_of_ambiguity=ambiguity, slant_range=r)


# ============================================================================ interferogram and coherence
def check_looks(looks: Any, shape: tuple[int, int]) -> tuple[int, int]:
    """``looks`` as ``(az, rg)`` whole numbers, each in ``[1, n]`` for an image of ``shape``.

    Raises
    ------
    InterferometryError
        Naming the bad value, the valid range and the fix.
    """
    try:
        values = tuple(int(v) for v in looks)
        ok = len(values) == 2 and all(int(v) == v for v in looks)
    except (TypeError, ValueError):
        values, ok = (), False
    if not ok or not all(1 <= v <= n for v, n in zip(values, shape)):
        raise InterferometryError(f"looks must be two whole numbers AZ,RG with 1 <= AZ <= {shape[0]} and "
                                  f"1 <= RG <= {shape[1]} (the image's size), got {looks!r}: e.g. --looks 4,4")
    return values  # type: ignore[return-value]


def _boxcar(values: np.ndarray, looks: tuple[int, int]) -> np.ndarray:
    """Mean over an ``looks[0] x looks[1]`` window about each pixel (float64, same shape; see
    :func:`multilooked_interferogram` for the window and edge conventions)."""
    from scipy.ndimage import uniform_filter
    if np.iscomplexobj(values):
        return _boxcar(values.real, looks) + 1j * _boxcar(values.imag, looks)
    return uniform_filter(np.asarray(values, np.float64), size=looks, mode="reflect")


def interferogram(primary: SarImage, secondary: SarImage, primary_raw: RawData | None = None,
                  secondary_raw: RawData | None = None, remove_flat_earth: bool = True) -> np.ndarray:
    """The single-look interferogram ``I1 I2*`` of two passes on one ground grid.

    Parameters
    ----------
    primary, secondary : SarImage
        Focused on one ground grid (:func:`check_pair`).
    primary_raw, secondary_raw : RawData, optional
        Needed only for ``remove_flat_earth=False``.
    remove_flat_earth : bool, default True
        True: as focused, the flat-earth phase removed (exactly, by the ground backprojection).
        False: ``I1 I2* exp(j phi_fe)`` with the flat-earth fringes of :func:`flat_earth_phase`
        put back, for inspection and for checking their rate.

    Returns
    -------
    complex64 [n_az, n_rg], m^2 (normalised radiometry)

    Raises
    ------
    InterferometryError
        The grids or carriers differ (:func:`check_pair`), or ``remove_flat_earth=False``
        without both raw data.
    """
    check_pair(primary, secondary, primary_raw, secondary_raw)
    product = primary.data.astype(np.complex128) * np.conj(secondary.data.astype(np.complex128))
    if not remove_flat_earth:
        if primary_raw is None or secondary_raw is None:
            raise InterferometryError("remove_flat_earth=False needs primary_raw and secondary_raw (the passes' "
                                      "RawData) to restore the flat-earth phase")
        product *= np.exp(1j * flat_earth_phase(primary, primary_raw, secondary_raw))
    return product.astype(np.complex64)


def _pair_data(primary: SarImage | np.ndarray, secondary: SarImage | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The complex samples of two images (SarImages: on one grid, :func:`check_pair`) as
    complex128 [n_az, n_rg] each."""
    if isinstance(primary, SarImage) and isinstance(secondary, SarImage):
        check_pair(primary, secondary)
    a, b = (np.asarray(x.data if isinstance(x, SarImage) else x) for x in (primary, secondary))
    if a.ndim != 2 or a.shape != b.shape:
        raise InterferometryError(f"the images must be two complex arrays [n_azimuth, n_range] of one shape, got "
                                  f"{list(a.shape)} and {list(b.shape)}")
    return a.astype(np.complex128), b.astype(np.complex128)


def multilooked_interferogram(primary: SarImage | np.ndarray, secondary: SarImage | np.ndarray,
                              looks: tuple[int, int] = (4, 4)) -> np.ndarray:
    """Boxcar-averaged interferogram ``<I1 I2*>`` on the full grid (not decimated).

    The window about pixel ``i`` spans ``i - l // 2 ... i + (l - 1) // 2`` along each axis
    (``scipy.ndimage.uniform_filter``): centred for odd looks, half a pixel toward lower
    indices for even looks. Beyond the image edges the samples are mirrored (``mode="reflect"``).

    Parameters
    ----------
    primary, secondary : SarImage (on one grid) or complex arrays [n_az, n_rg]
    looks : (int, int)
        Window size in azimuth and range pixels, each in ``[1, n]``.

    Returns
    -------
    complex64 [n_az, n_rg], m^2

    Raises
    ------
    InterferometryError
        Different grids or shapes, or bad looks (:func:`check_looks`).
    """
    a, b = _pair_data(primary, secondary)
    return _boxcar(a * np.conj(b), check_looks(looks, a.shape)).astype(np.complex64)


def coherence(primary: SarImage | np.ndarray, secondary: SarImage | np.ndarray,
              looks: tuple[int, int] = (4, 4)) -> np.ndarray:
    """Boxcar coherence estimate ``|<I1 I2*>| / sqrt(<|I1|^2> <|I2|^2>)`` (Hanssen 2001, eq. 4.2.9).

    Windows as in :func:`multilooked_interferogram`. The estimate is biased upward for few looks
    ``N = looks[0] looks[1]``: two independent speckle images read about ``sqrt(pi / (4 N))``
    rather than 0 (Touzi et al., IEEE TGRS 37(1), 1999).

    Returns
    -------
    float32 [n_az, n_rg] in [0, 1]
        0 where either image is zero over the whole window (its mean power below 1e-12 of the
        image's largest window mean; no NaN); rounding above 1 is cut to 1.

    Raises
    ------
    InterferometryError
        Different grids or shapes, or bad looks.
    """
    a, b = _pair_data(primary, secondary)
    looks = check_looks(looks, a.shape)
    numerator = np.abs(_boxcar(a * np.conj(b), looks))
    # a running-sum mean of powers rounds to about +-1e-16 of the image's peak beside bright pixels:
    # a window whose mean power is below 1e-12 of the peak's holds nothing
    power_a, power_b = (_boxcar(np.abs(x) ** 2, looks) for x in (a, b))
    power_a, power_b = (np.where(p > 1e-12 * max(float(p.max()), 0.0), p, 0.0) for p in (power_a, power_b))
    denominator = np.sqrt(power_a * power_b)
    ok = denominator > 0
    out = np.zeros(a.shape, np.float64)
    out[ok] = numerator[ok] / denominator[ok]
    return np.minimum(out, 1.0).astype(np.float32)


# ============================================================================ height
def unwrapped_phase(multilooked: np.ndarray, gamma: np.ndarray) -> np.ndarray:
    """The unwrapped phase of a multilooked interferogram, referenced to the ground.

    ``skimage.restoration.unwrap_phase`` (Herraez et al., Applied Optics 41(35), 2002) unwraps
    ``angle(multilooked)`` up to one unknown multiple of 2 pi, which is removed by assuming that
    the grid plane (open ground, phase 0 after ground backprojection) is the commonest height
    among the coherent pixels: of the pixels whose coherence is at least the median coherence,
    the most frequent ``round(phase / 2 pi)`` is taken as the ground's cycle and subtracted.

    ``multilooked`` complex [n_az, n_rg] (:func:`multilooked_interferogram`), ``gamma`` float
    [n_az, n_rg] (:func:`coherence` of the same looks); returns float64 [n_az, n_rg] rad.
    """
    from skimage.restoration import unwrap_phase
    unwrapped = np.asarray(unwrap_phase(np.angle(multilooked).astype(np.float64)), np.float64)
    cycles, counts = np.unique(np.round(unwrapped[gamma >= np.median(gamma)] / (2.0 * math.pi)), return_counts=True)
    return unwrapped - 2.0 * math.pi * float(cycles[np.argmax(counts)])


def height(primary: SarImage, secondary: SarImage, primary_raw: RawData, secondary_raw: RawData,
           looks: tuple[int, int] = (4, 4), k_z: np.ndarray | None = None) -> np.ndarray:
    """Height above the grid plane from the interferometric phase: ``phi_unwrapped / k_z``.

    The multilooked interferogram (:func:`multilooked_interferogram`) is unwrapped and referenced
    to the ground (:func:`unwrapped_phase`) and divided by each pixel's vertical wavenumber
    (:func:`height_sensitivity`, or ``k_z`` when given). A layover pixel mixing roof, wall and
    ground reads a coherence-weighted mixture of their heights.

    Returns
    -------
    float64 [n_az, n_rg], m
        NaN where the baseline gives no height sensitivity (height of ambiguity ``2 pi / |k_z|``
        above :data:`MAX_HEIGHT_OF_AMBIGUITY_M`: a zero-baseline pair).

    Raises
    ------
    InterferometryError
        Different grids or carriers, bad looks, unusable tracks.
    """
    check_pair(primary, secondary, primary_raw, secondary_raw)
    if k_z is None:
        k_z = height_sensitivity(primary, primary_raw, secondary_raw)
    phase = unwrapped_phase(multilooked_interferogram(primary, secondary, looks), coherence(primary, secondary, looks))
    return height_from_phase(phase, k_z)


def height_from_phase(phase: np.ndarray, k_z: np.ndarray) -> np.ndarray:
    """``phase / k_z`` [m], NaN where the height of ambiguity exceeds :data:`MAX_HEIGHT_OF_AMBIGUITY_M`."""
    sensitive = np.abs(k_z) * MAX_HEIGHT_OF_AMBIGUITY_M > 2.0 * math.pi
    return np.where(sensitive, phase / np.where(sensitive, k_z, 1.0), np.nan)

