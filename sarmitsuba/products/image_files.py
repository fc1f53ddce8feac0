"""Image products: OpenEXR channels and PNG quicklooks of a :class:`SarImage` (docs/design.md section 3).

Images are drawn here and in other modules: :mod:`sarmitsuba.products.figures` (the explanatory
figures of a simulation, with :mod:`sarmitsuba.products.figures_raw` and :mod:`sarmitsuba.products.figures_point`)
and :mod:`sarmitsuba.products.preview` (the optical preview of an acquisition). All of them take the
display conventions (dB re the 99.5th percentile, multilooks, axis labels, colour bars, Agg
figures) from :mod:`sarmitsuba.products.plotting` and the atomic writes from :mod:`sarmitsuba.core.outputs`.
Every writer here is atomic: it writes a temporary file next to the target
(``.<name>.partial``) and renames it over the target with :func:`os.replace`, so readers
never see half a file and a failed write leaves any previous file untouched. A failed write
removes the temporary file and raises :class:`WriteError`, an OSError whose message names the
target path the caller gave.

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

from ..core.image import SarImage
from ..core.outputs import WriteError, atomic_write, json_default
from .plotting import (REFERENCE_PERCENTILE, agg_figure, check_dynamic_range, colorbar, decibels, display_looks,
                       has_signal, intensity, multilook, reference_intensity, save_png, show_db_image,
                       RELATIVE_DB)

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

    Raises
    ------
    WriteError
        An OSError naming ``path`` when it cannot be written (no temporary file is left).

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
    """
    import OpenEXR

    data = image.data
    power = intensity(data, np.float32)
    channels = {"intensity": power,
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

    Raises
    ------
    ValueError
        When ``dynamic_range_db`` is not a finite positive number, or ``figsize``/``dpi``
        are not positive.
    WriteError
        An OSError naming ``path`` when it cannot be written (no temporary file is left).

    Notes
    -----
    The x axis is range (ground range from the scene centre, or closest-approach slant range,
    per ``image.plane``), the y axis azimuth, both in metres with pixel centres at the axis
    values (``origin="lower"``: azimuth, the flight direction, increases upward; an arrow
    marks it). Near range (the sensor side) is on the left, marked under the axis label with
    far range on the right. The colour bar is as tall as the image; its dB are relative to
    ``I_ref``, not to 1 m^2, and for a calibrated image (``metadata["units"]`` sqrt(m^2)) it gives
    ``I_ref`` in dBsm (a point target's peak intensity is its RCS). Absolute values are in the
    GeoTIFF and from ``analyze``. An all-zero or non-finite
    image is drawn uniformly at ``-dynamic_range_db`` and says so in the title; no NaN or
    divide-by-zero warning is raised.
    Rendered with matplotlib's Agg canvas and no pyplot state.
    """
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    fig = agg_figure(figsize, dpi)
    looks = display_looks(image.data.shape, max_pixels)
    power = multilook(image.data, looks)
    empty = not has_signal(power)
    reference = 1.0 if empty else reference_intensity(power)
    db = np.full(power.shape, -dynamic_range_db) if empty else decibels(power, reference, dynamic_range_db)
    ax = fig.add_subplot()
    shown = show_db_image(ax, image, db, looks, dynamic_range_db, aspect=aspect)
    # relative (a lone target's sidelobes sit near 0 dB); a calibrated image also says what 0 dB is
    calibrated = str(image.metadata.get("units", "")).startswith("sqrt(m^2)") and not empty
    colorbar(fig, ax, shown, RELATIVE_DB + (f"\n(0 dB = {10.0 * np.log10(reference):.1f} dBsm)" if calibrated else ""))
    ax.set_title(_title(image, title, dynamic_range_db, empty, looks), fontsize="small")
    return save_png(fig, path, dpi, "quicklook")


# ============================================================================ helpers
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
