"""The standard-format files of a render or a focusing, by name: which exist, which a collection
allows, and writing them into an output directory.

``render(formats=...)``, ``render --cphd/--sicd/--geotiff`` and ``focus --sicd/--geotiff`` all
come through :func:`check_formats` (before any tracing) and :func:`write_exports` (with the
other products, all or nothing).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..core.image import SarImage
from ..core.outputs import OutputDirectory
from ..core.radar import ParameterError
from ..core.raw import RawData

__all__ = ["EXPORT_FILES", "SICD_CHOICES", "check_formats", "write_exports"]

#: Standard-format files of ``render(formats=...)`` and ``focus --sicd``, by format: CPHD 1.1
#: phase history (:mod:`sarmitsuba.formats.cphd`), SICD 1.x complex image in NITF (:mod:`sarmitsuba.formats.sicd`),
#: GeoTIFF ground-plane intensity in UTM (:mod:`sarmitsuba.formats.geotiff`).
EXPORT_FILES = {"cphd": "raw.cphd", "sicd": "image.nitf", "geotiff": "image.tif"}


#: Values of ``render``'s ``sicd_plane`` and ``sicd_weighting`` (the default first).
SICD_CHOICES = {"sicd_plane": ("slant", "image"), "sicd_weighting": ("uniform", "image")}


def check_formats(formats: Sequence[str], sicd_plane: str = "slant", sicd_weighting: str = "uniform",
                  params: Any = None) -> None:
    """Raise ParameterError naming ``formats`` unless every entry is a key of :data:`EXPORT_FILES`
    (and not ``sicd`` where the scene's RadarParameters ``params`` have a receiver_* platform), or
    naming ``sicd_plane`` / ``sicd_weighting`` unless it is one of its two values."""
    unknown = [f for f in formats if f not in EXPORT_FILES]
    if unknown:
        raise ParameterError(f"formats = {unknown!r}: valid formats are {', '.join(EXPORT_FILES)}")
    if "sicd" in formats and params is not None and params.receiver:
        raise ParameterError("formats includes 'sicd' (--sicd), but a receiver_* platform makes the data bistatic "
                             "(docs/physics.md (B1)) and a SICD describes a monostatic collection: write --cphd instead")
    for name, value in (("sicd_plane", sicd_plane), ("sicd_weighting", sicd_weighting)):
        if value not in SICD_CHOICES[name]:
            raise ParameterError(f"{name} = {value!r}: valid values are {' and '.join(SICD_CHOICES[name])} (the "
                                 "first is the default, the SICD as producers write it)")


def write_exports(out: OutputDirectory, raw: RawData | None, image: SarImage | None, formats: Sequence[str],
                  suffix: str = "", geotiff_north_up: bool = True, sicd_plane: str = "slant",
                  sicd_weighting: str = "uniform") -> dict:
    """Write the standard-format files of ``formats`` (:data:`EXPORT_FILES`) into the open output
    directory ``out``: CPHD from ``raw``, SICD from ``image`` (with ``raw``'s geometry when given),
    GeoTIFF from ``image`` (resampled onto a north-up UTM grid, or with ``geotiff_north_up``
    False on the image's own grid with a rotated geotransform); the SICD on ``sicd_plane`` with
    ``sicd_weighting`` (:func:`sarmitsuba.pipeline.render`). ``suffix`` (``_HV``) goes
    before the extension. Returns paths by format. Raises ParameterError for SICD of bistatic
    ``raw`` (docs/physics.md (B1)), before any file is written."""
    writers = {}
    if "cphd" in formats:
        from .cphd import write_cphd
        writers["cphd"] = lambda path: write_cphd(raw, path)
    if "sicd" in formats:
        from .sicd import write_sicd
        if raw is not None and raw.rx_time is None and not np.array_equal(raw.tx_position, raw.rx_position):
            raise ParameterError("--sicd (formats = sicd): the data are bistatic, and the SICD writer describes a "
                                 "monostatic collection; use --cphd (CollectType BISTATIC) or --geotiff instead")
        writers["sicd"] = lambda path: write_sicd(image, path, raw=raw, plane=sicd_plane, weighting=sicd_weighting)
    if "geotiff" in formats:
        from .geotiff import write_geotiff
        writers["geotiff"] = lambda path: write_geotiff(image, path, north_up=geotiff_north_up)
    return {f"{fmt}{suffix}": out.write(EXPORT_FILES[fmt].replace(".", f"{suffix}."), writer)
            for fmt, writer in writers.items()}
