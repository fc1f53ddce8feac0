"""The along-track interferometry figure: the fore image, its ATI phase where it is bright, and
the DPCA image (docs/physics.md (V6), (V7)).

:func:`write_ati_figure` draws three panels on one ground grid: the fore channel's intensity in
dB; the interferogram's phase ``arg(I_fore I_aft*)`` (cyclic colours, ``4 pi v_r d / (lambda
V)`` at a target of range rate ``v_r``) over the pixels within ``PHASE_FLOOR_DB`` of the fore
image's reference intensity, grey elsewhere; and the DPCA image ``|I_fore - I_aft|`` in dB on the
fore image's scale, in which still clutter is gone and moving targets stay.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..core.image import SarImage
from .plotting import (agg_figure, colorbar, decibels, display_looks, multilook, reference_intensity, save_png,
                       show_db_image)

__all__ = ["PHASE_FLOOR_DB", "write_ati_figure"]

#: The interferogram's phase is drawn where the fore image lies within this many dB of its
#: reference intensity (elsewhere the phase is clutter's noise).
PHASE_FLOOR_DB = 25.0
#: Displayed dynamic range of the intensity panels [dB].
DYNAMIC_RANGE_DB = 40.0


def write_ati_figure(fore: SarImage, interferogram: np.ndarray, dpca: np.ndarray, path: str | os.PathLike,
                     title: str, max_pixels: int = 1_500_000) -> Path:
    """Write the three-panel PNG (fore intensity, ATI phase, DPCA intensity) to ``path``.

    ``interferogram`` and ``dpca`` are complex [n_az, n_rg] on ``fore``'s grid
    (:func:`sarmitsuba.stacks.along_track.ati_interferogram`, :func:`~sarmitsuba.stacks.along_track.dpca_image`).
    Returns the path. Raises OSError when it cannot be written."""
    looks = display_looks(fore.data.shape, max_pixels)
    power = multilook(fore.data, looks)
    reference = reference_intensity(power)
    n0, n1 = power.shape
    product = np.asarray(interferogram)[:n0 * looks[0], :n1 * looks[1]].reshape(n0, looks[0], n1, looks[1]).mean(
        axis=(1, 3))                                    # the complex mean: phases average, not powers
    bright = decibels(power, reference, 200.0) > -PHASE_FLOOR_DB
    fig = agg_figure((16.0, 5.6), 100)
    axes = fig.subplots(1, 3, sharex=True, sharey=True)
    show_db_image(axes[0], fore, decibels(power, reference, DYNAMIC_RANGE_DB), looks, DYNAMIC_RANGE_DB)
    axes[0].set_title("fore channel [dB]")
    show_db_image(axes[1], fore, np.full(power.shape, -DYNAMIC_RANGE_DB / 2), looks, DYNAMIC_RANGE_DB)
    phase = np.ma.masked_where(~bright, np.angle(product))
    shown = axes[1].imshow(phase, cmap="twilight", vmin=-np.pi, vmax=np.pi, origin="lower",
                           extent=axes[1].images[0].get_extent(), interpolation="nearest")
    axes[1].set_title(f"ATI phase where within {PHASE_FLOOR_DB:g} dB")
    colorbar(fig, axes[1], shown, "arg(I_fore I_aft*) [rad]")
    dpca_power = multilook(dpca, looks)
    show_db_image(axes[2], fore, decibels(dpca_power, reference, DYNAMIC_RANGE_DB), looks, DYNAMIC_RANGE_DB)
    axes[2].set_title("DPCA |I_fore - I_aft| [dB, fore's scale]")
    fig.suptitle(title)
    return save_png(fig, path, 100, "ATI figure")
