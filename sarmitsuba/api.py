"""One-call Python entries that the package exposes at the top level (``sarmitsuba.analyze``).

:func:`analyze` does in Python what ``sarmitsuba analyze IMAGE --target ...`` does on the command
line: the point-target report of :func:`sarmitsuba.analysis.point_target.analyze_point_target`, with the
carrier ramp from the raw data and the resolution read from the image's metadata.
"""
from __future__ import annotations

import os
from typing import Any, Sequence

import numpy as np

__all__ = ["analyze", "unweighted_widths"]


def analyze(image: Any, target: Sequence[float], *, raw: Any = None, **options: Any):
    """Point-target analysis of a focused image (the ``analyze`` command, in Python).

    Parameters
    ----------
    image : SarImage or path
        The focused image, or its ``.npz`` file (:meth:`sarmitsuba.core.image.SarImage.save`).
    target : 3 floats (world position, m) or 2 floats (azimuth, range image coordinates, m)
        Where the point target is; a world point is looked for at its layover position.
    raw : RawData or path, optional
        The data that were focused: with a world ``target``, gives the exact carrier ramp
        (:func:`sarmitsuba.analysis.point_target.carrier_ramp`), so the peak phase is right between pixels.
    **options
        Keyword arguments of :func:`sarmitsuba.analysis.point_target.analyze_point_target` (``chip``,
        ``oversample``, ``predicted``, ``resolution``, ``carrier``, ``sidelobes``,
        ``energy_extent``, ``search_radius``). Without ``resolution``, the energy widths come
        from the image metadata (windows, pattern, geometry) or, when they do not record the
        focusing (omega-K, RDA), from its radar parameters (unweighted widths).

    Returns
    -------
    sarmitsuba.analysis.point_target.PointTargetReport
        ``report.to_dict()`` is the JSON of the command line.

    Raises
    ------
    sarmitsuba.core.image.SarImageError, sarmitsuba.core.raw.RawDataError
        An unreadable image or raw file.
    ValueError
        A bad target or option, or a target whose chip does not fit in the image.
    """
    from .analysis.point_target import analyze_point_target, carrier_ramp, image_coordinates
    from .core.image import SarImage
    from .core.raw import RawData
    if isinstance(image, (str, os.PathLike)):
        image = SarImage.load(image)
    if not isinstance(image, SarImage):
        raise ValueError(f"image must be a sarmitsuba.core.image.SarImage or the path of its .npz, "
                         f"got {type(image).__name__}")
    if isinstance(raw, (str, os.PathLike)):
        raw = RawData.load(raw)
    if raw is not None and options.get("carrier") is None and np.size(target) == 3:
        az, rg = image_coordinates(image, target)           # the target's layover position
        world = image.origin + az * image.azimuth_direction + rg * image.range_direction
        options["carrier"] = carrier_ramp(raw, image, world)
    if options.get("resolution") is None:
        options["resolution"] = unweighted_widths(image)
    return analyze_point_target(image, target, **options)


def unweighted_widths(image: Any) -> tuple[float, float] | None:
    """None when :func:`sarmitsuba.analysis.point_target.energy_widths` reads the image (the analysis then uses
    it at the peak); else ``(rho_az, rho_rg)`` [m] of its radar parameters; else None."""
    from .analysis.point_target import energy_widths
    from .core.radar import RadarParameters
    try:
        energy_widths(image)
        return None
    except ValueError:
        pass
    try:
        radar = RadarParameters.from_mapping({k: v for k, v in image.metadata["radar"].items() if v is not None})
    except (KeyError, TypeError, ValueError):
        return None
    ground = radar.ground_range_resolution if image.plane == "ground" else radar.slant_range_resolution
    return radar.azimuth_resolution, ground
