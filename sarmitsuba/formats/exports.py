"""The standard-format files of a render or a focusing, by name: which exist, which a collection
allows, and writing them into an output directory.

``render(formats=...)``, ``render --cphd/--sicd/--geotiff`` and ``focus --cphd/--sicd/--geotiff`` all
come through :func:`check_formats` (before any tracing) and :func:`write_exports` (with the
other products, all or nothing); ``cphd_domain`` (``--cphd-domain``) picks the CPHD's signal
domain, time of arrival (``toa``, the default) or frequency (``fx``, docs/physics.md (GEO2')).
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..core.image import SarImage
from ..core.outputs import OutputDirectory
from ..core.radar import ParameterError
from ..core.raw import RawData
from .cphd import DOMAINS

__all__ = ["EXPORT_FILES", "SICD_CHOICES", "CPHD_DOMAINS", "check_formats", "write_exports"]

#: Standard-format files of ``render(formats=...)`` and ``focus --cphd --sicd --geotiff``, by format: CPHD 1.1
#: phase history (:mod:`sarmitsuba.formats.cphd`), SICD 1.x complex image in NITF (:mod:`sarmitsuba.formats.sicd`),
#: GeoTIFF ground-plane intensity in UTM (:mod:`sarmitsuba.formats.geotiff`).
EXPORT_FILES = {"cphd": "raw.cphd", "sicd": "image.nitf", "geotiff": "image.tif"}


#: Values of ``render``'s ``sicd_plane`` and ``sicd_weighting`` (the default first).
SICD_CHOICES = {"sicd_plane": ("slant", "image"), "sicd_weighting": ("uniform", "image")}
#: Values of ``cphd_domain`` (``--cphd-domain``; the default first): the CPHD's ``Global/DomainType``.
CPHD_DOMAINS = DOMAINS


def check_formats(formats: Sequence[str], sicd_plane: str = "slant", sicd_weighting: str = "uniform",
                  params: Any = None, cphd_domain: str = "toa", raw: RawData | None = None) -> None:
    """Raise ParameterError naming ``formats`` unless every entry is a key of :data:`EXPORT_FILES`
    (and not ``sicd`` where the scene's RadarParameters ``params`` have a receiver_* platform), or
    naming ``sicd_plane`` / ``sicd_weighting`` unless it is one of its two values, or naming
    ``cphd_domain`` (``--cphd-domain``) unless it is one of :data:`CPHD_DOMAINS`, and for ``fx`` with
    ``cphd`` of chirped data (``params.output`` ``"raw"``, or ``raw`` not range compressed): an FX
    vector is the deramped phase history (:func:`sarmitsuba.formats.cphd.check_domain`)."""
    if cphd_domain not in CPHD_DOMAINS:
        raise ParameterError(f"cphd_domain (--cphd-domain) = {cphd_domain!r}: valid domains are "
                             f"{' and '.join(CPHD_DOMAINS)} (the first is the default)")
    chirped = (params is not None and getattr(params, "output", "compressed") == "raw") or (
        raw is not None and not raw.range_compressed)
    if "cphd" in formats and cphd_domain == "fx" and chirped:
        raise ParameterError("--cphd-domain fx (cphd_domain = 'fx'): the raw data are chirped (sensor output=raw), and "
                             "an FX-domain CPHD holds the deramped phase history; write --cphd-domain toa, or render "
                             "with output=compressed (the default)")
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
                  sicd_weighting: str = "uniform", cphd_domain: str = "toa") -> dict:
    """Write the standard-format files of ``formats`` (:data:`EXPORT_FILES`) into the open output
    directory ``out``: CPHD from ``raw``, SICD from ``image`` (with ``raw``'s geometry when given),
    GeoTIFF from ``image`` (resampled onto a north-up UTM grid, or with ``geotiff_north_up``
    False on the image's own grid with a rotated geotransform); the SICD on ``sicd_plane`` with
    ``sicd_weighting`` (:func:`sarmitsuba.pipeline.render`), the CPHD in the ``cphd_domain``
    (:data:`CPHD_DOMAINS`). ``suffix`` (``_HV``) goes before the extension. Returns paths by
    format. Raises ParameterError for SICD of bistatic ``raw`` (docs/physics.md (B1)), and for a
    ``cphd_domain`` :func:`check_formats` refuses, before any file is written."""
    writers = {}
    if "cphd" in formats:
        from .cphd import write_cphd
        check_formats(formats, sicd_plane, sicd_weighting, cphd_domain=cphd_domain, raw=raw)
        writers["cphd"] = lambda path: write_cphd(raw, path, domain=cphd_domain)
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
