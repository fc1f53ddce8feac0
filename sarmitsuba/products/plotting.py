"""Shared display conventions of every drawn image: dB scale, multilooks, axes, colour bars.

Used by :mod:`sarmitsuba.products.image_files` (the PNG quicklook), :mod:`sarmitsuba.products.figures` and its
siblings (the explanatory figures) and :mod:`sarmitsuba.products.preview` (the optical preview), so a
quicklook and a figure of the same image look the same:

====================================  ====================================================================
:func:`intensity`                     ``|data|^2`` of complex data in float64, a band of rows at a time.
:func:`multilook`                     Intensity block-averaged by whole ``looks`` per axis.
:func:`display_looks`                 The looks that keep each axis within ``max_pixels``.
:func:`has_signal`                    Whether any finite intensity is > 0.
:func:`reference_intensity`           ``I_ref``: the :data:`REFERENCE_PERCENTILE` of non-zero intensities.
:func:`decibels`                      ``10 log10(I / I_ref)`` clipped to ``[-dynamic_range_db, 0]``.
:func:`check_dynamic_range`           Validates ``dynamic_range_db`` (finite, > 0).
:func:`edges`, :func:`image_extent`   ``imshow`` extents from axes of pixel centres.
:func:`show_db_image`                 An image in dB on an axes: grey, metres, axes labelled.
:func:`label_image_axes`              Range/azimuth labels, near/far range and a flight arrow.
:func:`colorbar`                      A colour bar as tall as an aspect-locked image.
:func:`window_label`                  The window an image was focused with, for titles.
:func:`agg_figure`, :func:`save_png`  A pyplot-free Agg figure, written atomically.
====================================  ====================================================================
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..core.image import SarImage
from ..core.outputs import atomic_write

__all__ = ["REFERENCE_PERCENTILE", "MAX_BOX_ASPECT", "RELATIVE_DB",
           "intensity", "multilook", "display_looks", "has_signal", "reference_intensity", "decibels",
           "check_dynamic_range", "edges", "image_extent", "show_db_image", "axis_labels", "label_image_axes",
           "colorbar", "window_label", "agg_figure", "save_png"]

#: Percentile of the non-zero intensities shown as 0 dB (brighter pixels saturate).
REFERENCE_PERCENTILE = 99.5
#: Rows of an image turned into intensity at once (bounds the float64 temporaries).
ROWS_PER_BAND = 256
#: Largest height-to-width ratio (and its inverse) of an image's box drawn to scale: a longer image
#: (a spaceborne slant image is 25 times longer in azimuth than in range) is drawn in a box of this
#: ratio and says how much it is compressed, instead of as a sliver its labels cannot fit beside.
MAX_BOX_ASPECT = 2.5
#: Colour-bar label of a dB scale relative to :data:`REFERENCE_PERCENTILE`.
RELATIVE_DB = f"dB re the {REFERENCE_PERCENTILE:g}th percentile"


# ============================================================================ numbers
def intensity(data: np.ndarray, dtype: Any = np.float64) -> np.ndarray:
    """``|data|^2`` of complex ``data`` [n0, n1], computed in float64 a band of
    :data:`ROWS_PER_BAND` rows at a time, stored as ``dtype`` (same shape; m^2 for an image)."""
    out = np.empty(data.shape, dtype)
    for r0 in range(0, data.shape[0], ROWS_PER_BAND):
        part = data[r0:r0 + ROWS_PER_BAND]
        out[r0:r0 + ROWS_PER_BAND] = part.real.astype(np.float64) ** 2 + part.imag.astype(np.float64) ** 2
    return out


def multilook(data: np.ndarray, looks: tuple[int, int]) -> np.ndarray:
    """Intensity ``|data|^2`` of complex ``data`` [n0, n1] averaged over ``looks`` blocks, float64
    ``[n0 // looks[0], n1 // looks[1]]`` (trailing partial blocks dropped, at least one block).

    Computed a band of rows at a time (:func:`intensity`); ``looks == (1, 1)`` is the intensity.
    """
    n0 = max(1, data.shape[0] // looks[0]) * looks[0]
    n1 = max(1, data.shape[1] // looks[1]) * looks[1]
    if looks == (1, 1):
        return intensity(data, np.float64)
    out = np.empty((n0 // looks[0], n1 // looks[1]))
    band = max(1, ROWS_PER_BAND // looks[0]) * looks[0]
    for r0 in range(0, n0, band):
        power = intensity(data[r0:min(r0 + band, n0), :n1], np.float64)
        out[r0 // looks[0]:r0 // looks[0] + power.shape[0] // looks[0]] = \
            power.reshape(-1, looks[0], n1 // looks[1], looks[1]).mean(axis=(1, 3))
    return out


def display_looks(shape: tuple[int, ...], max_pixels: int) -> tuple[int, int]:
    """Whole looks ``(l0, l1)`` per axis of an array of ``shape`` so that neither of its first two
    axes exceeds ``max_pixels`` multilooked pixels (``ceil(n / max_pixels)``, at least 1).

    Raises
    ------
    ValueError
        ``max_pixels`` is not a whole number >= 1.
    """
    if int(max_pixels) != max_pixels or max_pixels < 1:
        raise ValueError(f"max_pixels must be a whole number >= 1, got {max_pixels!r}")
    return tuple(max(1, -(-n // int(max_pixels))) for n in shape[:2])  # type: ignore[return-value]


def has_signal(power: np.ndarray) -> bool:
    """Whether ``power`` holds any finite intensity > 0 (else it is drawn uniformly dark)."""
    return bool(np.any(np.isfinite(power) & (power > 0)))


def reference_intensity(*powers: np.ndarray) -> float:
    """``I_ref``: the :data:`REFERENCE_PERCENTILE` (99.5th) percentile of the non-zero finite values of
    all ``powers`` pooled (float64 arrays of any shape, intensities), so a few bright corner
    reflectors saturate instead of pushing distributed clutter below the display; 1.0 when none."""
    values = np.concatenate([p[np.isfinite(p) & (p > 0)].ravel() for p in powers])
    return float(np.percentile(values, REFERENCE_PERCENTILE)) if values.size else 1.0


def decibels(power: np.ndarray, reference: float, dynamic_range_db: float) -> np.ndarray:
    """``10 log10(power / reference)`` [dB], float64 of ``power``'s shape, clipped to
    ``[-dynamic_range_db, 0]``; non-finite intensities are shown at ``-dynamic_range_db``."""
    floor = reference * 10.0 ** (-dynamic_range_db / 10.0)
    power = np.where(np.isfinite(power), np.maximum(power, floor), floor)
    return np.minimum(10.0 * np.log10(power / reference), 0.0)


def check_dynamic_range(dynamic_range_db: Any) -> float:
    """``dynamic_range_db`` as a float [dB].

    Raises
    ------
    ValueError
        It is not a finite number > 0.
    """
    value = float(dynamic_range_db)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"dynamic_range_db must be a finite number > 0 (dB), got {dynamic_range_db!r}")
    return value


# ============================================================================ axes
def edges(axis: np.ndarray) -> tuple[float, float]:
    """Outer pixel edges of a float [n] axis of pixel centres (half a spacing beyond each end;
    half a unit when ``n == 1``), in the axis' unit."""
    half = 0.5 * float(axis[-1] - axis[0]) / (axis.size - 1) if axis.size > 1 else 0.5
    return float(axis[0]) - half, float(axis[-1]) + half


def image_extent(image: SarImage, shown: tuple[int, ...], looks: tuple[int, int]) -> tuple[float, ...]:
    """``imshow`` extent ``(range_lo, range_hi, azimuth_lo, azimuth_hi)`` [m] of the ``shown``
    ``(n_az, n_rg)`` multilooked pixels of ``image`` made with ``looks``."""
    return (*edges(image.range[:shown[1] * looks[1]]), *edges(image.azimuth[:shown[0] * looks[0]]))


def show_db_image(ax: Any, image: SarImage, db: np.ndarray, looks: tuple[int, int], dynamic_range_db: float,
                  aspect: str | float = "equal") -> Any:
    """Draw ``db`` [n_az, n_rg] (dB, multilooked by ``looks``) of ``image`` on ``ax`` in grey over
    ``[-dynamic_range_db, 0]``, range on x and azimuth upward in metres, axes labelled
    (:func:`label_image_axes`); returns the AxesImage.

    With ``aspect="equal"`` an image longer than :data:`MAX_BOX_ASPECT` times its width (or wider
    than that times its length) is drawn in a box of that ratio, not to scale, and says so in its
    lower right corner. Tick labels are plain metres, without an offset; range ticks of six
    digits or more (slant ranges from orbit) are at most three."""
    extent = image_extent(image, db.shape, looks)
    stretch = 1.0
    if isinstance(aspect, str) and aspect == "equal":
        ratio = abs(extent[3] - extent[2]) / max(abs(extent[1] - extent[0]), 1e-300)
        box = min(max(ratio, 1.0 / MAX_BOX_ASPECT), MAX_BOX_ASPECT)
        if box != ratio:
            aspect, stretch = "auto", ratio / box
            ax.set_box_aspect(box)
    shown = ax.imshow(db, cmap="gray", vmin=-dynamic_range_db, vmax=0.0, origin="lower",
                      extent=extent, aspect=aspect, interpolation="nearest")
    ax.ticklabel_format(axis="both", style="plain", useOffset=False)
    if max(abs(extent[0]), abs(extent[1])) >= 1e5:
        from matplotlib.ticker import MaxNLocator
        ax.xaxis.set_major_locator(MaxNLocator(nbins=3, steps=[1, 2, 2.5, 5, 10]))
    label_image_axes(ax, image)
    if stretch != 1.0:
        from matplotlib import patheffects
        which, factor = ("azimuth", stretch) if stretch > 1.0 else ("range", 1.0 / stretch)
        ax.annotate(f"not to scale:\n{which} {factor:.3g}x shorter", xy=(0.97, 0.03), xycoords="axes fraction",
                    ha="right", va="bottom", fontsize="x-small", color="yellow",
                    path_effects=[patheffects.withStroke(linewidth=2.0, foreground="black")])
    return shown


def axis_labels(image: SarImage) -> tuple[str, str]:
    """``(x, y)`` axis labels of an image: what range and azimuth are measured from.

    Ground images (:meth:`~sarmitsuba.focus.ImageGrid.ground`, :func:`sarmitsuba.pipeline.image_grid`)
    are centred on the scene centre; slant images
    (:func:`~sarmitsuba.focus.stripmap.slant_output_grid`) hold the absolute closest-approach
    slant range and the azimuth from the scene centre's closest approach (docs/design.md section 8).
    """
    if image.plane == "ground":
        return "ground range from scene centre [m]", "azimuth from scene centre [m]"
    return "slant range (closest approach) [m]", "azimuth from scene centre [m]"


def label_image_axes(ax: Any, image: SarImage) -> None:
    """Axis labels, near/far range under the x label and a flight arrow, on an image's axes.

    Range grows away from the sensor (``image.range_direction``), so near range is on the left;
    azimuth grows along the flight direction (upward with ``origin="lower"``).
    """
    x_label, y_label = axis_labels(image)
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    below = {"xycoords": (ax.transAxes, ax.xaxis.label), "xytext": (0, -2), "textcoords": "offset points",
             "va": "top", "fontsize": "x-small", "color": "0.2"}
    ax.annotate("\u2190 near range\n(sensor side)", xy=(0.0, 0.0), ha="left", multialignment="left", **below)
    ax.annotate("far range \u2192", xy=(1.0, 0.0), ha="right", **below)
    from matplotlib import patheffects
    outline = [patheffects.withStroke(linewidth=2.0, foreground="black")]
    head = {"xy": (0.03, 0.97), "xycoords": "axes fraction", "textcoords": "offset points"}
    ax.annotate("", xytext=(0, -32), **head,
                arrowprops={"arrowstyle": "-|>", "color": "yellow", "lw": 1.2, "path_effects": outline})
    ax.annotate("flight\n(azimuth)", xytext=(5, -16), ha="left", va="center", fontsize="x-small",
                color="yellow", path_effects=outline, **head)


def colorbar(fig: Any, ax: Any, mappable: Any, label: str) -> Any:
    """A colour bar beside ``ax`` exactly as tall as its (aspect-locked) image box; returns it."""
    cax = ax.inset_axes([1.03, 0.0, 0.035, 1.0])
    return fig.colorbar(mappable, cax=cax, label=label)


def window_label(image: SarImage) -> str:
    """``image.window``, or the range window of ``metadata["range_window"]`` when that was
    applied before a focuser that itself records ``"rect"`` (backprojection)."""
    applied = image.metadata.get("range_window")
    name = applied.get("name") if isinstance(applied, dict) else None
    if image.window == "rect" and name and name != "rect":
        return f"{name} range"
    return image.window


# ============================================================================ files
def agg_figure(figsize: tuple[float, float], dpi: int, layout: str | None = "constrained") -> Any:
    """A matplotlib Figure on an Agg canvas (no pyplot state) of ``figsize`` inches at ``dpi``.

    ``layout="compressed"`` suits rows of equal-aspect images sharing a colour bar (the bar
    then spans the images' height, not the grid cell's; not with a suptitle, which upsets it).

    Raises
    ------
    ValueError
        ``figsize`` is not two positive inches or ``dpi`` is not positive.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    if not (len(figsize) == 2 and min(figsize) > 0 and dpi > 0):
        raise ValueError(f"figsize must be two positive inches and dpi > 0, got {figsize!r}, {dpi!r}")
    fig = Figure(figsize=figsize, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def save_png(fig: Any, path: str | os.PathLike, dpi: int, what: str = "figure") -> Path:
    """Write ``fig`` as a PNG at ``dpi`` atomically (:func:`sarmitsuba.core.outputs.atomic_write`).

    Raises
    ------
    sarmitsuba.core.outputs.WriteError
        An OSError naming ``path`` (described as ``what``) when it cannot be written.
    """
    return atomic_write(Path(path), lambda tmp: fig.savefig(tmp, format="png", dpi=dpi), what)
