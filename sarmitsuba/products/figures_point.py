"""The point-target figure: chip and cuts of an impulse response with IRW, PSLR and ISLR marked.

Part of the explanatory figures of :mod:`sarmitsuba.products.figures` (which re-exports
:func:`point_target_figure`), drawn from a :class:`~sarmitsuba.core.image.SarImage` and the report
of :func:`sarmitsuba.analysis.point_target.analyze_point_target` (or a dict with the same keys).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..signal.bandlimited import dft_rows
from ..core.image import SarImage
from .plotting import agg_figure, check_dynamic_range, decibels, save_png, window_label

__all__ = ["point_target_figure"]


def _report_value(report: Any, name: str, default: Any = None) -> Any:
    if isinstance(report, Mapping):
        value = report.get(name, default)
    else:
        value = getattr(report, name, default)
    return default if value is None else value


def point_target_figure(image: SarImage, report: Any, path: str | os.PathLike, *, oversample: int = 16,
                        dynamic_range_db: float = 40.0, figsize: tuple[float, float] = (13.0, 4.6),
                        dpi: int = 100) -> Path:
    """The standard point-target figure: chip, range and azimuth cuts, with IRW and sidelobes.

    Parameters
    ----------
    image : SarImage
        The analysed image.
    report : PointTargetReport or mapping
        From :func:`sarmitsuba.analysis.point_target.analyze_point_target`, or a dict with the same keys.
        Required: ``row``, ``column`` (fractional pixel of the peak), ``irw_azimuth``,
        ``irw_range`` [m], ``pslr_azimuth_db``, ``pslr_range_db`` [dB]. Optional:
        ``first_null_azimuth``, ``first_null_range`` [m], ``islr_azimuth_nullbounded_db``,
        ``islr_range_nullbounded_db`` [dB], ``phase_ramp_azimuth``, ``phase_ramp_range``
        [rad / pixel] (default: estimated from the chip, as the analysis does), ``chip``
        [pixels] (default 64), ``rcs_db``, ``azimuth_error``, ``range_error`` [m].
    path : str or os.PathLike
        Target PNG.
    oversample : int, default 16
        Samples per pixel of the drawn cuts (exact band-limited DFT interpolation of the
        de-ramped chip); the chip image is drawn at ``oversample / 4``.
    dynamic_range_db : float, default 40
        Shown range below the peak.
    figsize, dpi
        As :func:`raw_figure`.

    Returns
    -------
    Path

    Raises
    ------
    ValueError
        A required key is missing or the chip does not fit in the image.
    """
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    missing = [k for k in ("row", "column", "irw_azimuth", "irw_range", "pslr_azimuth_db", "pslr_range_db")
               if _report_value(report, k) is None]
    if missing:
        raise ValueError(f"point-target report lacks {missing}")
    ov = int(oversample)
    if ov < 1:
        raise ValueError(f"oversample must be >= 1, got {oversample!r}")
    n_az, n_rg = image.data.shape
    row, col = float(_report_value(report, "row")), float(_report_value(report, "column"))
    r, c = int(round(row)), int(round(col))
    chip = min(int(_report_value(report, "chip", 64)), 2 * min(r, n_az - r, c, n_rg - c)) // 2 * 2
    if chip < 8:
        raise ValueError(f"the peak at pixel ({row:.1f}, {col:.1f}) is too close to the image edge for a chip")
    i0, j0 = r - chip // 2, c - chip // 2
    z = image.data[i0:i0 + chip, j0:j0 + chip].astype(np.complex128)
    w_az = _report_value(report, "phase_ramp_azimuth", float(np.angle(np.sum(z[1:] * np.conj(z[:-1])))))
    w_rg = _report_value(report, "phase_ramp_range", float(np.angle(np.sum(z[:, 1:] * np.conj(z[:, :-1])))))
    n = np.arange(chip)
    spectrum = np.fft.fft2(z * np.exp(-1j * (w_az * n[:, None] + w_rg * n[None, :])))
    u_pk, v_pk = row - i0, col - j0
    steps = (abs(float(image.azimuth[1] - image.azimuth[0])), abs(float(image.range[1] - image.range[0])))
    t = np.arange(-(chip // 2) * ov, (chip // 2) * ov) / ov                       # pixels from the peak
    cut_az = np.abs(dft_rows(chip, u_pk + t) @ spectrum @ dft_rows(chip, [v_pk]).T)[:, 0]
    cut_rg = np.abs(dft_rows(chip, [u_pk]) @ spectrum @ dft_rows(chip, v_pk + t).T)[0]
    peak = max(cut_az.max(), cut_rg.max())
    fine = np.arange(0, chip, 4 / ov) if ov >= 4 else np.arange(chip, dtype=float)
    chip_img = np.abs(dft_rows(chip, fine) @ spectrum @ dft_rows(chip, fine).T) ** 2
    fig = agg_figure(figsize, dpi)
    ax_chip, ax_rg, ax_az = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.0, 1.3, 1.3]})
    extent = ((fine[0] - v_pk) * steps[1], (fine[-1] - v_pk) * steps[1],
              (fine[0] - u_pk) * steps[0], (fine[-1] - u_pk) * steps[0])
    db = decibels(chip_img, peak ** 2, dynamic_range_db)
    shown = ax_chip.imshow(db, cmap="viridis", vmin=-dynamic_range_db, vmax=0, origin="lower", extent=extent,
                           aspect="equal", interpolation="bilinear")
    ax_chip.contour(db, levels=[-3.0], colors="white", linewidths=0.8, origin="lower", extent=extent)
    ax_chip.axhline(0, color="w", lw=0.5, ls=":")
    ax_chip.axvline(0, color="w", lw=0.5, ls=":")
    fig.colorbar(shown, ax=ax_chip, label="dB (peak = 0)", shrink=0.8)
    ax_chip.set_xlabel("range from peak [m]")
    ax_chip.set_ylabel("azimuth from peak [m]")
    ax_chip.set_title(f"chip {chip}x{chip} px (white: -3 dB)", fontsize="small")
    for ax, cut, axis, step in ((ax_rg, cut_rg, "range", steps[1]), (ax_az, cut_az, "azimuth", steps[0])):
        _draw_cut(ax, t * step, cut / peak, report, axis, dynamic_range_db)
    extra = [f"{k.replace('_', ' ').replace(' db', '')} {float(_report_value(report, k)):.3g} {unit}"
             for k, unit in (("azimuth_error", "m"), ("range_error", "m"), ("rcs_db", "dBsm"))
             if _report_value(report, k) is not None]
    # three short lines, not one: the window's name alone is 62 characters (taylor twice)
    fig.suptitle(f"point target at azimuth {float(image.azimuth[0]) + row * steps[0]:.2f} m, range "
                 f"{float(image.range[0]) + col * steps[1]:.2f} m\n{window_label(image)} window"
                 + (f"\n{', '.join(extra)}" if extra else ""), fontsize="medium")
    return save_png(fig, path, dpi)


def _draw_cut(ax: Any, x: np.ndarray, amplitude: np.ndarray, report: Any, axis: str,
              dynamic_range_db: float) -> None:
    """One cut in dB with -3 dB, IRW, first nulls and PSLR marked."""
    db = 20 * np.log10(np.maximum(amplitude, 10 ** (-dynamic_range_db / 20 - 1)))
    irw = float(_report_value(report, f"irw_{axis}"))
    pslr = float(_report_value(report, f"pslr_{axis}_db"))
    islr = _report_value(report, f"islr_{axis}_nullbounded_db")
    null = _report_value(report, f"first_null_{axis}")
    ax.plot(x, db, color="k", lw=1.0)
    ax.axhline(-3.0, color="tab:blue", lw=0.8, ls="--", label="-3 dB")
    for s in (-0.5, 0.5):
        ax.axvline(s * irw, color="tab:blue", lw=0.8)
    ax.axhline(pslr, color="tab:red", lw=0.8, ls="--", label=f"PSLR {pslr:.2f} dB")
    if null is not None:
        for s in (-1.0, 1.0):
            ax.axvline(s * float(null), color="0.5", lw=0.6, ls=":")
    ax.set_xlim(x[0], x[-1])
    ax.set_ylim(-dynamic_range_db, 3.0)
    ax.set_xlabel(f"{axis} from peak [m]")
    ax.set_ylabel("dB (peak = 0)")
    text = f"IRW {irw:.3f} m" + (f", ISLR {float(islr):.2f} dB" if islr is not None else "")
    ax.set_title(f"{axis} cut: {text}", fontsize="small")
    ax.legend(loc="upper right", fontsize="x-small")
