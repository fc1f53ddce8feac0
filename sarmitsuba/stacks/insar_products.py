"""Repeat-pass interferometry products: reading two renders, writing interferogram/coherence/height
files and the figure. :func:`write_products` reads two render directories (:func:`read_render`),
checks that they form a pair and writes the interferogram, coherence and height of
:mod:`sarmitsuba.stacks.interferometry` (docs/physics.md (I1)-(I4)), where the math lives, as
``.npz`` files with their grid and metadata plus a three-panel figure, all or none
(:data:`~sarmitsuba.stacks.interferometry.PRODUCT_FILES`).
"""
from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from ..scene.baseline import Baseline
from ..core.image import SarImage
from ..core.outputs import OutputDirectory, atomic_savez, json_default
from ..core.raw import RawData
from .interferometry import (PRODUCT_FILES, InterferometryError, check_looks, check_pair, coherence,
                             height_from_phase, height_sensitivity, interferogram, multilooked_interferogram,
                             pair_baseline, unwrapped_phase)

__all__ = ["InterferometryProducts", "read_render", "write_products"]


def read_render(directory: str | os.PathLike, role: str) -> tuple[SarImage, RawData]:
    """The ``image.npz`` and ``raw.npz`` of a render directory.

    ``directory``: written by ``sarmitsuba render``; ``role``: ``"primary"`` or ``"secondary"``,
    for messages.

    Raises
    ------
    InterferometryError
        The directory or one of its files is missing, naming it.
    SarImageError, RawDataError
        A file is damaged (from :meth:`SarImage.load`, :meth:`RawData.load`, naming it).
    """
    folder = Path(directory)
    if not folder.is_dir():
        what = "is a file, not a directory" if folder.exists() else "does not exist"
        raise InterferometryError(f"{role} directory {str(folder)!r} {what}: give a directory written by "
                                  "`sarmitsuba render` (holding image.npz and raw.npz)")
    for name in ("image.npz", "raw.npz"):
        if not (folder / name).is_file():
            raise InterferometryError(f"{role} directory {str(folder)!r} has no {name}: give a directory written "
                                      "by `sarmitsuba render` (holding image.npz and raw.npz)")
    return SarImage.load(folder / "image.npz"), RawData.load(folder / "raw.npz")


@dataclass(frozen=True)
class InterferometryProducts:
    """What :func:`write_products` wrote: ``paths`` (name -> Path of :data:`PRODUCT_FILES`),
    ``baseline`` (:class:`~sarmitsuba.scene.baseline.Baseline`), ``mean_coherence`` (float) and ``looks``."""

    paths: dict[str, Path]
    baseline: Baseline
    mean_coherence: float
    looks: tuple[int, int]
    seconds: float = 0.0

    def line(self) -> str:
        """One-line summary for the CLI."""
        b = self.baseline
        ambiguity = f"{b.height_of_ambiguity:.2f} m" if math.isfinite(b.height_of_ambiguity) else "inf (no height)"
        return (f"interferogram {self.looks[0]}x{self.looks[1]} looks: {self.seconds:.1f} s, "
                f"mean coherence {self.mean_coherence:.3f}, "
                f"B_perp {b.perpendicular:.3f} m (critical {b.critical:.3f} m), height of ambiguity {ambiguity} "
                f"-> {self.paths['figure'].parent}")


def _metadata(primary_dir: Path, secondary_dir: Path, baseline: Baseline, looks: tuple[int, int],
              raw: RawData) -> str:
    """The JSON metadata string stored in every product file (an infinite height of ambiguity as null)."""
    figures = {k: (v if not isinstance(v, float) or math.isfinite(v) else None) for k, v in vars(baseline).items()}
    return json.dumps({"primary": str(primary_dir), "secondary": str(secondary_dir), "looks": list(looks),
                       "wavelength_m": raw.wavelength, "flat_earth": "removed (ground backprojection)",
                       "baseline_m": figures}, default=json_default)


def _grid(image: SarImage) -> dict[str, Any]:
    """The grid arrays stored with every product (as in image.npz)."""
    return {"azimuth": image.azimuth, "range": image.range, "origin": image.origin,
            "azimuth_direction": image.azimuth_direction, "range_direction": image.range_direction,
            "plane": np.str_(image.plane)}


def write_products(out_dir: str | os.PathLike, primary_dir: str | os.PathLike, secondary_dir: str | os.PathLike,
                   looks: tuple[int, int] = (4, 4), progress: bool = False) -> InterferometryProducts:
    """Read two render directories and write the interferometric products into ``out_dir``.

    Files (:data:`PRODUCT_FILES`; each ``.npz`` also holds the grid of ``image.npz`` -- ``azimuth``,
    ``range``, ``origin``, ``azimuth_direction``, ``range_direction``, ``plane`` -- and a JSON
    ``metadata`` string: directories, looks, wavelength, baseline figures of :func:`pair_baseline`):

    * ``interferogram.npz``: ``interferogram`` complex64 [n_az, n_rg] ``I1 I2*``, flat earth
      removed; ``multilooked`` complex64, its boxcar average over ``looks``;
    * ``coherence.npz``: ``coherence`` float32 [n_az, n_rg] in [0, 1];
    * ``height.npz``: ``height`` float64 [n_az, n_rg] m above the grid plane (NaN without height
      sensitivity), ``k_z`` float64 rad/m, ``unwrapped_phase`` float64 rad;
    * ``interferogram.png``: wrapped phase, coherence and height.

    All files appear together or none (:class:`~sarmitsuba.core.outputs.OutputDirectory`).
    ``progress`` shows a tqdm bar over the steps after reading (interferogram, coherence, height,
    write).

    Raises
    ------
    InterferometryError
        A missing directory or file, different grids or carriers, bad looks.
    SarImageError, RawDataError
        A damaged input file.
    OSError
        ``out_dir`` cannot be written.
    """
    start = time.perf_counter()
    primary, primary_raw = read_render(primary_dir, "primary")          # input checked before the bar starts
    secondary, secondary_raw = read_render(secondary_dir, "secondary")
    check_pair(primary, secondary, primary_raw, secondary_raw)
    looks = check_looks(looks, primary.data.shape)
    with tqdm(total=4, desc="interferogram", unit="step", disable=not progress) as bar:
        bar.set_postfix_str("interferogram")
        multilooked = multilooked_interferogram(primary, secondary, looks)
        bar.update()
        bar.set_postfix_str("coherence")
        gamma = coherence(primary, secondary, looks)
        bar.update()
        bar.set_postfix_str("height")
        k_z = height_sensitivity(primary, primary_raw, secondary_raw)
        phase = unwrapped_phase(multilooked, gamma)
        heights = height_from_phase(phase, k_z)
        baseline = pair_baseline(primary, primary_raw, secondary_raw)
        bar.update()
        bar.set_postfix_str("write")
        paths = _write(out_dir, primary, secondary, multilooked, gamma, k_z, phase, heights, baseline, looks,
                       np.str_(_metadata(Path(primary_dir), Path(secondary_dir), baseline, looks, primary_raw)))
        bar.update()
    return InterferometryProducts(paths, baseline, float(np.mean(gamma)), looks, time.perf_counter() - start)


def _write(out_dir, primary: SarImage, secondary: SarImage, multilooked: np.ndarray, gamma: np.ndarray,
           k_z: np.ndarray, phase: np.ndarray, heights: np.ndarray, baseline: Baseline, looks: tuple[int, int],
           meta: np.str_) -> dict[str, Path]:
    """The files of :func:`write_products`, all or none."""
    grid = _grid(primary)
    with OutputDirectory(out_dir) as out:
        paths = {
            "interferogram": out.write(PRODUCT_FILES["interferogram"], lambda p: atomic_savez(
                p, interferogram=interferogram(primary, secondary), multilooked=multilooked, metadata=meta, **grid)),
            "coherence": out.write(PRODUCT_FILES["coherence"], lambda p: atomic_savez(
                p, coherence=gamma, metadata=meta, **grid)),
            "height": out.write(PRODUCT_FILES["height"], lambda p: atomic_savez(
                p, height=heights, k_z=k_z, unwrapped_phase=phase, metadata=meta, **grid)),
            "figure": out.write(PRODUCT_FILES["figure"], lambda p: _draw(
                p, primary, multilooked, gamma, heights, baseline, looks))}
    return paths


def _draw(path: Path, image: SarImage, multilooked: np.ndarray, gamma: np.ndarray, heights: np.ndarray,
          baseline: Baseline, looks: tuple[int, int]) -> Path:
    """The three-panel figure: wrapped phase (twilight), coherence [0, 1], height [m]; pixels whose
    ``|<I1 I2*>|`` is 40 dB below its 99th percentile (no scene there) are drawn grey."""
    from ..products.plotting import agg_figure, colorbar, image_extent, label_image_axes, save_png
    fig = agg_figure((16.0, 5.2), 100)
    extent = image_extent(image, multilooked.shape, (1, 1))
    strength = np.abs(multilooked)
    dark = strength <= 1e-4 * np.percentile(strength, 99)
    multilooked, gamma, heights = (np.where(dark, np.nan, v) for v in (multilooked, gamma, heights))
    finite = heights[np.isfinite(heights)]
    low, high = (np.percentile(finite, [1, 99]) if finite.size else (0.0, 1.0))
    panels = (("interferometric phase (flat earth removed)", np.angle(multilooked), "twilight", -np.pi, np.pi,
               "phase [rad]"),
              ("coherence", gamma, "gray", 0.0, 1.0, "coherence"),
              ("height above the ground plane", heights, "viridis", float(low), float(max(high, low + 1e-6)),
               "height [m]"))
    for k, (title, values, cmap, vmin, vmax, label) in enumerate(panels):
        ax = fig.add_subplot(1, 3, k + 1, facecolor="0.8")
        shown = ax.imshow(values, cmap=cmap, vmin=vmin, vmax=vmax, origin="lower", extent=extent,
                          aspect="equal", interpolation="nearest")
        ax.set_title(title, fontsize="medium")
        label_image_axes(ax, image)
        colorbar(fig, ax, shown, label)
    ambiguity = (f"{baseline.height_of_ambiguity:.2f} m" if math.isfinite(baseline.height_of_ambiguity)
                 else "infinite")
    fig.suptitle(f"B_perp {baseline.perpendicular:.3f} m, height of ambiguity {ambiguity}, "
                 f"{looks[0]}x{looks[1]} looks")
    return save_png(fig, path, 100)
