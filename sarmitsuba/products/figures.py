"""Figures that explain a simulation, drawn from the saved containers only (no tracing).

Every function reads :class:`~sarmitsuba.core.raw.RawData` / :class:`~sarmitsuba.core.image.SarImage`
objects (as loaded from ``raw.npz`` / ``image*.npz``) and, where it needs geometry, a
:class:`~sarmitsuba.scene.loader.LoadedScene` for the geometric ground truth of
:mod:`sarmitsuba.products.groundtruth` (ray casts against the scene, no SAR tracing). Each writes
one PNG with matplotlib's Agg canvas (no pyplot state), atomically (temporary name, then
rename). The raw-data and point-target figures live in :mod:`sarmitsuba.products.figures_raw` and
:mod:`sarmitsuba.products.figures_point` and are importable from here too.

==============================  ================================================================
:func:`raw_figure`              Raw data: magnitude (dB) and phase, pulses x slant range; zoom on
                                the brightest point-like target (or a note that none is):
                                range migration, phase history against a point's
                                (:mod:`sarmitsuba.products.figures_raw`).
:func:`image_figure`            Focused image in dB, axes in metres.
:func:`bounce_orders_figure`    Single, double, triple bounce side by side, on one dB scale.
:func:`overlay_figure`          Image with building footprints, layover, shadow and double-bounce
                                lines from the scene; returns how well they match the image.
:func:`comparison_figure`       Any labelled images side by side, resolutions annotated.
:func:`point_target_figure`     Point-target chip and cuts with IRW, PSLR and ISLR marked
                                (:mod:`sarmitsuba.products.figures_point`).
:func:`write_figures`           All figures that apply, into a directory (plus ``figures.json``).
:func:`redraw`                  :func:`write_figures` from the files of a ``render`` output.
==============================  ================================================================

Display conventions (:mod:`sarmitsuba.products.plotting`, shared with
:func:`sarmitsuba.products.image_files.write_quicklook`): intensity ``|I|^2``
multilooked by whole factors so no axis exceeds ``max_pixels``; ``10 log10(I / I_ref)``
with ``I_ref`` the 99.5th percentile of the non-zero intensities (bright corners saturate),
clipped to ``dynamic_range_db``; range on x (near range, the sensor side, on the left),
azimuth on y (the flight direction, upward), metres from the scene centre (ground images) or
closest-approach slant range and azimuth from the scene centre (slant images), marked on every
image panel; colour bars as tall as the images. A figure that cannot be written raises
:class:`sarmitsuba.products.image_files.WriteError` naming the target file (no temporary file is left).
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from .figures_point import point_target_figure
from .figures_raw import MIN_LIT_FRACTION, POINT_PHASE_RMS, raw_figure
from ..core.image import SarImage
from ..core.outputs import OutputDirectory, atomic_write, json_default
from .plotting import (REFERENCE_PERCENTILE, RELATIVE_DB, agg_figure, check_dynamic_range, colorbar, decibels,
                       display_looks, image_extent, multilook, reference_intensity, save_png, show_db_image, window_label)
from ..core.raw import RawData

__all__ = ["raw_figure", "image_figure", "bounce_orders_figure", "overlay_figure", "comparison_figure",
           "point_target_figure", "write_figures", "redraw", "image_resolution", "FIGURE_FILES",
           "POINT_PHASE_RMS", "MIN_LIT_FRACTION"]

#: Files written by :func:`write_figures`, by role.
FIGURE_FILES = {"raw": "fig_raw.png", "image": "fig_image.png", "bounce_orders": "fig_bounce_orders.png",
                "overlay": "fig_overlay.png", "stats": "figures.json"}
_ORDER_NAMES = {1: "single bounce", 2: "double bounce", 3: "triple bounce"}


# ============================================================================ helpers
def _show_image(ax: Any, image: SarImage, power: np.ndarray, looks: tuple[int, int], reference: float,
                dynamic_range_db: float) -> Any:
    """Draw multilooked ``power`` of ``image`` in dB re ``reference`` on ``ax``; returns the AxesImage."""
    return show_db_image(ax, image, decibels(power, reference, dynamic_range_db), looks, dynamic_range_db)


def _percent(fraction: float | None) -> str:
    return "n/a" if fraction is None else f"{100 * fraction:.0f} %"


def _block(mask: np.ndarray, looks: tuple[int, int], how: str) -> np.ndarray:
    """Downsample a bool mask by ``looks``: ``"any"`` pixel or ``"half"`` of the block set."""
    n0, n1 = (max(1, mask.shape[0] // looks[0]) * looks[0], max(1, mask.shape[1] // looks[1]) * looks[1])
    blocks = mask[:n0, :n1].reshape(n0 // looks[0], looks[0], n1 // looks[1], looks[1])
    return blocks.any(axis=(1, 3)) if how == "any" else blocks.mean(axis=(1, 3)) >= 0.5


def image_resolution(image: SarImage) -> tuple[float, float] | None:
    """Nominal (unweighted) ``(rho_azimuth, rho_range)`` [m] of an image, from its metadata, or None.

    ``metadata["focus"]["azimuth_resolution"]`` / ``["range_resolution"]`` when the focuser
    recorded them (e.g. spotlight), else from ``metadata["radar"]``
    (:class:`~sarmitsuba.core.radar.RadarParameters`): ground- or slant-range resolution per
    ``image.plane`` and the stripmap azimuth resolution.
    """
    focus = image.metadata.get("focus") if isinstance(image.metadata.get("focus"), dict) else {}
    if "azimuth_resolution" in focus and "range_resolution" in focus:
        return float(focus["azimuth_resolution"]), float(focus["range_resolution"])
    radar = image.metadata.get("radar")
    if not isinstance(radar, dict):
        return None
    from ..core.radar import RadarParameters
    try:
        names = set(RadarParameters.names())
        values = {k: v for k, v in radar.items() if k in names}
        if values.get("scene_center") is not None:
            values["scene_center"] = tuple(values["scene_center"])
        p = RadarParameters(**values)
    except (TypeError, ValueError):
        return None
    rho_rg = p.ground_range_resolution if image.plane == "ground" else p.slant_range_resolution
    return float(p.azimuth_resolution), float(rho_rg)


def _order_label(image: SarImage, k: int) -> str:
    order = int(image.metadata.get("bounce_order", k))
    return f"order {order} ({_ORDER_NAMES.get(order, f'{order} bounces')})"


# ============================================================================ images
def image_figure(image: SarImage, path: str | os.PathLike, *, dynamic_range_db: float = 40.0,
                 title: str | None = None, figsize: tuple[float, float] = (9.0, 7.5), dpi: int = 100,
                 max_pixels: int = 800) -> Path:
    """The focused image in dB with axes in metres, resolution and grid annotated.

    Parameters
    ----------
    image : SarImage
    path : str or os.PathLike
        Target PNG.
    dynamic_range_db : float, default 40
        Shown range below ``I_ref`` (99.5th percentile) in dB.
    title : str, optional
        First title line (default: the scene name).
    figsize, dpi, max_pixels
        As :func:`raw_figure`.

    Returns
    -------
    Path
    """
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    looks = display_looks(image.data.shape, max_pixels)
    power = multilook(image.data, looks)
    fig = agg_figure(figsize, dpi)
    ax = fig.add_subplot()
    shown = _show_image(ax, image, power, looks, reference_intensity(power), dynamic_range_db)
    colorbar(fig, ax, shown, RELATIVE_DB)
    ax.set_title(f"{title or image.metadata.get('scene', 'SAR image')}\n{_describe(image, looks)}", fontsize="small")
    return save_png(fig, path, dpi)


def _describe(image: SarImage, looks: tuple[int, int] = (1, 1)) -> str:
    spacing = (abs(float(image.azimuth[1] - image.azimuth[0])) if image.azimuth.size > 1 else float("nan"),
               abs(float(image.range[1] - image.range[0])) if image.range.size > 1 else float("nan"))
    # the window on a line of its own: weighted windows have long names (taylor(nbar=4, sll=-35) twice)
    first = f"{image.algorithm}, {window_label(image)} window"
    second = [f"{image.plane} plane, {image.data.shape[0]}x{image.data.shape[1]} px of "
              f"{spacing[0]:.2f} x {spacing[1]:.2f} m"]
    res = image_resolution(image)
    if res is not None:
        second.append(f"nominal resolution {res[0]:.2f} m (az) x {res[1]:.2f} m ({image.plane} rg)")
    if looks != (1, 1):
        second.append(f"shown with {looks[0]}x{looks[1]} looks")
    return "\n".join([first, second[0]] + ([", ".join(second[1:])] if second[1:] else []))


def bounce_orders_figure(images_per_order: Sequence[SarImage] | Mapping[str, SarImage], path: str | os.PathLike, *,
                         dynamic_range_db: float = 40.0, dpi: int = 100, max_pixels: int = 600,
                         panel_size: tuple[float, float] = (5.0, 5.2)) -> Path:
    """Images of each bounce order side by side, on one dB scale.

    Parameters
    ----------
    images_per_order : sequence of SarImage (order 1, 2, ...) or mapping label -> SarImage
        As :attr:`sarmitsuba.pipeline.Simulation.images_per_order` or the saved
        ``image_order*.npz``; all on the same grid.
    path : str or os.PathLike
        Target PNG.
    dynamic_range_db : float, default 40
        Shown range in dB below the common reference: the 99.5th percentile of the pooled
        intensities of all panels, so a dark panel is dark because its order is weak.
    dpi, max_pixels
        As :func:`raw_figure`.
    panel_size : (float, float), default (5, 5.2)
        Inches per panel; the PNG is ``(n * width, height) * dpi`` pixels.

    Returns
    -------
    Path

    Notes
    -----
    Each title gives the order's share of the total image energy ``sum |I|^2``.
    """
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    if isinstance(images_per_order, Mapping):
        labelled = list(images_per_order.items())
    else:
        labelled = [(_order_label(im, k), im) for k, im in enumerate(images_per_order, start=1)]
    if not labelled:
        raise ValueError("bounce_orders_figure needs at least one image")
    looks = display_looks(labelled[0][1].data.shape, max_pixels)
    powers = [multilook(im.data, looks) for _, im in labelled]
    reference = reference_intensity(*powers)
    energy = np.array([float(np.sum(np.abs(im.data.astype(np.complex128)) ** 2)) for _, im in labelled])
    share = energy / energy.sum() if energy.sum() > 0 else np.zeros_like(energy)
    fig = agg_figure((panel_size[0] * len(labelled), panel_size[1]), dpi)
    axes = np.atleast_1d(fig.subplots(1, len(labelled), sharex=True, sharey=True))
    for ax, (label, im), power, s in zip(axes, labelled, powers, share):
        shown = _show_image(ax, im, power, looks, reference, dynamic_range_db)
        ax.set_title(f"{label}\n{100 * s:.1f} % of the image energy", fontsize="small")
    colorbar(fig, axes[-1], shown, "dB re common reference")      # all panels share the grid and scale
    fig.suptitle(f"{labelled[0][1].metadata.get('scene', '')}: bounce orders on one scale "
                 f"({dynamic_range_db:g} dB shown)", fontsize="medium")
    return save_png(fig, path, dpi)


def comparison_figure(images: Mapping[str, SarImage], path: str | os.PathLike, *, dynamic_range_db: float = 40.0,
                      common_scale: bool = True, dpi: int = 100, max_pixels: int = 600,
                      panel_size: tuple[float, float] = (5.5, 5.5)) -> Path:
    """Labelled images side by side (e.g. stripmap vs spotlight), resolutions annotated.

    Parameters
    ----------
    images : mapping label -> SarImage
        Any images (grids may differ); one panel each, in order.
    path : str or os.PathLike
        Target PNG.
    dynamic_range_db : float, default 40
    common_scale : bool, default True
        One dB reference for all panels (calibrated images compare directly); False = each
        panel relative to its own 99.5th percentile.
    dpi, max_pixels, panel_size
        As :func:`bounce_orders_figure`.

    Returns
    -------
    Path

    Notes
    -----
    Each panel title gives the algorithm, window, grid and pixel spacing, and the nominal
    resolution of :func:`image_resolution` when the metadata allow it.
    """
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    if not images:
        raise ValueError("comparison_figure needs at least one image")
    labelled = list(images.items())
    looks = [display_looks(im.data.shape, max_pixels) for _, im in labelled]
    powers = [multilook(im.data, lk) for (_, im), lk in zip(labelled, looks)]
    common = reference_intensity(*powers)
    # constrained, not compressed: each panel keeps its cell's width, so that a title wider than a
    # narrow (slant, spaceborne) image stays over its own panel
    fig = agg_figure((panel_size[0] * len(labelled), panel_size[1]), dpi)
    axes = np.atleast_1d(fig.subplots(1, len(labelled)))
    for ax, (label, im), power, lk in zip(axes, labelled, powers, looks):
        shown = _show_image(ax, im, power, lk, common if common_scale else reference_intensity(power), dynamic_range_db)
        ax.set_title(f"{label}\n" + _describe(im, lk), fontsize="x-small")
    fig.colorbar(shown, ax=list(axes), shrink=0.8,
                 label=f"dB re the common {REFERENCE_PERCENTILE:g}th percentile" if common_scale else RELATIVE_DB)
    return save_png(fig, path, dpi)


# ============================================================================ ground truth
def overlay_figure(image: SarImage, loaded: Any, path: str | os.PathLike, *, truth: Any = None,
                   threshold_db: float = 6.0, dynamic_range_db: float = 40.0, dpi: int = 100,
                   max_pixels: int = 700, figsize: tuple[float, float] = (13.0, 5.4)) -> dict[str, Any]:
    """The image with the scene's geometric ground truth drawn in, and how well they agree.

    Left: the image in dB with layover (orange) and shadow (blue) as transparent fills,
    building footprints as yellow outlines and the double-bounce lines (wall feet facing
    the sensor) in red. Right: the same masks as a label map.

    Parameters
    ----------
    image : SarImage
        Ground-plane image.
    loaded : LoadedScene
        The scene the image was made from (see :func:`sarmitsuba.products.groundtruth.ground_truth`).
    path : str or os.PathLike
        Target PNG.
    truth : GroundTruth, optional
        Precomputed masks; default computed here (ray casts, about 1 s for ``urban``).
    threshold_db : float, default 6
        "Bright" means an intensity ``threshold_db`` above the image median; "dark" means
        ``threshold_db`` below it.
    dynamic_range_db, dpi, max_pixels, figsize
        Display, as :func:`image_figure`.

    Returns
    -------
    dict
        ``path`` (Path) plus the numbers of :func:`sarmitsuba.products.groundtruth.agreement`:
        ``layover_overlap`` (fraction of layover-mask pixels whose intensity exceeds the
        image median by ``threshold_db``), ``double_bounce_bright``, ``shadow_dark``, mean
        levels and pixel counts.
    """
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from .groundtruth import agreement, ground_truth
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    truth = ground_truth(loaded, image) if truth is None else truth
    stats = agreement(image, truth, threshold_db)
    looks = display_looks(image.data.shape, max_pixels)
    power = multilook(image.data, looks)
    fig = agg_figure(figsize, dpi)
    ax, ax_labels = fig.subplots(1, 2, sharex=True, sharey=True)
    shown = _show_image(ax, image, power, looks, reference_intensity(power), dynamic_range_db)
    colorbar(fig, ax, shown, RELATIVE_DB)
    extent = image_extent(image, power.shape, looks)
    layers = (("layover", "half", (1.0, 0.55, 0.0, 0.40)), ("shadow", "half", (0.1, 0.55, 1.0, 0.45)),
              ("double_bounce", "any", (1.0, 0.0, 0.0, 0.95)))
    footprint = _block(truth.footprint, looks, "half").astype(float)
    if footprint.any() and footprint.shape[0] > 1 and footprint.shape[1] > 1:
        x = np.linspace(extent[0], extent[1], footprint.shape[1] + 1)
        y = np.linspace(extent[2], extent[3], footprint.shape[0] + 1)
        ax.contour(0.5 * (x[1:] + x[:-1]), 0.5 * (y[1:] + y[:-1]), footprint, levels=[0.5], colors="yellow",
                   linewidths=1.0, zorder=2)
    for name, how, colour in layers:
        mask = _block(getattr(truth, name), looks, how)
        rgba = np.zeros((*mask.shape, 4))
        rgba[mask] = colour
        ax.imshow(rgba, origin="lower", extent=extent, aspect="equal", interpolation="nearest",
                  zorder=3 if name == "double_bounce" else 1)
    ax.set_title(f"{image.metadata.get('scene', 'SAR image')} with the scene's ground truth\n"
                 f"layover: {_percent(stats['layover_overlap'])} of its pixels > median + {threshold_db:g} dB; "
                 f"shadow: {_percent(stats['shadow_dark'])} < median - {threshold_db:g} dB", fontsize="small")
    labels = np.zeros(power.shape, np.uint8)          # later labels win: double bounce on top
    for value, name in ((1, "footprint"), (2, "shadow"), (3, "layover"), (4, "double_bounce")):
        labels[_block(getattr(truth, name), looks, "any" if name == "double_bounce" else "half")] = value
    colours = ["0.92", "0.45", "deepskyblue", "darkorange", "red"]
    ax_labels.imshow(labels, cmap=ListedColormap(colours), vmin=-0.5, vmax=4.5,
                     origin="lower", extent=extent, aspect="equal", interpolation="nearest")
    ax_labels.set_xlabel(ax.get_xlabel())
    ax_labels.set_title(f"ground truth from the scene geometry (height threshold {truth.height_threshold:g} m)",
                        fontsize="small")
    names = ["open ground", "building footprint", "shadow", "layover", "double bounce (wall foot)"]
    ax_labels.legend(handles=[Patch(color=c, label=n) for c, n in zip(colours, names)], loc="center left",
                     bbox_to_anchor=(1.02, 0.5), fontsize="x-small", frameon=False)   # beside: clear of the labels
    stats["path"] = save_png(fig, path, dpi)
    return stats


# ============================================================================ batch
def write_figures(out_dir: str | os.PathLike | OutputDirectory, raw: RawData | None, image: SarImage,
                  images_per_order: Sequence[SarImage] = (), loaded: Any = None) -> dict[str, Path]:
    """Write every figure that applies into ``out_dir`` (names: :data:`FIGURE_FILES`).

    Parameters
    ----------
    out_dir : path or OutputDirectory
        Existing or new directory (each file written atomically), or an open
        :class:`~sarmitsuba.core.outputs.OutputDirectory` (staged, moved in with its other files).
    raw : RawData or None
        Gives ``fig_raw.png``.
    image : SarImage
        Gives ``fig_image.png``.
    images_per_order : sequence of SarImage
        Per-bounce-order images (``fig_bounce_orders.png`` when there are any).
    loaded : LoadedScene, optional
        The scene (``fig_overlay.png``, ground-plane images only).

    Returns
    -------
    dict
        Role -> path written (the final path). ``"stats"`` is ``figures.json``: the overlay
        numbers of :func:`overlay_figure` (when drawn) and the list of figures.

    Raises
    ------
    sarmitsuba.core.outputs.WriteError
        A figure cannot be written into the directory, naming it (an OSError naming it, given an
        OutputDirectory).
    """
    if isinstance(out_dir, OutputDirectory):
        put = out_dir.write
    else:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)

        def put(name: str, draw: Any) -> Path:
            draw(out / name)
            return out / name
    paths: dict[str, Path] = {}
    stats: dict[str, Any] = {}
    if raw is not None:
        paths["raw"] = put(FIGURE_FILES["raw"], lambda path: raw_figure(raw, path))
    paths["image"] = put(FIGURE_FILES["image"], lambda path: image_figure(image, path))
    if len(images_per_order):
        paths["bounce_orders"] = put(FIGURE_FILES["bounce_orders"],
                                     lambda path: bounce_orders_figure(list(images_per_order), path))
    if loaded is not None and image.plane == "ground":
        paths["overlay"] = put(FIGURE_FILES["overlay"],
                               lambda path: stats.update(overlay=overlay_figure(image, loaded, path)))
        stats["overlay"].pop("path")
    stats["figures"] = {role: str(p) for role, p in paths.items()}
    paths["stats"] = put(FIGURE_FILES["stats"], lambda path: atomic_write(path, lambda tmp: tmp.write_text(
        json.dumps(stats, indent=2, default=json_default)), "figure statistics"))
    return paths


def redraw(out_dir: str | os.PathLike, *, scene: bool | str = True) -> dict[str, Path]:
    """Redraw every figure from the files of a ``render`` output directory, without tracing.

    Reads ``raw.npz`` (if present), ``image.npz`` and ``image_order<k>.npz`` (sorted by
    ``k``), or for a quad-pol render the HH channel's (``raw_HH.npz``, ``image_HH.npz``, ...).
    With ``scene`` (default True), also loads the scene with the radar parameters the image was
    made with (``image.metadata["radar"]``) for the overlay: ``scene`` itself when it is a
    string (a scene as ``load_scene`` takes it: the command line passes the one it rendered),
    else the one ``image.metadata["scene"]`` names when it can be found from here (a built-in
    or Sionna name, or a file name in the working directory: the metadata keep no absolute
    paths). The figures appear
    together or none (:class:`~sarmitsuba.core.outputs.OutputDirectory`) and join the render's
    list of products (``summary.json["files"]``), so a later render that draws none removes them.

    Returns
    -------
    dict
        As :func:`write_figures`.

    Raises
    ------
    sarmitsuba.core.image.SarImageError
        No readable ``image.npz``.
    OSError
        A figure cannot be written, naming it (nothing is then written).
    """
    out = Path(out_dir)
    # a quad-pol render has no image.npz: its HH channel is drawn (image_HH.npz, raw_HH.npz, ...)
    tag = "_HH" if not (out / "image.npz").is_file() and (out / "image_HH.npz").is_file() else ""
    image = SarImage.load(out / f"image{tag}.npz")
    raw = RawData.load(out / f"raw{tag}.npz") if (out / f"raw{tag}.npz").is_file() else None
    orders = sorted(out.glob(f"image{tag}_order*.npz"), key=lambda p: int(re.sub(r"\D", "", p.stem) or 0))
    per_order = [SarImage.load(p) for p in orders]
    loaded = _scene_of(image, scene if isinstance(scene, str) else None) if scene else None
    with OutputDirectory(out, products="add") as staged:
        return write_figures(staged, raw, image, per_order, loaded)


def _scene_of(image: SarImage, source: str | None = None) -> Any:
    """The scene an image was made from (``source``, else the one its metadata name), with its
    radar parameters; None when it cannot be found."""
    from ..scene.loader import SceneError, load_scene, resolve_source
    for candidate in (source,) if source else (image.metadata.get("scene"), image.metadata.get("scene_path")):
        try:
            if candidate and resolve_source(str(candidate)) is not None:
                source = candidate
                break
        except SceneError:
            continue
    else:
        return None
    radar = image.metadata.get("radar") or {}
    overrides = {k: v for k, v in radar.items() if v is not None}
    return load_scene(str(source), sensor_overrides=overrides)
