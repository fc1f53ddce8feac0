"""Image products: OpenEXR channels and PNG quicklooks of a :class:`SarImage` (docs/design.md section 3).

Figures are drawn here and in two other modules: :mod:`sarmitsuba.figures` (the explanatory
figures of a simulation) and :mod:`sarmitsuba.preview` (the optical preview of an
acquisition), which share this module's atomic writes (and, for figures, its axis labels and
colour bars). Every writer here is atomic: it writes a temporary file next to the target
(``.<name>.partial``) and renames it over the target with :func:`os.replace`, so readers
never see half a file and a failed write leaves any previous file untouched. A failed write removes the temporary file and raises :class:`WriteError`,
an OSError whose message names the target path the caller gave.

=========================  ===================================================================
:func:`write_exr`          float32 channels ``intensity`` (``|data|^2``), ``real``, ``imag``.
:func:`write_quicklook`    PNG: dB of ``|data|`` over a fixed dynamic range, axes in metres.
=========================  ===================================================================
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from .image import SarImage
from .outputs import WriteError, atomic_write, json_default

__all__ = ["write_exr", "write_quicklook", "WriteError"]

_MAX_HEADER_JSON = 1 << 18  # characters of JSON in the EXR header attribute "sarmitsuba"


def write_exr(image: SarImage, path: str | os.PathLike) -> Path:
    """Write ``image`` as a single-part scanline OpenEXR file with float32 channels.

    Parameters
    ----------
    image : SarImage
        The focused image; ``data`` is complex64 ``[n_az, n_rg]``.
    path : str or os.PathLike
        Target file, conventionally ``*.exr``.

    Returns
    -------
    Path
        The path written.

    Notes
    -----
    Channels (each float32 ``[n_az, n_rg]``; EXR width = ``n_rg``, height = ``n_az``,
    row ``i`` of the file is ``azimuth[i]``, so the first row is the smallest azimuth):

    ``intensity``
        ``|data|^2`` in m^2 (normalised radiometry), computed in float64 then rounded.
    ``real``, ``imag``
        The complex samples, exactly as stored in complex64.

    Custom channel names keep OpenEXR 3.5's Python reader (``OpenEXR.File``) from
    grouping them into an RGB(A) array; they are read back as
    ``File(path).channels()["intensity"].pixels``. Uncompressed: float32 SAR data hardly
    compress (ZIP: 145 MB instead of 146 MB for Munich's image, at 1.9 s instead of 0.07 s). The header
    attribute ``sarmitsuba`` holds JSON: plane, algorithm, window, origin, directions,
    both axes in metres and the image metadata (replaced by a note when longer than
    256 Ki characters).

    Raises
    ------
    WriteError
        An OSError naming ``path`` when it cannot be written (no temporary file is left).
    """
    import OpenEXR

    data = image.data
    intensity = _intensity(data, np.float32)
    channels = {"intensity": intensity,
                "real": np.ascontiguousarray(data.real, dtype=np.float32),
                "imag": np.ascontiguousarray(data.imag, dtype=np.float32)}
    info = {"plane": image.plane, "algorithm": image.algorithm, "window": image.window,
            "origin": image.origin, "azimuth_direction": image.azimuth_direction,
            "range_direction": image.range_direction, "azimuth": image.azimuth, "range": image.range,
            "units": {"intensity": "m^2", "real": "sqrt(m^2)", "imag": "sqrt(m^2)", "axes": "m"},
            "metadata": image.metadata}
    text = json.dumps(info, default=json_default)
    if len(text) > _MAX_HEADER_JSON:  # keep EXR headers small; the .npz keeps the full metadata
        info["metadata"] = {"omitted": f"metadata longer than {_MAX_HEADER_JSON} characters"}
        text = json.dumps(info, default=json_default)
    header = {"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage,
              "comment": f"sarmitsuba {image.algorithm} image, {image.plane} plane: "
                         "channels intensity = |data|^2, real, imag",
              "sarmitsuba": text}
    exr = OpenEXR.File(header, channels)
    return atomic_write(Path(path), lambda tmp: _write_exr_file(exr, tmp, Path(path)), "EXR image")


def _write_exr_file(exr: Any, tmp: Path, path: Path) -> None:
    """``exr.write(tmp)``, with OpenEXR's RuntimeErrors as OSErrors that name ``path``."""
    tmp.open("wb").close()                      # a missing folder or no permission: a plain OSError
    try:
        exr.write(str(tmp))
    except RuntimeError as exc:
        raise OSError(None, str(exc).replace(str(tmp), str(path))) from None


def write_quicklook(image: SarImage, path: str | os.PathLike, dynamic_range_db: float = 40.0,
                    title: str | None = None, *, figsize: tuple[float, float] = (8.0, 6.0),
                    dpi: int = 100, aspect: str | float = "equal", max_pixels: int = 800) -> Path:
    """Write a PNG quicklook: ``10 log10(I / I_ref)`` clipped to ``[-dynamic_range_db, 0]``.

    ``I_ref`` is the 99.5th percentile of the non-zero intensities, so a few bright corner
    reflectors saturate instead of pushing distributed clutter below the display range.

    ``I`` is the intensity ``|data|^2``, multilooked (block-averaged) by whole factors per
    axis so that neither axis exceeds ``max_pixels``: a one-pixel-wide double-bounce line
    survives as a block average instead of vanishing in screen resampling.

    Parameters
    ----------
    image : SarImage
        The focused image.
    path : str or os.PathLike
        Target file, conventionally ``*.png``.
    dynamic_range_db : float, default 40
        Shown range below the peak in dB (> 0); darker pixels are clipped to
        ``-dynamic_range_db``.
    title : str, optional
        First title line; default ``metadata["scene"]`` or ``"SAR image"``. Then the
        algorithm and window, and a line of the key parameters (plane, fc, B, pulses, size);
        fc and B are left out when ``title`` already gives a frequency in GHz and a
        bandwidth in MHz.
    figsize : (float, float), default (8, 6)
        Figure size in inches; the PNG is ``figsize * dpi`` pixels (no tight cropping).
    dpi : int, default 100
        Dots per inch.
    aspect : "equal", "auto" or float, default "equal"
        Passed to :meth:`matplotlib.axes.Axes.imshow`; "equal" keeps metres square.
    max_pixels : int, default 800
        Largest number of multilooked pixels shown per axis (>= 1).

    Returns
    -------
    Path
        The path written.

    Notes
    -----
    The x axis is range (ground range from the scene centre, or closest-approach slant range,
    per ``image.plane``), the y axis azimuth, both in metres with pixel centres at the axis
    values (``origin="lower"``: azimuth, the flight direction, increases upward; an arrow
    marks it). Near range (the sensor side) is on the left, marked under the axis label with
    far range on the right. The colour bar is as tall as the image. An all-zero or non-finite
    image is drawn uniformly at ``-dynamic_range_db`` and says so in the title; no NaN or
    divide-by-zero warning is raised.
    Rendered with matplotlib's Agg canvas and no pyplot state.

    Raises
    ------
    ValueError
        When ``dynamic_range_db`` is not a finite positive number, or ``figsize``/``dpi``
        are not positive.
    WriteError
        An OSError naming ``path`` when it cannot be written (no temporary file is left).
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    dynamic_range_db = float(dynamic_range_db)
    if not (np.isfinite(dynamic_range_db) and dynamic_range_db > 0):
        raise ValueError(f"dynamic_range_db must be a finite number > 0 (dB), got {dynamic_range_db!r}")
    if not (len(figsize) == 2 and min(figsize) > 0 and dpi > 0):
        raise ValueError(f"figsize must be two positive inches and dpi > 0, got {figsize!r}, {dpi!r}")
    if int(max_pixels) != max_pixels or max_pixels < 1:
        raise ValueError(f"max_pixels must be a whole number >= 1, got {max_pixels!r}")
    looks = tuple(max(1, -(-n // int(max_pixels))) for n in image.data.shape)
    db, empty = _decibels(_multilook(image.data, looks), dynamic_range_db)

    fig = Figure(figsize=figsize, dpi=dpi, layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    shown = ax.imshow(db, cmap="gray", vmin=-dynamic_range_db, vmax=0.0, origin="lower",
                      extent=(*_edges(image.range[:db.shape[1] * looks[1]]),
                              *_edges(image.azimuth[:db.shape[0] * looks[0]])), aspect=aspect,
                      interpolation="nearest")
    _label_image_axes(ax, image)
    _colorbar(fig, ax, shown, "dB")
    ax.set_title(_title(image, title, dynamic_range_db, empty, looks), fontsize="small")
    return atomic_write(Path(path), lambda tmp: fig.savefig(tmp, format="png", dpi=dpi), "quicklook")


# ============================================================================ helpers
def _axis_labels(image: SarImage) -> tuple[str, str]:
    """``(x, y)`` axis labels of an image: what range and azimuth are measured from.

    Ground images (:meth:`~sarmitsuba.focus.ImageGrid.ground`, :func:`sarmitsuba.pipeline.image_grid`)
    are centred on the scene centre; slant images
    (:func:`~sarmitsuba.focus.stripmap.slant_output_grid`) hold the absolute closest-approach
    slant range and the azimuth from the scene centre's closest approach (docs/design.md section 8).
    """
    if image.plane == "ground":
        return "ground range from scene centre [m]", "azimuth from scene centre [m]"
    return "slant range (closest approach) [m]", "azimuth from scene centre [m]"


def _label_image_axes(ax: Any, image: SarImage) -> None:
    """Axis labels, near/far range under the x label and a flight arrow, on an image's axes.

    Range grows away from the sensor (``image.range_direction``), so near range is on the left;
    azimuth grows along the flight direction (upward with ``origin="lower"``).
    """
    x_label, y_label = _axis_labels(image)
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    below = {"xycoords": (ax.transAxes, ax.xaxis.label), "xytext": (0, -2), "textcoords": "offset points",
             "va": "top", "fontsize": "x-small", "color": "0.2"}
    ax.annotate("\u2190 near range (sensor side)", xy=(0.0, 0.0), ha="left", **below)
    ax.annotate("far range \u2192", xy=(1.0, 0.0), ha="right", **below)
    from matplotlib import patheffects
    outline = [patheffects.withStroke(linewidth=2.0, foreground="black")]
    head = {"xy": (0.03, 0.97), "xycoords": "axes fraction", "textcoords": "offset points"}
    ax.annotate("", xytext=(0, -32), **head,
                arrowprops={"arrowstyle": "-|>", "color": "yellow", "lw": 1.2, "path_effects": outline})
    ax.annotate("flight\n(azimuth)", xytext=(5, -16), ha="left", va="center", fontsize="x-small",
                color="yellow", path_effects=outline, **head)


def _colorbar(fig: Any, ax: Any, mappable: Any, label: str) -> Any:
    """A colour bar beside ``ax`` exactly as tall as its (aspect-locked) image box."""
    cax = ax.inset_axes([1.03, 0.0, 0.035, 1.0])
    return fig.colorbar(mappable, cax=cax, label=label)


def _multilook(data: np.ndarray, looks: tuple[int, int]) -> np.ndarray:
    """Intensity ``|data|^2`` averaged over ``looks`` blocks (trailing partial blocks dropped),
    float64; computed a band of rows at a time (:func:`_intensity`)."""
    n0 = max(1, data.shape[0] // looks[0]) * looks[0]
    n1 = max(1, data.shape[1] // looks[1]) * looks[1]
    if looks == (1, 1):
        return _intensity(data, np.float64)
    out = np.empty((n0 // looks[0], n1 // looks[1]))
    band = max(1, _ROWS // looks[0]) * looks[0]
    for r0 in range(0, n0, band):
        power = _intensity(data[r0:min(r0 + band, n0), :n1], np.float64)
        out[r0 // looks[0]:r0 // looks[0] + power.shape[0] // looks[0]] = \
            power.reshape(-1, looks[0], n1 // looks[1], looks[1]).mean(axis=(1, 3))
    return out


#: Rows of an image turned into intensity at once (bounds the float64 temporaries).
_ROWS = 256


def _intensity(data: np.ndarray, dtype) -> np.ndarray:
    """``|data|^2`` of complex64 ``data``, computed in float64 a band of :data:`_ROWS` rows at a
    time, stored as ``dtype``."""
    out = np.empty(data.shape, dtype)
    for r0 in range(0, data.shape[0], _ROWS):
        part = data[r0:r0 + _ROWS]
        out[r0:r0 + _ROWS] = part.real.astype(np.float64) ** 2 + part.imag.astype(np.float64) ** 2
    return out


#: Percentile of the non-zero intensities shown as 0 dB (brighter pixels saturate).
REFERENCE_PERCENTILE = 99.5


def _decibels(power: np.ndarray, dynamic_range_db: float) -> tuple[np.ndarray, bool]:
    """dB of the intensity relative to its 99.5th percentile of non-zero values (0 dB; the few
    brighter pixels, such as corner reflectors, saturate), floored at ``-dynamic_range_db``."""
    finite = np.isfinite(power)
    positive = power[finite & (power > 0)]
    if positive.size == 0:
        return np.full(power.shape, -dynamic_range_db), True
    peak = float(np.percentile(positive, REFERENCE_PERCENTILE))
    floor = peak * 10.0 ** (-dynamic_range_db / 10.0)
    power = np.where(finite, np.maximum(power, floor), floor)
    return np.minimum(10.0 * np.log10(power / peak), 0.0), False


def _edges(axis: np.ndarray) -> tuple[float, float]:
    """Outer pixel edges of an axis of pixel centres (half a spacing beyond each end)."""
    half = 0.5 * float(axis[-1] - axis[0]) / (axis.size - 1) if axis.size > 1 else 0.5
    return float(axis[0]) - half, float(axis[-1]) + half


def _title(image: SarImage, title: str | None, dynamic_range_db: float, empty: bool,
           looks: tuple[int, int] = (1, 1)) -> str:
    """Three title lines: ``title`` (or the scene name), algorithm and window, then plane, fc
    and B (left out when ``title`` already names a frequency in GHz / a bandwidth in MHz),
    pulses, size, display range and looks."""
    meta = image.metadata
    focus = meta.get("focus", {}) if isinstance(meta.get("focus"), dict) else {}
    first = title if title is not None else str(meta.get("scene", "SAR image"))
    # the window on a line of its own: weighted windows have long names (taylor(nbar=4, sll=-35) twice)
    window = f"{image.algorithm}, {image.window} window"
    parts = [f"{image.plane} plane"]
    if "fc" in focus and "GHz" not in first:             # once: a caller's title may already give fc and B
        parts.append(f"fc {focus['fc'] / 1e9:.3g} GHz")
    if "bandwidth" in focus and "MHz" not in first:
        parts.append(f"B {focus['bandwidth'] / 1e6:.4g} MHz")
    if "n_pulses" in focus:
        parts.append(f"{focus['n_pulses']} pulses")
    parts.append(f"{image.data.shape[0]}x{image.data.shape[1]} px, {dynamic_range_db:g} dB "
                 f"below the {REFERENCE_PERCENTILE:g}th percentile")
    if looks != (1, 1):
        parts.append(f"{looks[0]}x{looks[1]} looks")
    if empty:
        parts.append("all-zero image")
    return f"{first}\n{window}\n" + ", ".join(parts)
