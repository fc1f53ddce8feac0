"""Bistatic angle, bisector and ground-range resolution of a transmitter-receiver pair.

For a transmitter at ``T``, a receiver at ``R`` and a scene point ``X``, with the unit vectors
``u_t = (T - X) / |T - X|`` and ``u_r = (R - X) / |R - X|`` toward the two antennas:

* the **bistatic angle** ``beta`` is the angle between ``u_t`` and ``u_r`` at ``X``
  (:func:`bistatic_angle`; 0 for a monostatic radar);
* the **bisector** ``b = (u_t + u_r) / |u_t + u_r|`` (:func:`bistatic_bisector`) is the gradient
  direction of the range sum ``L = |T - X| + |R - X|``: ``grad_X L = -(u_t + u_r)``, whose length
  is ``2 cos(beta / 2)``. Iso-range surfaces (ellipsoids with foci ``T`` and ``R``) are therefore
  spaced ``c / (2 B cos(beta / 2))`` apart along ``b`` for a bandwidth ``B``: the bistatic slant
  range resolution (Willis 2005, sec. 8.1; Cardillo 1990; Moccia and Renga 2011, eq. 10);
* on the ground (the horizontal plane through ``X``) the range sum changes along the horizontal
  part ``b_h`` of ``b`` only, at the rate ``2 cos(beta / 2) |b_h|``, so the **ground-range
  resolution** is ``rho_g = c / (2 B cos(beta / 2) |b_h|)`` along the unit horizontal bisector
  ``b_h / |b_h|`` (:func:`bistatic_ground_range_resolution`). Monostatic (``T = R``):
  ``beta = 0``, ``|b_h| = sin(theta_inc)``, and ``rho_g = c / (2 B sin(theta_inc))``.

These are resolution *cell* sizes (the reciprocal of the range-sum bandwidth); the -3 dB
impulse-response width is ``k_w`` times them, ``k_w = 0.886`` for an unweighted (rect) range
spectrum (:func:`sarmitsuba.focus.windows.impulse_response_width`).

Frame: any right-handed Cartesian frame in metres with ``z`` up (the scene's ENU frame).

References
----------
.. [1] N. J. Willis, *Bistatic Radar*, 2nd ed., SciTech Publishing, 2005, sec. 8.1 (range
   resolution ``c / (2 B cos(beta / 2))`` along the bisector).
.. [2] G. P. Cardillo, "On the use of the gradient to determine bistatic SAR resolution",
   Proc. IEEE AP-S Int. Symp., 1990, pp. 1032-1035.
.. [3] A. Moccia and A. Renga, "Spatial resolution of bistatic synthetic aperture radar: impact
   of acquisition geometry on imaging performance", IEEE Trans. Geosci. Remote Sens. 49(10),
   3487-3503, 2011.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..core.constants import SPEED_OF_LIGHT

__all__ = ["bistatic_angle", "bistatic_bisector", "bistatic_ground_range_resolution", "ground_range_direction",
           "bistatic_summary"]


def _legs(tx: Any, rx: Any, point: Any) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors float64 [..., 3] from ``point`` toward the transmitter and the receiver."""
    tx, rx, point = (np.asarray(v, dtype=np.float64) for v in (tx, rx, point))
    if tx.shape[-1:] != (3,) or rx.shape[-1:] != (3,) or point.shape[-1:] != (3,):
        raise ValueError(f"tx, rx and point must be [..., 3] arrays in metres, got shapes "
                         f"{tx.shape}, {rx.shape}, {point.shape}")
    to_tx, to_rx = tx - point, rx - point
    n_tx, n_rx = np.linalg.norm(to_tx, axis=-1), np.linalg.norm(to_rx, axis=-1)
    if not (np.all(np.isfinite(n_tx)) and np.all(np.isfinite(n_rx))):
        raise ValueError("tx, rx and point must be finite (metres)")
    if np.any(n_tx == 0) or np.any(n_rx == 0):
        raise ValueError("the point coincides with the transmitter or the receiver: no direction to it")
    return to_tx / n_tx[..., None], to_rx / n_rx[..., None]


def bistatic_angle(tx: Any, rx: Any, point: Any) -> np.ndarray | float:
    """Bistatic angle ``beta`` at ``point``: the angle between the directions to ``tx`` and ``rx``.

    Parameters
    ----------
    tx, rx : float64 [..., 3], m
        Transmitter and receiver phase centres (broadcast against each other and ``point``).
    point : float64 [..., 3], m
        Scene point.

    Returns
    -------
    float64 [...] (a float for single points), rad
        ``beta`` in ``[0, pi]``, from ``atan2(|u_t x u_r|, u_t . u_r)`` (accurate near 0 and pi).

    Raises
    ------
    ValueError
        Shapes not ``[..., 3]``, non-finite values, or ``point`` at an antenna.
    """
    u_t, u_r = _legs(tx, rx, point)
    beta = np.arctan2(np.linalg.norm(np.cross(u_t, u_r), axis=-1), np.sum(u_t * u_r, axis=-1))
    return float(beta) if np.ndim(beta) == 0 else beta


def bistatic_bisector(tx: Any, rx: Any, point: Any) -> np.ndarray:
    """Unit bisector ``b = (u_t + u_r) / |u_t + u_r|`` of the bistatic angle at ``point``.

    Parameters
    ----------
    tx, rx, point : float64 [..., 3], m
        As in :func:`bistatic_angle`.

    Returns
    -------
    float64 [..., 3]
        Unit vector from ``point`` between the directions to the two antennas: ``-grad L / |grad L|``
        of the range sum ``L = |T - X| + |R - X|`` (Cardillo 1990).

    Raises
    ------
    ValueError
        As :func:`bistatic_angle`, or ``beta = pi`` (the point between the antennas: no bisector).
    """
    u_t, u_r = _legs(tx, rx, point)
    total = u_t + u_r
    norm = np.linalg.norm(total, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ValueError("the bistatic angle is 180 deg (the point lies between the antennas): no bisector")
    return total / norm


def ground_range_direction(tx: Any, rx: Any, point: Any) -> np.ndarray:
    """Unit horizontal bisector ``b_h / |b_h|``: the ground direction of the bistatic range resolution.

    Parameters
    ----------
    tx, rx, point : float64 [..., 3], m
        As in :func:`bistatic_angle` (``z`` up).

    Returns
    -------
    float64 [..., 3]
        Horizontal unit vector (``z = 0``) pointing from ``point`` toward the antennas' side: the
        range sum decreases along it fastest among ground directions.

    Raises
    ------
    ValueError
        As :func:`bistatic_bisector`, or a vertical bisector (no ground-range direction).
    """
    b = bistatic_bisector(tx, rx, point)
    b_h = b * np.array([1.0, 1.0, 0.0])
    norm = np.linalg.norm(b_h, axis=-1, keepdims=True)
    if np.any(norm < 1e-12):
        raise ValueError("the bisector is vertical (both antennas overhead): no ground-range direction")
    return b_h / norm


def bistatic_ground_range_resolution(bandwidth: float, tx: Any, rx: Any, point: Any) -> np.ndarray | float:
    """Ground-range resolution ``rho_g = c / (2 B cos(beta / 2) |b_h|)`` of a bistatic pair at ``point``.

    Parameters
    ----------
    bandwidth : float, Hz
        Range (chirp) bandwidth ``B`` > 0.
    tx, rx, point : float64 [..., 3], m
        As in :func:`bistatic_angle` (``z`` up; the ground is the horizontal plane through ``point``).

    Returns
    -------
    float64 [...] (a float for single points), m
        The bistatic slant-range resolution ``c / (2 B cos(beta / 2))`` along the bisector (Willis
        2005, sec. 8.1) divided by the horizontal fraction ``|b_h|`` of the unit bisector (Moccia and
        Renga 2011): the spacing on the ground, along :func:`ground_range_direction`, of range sums
        ``c / B`` apart. Monostatic: ``c / (2 B sin(theta_inc))``. Multiply by the window's IRW
        factor (0.886 rect) for the -3 dB width.

    Raises
    ------
    ValueError
        ``bandwidth`` not a positive finite number, or as :func:`ground_range_direction`.
    """
    bandwidth = float(bandwidth)
    if not (np.isfinite(bandwidth) and bandwidth > 0):
        raise ValueError(f"bandwidth must be a positive number of Hz, got {bandwidth!r}")
    u_t, u_r = _legs(tx, rx, point)
    total = u_t + u_r                                   # length 2 cos(beta / 2)
    horizontal = np.linalg.norm(total[..., :2], axis=-1)   # 2 cos(beta / 2) |b_h|
    if np.any(horizontal < 1e-12):
        raise ValueError("the bisector is vertical (both antennas overhead): no ground-range resolution")
    rho = SPEED_OF_LIGHT / (bandwidth * horizontal)
    return float(rho) if np.ndim(rho) == 0 else rho


def bistatic_summary(bandwidth: float, tx: Any, rx: Any, point: Any) -> dict:
    """The bistatic geometry at one scene point, as ``info`` reports it (docs/physics.md (B4)):
    ``angle_deg``; ``slant_range_resolution_m`` ``c / (2 B cos(beta / 2))`` along the bisector;
    ``ground_range_resolution_m`` (:func:`bistatic_ground_range_resolution`) along
    ``ground_direction`` (a tuple of 3 floats, unit); ``receiver_range_m``. ``tx``, ``rx``,
    ``point`` float64 [3], m; ``bandwidth`` Hz. Raises ValueError as :func:`bistatic_angle`."""
    beta = float(bistatic_angle(tx, rx, point))
    return {"angle_deg": float(np.degrees(beta)),
            "slant_range_resolution_m": SPEED_OF_LIGHT / (2.0 * bandwidth * np.cos(0.5 * beta)),
            "ground_range_resolution_m": float(bistatic_ground_range_resolution(bandwidth, tx, rx, point)),
            "ground_direction": tuple(float(v) for v in ground_range_direction(tx, rx, point)),
            "receiver_range_m": float(np.linalg.norm(np.subtract(rx, point)))}

