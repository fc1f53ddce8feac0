"""Scene geometry of a CPHD file written from RawData: the scene reference point and the image area.

Used by :mod:`sarmitsuba.formats.cphd`. Everything here is in the local east-north-up frame of
the RawData (metres, world frame: the traced frame's ``frame_offset`` already added), whose
origin is the IARP, so image area coordinates (IAX east, IAY north) are the local x and y.

- **Scene reference point (SRP)**: the scene centre (``metadata["radar"]["scene_center"]``), else
  the mean of the pulses' closest points on the ground at mid-swath (:func:`scene_reference_point`).
- **Image area** (``SceneCoordinates/ImageArea``, ``Channel/Parameters/ImageArea``, ``ImageGrid``):
  the rectangle, aligned with east and north, that holds what the data can show
  (:func:`image_area`):

  * with the scene's bounding box in the metadata (``scene_info["bbox_min"/"bbox_max"]``, traced
    frame, plus ``frame_offset``): the box's corners and where a ground-plane image lays them over
    (a point ``dz`` above the ground plane appears toward the sensor by about ``dz / tan(theta)``),
    plus :data:`MARGIN_CELLS` ground-range resolution cells on every side for the impulse
    response's sidelobes (as the focuser's own ground grid), and the SRP. Nothing outside the box
    echoes, so this is the tightest bound the file can give; for the 2 m trihedral it is about
    47 m square where the fast-time window spans 110 m of slant range.
  * without it (other tools' RawData): the fast-time window projected to the ground around the
    SRP. Across track, the ground ranges of the window's first and last samples seen from the
    reference (middle) pulse; along track, the track's span widened by half the swath on either
    side (the beam's footprint is not recorded).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core import georef
from ..core.constants import SPEED_OF_LIGHT
from ..core.raw import RawData

__all__ = ["MARGIN_CELLS", "scene_reference_point", "srp_delay", "unit", "bistatic", "receiver_velocity",
           "ground_at_range_sum", "scene_box", "image_area", "scene_coordinates", "image_grid"]

#: Ground-range resolution cells added on every side of the scene's box (its sidelobes).
MARGIN_CELLS = 16


def unit(vectors: np.ndarray) -> np.ndarray:
    """Unit vectors [..., 3] along ``vectors`` [..., 3]."""
    return vectors / np.linalg.norm(vectors, axis=-1, keepdims=True)


def srp_delay(tx: np.ndarray, rx: np.ndarray, srp: np.ndarray) -> np.ndarray:
    """float64 [n]: two-way delay [s] from the Tx and Rcv positions [n, 3] to the SRP [3] or [n, 3] (m)."""
    return (np.linalg.norm(tx - srp, axis=-1) + np.linalg.norm(rx - srp, axis=-1)) / SPEED_OF_LIGHT


def bistatic(raw: RawData) -> bool:
    """Whether ``raw`` has a receiver on another platform (CPHD ``CollectType`` BISTATIC): the receiver
    is away from the transmitter in stop-and-hop data (``rx_time`` None). Continuous-motion data
    (``rx_time`` given) are one antenna that moved during the echo: MONOSTATIC (CPHD 1.1 sec. 2)."""
    return raw.rx_time is None and not np.array_equal(raw.tx_position, raw.rx_position)


def receiver_velocity(raw: RawData) -> np.ndarray:
    """float64 [n_pulses, 3] m/s, local frame: the receiver's velocity (``RcvVel``).

    RawData record one velocity, the transmitter's (``raw.velocity``), which is the receiver's too for
    one antenna. A receiver on another platform (:func:`bistatic`) gets the derivative of
    ``raw.rx_position`` over ``raw.pulse_time`` (second-order central differences, one-sided at the
    ends: exact for uniform straight motion); zero for a single pulse."""
    if not bistatic(raw):
        return np.asarray(raw.velocity, dtype=np.float64)
    if raw.n_pulses < 2:
        return np.zeros_like(raw.rx_position)
    return np.gradient(raw.rx_position, raw.pulse_time, axis=0, edge_order=2 if raw.n_pulses > 2 else 1)


def ground_at_range_sum(tx: np.ndarray, rx: np.ndarray, start: np.ndarray, look: np.ndarray, total: np.ndarray,
                        height: float = 0.0) -> np.ndarray:
    """float64 [n] m: how far along the horizontal unit ``look`` [n, 2] from ``start`` [n, 2] the point
    ``P = (start + g look, height)`` has the range sum ``|tx - P| + |rx - P| = total`` [n] (m), with
    ``tx``, ``rx`` [n, 3] (m). The range sum is convex in ``g`` (a sum of norms of affine functions):
    the root is the one beyond its minimum (golden-section search), found by bisection; where even the
    minimum exceeds ``total`` (the window does not reach that plane) the minimum's ``g``."""
    def length(g: np.ndarray) -> np.ndarray:
        point = np.column_stack([start + g[:, None] * look, np.full(g.size, height)])
        return np.linalg.norm(tx - point, axis=1) + np.linalg.norm(rx - point, axis=1)
    total = np.broadcast_to(np.asarray(total, dtype=np.float64), (len(start),))
    lo, hi = np.zeros(len(start)), np.maximum(total, 0.0)      # |tx - P| >= g: the sum exceeds total at g = total
    golden = 0.5 * (np.sqrt(5.0) - 1.0)
    for _ in range(90):                                        # the minimum of the convex range sum
        a, b = hi - golden * (hi - lo), lo + golden * (hi - lo)
        left = length(a) < length(b)
        lo, hi = np.where(left, lo, a), np.where(left, b, hi)
    low = 0.5 * (lo + hi)
    reached = length(low) < total
    lo, hi = low.copy(), np.maximum(total, low)
    for _ in range(90):                                        # the root beyond it
        mid = 0.5 * (lo + hi)
        short = length(mid) < total
        lo, hi = np.where(short, mid, lo), np.where(short, hi, mid)
    return np.where(reached, 0.5 * (lo + hi), low)


def radar_of(raw: RawData) -> dict[str, Any]:
    """``raw.metadata["radar"]`` when it is a dictionary, else ``{}``."""
    radar = raw.metadata.get("radar") if isinstance(raw.metadata, dict) else None
    return radar if isinstance(radar, dict) else {}


def scene_reference_point(raw: RawData) -> np.ndarray:
    """float64 [3] m, local frame: the scene centre, else the mean of the pulses' closest ground points.

    The fallback (data without sarmitsuba's radar metadata) takes, for every pulse, the point on
    the ground (``z = 0``) right of its velocity, in the plane normal to it through the antenna
    (Tx and Rcv midpoint), at the slant range of the middle of the fast-time window
    ``c (t_first + t_last) / 4``; the SRP is their mean. A straight level track at height ``H``
    whose window is centred on the slant range ``H / cos(theta)`` gives the point ``H tan(theta)``
    right of the track's middle. A pulse whose range does not reach the ground gives its nadir.
    Bistatic data (:func:`bistatic`): the ground point right of the transmitter's velocity, from its
    nadir, whose range sum ``|T - P| + |R - P|`` is the window's middle ``c (t_first + t_last) / 2``
    (:func:`ground_at_range_sum`; the midpoint of two platforms far apart is no antenna).
    """
    radar = radar_of(raw)
    if radar.get("scene_center") is not None:
        return np.asarray(radar["scene_center"], dtype=np.float64)
    position = 0.5 * (raw.tx_position + raw.rx_position)
    slant = 0.25 * SPEED_OF_LIGHT * float(raw.fast_time[0] + raw.fast_time[-1])
    right = np.column_stack([raw.velocity[:, 1], -raw.velocity[:, 0]])
    norm = np.linalg.norm(right, axis=1, keepdims=True)
    right = np.divide(right, norm, out=np.zeros_like(right), where=norm > 0)
    if bistatic(raw):
        position = raw.tx_position
        ground = ground_at_range_sum(raw.tx_position, raw.rx_position, position[:, :2], right, 2.0 * slant)
    else:
        ground = np.sqrt(np.maximum(slant ** 2 - position[:, 2] ** 2, 0.0))
    points = position[:, :2] + ground[:, None] * right
    return np.array([*points.mean(axis=0), 0.0])


def scene_box(raw: RawData) -> tuple[np.ndarray, np.ndarray] | None:
    """(lowest, highest corner) float64 [3] m of the scene's bounding box in the local (world) frame:
    ``metadata["scene_info"]["bbox_min"/"bbox_max"]`` plus ``metadata["frame_offset"]``; None when
    the metadata lack them or they are not three finite numbers each."""
    meta = raw.metadata if isinstance(raw.metadata, dict) else {}
    info = meta.get("scene_info")
    try:
        offset = np.asarray(meta.get("frame_offset") or [0.0, 0.0, 0.0], dtype=np.float64)
        lo = np.asarray(info["bbox_min"], dtype=np.float64) + offset
        hi = np.asarray(info["bbox_max"], dtype=np.float64) + offset
    except (KeyError, TypeError, ValueError):
        return None
    if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite([lo, hi])) or np.any(hi < lo):
        return None
    return lo, hi


def laid_over(raw: RawData, points: np.ndarray) -> np.ndarray:
    """float64 [n, 2]: where a ground-plane (``z = 0``) image places ``points`` [n, 3] m: at the same
    range from the antenna position closest to each point, in the vertical plane through both."""
    arp = 0.5 * (raw.tx_position + raw.rx_position)
    nearest = arp[np.argmin(np.linalg.norm(arp[None, :, :] - points[:, None, :], axis=2), axis=1)]
    offset = points[:, :2] - nearest[:, :2]
    ground = np.linalg.norm(offset, axis=1)
    height = nearest[:, 2]
    laid = np.sqrt(np.maximum(ground ** 2 + (height - points[:, 2]) ** 2 - height ** 2, 0.0))
    scale = np.divide(laid, ground, out=np.ones_like(ground), where=ground > 0)
    return nearest[:, :2] + scale[:, None] * offset


def ground_resolution(raw: RawData, srp: np.ndarray) -> float:
    """Ground-range resolution [m] at the SRP seen from the middle pulse: ``c / (B |(u_t + u_r)_h|)``,
    ``u_t``, ``u_r`` the unit vectors from the SRP to the transmitter and the receiver and ``_h`` the
    horizontal part (Willis, *Bistatic Radar*, 2005, sec. 8.1: ``c / (2 B cos(beta / 2))`` along the
    bisector, over its horizontal fraction); monostatic ``c / (2 B sin(theta))``. ``|(u_t + u_r)_h|``
    is at least 0.2 (``sin(theta)`` 0.1, near the nadir)."""
    mid = raw.n_pulses // 2
    legs = unit(raw.tx_position[mid] - srp) + unit(raw.rx_position[mid] - srp)
    return SPEED_OF_LIGHT / (raw.bandwidth * max(float(np.linalg.norm(legs[:2])), 0.2))


def swath_area(raw: RawData, srp: np.ndarray) -> np.ndarray:
    """float64 [4, 2] m: the corners of the fast-time window projected to the ground around the SRP
    (module docstring): the ground points at the window's first and last ranges from the middle
    pulse, on the line from its nadir through the SRP, moved along track (the mean velocity's
    horizontal direction) over the track's span plus half the swath on either side."""
    arp = raw.tx_position if bistatic(raw) else 0.5 * (raw.tx_position + raw.rx_position)
    mid = raw.n_pulses // 2
    look = (srp - arp[mid])[:2]
    heading = raw.velocity.mean(axis=0)[:2]
    if np.linalg.norm(look) < 1e-9:
        look = np.array([heading[1], -heading[0]])
    look = look / max(float(np.linalg.norm(look)), 1e-12)
    along = heading / float(np.linalg.norm(heading)) if np.linalg.norm(heading) > 1e-9 else np.array(
        [-look[1], look[0]])
    height = arp[mid, 2] - srp[2]
    tau = float(srp_delay(raw.tx_position[mid], raw.rx_position[mid], srp))
    slant = np.linalg.norm(arp[mid] - srp) + 0.5 * SPEED_OF_LIGHT * (raw.fast_time[[0, -1]] - tau)
    ground = np.sqrt(np.maximum(slant ** 2 - height ** 2, 0.0)) - np.linalg.norm((srp - arp[mid])[:2])
    if bistatic(raw):          # the window's range sums on the ground, along the look from the transmitter
        ends = ground_at_range_sum(raw.tx_position[[mid, mid]], raw.rx_position[[mid, mid]], arp[[mid, mid], :2],
                                   np.tile(look, (2, 1)), SPEED_OF_LIGHT * raw.fast_time[[0, -1]], float(srp[2]))
        ground = ends - np.linalg.norm((srp - arp[mid])[:2])
    reach = (arp[:, :2] - srp[:2]) @ along
    half_swath = 0.5 * float(ground[1] - ground[0])
    shifts = (float(reach.min()) - half_swath, float(reach.max()) + half_swath)
    return np.array([srp[:2] + g * look + a * along for g in ground for a in shifts])


def image_area(raw: RawData, srp: np.ndarray) -> np.ndarray:
    """float64 [2, 2] m: ``[[x1, y1], [x2, y2]]``, the image area's rectangle (IAX east, IAY north about
    the IARP, the local origin) that holds what ``raw`` can show, and the SRP [3] (module docstring)."""
    box = scene_box(raw)
    if box is None:
        points = np.vstack([swath_area(raw, srp), srp[None, :2]])
        return np.array([points.min(axis=0), points.max(axis=0)])
    lo, hi = box
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    points = np.vstack([corners[:, :2], laid_over(raw, corners), srp[None, :2]])
    margin = MARGIN_CELLS * ground_resolution(raw, srp)
    return np.array([points.min(axis=0) - margin, points.max(axis=0) + margin])


def scene_coordinates(raw: RawData, ref: georef.GeoReference,
                      srp: np.ndarray) -> tuple[dict[str, Any], dict[str, Any]]:
    """(``SceneCoordinates``, image area) in sarkit's dictionary form: the IARP at the local origin,
    a ground plane with axes east and north, and the :func:`image_area` rectangle (its polygon
    clockwise), the same area for the channel."""
    import sarkit.wgs84
    rot = georef.enu_axes(ref)
    (x1, y1), (x2, y2) = image_area(raw, srp)
    corners = np.array([[x1, y1], [x1, y2], [x2, y2], [x2, y1]])
    corner_ecef = georef.enu_to_ecef(np.column_stack([corners, np.zeros(4)]), ref)
    area = {"X1Y1": corners[0], "X2Y2": corners[2], "Polygon": corners}
    return {"EarthModel": "WGS_84",
            "IARP": {"ECF": georef.enu_to_ecef(np.zeros(3), ref),
                     "LLH": np.array([ref.latitude_deg, ref.longitude_deg, ref.height_m])},
            "ReferenceSurface": {"Planar": {"uIAX": rot[0], "uIAY": rot[1]}},
            "ImageArea": area,
            "ImageAreaCornerPoints": sarkit.wgs84.cartesian_to_geodetic(corner_ecef)[:, :2],
            "ImageGrid": image_grid(corners[0], corners[2], SPEED_OF_LIGHT / (2.0 * raw.bandwidth))}, area


def image_grid(low: np.ndarray, high: np.ndarray, resolution: float) -> dict[str, Any]:
    """``ImageGrid`` covering the image area from ``low`` = (x1, y1) to ``high`` = (x2, y2) [m] with
    square pixels of about ``resolution`` [m]; the IARP's (line, sample) follows from CPHD's rule
    that line ``l`` spans ``x = (l - IARPLine - 1/2 .. l - IARPLine + 1/2) LineSpacing``."""
    size = np.asarray(high, float) - np.asarray(low, float)
    n = np.maximum(np.ceil(size / resolution).astype(int), 1)
    spacing = size / n
    return {"IARPLocation": -np.asarray(low, float) / spacing - 0.5,
            "IAXExtent": {"LineSpacing": float(spacing[0]), "FirstLine": 0, "NumLines": int(n[0])},
            "IAYExtent": {"SampleSpacing": float(spacing[1]), "FirstSample": 0, "NumSamples": int(n[1])}}
