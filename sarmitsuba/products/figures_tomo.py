"""The tomography figures: a tomogram along one range line, and the point cloud coloured by height.

:func:`write_tomogram` draws the reflectivity profiles of one azimuth row's pixels as an image over
ground range and elevation (dB below the row's peak), with the detected scatterers and, when
given, the geometry's true crossings of each pixel's iso-range circle. :func:`write_point_cloud`
draws the detected scatterers in the scene frame: a map view coloured by height and a view
along the track (ground range against height).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .plotting import agg_figure, colorbar, save_png

__all__ = ["write_tomogram", "write_point_cloud", "TOMOGRAM_RANGE_DB"]

#: Displayed dynamic range of the tomogram [dB].
TOMOGRAM_RANGE_DB = 30.0


def write_tomogram(ground_range: np.ndarray, elevation: np.ndarray, profiles: np.ndarray, path: str | os.PathLike,
                   title: str, detected: tuple[np.ndarray, np.ndarray] | None = None,
                   truth: tuple[np.ndarray, np.ndarray] | None = None) -> Path:
    """Write the tomogram PNG of one range line to ``path``.

    Parameters
    ----------
    ground_range : float [n_rg], m
        The row's range axis.
    elevation : float [S], m
    profiles : float [n_rg, S]
        Power over elevation of each pixel of the row (0 where not inverted).
    title : str
    detected, truth : (ground range float [M], elevation float [M]) m, optional
        Scatterers drawn as white dots, truth as red crosses.

    Returns the path; raises OSError when it cannot be written.
    """
    p = np.asarray(profiles, np.float64)
    peak = float(p.max()) if p.size and p.max() > 0 else 1.0
    db = 10.0 * np.log10(np.maximum(p / peak, 10.0 ** (-TOMOGRAM_RANGE_DB / 10.0)))
    fig = agg_figure((10.0, 5.0), 110)
    ax = fig.subplots()
    shown = ax.imshow(db.T, origin="lower", aspect="auto", cmap="inferno", vmin=-TOMOGRAM_RANGE_DB, vmax=0.0,
                      extent=(ground_range[0], ground_range[-1], elevation[0], elevation[-1]), interpolation="nearest")
    if truth is not None and len(truth[0]):
        ax.plot(truth[0], truth[1], "+", color="tab:red", ms=6, label="geometry (truth)")
    if detected is not None and len(detected[0]):
        ax.plot(detected[0], detected[1], ".", color="white", ms=4, label="detected")
    if (truth is not None and len(truth[0])) or (detected is not None and len(detected[0])):
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xlabel("ground range [m]")
    ax.set_ylabel("elevation s [m]")
    ax.set_ylim(elevation[0], elevation[-1])
    colorbar(fig, ax, shown, "power [dB below the line's peak]")
    ax.set_title(title)
    return save_png(fig, path, 110, "tomogram")


def write_point_cloud(x: np.ndarray, y: np.ndarray, height: np.ndarray, ground_range: np.ndarray,
                      path: str | os.PathLike, title: str) -> Path:
    """Write the point-cloud PNG to ``path``: map view (x, y [m], world frame) and a view along the
    track (``ground_range`` [m] against ``height`` [m] above the grid plane), both coloured by height.

    Returns the path; raises OSError when it cannot be written.
    """
    fig = agg_figure((13.0, 5.5), 100)
    axes = fig.subplots(1, 2)
    order = np.argsort(np.asarray(height, np.float64), kind="stable")     # the highest drawn last, on top
    x, y, ground_range = (np.asarray(v, np.float64)[order] for v in (x, y, ground_range))
    h = np.asarray(height, np.float64)[order]
    limits = (float(np.nanmin(h)), float(np.nanmax(h))) if h.size else (0.0, 1.0)
    shown = axes[0].scatter(x, y, c=h, s=2, cmap="viridis", vmin=limits[0], vmax=max(limits[1], limits[0] + 1e-3))
    axes[0].set_aspect("equal")
    axes[0].set_xlabel("x [m]")
    axes[0].set_ylabel("y [m]")
    axes[0].set_title(f"{h.size} scatterers, map view")
    axes[1].scatter(ground_range, h, c=h, s=2, cmap="viridis", vmin=limits[0], vmax=max(limits[1], limits[0] + 1e-3))
    axes[1].set_xlabel("ground range of the scatterer [m]")
    axes[1].set_ylabel("height above the grid plane [m]")
    axes[1].set_title("view along the track")
    colorbar(fig, axes[1], shown, "height [m]")
    fig.suptitle(title)
    return save_png(fig, path, 100, "point cloud")
