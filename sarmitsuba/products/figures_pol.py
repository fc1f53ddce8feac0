"""The Pauli RGB picture of a quad-pol image set.

The Pauli scattering vector of a backscatter matrix ``S`` (Lee and Pottier, *Polarimetric
Radar Imaging*, 2009, ch. 3, the Pauli basis) has the components

* ``k1 = (S_HH + S_VV) / sqrt(2)``: odd-bounce scattering (surfaces, plates, trihedrals),
* ``k2 = (S_HH - S_VV) / sqrt(2)``: even-bounce scattering (dihedrals, wall-ground corners),
* ``k3 = (S_HV + S_VH) / sqrt(2)``: structures rotated about the line of sight, volumes.

The usual Pauli RGB display draws ``|k2|`` red, ``|k3|`` green and ``|k1|`` blue. Here each
power ``|k_i|^2`` is multilooked like the quicklook (:func:`sarmitsuba.products.image_files.write_quicklook`)
and shown in dB against ONE reference intensity common to the three channels (the 99.5th
percentile of their pooled non-zero powers, :func:`sarmitsuba.products.plotting.reference_intensity`),
so that the colour of a pixel tells the physical ratio of its mechanisms.

=========================  ===================================================================
:func:`check_channels`     the HH, HV, VH, VV images, checked to lie on one grid.
:func:`pauli_components`   ``(k1, k2, k3)`` complex images of the Pauli basis.
:func:`pauli_powers`       multilooked ``|k2|^2, |k3|^2, |k1|^2`` (R, G, B) and the looks.
:func:`powers_to_rgb`      those powers in dB re one common reference, mapped to ``[0, 1]``.
:func:`pauli_rgb`          float ``[n_az', n_rg', 3]`` display colours in ``[0, 1]``.
:func:`write_pauli`        the PNG: the RGB image in metres, a colour legend and a title.
=========================  ===================================================================
"""
from __future__ import annotations

import math
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from ..core.image import SarImage
from ..core.radar import CHANNELS
from .plotting import (REFERENCE_PERCENTILE, agg_figure, check_dynamic_range, decibels, display_looks, has_signal,
                       image_extent, label_image_axes, multilook, reference_intensity, save_png, window_label)

__all__ = ["CHANNELS", "PAULI_LEGEND", "check_channels", "pauli_components", "pauli_powers", "powers_to_rgb",
           "pauli_rgb", "write_pauli"]

#: (RGB colour, legend text) of the three display channels, in R, G, B order.
PAULI_LEGEND = (((1.0, 0.0, 0.0), "red |HH-VV|: double bounce"),
                ((0.0, 1.0, 0.0), "green |HV+VH|: rotated structures, volume"),
                ((0.0, 0.0, 1.0), "blue |HH+VV|: odd bounce (surfaces, trihedrals)"))
#: Largest axis difference [m] between channels still taken as one grid.
_AXIS_TOLERANCE = 1e-6


def check_channels(images: Mapping[str, SarImage]) -> tuple[SarImage, ...]:
    """The ``(HH, HV, VH, VV)`` SarImages of ``images``, checked to lie on one grid.

    Raises
    ------
    ValueError
        ``images`` is not a mapping, a channel is missing or not a SarImage, or a channel's
        shape, plane, axes, origin or directions differ from HH's (the message names it).
    """
    if not isinstance(images, Mapping):
        raise ValueError(f"images must map {', '.join(CHANNELS)} to SarImages, got {type(images).__name__}")
    missing = [name for name in CHANNELS if name not in images]
    if missing:
        raise ValueError(f"images lacks channel(s) {', '.join(missing)}: a Pauli picture needs all of "
                         f"{', '.join(CHANNELS)} (render with polarization = quad)")
    for name in CHANNELS:
        if not isinstance(images[name], SarImage):
            raise ValueError(f"images[{name!r}] must be a SarImage, got {type(images[name]).__name__}")
    hh = images["HH"]
    for name in CHANNELS[1:]:
        other = images[name]
        if other.data.shape != hh.data.shape:
            raise ValueError(f"images[{name!r}] has shape {list(other.data.shape)} but images['HH'] has "
                             f"{list(hh.data.shape)}: give the four channels of one quad-pol simulation")
        differs = [field for field in ("azimuth", "range", "origin", "azimuth_direction", "range_direction")
                   if not np.allclose(getattr(other, field), getattr(hh, field), rtol=0.0, atol=_AXIS_TOLERANCE)]
        differs += ["plane"] if other.plane != hh.plane else []
        if differs:
            raise ValueError(f"images[{name!r}] is not on the grid of images['HH'] ({', '.join(differs)} "
                             "differ): give the four channels of one quad-pol simulation")
    return tuple(images[name] for name in CHANNELS)


def pauli_components(images: Mapping[str, SarImage]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Pauli basis components of a quad-pol image set (Lee and Pottier 2009, ch. 3).

    ``k1 = (HH + VV) / sqrt 2`` (odd bounce), ``k2 = (HH - VV) / sqrt 2`` (even bounce),
    ``k3 = (HV + VH) / sqrt 2`` (rotated structures, volume).

    Parameters
    ----------
    images : mapping of str to SarImage
        Keys ``"HH"``, ``"HV"``, ``"VH"``, ``"VV"``; complex64 ``[n_az, n_rg]`` on one grid.

    Returns
    -------
    (k1, k2, k3) : three complex64 [n_az, n_rg]
        In the images' unit (sqrt(m^2) in normalised radiometry); ``|k1|^2 + |k2|^2 + |k3|^2``
        is the span ``|HH|^2 + |VV|^2 + (|HV + VH|^2) / 2``.

    Raises
    ------
    ValueError
        A channel is missing or the channels are not on one grid (:func:`check_channels`).
    """
    hh, hv, vh, vv = (image.data for image in check_channels(images))
    scale = np.float32(1.0 / math.sqrt(2.0))
    return (hh + vv) * scale, (hh - vv) * scale, (hv + vh) * scale


def pauli_powers(images: Mapping[str, SarImage], max_pixels: int = 800) -> tuple[list[np.ndarray], tuple[int, int]]:
    """The display powers ``[|k2|^2, |k3|^2, |k1|^2]`` (R, G, B order), each float64
    ``[n_az // l0, n_rg // l1]`` [m^2], block-averaged by the whole looks ``(l0, l1)`` that keep
    each axis within ``max_pixels`` (as the quicklook); returns ``(powers, looks)``.

    Raises
    ------
    ValueError
        As :func:`pauli_components`, or ``max_pixels`` is not a whole number >= 1.
    """
    k1, k2, k3 = pauli_components(images)
    looks = display_looks(k1.shape, max_pixels)
    return [multilook(k, looks) for k in (k2, k3, k1)], looks


def powers_to_rgb(powers: list[np.ndarray], dynamic_range_db: float) -> np.ndarray:
    """Colours float64 ``[n0, n1, 3]`` in ``[0, 1]`` of R, G, B ``powers`` [m^2]: ``1 + dB / dynamic_range_db``
    with dB re one reference common to the three (:func:`~sarmitsuba.products.plotting.reference_intensity`
    of all of them), clipped to ``[-dynamic_range_db, 0]``; all black when no power is > 0."""
    if not any(has_signal(p) for p in powers):
        return np.zeros((*powers[0].shape, 3))
    reference = reference_intensity(*powers)
    return np.stack([1.0 + decibels(p, reference, dynamic_range_db) / dynamic_range_db for p in powers], axis=-1)


def pauli_rgb(images: Mapping[str, SarImage], dynamic_range_db: float = 30.0, max_pixels: int = 800) -> np.ndarray:
    """The Pauli RGB colours of a quad-pol image set: R = ``|HH-VV|``, G = ``|HV+VH|``, B = ``|HH+VV|``.

    Each power ``|k_i|^2`` (:func:`pauli_components`) is multilooked by whole looks so that
    no axis exceeds ``max_pixels``, put in dB against ONE reference intensity for all three
    channels (the 99.5th percentile of their pooled non-zero powers), clipped to
    ``[-dynamic_range_db, 0]`` and mapped linearly to ``[0, 1]``: a pixel at the reference is
    1, one ``x`` dB below it ``1 - x / dynamic_range_db``, one ``dynamic_range_db`` or more
    below it (or zero, or non-finite) 0.

    Parameters
    ----------
    images : mapping of str to SarImage
        Keys ``"HH"``, ``"HV"``, ``"VH"``, ``"VV"`` on one grid, complex64 ``[n_az, n_rg]``.
    dynamic_range_db : float, default 30
        Shown range below the reference in dB (> 0).
    max_pixels : int, default 800
        Largest number of multilooked pixels per axis (>= 1).

    Returns
    -------
    float64 [n_az // l0, n_rg // l1, 3]
        Row ``i`` is azimuth (increasing), column ``j`` range (increasing); all zeros when every
        channel is zero.

    Raises
    ------
    ValueError
        A channel is missing or off the grid, ``dynamic_range_db`` is not a finite number > 0
        or ``max_pixels`` is not a whole number >= 1.
    """
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    powers, _ = pauli_powers(images, max_pixels)
    return powers_to_rgb(powers, dynamic_range_db)


def write_pauli(images: Mapping[str, SarImage], path: str | os.PathLike, dynamic_range_db: float = 30.0,
                title: str | None = None, *, figsize: tuple[float, float] = (10.0, 8.0), dpi: int = 110,
                max_pixels: int = 800) -> Path:
    """Write the Pauli RGB picture of a quad-pol image set as a PNG (:func:`pauli_rgb`).

    Parameters
    ----------
    images : mapping of str to SarImage
        Keys ``"HH"``, ``"HV"``, ``"VH"``, ``"VV"`` on one grid.
    path : str or os.PathLike
        Target file, conventionally ``pauli.png``.
    dynamic_range_db : float, default 30
        Shown range below the common reference in dB (> 0).
    title : str, optional
        First title line; default ``metadata["scene"]`` of HH or ``"SAR image"``. Then
        "Pauli RGB" with the algorithm and window, and the size, dynamic range and looks.
    figsize : (float, float), default (10, 8)
        Figure size in inches; the PNG is ``figsize * dpi`` pixels.
    dpi : int, default 110
        Dots per inch.
    max_pixels : int, default 800
        Largest number of multilooked pixels shown per axis (>= 1).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    ValueError
        A channel is missing or off the grid, or ``dynamic_range_db``, ``max_pixels``,
        ``figsize`` or ``dpi`` is invalid.
    sarmitsuba.core.outputs.WriteError
        An OSError naming ``path`` when it cannot be written (no temporary file is left).

    Notes
    -----
    Axes as the quicklook: range on x (near range, the sensor side, on the left), azimuth
    upward, both in metres at the pixel centres; a legend beside the image names the colours.
    All-zero (or non-finite) images are drawn black, say so in the title and raise no warning.
    """
    dynamic_range_db = check_dynamic_range(dynamic_range_db)
    powers, looks = pauli_powers(images, max_pixels)
    rgb = powers_to_rgb(powers, dynamic_range_db)
    empty = not any(has_signal(p) for p in powers)
    fig = agg_figure(figsize, dpi)
    ax = fig.add_subplot()
    hh = images["HH"]
    ax.imshow(rgb, origin="lower", extent=image_extent(hh, rgb.shape[:2], looks), aspect="equal",
              interpolation="nearest")
    label_image_axes(ax, hh)
    _legend(fig)
    ax.set_title(_title(hh, title, dynamic_range_db, empty, looks), fontsize="small")
    return save_png(fig, path, dpi, "Pauli picture")


# ============================================================================ helpers
def _legend(fig) -> None:
    """The colour legend (:data:`PAULI_LEGEND`) below the image, clear of its axis labels."""
    from matplotlib.patches import Patch
    handles = [Patch(facecolor=colour, edgecolor="0.3", label=text) for colour, text in PAULI_LEGEND]
    fig.legend(handles=handles, loc="outside lower center", fontsize="small", frameon=False)


def _title(image: SarImage, title: str | None, dynamic_range_db: float, empty: bool, looks: tuple[int, int]) -> str:
    """Three title lines: ``title`` (or the scene name), "Pauli RGB" with the algorithm and window,
    then size, dynamic range below the common reference, looks and an all-zero note."""
    first = title if title is not None else str(image.metadata.get("scene", "SAR image"))
    parts = [f"{image.plane} plane, {image.data.shape[0]}x{image.data.shape[1]} px",
             f"{dynamic_range_db:g} dB below the {REFERENCE_PERCENTILE:g}th percentile of all three channels"]
    if looks != (1, 1):
        parts.append(f"{looks[0]}x{looks[1]} looks")
    if empty:
        parts.append("all-zero images")
    return (f"{first}\nPauli RGB (R |HH-VV|, G |HV+VH|, B |HH+VV|), {image.algorithm}, "
            f"{window_label(image)} window\n" + ", ".join(parts))
