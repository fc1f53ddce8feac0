"""Focused SAR image: the contract between the focusing stage and the products (docs/design.md section 3).

A ground-plane image lives on a local grid around the scene centre. Pixel ``(i, j)`` sits
at the world position ``origin + azimuth[i] * azimuth_direction + range[j] * range_direction``
(metres, z up). For ``plane == "ground"`` the range axis is ground range, increasing away
from the sensor; for ``plane == "slant"`` it is slant range.

:func:`image_coordinates` and :func:`layover_position` say where a world point appears in an
image: where a focuser matched to its range history from the recorded straight track
(:func:`image_track`) puts it (docs/physics.md (G2)).
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .outputs import atomic_savez, json_default
from .raw import read_npz, refuse_non_finite

__all__ = ["SarImage", "SarImageError", "image_coordinates", "image_track", "layover_position", "layover_positions"]

_PLANES = ("ground", "slant")
_ARRAYS = ("data", "azimuth", "range", "origin", "azimuth_direction", "range_direction")
_STRINGS = ("plane", "algorithm", "window")


def _fractional_index(axis: np.ndarray, value: float) -> float:
    """Fractional index of ``value`` on a monotonic axis: linear between samples, extrapolated
    with the end steps beyond them (0.0 for a one-sample axis)."""
    n = axis.size
    if n < 2:
        return 0.0
    sign = 1.0 if axis[-1] >= axis[0] else -1.0
    a, v = sign * axis, sign * float(value)
    if v < a[0]:
        return float((v - a[0]) / (a[1] - a[0]))
    if v > a[-1]:
        return float(n - 1 + (v - a[-1]) / (a[-1] - a[-2]))
    return float(np.interp(v, a, np.arange(n)))


class SarImageError(ValueError):
    """A SarImage file or array set does not honour the contract of docs/design.md section 3."""


@dataclass(frozen=True)
class SarImage:
    """Complex focused image on an azimuth x range grid.

    Attributes
    ----------
    data : complex64 [n_azimuth, n_range]
        Focused complex image (sqrt(m^2) in normalised radiometry).
    azimuth : float64 [n_azimuth], m
        Along-track coordinate of each row, relative to ``origin``.
    range : float64 [n_range], m
        Ground range (``plane == "ground"``) or slant range (``"slant"``) of each column,
        relative to ``origin``; increases away from the sensor.
    origin : float64 [3], m
        World position of ``azimuth == 0, range == 0`` (the scene centre for ground grids).
    azimuth_direction, range_direction : float64 [3]
        Unit vectors in the world frame spanning the grid.
    plane : str
        ``"ground"`` or ``"slant"``.
    algorithm : str
        Focusing algorithm that made the image (``"backprojection"``, ...).
    window : str
        Window applied in focusing (``"rect"`` when none).
    metadata : dict
        The RawData metadata plus the focusing parameters and timing.

    Raises
    ------
    SarImageError
        On a wrong dtype or shape (an axis length that disagrees with ``data``), a non-finite
        axis, origin or direction, or an unknown plane. Non-finite pixels are refused only by
        :meth:`load`.
    """

    data: np.ndarray
    azimuth: np.ndarray
    range: np.ndarray
    origin: np.ndarray
    azimuth_direction: np.ndarray
    range_direction: np.ndarray
    plane: str = "ground"
    algorithm: str = "backprojection"
    window: str = "rect"
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.data.ndim != 2 or self.data.dtype != np.complex64:
            raise SarImageError(f"data must be complex64 [n_azimuth, n_range], got {self.data.dtype} "
                                f"{list(self.data.shape)}")
        n_az, n_rg = self.data.shape
        for name, shape in (("azimuth", (n_az,)), ("range", (n_rg,)), ("origin", (3,)),
                            ("azimuth_direction", (3,)), ("range_direction", (3,))):
            value = getattr(self, name)
            if name in ("azimuth", "range") and value.ndim == 1 and value.size != shape[0]:
                rows = f"{n_az} azimuth rows" if name == "azimuth" else f"{n_rg} range columns"
                raise SarImageError(f"data has {rows} but {name} has {value.size} entries: the arrays are not "
                                    "of one image; focus the raw data again (sarmitsuba focus)")
            if value.shape != shape or value.dtype != np.float64:
                raise SarImageError(f"{name} must be float64 {list(shape)}, got {value.dtype} {list(value.shape)}")
            refuse_non_finite(value, name, "value", {"azimuth": ("row",), "range": ("column",)}.get(name, ("axis",)),
                               SarImageError,
                               "the image geometry is corrupt: focus the raw data again (sarmitsuba focus)")
        if self.plane not in _PLANES:
            raise SarImageError(f"plane must be one of {_PLANES}, got {self.plane!r}")

    def positions(self) -> np.ndarray:
        """World positions of all pixels, float64 [n_azimuth, n_range, 3] in metres."""
        return (self.origin
                + self.azimuth[:, None, None] * self.azimuth_direction
                + self.range[None, :, None] * self.range_direction)

    def pixel_of(self, point: np.ndarray) -> tuple[float, float]:
        """Fractional (row, column) at which the image shows the world point ``point`` (3 floats, m).

        The point is placed where a focuser matched to its range history puts it,
        :func:`image_coordinates`: when the metadata record the straight
        track, at the intersection of the point's closest-approach circle about the track with
        the image plane (zero-Doppler azimuth; ground images: its layover position; slant
        images of the FFT focusers: its closest-approach range); otherwise projected
        orthogonally on the axes. A point on the image plane maps to its own pixel, so
        ``pixel_of(positions()[i, j]) == (i, j)``. Linear in the axes and extrapolated beyond
        them: a point outside the grid gives an index outside ``[0, n - 1]`` (never clamped).
        Raises ValueError when the point is not 3 finite numbers or cannot appear in the image.
        """
        point = np.asarray(point, dtype=np.float64).reshape(-1)
        if point.shape != (3,):
            raise ValueError(f"point must be 3 finite numbers (world x, y, z in m), got {point.tolist()!r}")
        az, rg = image_coordinates(self, point)
        return _fractional_index(self.azimuth, az), _fractional_index(self.range, rg)

    def save(self, path: str | os.PathLike) -> Path:
        """Write the image as ``.npz`` atomically (temporary name, then rename)."""
        return atomic_savez(
            Path(path), data=self.data, azimuth=self.azimuth, range=self.range, origin=self.origin,
            azimuth_direction=self.azimuth_direction, range_direction=self.range_direction,
            plane=np.str_(self.plane), algorithm=np.str_(self.algorithm), window=np.str_(self.window),
            metadata=np.str_(json.dumps(self.metadata, default=json_default)))

    @classmethod
    def load(cls, path: str | os.PathLike) -> "SarImage":
        """Read a file written by :meth:`save`.

        Unlike an image built in memory (whose NaN pixels the quick-look tolerates), a loaded
        image must be finite: it is read for analysis and figures.

        Raises
        ------
        SarImageError
            Naming ``path`` and the problem: missing or unreadable file, not an ``.npz``
            archive, damaged archive (truncated, bad CRC), missing field, axis lengths that
            disagree with the data shape, non-finite geometry or pixels (count and first
            (azimuth, range) pixel).
        """
        kwargs = read_npz(path, "SarImage", SarImageError, _read_image_fields)
        try:
            image = cls(**kwargs)
            refuse_non_finite(image.data, "data", "pixel", ("azimuth", "range"), SarImageError,
                               "the image is damaged or was focused from non-finite raw data; focus a finite "
                               "raw.npz again (sarmitsuba focus)")
        except SarImageError as exc:
            raise SarImageError(f"{path}: {exc}") from None
        return image


# ============================================================================ where a world point appears
def image_coordinates(image: SarImage, point: Sequence[float] | np.ndarray, *,
                      layover: bool = True) -> tuple[float, float]:
    """``(azimuth, range)`` image coordinates [m] where a world point appears, or a coordinate pair.

    Parameters
    ----------
    image : SarImage
    point : 3 floats (world position, m) or 2 floats (azimuth, range in m)
        A world point is mapped through the range / zero-Doppler geometry when the image
        metadata record the straight track (``metadata["focus"]["track"]`` of a
        backprojected image, ``metadata["focus"]["geometry"]`` of an omega-K or RDA image,
        or sarmitsuba's ``metadata["radar"]``): see
        :func:`layover_position`. Otherwise, or with ``layover=False``, it is projected
        orthogonally on the image axes, ``((x - origin) . azimuth_direction,
        (x - origin) . range_direction)``. Both agree for a point on the image plane.
    layover : bool, default True
        Map world points through the imaging geometry when it is known.

    Raises
    ------
    ValueError
        When ``point`` is not 2 or 3 finite numbers, or the point's closest-approach circle
        does not meet the image plane.
    """
    p = np.asarray(point, dtype=np.float64).reshape(-1)
    if p.size not in (2, 3) or not np.all(np.isfinite(p)):
        raise ValueError(f"a target must be 3 finite numbers (world x, y, z in m) or 2 (azimuth, range in m), "
                         f"got {point!r}")
    if p.size == 2:
        return float(p[0]), float(p[1])
    if layover and image_track(image) is not None:
        return layover_position(image, p)
    rel = p - image.origin
    return float(rel @ image.azimuth_direction), float(rel @ image.range_direction)


def image_track(image: SarImage) -> tuple[np.ndarray, np.ndarray] | None:
    """The straight track the image was focused from, read from its metadata.

    Returns
    -------
    (point, direction) : tuple of float64 [3] arrays, or None
        A point of the track [m] and its unit direction: the backprojection's
        ``metadata["focus"]["track"]`` (mid-aperture transmitter, unit velocity), else the FFT
        focusers' ``metadata["focus"]["geometry"]`` (its ``origin`` lies on the fitted track
        line, ``azimuth_direction`` along it), else the mid-aperture position and track
        direction of sarmitsuba's ``metadata["radar"]`` parameters; None when the metadata
        hold none of them (or only malformed ones). Never raises.
    """
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    focus = meta.get("focus") if isinstance(meta.get("focus"), dict) else {}
    for record, point_key, direction_key in ((focus.get("track"), "position", "direction"),
                                             (focus.get("geometry"), "origin", "azimuth_direction")):
        line = _line_of(record, point_key, direction_key)
        if line is not None:
            return line
    params = _radar_of(image)
    if params is None:
        return None
    from .geometry import acquisition_geometry
    geometry = acquisition_geometry(replace(params, n_pulses=max(params.n_pulses, 1)))
    return geometry.positions[len(geometry.positions) // 2], geometry.track_direction


def _line_of(record: Any, point_key: str, direction_key: str) -> tuple[np.ndarray, np.ndarray] | None:
    """(point, unit direction) of a track line recorded as ``record[point_key]``,
    ``record[direction_key]`` (3 finite numbers each); None when absent or malformed."""
    if not isinstance(record, dict) or record.get(point_key) is None or record.get(direction_key) is None:
        return None
    try:
        point = np.asarray(record[point_key], float).reshape(3)
        direction = np.asarray(record[direction_key], float).reshape(3)
    except (TypeError, ValueError):
        return None
    norm = float(np.linalg.norm(direction))
    if not (np.all(np.isfinite(point)) and np.isfinite(norm) and norm > 0):
        return None
    return point, direction / norm


def _radar_of(image: SarImage):
    """The RadarParameters recorded in the image metadata (sarmitsuba renders), or None."""
    meta = image.metadata if isinstance(image.metadata, dict) else {}
    if not isinstance(meta.get("radar"), dict):
        return None
    from .radar import RadarParameters
    try:
        params = RadarParameters.from_mapping({k: v for k, v in meta["radar"].items() if v is not None})
    except (TypeError, ValueError, KeyError):
        return None
    return params if params.scene_center is not None else None


def layover_position(image: SarImage, point: Sequence[float] | np.ndarray) -> tuple[float, float]:
    """``(azimuth, range)`` image coordinates [m] at which a focuser puts a world point.

    For a straight track (point ``A``, unit direction ``t``, from the image metadata, see
    :func:`image_coordinates`), every point of the circle about the track through ``X`` has the
    same range history as ``X``: the same closest-approach range ``R0 = |X - F|``, at the same
    along-track position ``F = A + ((X - A) . t) t`` (its zero-Doppler point). A focuser matched
    to that history (backprojection, omega-K) therefore images ``X`` where this circle meets the
    image plane, on ``X``'s side of the track: ``Q = origin + a e_az + r e_rg`` with
    ``(Q - F) . t = 0`` and ``|Q - F| = R0`` (Cumming and Wong 2005, section 4.2). For a point at
    height ``h`` above a flat ground-plane image, a track at height ``H`` and ground distance ``Y``
    this is the layover ``sqrt(Y^2 - 2 H h + h^2) ~ Y - h / tan(theta)``: toward the sensor by
    ``h / tan(theta)`` in ground range (docs/physics.md (G2)). A point on the plane maps to itself.

    Parameters
    ----------
    image : SarImage
        Image whose metadata record the track.
    point : 3 floats, m
        World position.

    Returns
    -------
    (azimuth, range) : tuple of float, m

    Raises
    ------
    ValueError
        When the metadata record no track, the image plane contains the track direction in
        neither axis, or the circle does not reach the image plane.
    """
    x = np.asarray(point, dtype=np.float64).reshape(-1)
    if x.size != 3 or not np.all(np.isfinite(x)):
        raise ValueError(f"point must be 3 finite numbers (world x, y, z in m), got {point!r}")
    az, rg = layover_positions(image, x[None])
    if not np.isfinite(az[0]):
        track = image_track(image)
        r0 = float(np.linalg.norm(np.cross(x - track[0], track[1])))
        raise ValueError(f"the point {x.tolist()} lies {r0:.3f} m from the track, which the image plane does "
                         "not reach along its zero-Doppler line: it cannot appear in this image")
    return float(az[0]), float(rg[0])


def layover_positions(image: SarImage, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`layover_position` of many world points ``points`` float64 [n, 3] (m): ``(azimuth,
    range)`` float64 [n] each, NaN where a point's circle does not reach the image plane.

    Raises
    ------
    ValueError
        When the metadata record no track, or the image plane contains the track direction in
        neither axis.
    """
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    track = image_track(image)
    if track is None:
        raise ValueError("the image metadata record no track (focus['track'] or radar parameters): "
                         "give the target in image coordinates (azimuth, range)")
    a_point, t = track
    foot = a_point + ((x - a_point) @ t)[:, None] * t
    r0 = np.linalg.norm(x - foot, axis=1)
    e_a, e_r = np.asarray(image.azimuth_direction, float), np.asarray(image.range_direction, float)
    d = np.asarray(image.origin, float) - foot
    # (d + a e_a + r e_r) . t = 0: a line in (a, r); least-norm point plus a direction along it
    g = np.array([e_a @ t, e_r @ t])
    if np.linalg.norm(g) < 1e-12:
        raise ValueError("the image plane is normal to the track: no zero-Doppler line to map the target onto")
    base = -(d @ t)[:, None] * g / float(g @ g)
    step = np.array([g[1], -g[0]]) / np.linalg.norm(g)
    v0 = d + base[:, :1] * e_a + base[:, 1:] * e_r
    v1 = step[0] * e_a + step[1] * e_r
    qa, qb, qc = float(v1 @ v1), 2.0 * (v0 @ v1), np.einsum("ij,ij->i", v0, v0) - r0 * r0
    disc = qb * qb - 4.0 * qa * qc
    ok = (disc >= 0) & (qa > 0)
    root = np.sqrt(np.where(ok, disc, 0.0))
    best, score = None, None
    for lam in ((-qb + root) / (2 * qa), (-qb - root) / (2 * qa)):
        ar = base + lam[:, None] * step
        q = d + ar[:, :1] * e_a + ar[:, 1:] * e_r                       # Q - F
        here = np.einsum("ij,ij->i", q, x - foot)                        # on the point's side of the track
        best = ar if best is None else np.where((here > score)[:, None], ar, best)
        score = here if score is None else np.maximum(here, score)
    best = np.where(ok[:, None], best, np.nan)
    return best[:, 0], best[:, 1]


def _read_image_fields(f: Any) -> dict[str, Any]:
    """The keyword arguments of :class:`SarImage` from an open ``NpzFile``."""
    missing = [k for k in (*_ARRAYS, *_STRINGS, "metadata") if k not in f.files]
    if missing:
        raise KeyError(f"not a SarImage file, missing {missing}: give an image.npz written by SarImage.save "
                       "(sarmitsuba render or focus)")
    kwargs: dict[str, Any] = {k: np.asarray(f[k]) for k in _ARRAYS}
    kwargs.update({k: str(f[k]) for k in _STRINGS})
    kwargs["metadata"] = json.loads(str(f["metadata"]))
    return kwargs
