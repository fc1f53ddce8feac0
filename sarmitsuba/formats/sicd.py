"""SICD (NGA.STND.0024, Sensor Independent Complex Data) export and import of focused images.

The NITF container and the XML are written and read by sarkit (the NGA reference
implementation); this module maps a :class:`~sarmitsuba.core.image.SarImage` onto SICD 1.3.0, the
oldest version sarkit writes whose schema holds everything written here (nothing of 1.4.0 is
used; sarpy, NGA's older library, knows versions up to 1.3.0). Files of SICD 1.4.0, which
sarmitsuba wrote before, still read.

- **Array.** SICD's first index is the row. Rows are range (ground or slant range, increasing
  away from the sensor), columns azimuth, so the SICD array is ``[n_range, n_azimuth]`` (the
  transposed image); a file read back is transposed again. Signs: rows increase away from the
  sensor, columns along the flight direction, so ``Row x Col`` points up (away from the Earth)
  for a right-looking image and down for a left-looking one.
- **Grid** (``Type = PLANE``; SICD volume 1, Grid): by default ``ImagePlane = SLANT``, the slant
  plane at the SCP (``Row/UVectECF`` the line of sight from the antenna at the SCP's centre of
  aperture, ``Col/UVectECF`` the velocity across it), onto which a ground-plane image is
  resampled along SICD's range / range-rate projection (:mod:`sarmitsuba.formats.sicd_slant`,
  docs/physics.md (GEO4)); with ``plane="image"`` the image's own plane (``GROUND`` for a ground
  image: ``Row/UVectECF`` its range direction, ``Col/UVectECF`` its azimuth direction), in
  ECEF through the geographic reference (docs/physics.md (GEO1), (GEO3)). The SCP is the image's
  centre pixel. ``KCtr`` and ``ImpRespBW`` are those of the aperture that formed the SCP
  (:mod:`sarmitsuba.formats.sicd_support`); ``Sgn = -1``. By default the image's weighting is
  taken out of its spectrum while it is resampled (``WgtType = UNIFORM``, no ``WgtFunct``,
  ``ImpRespWid = 0.8859 / ImpRespBW``, docs/physics.md (K3)); ``weighting="image"`` keeps it
  (``WgtFunct``: the windows, the antenna pattern and the pulses' density). The image is resampled for the SICD onto
  a grid that samples the impulse response about twice in both directions, inside SICD's
  advised 1.1 to 2.2, carrier included, with ``DeltaKCOAPoly`` and ``DeltaK1``/``DeltaK2`` the
  local spectral centre (:mod:`sarmitsuba.formats.sicd_resample`); the ``.npz`` image keeps its own grid.
  ``TimeCOAPoly``: the time the antenna sees each pixel at the processed beam's centre (broadside
  without a beam); a constant, the middle of the aperture, in spotlight.
- **Geometry.** ``Position/ARPPoly`` is a quadratic fit of the antenna positions in ECEF against
  time from the first pulse: the raw data's transmit positions, else the track the image's radar
  parameters synthesise; ``Timeline`` one IPP set at the PRF from ``CollectStart``, the
  ``collection_start`` of the image's radar metadata (2000-01-01T00:00:00Z when absent);
  ``ImageCreation/DateTime`` the moment the file is written (UTC); ``SCPCOA`` is sarkit's own
  computation; ``GeoData/ImageCorners``, ``ValidData`` and ``RadarCollection/Area`` are the
  corner pixels on the ground (:mod:`sarmitsuba.formats.sicd_polygons`).
- **Radar.** ``RadarCollection`` carries the band, the polarization and one receive channel;
  ``ImageFormation/ImageFormAlgo = OTHER`` (backprojection is neither PFA, RMA nor RGAZCOMP);
  ``Radiometric`` the scale factors of the image's unit peak gain
  (:mod:`sarmitsuba.formats.sicd_radiometry`).
- **sarmitsuba's own metadata** (JSON, with the geographic origin of the local frame, the image
  grid's origin and the carrier the pixels lack) travel as ``CollectionInfo/Parameter``
  elements, so that :func:`read_sicd` gives back the image on the SICD grid with its metadata; no
  absolute path is written (``scene_path`` keeps the file name only). Other tools' PLANE-grid
  SICDs are read in the east-north-up frame of their SCP.
- **Checks.** :func:`check_sicd` runs sarkit's ``sicdcheck`` (schema, NITF headers, every
  consistency check, advisory ones included); a file written here passes all of them.
"""
from __future__ import annotations

import dataclasses
import datetime
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core import georef
from ..core.image import SarImage
from ..core.outputs import atomic_write, json_default
from ..core.raw import RawData
from .provenance import collection_start as provenance_start
from .provenance import portable_metadata, utc_now
from .sicd_polygons import PolygonError, set_polygons
from .sicd_radiometry import radiometric
from .sicd_slant import SlantError, resample_to_slant, slant_frame
from .sicd_resample import (Carrier, ResampleError, centred_axis, data_carrier, deltak_limits, fit_carrier,
                            poly2d_gradient, resample, sicd_spacing)
from .sicd_support import Aperture, SupportError, Track, Weighting, flattened, flattening_gain, grid_direction, \
    kept_fraction, track_of, uniform_metadata, uniform_weighting, window_of, window_weighting

__all__ = ["SicdError", "PLANES", "WEIGHTINGS", "write_sicd", "read_sicd", "check_sicd", "load_image", "SICD_NAMESPACE",
           "Layout", "sicd_layout", "build_xml", "image_from_parts", "collection_start"]

#: XML namespace of the SICD version written.
SICD_NAMESPACE = "urn:SICD:1.3.0"
_PARAM_METADATA = "SARMITSUBA_METADATA"
_PARAM_GRID = "SARMITSUBA_GRID"
#: Bytes of the file length FL in a NITF 2.1 / NSIF 1.0 file header (MIL-STD-2500C: every field before
#: it has a fixed length).
_NITF_FL = slice(342, 354)
#: Points per axis of the lattice on which the carrier and the centre-of-aperture times are fitted.
_LATTICE = 13


class SicdError(ValueError):
    """A SICD file cannot be written from, or read into, a SarImage (names the file and the reason)."""


def _reference(image: SarImage, ref: georef.GeoReference | None) -> georef.GeoReference:
    radar = image.metadata.get("radar", {}) if isinstance(image.metadata, dict) else {}
    return georef.of(radar if isinstance(radar, dict) else {}) if ref is None else ref


def scene_centre_point(image: SarImage) -> tuple[tuple[int, int], np.ndarray]:
    """((range index, azimuth index) of the image's centre pixel, its local position [3] m): the SCP."""
    n_az, n_rg = image.data.shape
    i, j = n_az // 2, n_rg // 2
    point = (np.asarray(image.origin, float) + image.azimuth[i] * np.asarray(image.azimuth_direction, float)
             + image.range[j] * np.asarray(image.range_direction, float))
    return (j, i), point


def collection_start(image: SarImage, path: Any = "the SICD file") -> datetime.datetime:
    """``Timeline/CollectStart`` (:func:`sarmitsuba.formats.provenance.collection_start`); raises
    SicdError naming ``path`` for a value that is no ISO 8601 time with a UTC offset."""
    try:
        return provenance_start(image.metadata)
    except ValueError as exc:
        raise SicdError(f"cannot write SICD file {path}: metadata radar {exc}") from None


@dataclass(frozen=True)
class Layout:
    """The SICD grid of an image: ``rows`` / ``cols`` the range / azimuth positions [m] of the SICD
    rows and columns on the image's axes (float64, odd lengths, the SCP in the middle), ``scp`` the
    SCP's (range, azimuth) [m] and local position ``scp_point`` [3] m, ``kctr`` and ``bandwidth``
    (row, col) [cycles/m], the two :class:`~sarmitsuba.formats.sicd_support.Weighting` s the SICD
    declares, the image's ``carrier``, the carrier ``removed`` from the pixels (row, col)
    [cycles/m], ``deltakcoa`` (row, col) Poly2D [cycles/m], ``coa`` (TimeCOAPoly, s), the image's
    own weightings ``source`` over its whole support ``support`` (row, col) [cycles/m], and the
    share ``kept`` (row, col) of that support a uniform SICD keeps (1, 1 when the SICD declares
    the image's own weighting)."""

    rows: np.ndarray
    cols: np.ndarray
    scp: tuple[float, float]
    scp_point: np.ndarray
    kctr: tuple[float, float]
    bandwidth: tuple[float, float]
    weighting: tuple[Weighting, Weighting]
    carrier: Carrier
    removed: tuple[float, float]
    deltakcoa: tuple[np.ndarray, np.ndarray]
    coa: np.ndarray
    source: tuple[Weighting, Weighting]
    support: tuple[float, float]
    kept: tuple[float, float]

    def gains(self) -> tuple:
        """The spectral gains (row, col) that take the image's own weighting out for the declared
        uniform one (:func:`~sarmitsuba.formats.sicd_support.flattening_gain`); (None, None) when
        the SICD declares the image's own weighting or it is uniform already."""
        if self.weighting[0].name != "UNIFORM" or self.weighting[1].name != "UNIFORM":
            return None, None
        return tuple(flattening_gain(w, b, k) for w, b, k in zip(self.source, self.support, self.kept))


def _lattice(image: SarImage, scp: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(x [n], y [n] row and column coordinates from the SCP [m], local points [n, 3]) of a
    :data:`_LATTICE`-square lattice over the image."""
    rg = np.linspace(image.range[0], image.range[-1], _LATTICE)
    az = np.linspace(image.azimuth[0], image.azimuth[-1], _LATTICE)
    rg, az = (a.ravel() for a in np.meshgrid(rg, az, indexing="ij"))
    points = (np.asarray(image.origin, float) + az[:, None] * np.asarray(image.azimuth_direction, float)
              + rg[:, None] * np.asarray(image.range_direction, float))
    return rg - scp[0], az - scp[1], points


def _coa_poly(aperture: Aperture, image: SarImage, scp: tuple[float, float], scp_point: np.ndarray) -> np.ndarray:
    """``TimeCOAPoly`` [s]: spotlight a constant; else ``1, x, x^2, y`` fitted on the lattice."""
    if _mode(image) == "spotlight":
        return np.array([[float(aperture.coa_time(scp_point, spotlight=True)[0])]])
    x, y, points = _lattice(image, scp)
    t = aperture.coa_time(points, spotlight=False)
    design = np.stack([np.ones_like(x), y, x, x ** 2], axis=1)
    c = np.linalg.lstsq(design, t, rcond=None)[0]
    c[0] = float(aperture.coa_time(scp_point, spotlight=False)[0])
    return np.array([[c[0], c[1]], [c[2], 0.0], [c[3], 0.0]])


def _mode(image: SarImage) -> str:
    radar = image.metadata.get("radar", {}) if isinstance(image.metadata, dict) else {}
    return str(radar.get("mode", "stripmap")) if isinstance(radar, dict) else "stripmap"


def _folded(poly: np.ndarray, spacing: float) -> np.ndarray:
    """``poly`` less the whole number of ``1 / spacing`` that brings its value at the SCP nearest 0."""
    out = poly.copy()
    out[0, 0] -= round(out[0, 0] * spacing) / spacing
    return out


def sicd_layout(image: SarImage, track: Track, weighting: str = "image",
                kept: tuple[float, float] | None = None) -> Layout:
    """The :class:`Layout` of ``image`` focused from ``track``: the support at the SCP, spacings
    (:func:`~sarmitsuba.formats.sicd_resample.sicd_spacing`), the grid centred on the SCP within the
    image, the carrier (the aperture's local support centres for a backprojected image, the data's
    spectral centre otherwise). ``weighting`` ``"image"`` declares the image's own weighting,
    ``"uniform"`` a uniform one over the share ``kept`` of the support (default
    :func:`~sarmitsuba.formats.sicd_support.kept_fraction` of the image's weighting; the
    declared ``ImpRespBW`` is that share of the support). An image read from a uniform SICD is
    uniform already (:func:`flattened`). Raises SicdError when the image admits no SICD grid."""
    (j, i), scp_point = scene_centre_point(image)
    scp = (float(image.range[j]), float(image.azimuth[i]))
    try:
        aperture = Aperture(image, track)
        at_scp = {k: float(v[0]) for k, v in aperture.support(scp_point).items()}
        kctr, support = (at_scp["kctr_row"], at_scp["kctr_col"]), (at_scp["bw_row"], at_scp["bw_col"])
        source = (window_weighting(window_of(image, "window_range")), aperture.azimuth_weighting(scp_point))
        done = flattened(image)
        if done is not None:                    # read from a uniform SICD: its support is the share kept
            source, support = (uniform_weighting(), uniform_weighting()), (support[0] * done[0], support[1] * done[1])
        if weighting == "uniform":
            kept = (kept_fraction(source[0]), kept_fraction(source[1])) if kept is None else kept
            declared = (uniform_weighting(), uniform_weighting())
        else:
            kept, declared = (1.0, 1.0), source
        bandwidth = (support[0] * kept[0], support[1] * kept[1])
        spacing = (sicd_spacing(bandwidth[0], kctr[0]), sicd_spacing(bandwidth[1], kctr[1]))
        rows, cols = centred_axis(image.range, scp[0], spacing[0]), centred_axis(image.azimuth, scp[1], spacing[1])
        if image.algorithm == "backprojection":
            x, y, points = _lattice(image, scp)
            local = aperture.support(points)
            lit = local["bw_col"] > 1e-3 * bandwidth[1]                 # pixels some pulse imaged
            carrier = fit_carrier(kctr, x[lit], y[lit], local["kctr_row"][lit], local["kctr_col"][lit])
        else:
            carrier = data_carrier(image, kctr)
        coa = _coa_poly(aperture, image, scp, scp_point)
    except (SupportError, ResampleError) as exc:
        raise SicdError(str(exc)) from None
    removed = tuple(0.0 if abs(k * s - round(k * s)) < 1e-9 else float(k - round(k * s) / s)
                    for k, s in zip(kctr, spacing))                # KCtr SS whole: nothing removed
    gradient = poly2d_gradient(carrier.phi)
    deltakcoa = (_folded(gradient[0], spacing[0]), _folded(gradient[1], spacing[1]))
    return Layout(rows, cols, scp, scp_point, kctr, bandwidth, declared, carrier, removed, deltakcoa, coa, source,
                  support, kept)


def _grid(image: SarImage, layout: Layout, axes: np.ndarray) -> dict[str, Any]:
    """``Grid`` (sarkit's dictionary form) of the SICD grid ``layout``."""
    spacing = (float(layout.rows[1] - layout.rows[0]), float(layout.cols[1] - layout.cols[0]))
    half = (0.5 * (layout.rows.size - 1) * spacing[0], 0.5 * (layout.cols.size - 1) * spacing[1])
    corners_x, corners_y = np.array([-1, -1, 1, 1]) * half[0], np.array([-1, 1, 1, -1]) * half[1]
    directions = {}
    for k, (name, unit) in enumerate((("Row", image.range_direction), ("Col", image.azimuth_direction))):
        deltak = deltak_limits(layout.deltakcoa[k], corners_x, corners_y, layout.bandwidth[k], spacing[k])
        directions[name] = grid_direction(np.asarray(unit, float) @ axes, spacing[k], layout.bandwidth[k],
                                          layout.kctr[k], layout.weighting[k], deltak, layout.deltakcoa[k])
    return {"ImagePlane": "GROUND" if image.plane == "ground" else "SLANT", "Type": "PLANE",
            "TimeCOAPoly": layout.coa, **directions}


def _normal_up(image: SarImage) -> SarImage:
    """``image``, its azimuth axis reversed (pixels, axis and direction; every position kept) when
    ``range_direction x azimuth_direction`` points down (a left-looking image): SICD's ``Row x Col``
    points away from the Earth (sarkit's ``check_grid_normal_away_from_earth``)."""
    if np.cross(np.asarray(image.range_direction, float), np.asarray(image.azimuth_direction, float))[2] >= 0:
        return image
    return dataclasses.replace(image, data=np.ascontiguousarray(image.data[::-1]),
                               azimuth=np.ascontiguousarray(-image.azimuth[::-1]),
                               azimuth_direction=-np.asarray(image.azimuth_direction, float))


def _check_uniform(axis: np.ndarray) -> None:
    """SicdError unless ``axis`` is uniform and increasing with at least two samples (a PLANE grid)."""
    steps = np.diff(np.asarray(axis, dtype=np.float64))
    if steps.size == 0 or np.ptp(steps) > 1e-6 * abs(steps.mean()) or steps.mean() <= 0:
        raise SicdError("a SICD PLANE grid needs uniformly sampled, increasing image axes with at least two samples")


def _polarization(image: SarImage) -> tuple[str, str]:
    """(transmit, receive) of the image's channel: ``"V"``/``"H"``, ``"OTHER"`` when unknown."""
    pol = str(image.metadata.get("polarization", "")) if isinstance(image.metadata, dict) else ""
    return (pol[0], pol[1]) if len(pol) == 2 and set(pol) <= {"H", "V"} else ("OTHER", "OTHER")


def _parameters(image: SarImage, ref: georef.GeoReference, layout: Layout) -> list[tuple[str, str]]:
    """CollectionInfo/Parameter entries: the metadata (JSON, no absolute path), the local frame, the
    grid origin and the carrier the pixels lack."""
    grid = {"geo_origin": ref.as_tuple(), "origin": np.asarray(image.origin, float).tolist(),
            "azimuth0": float(layout.cols[0]), "range0": float(layout.rows[0]),
            "algorithm": image.algorithm, "window": image.window, "carrier_removed": list(layout.removed)}
    metadata = json.dumps(portable_metadata(image.metadata), default=json_default)
    return [(_PARAM_GRID, json.dumps(grid)), (_PARAM_METADATA, metadata)]


def sicd_dict(image: SarImage, track: Track, ref: georef.GeoReference, layout: Layout,
              start: datetime.datetime, created: datetime.datetime) -> dict[str, Any]:
    """The SICD XML in sarkit's dictionary form, less SCPCOA, the polygons and Radiometric."""
    axes = georef.enu_axes(ref)
    times, n_pulses = track.pulse_time - track.pulse_time[0], len(track.pulse_time)
    duration = n_pulses / track.prf                  # IPP count n at TEnd: IPPEnd = n - 1 (vol. 1, Timeline)
    pol = _polarization(image)
    fit = np.polynomial.polynomial.polyfit(times, georef.enu_to_ecef(track.position, ref), 2 if len(times) > 2 else 1)
    n_rows, n_cols = layout.rows.size, layout.cols.size
    band = (track.fc - 0.5 * track.bandwidth, track.fc + 0.5 * track.bandwidth)
    mode = "SPOTLIGHT" if _mode(image) == "spotlight" else "STRIPMAP"
    core = str(image.metadata.get("scene", "scene")) if isinstance(image.metadata, dict) else "scene"
    return {
        "CollectionInfo": {"CollectorName": "sarmitsuba", "CoreName": core or "scene", "CollectType": "MONOSTATIC",
                           "RadarMode": {"ModeType": mode}, "Classification": "UNCLASSIFIED",
                           "Parameter": _parameters(image, ref, layout)},
        "ImageCreation": {"Application": "sarmitsuba", "DateTime": created},
        "ImageData": {"PixelType": "RE32F_IM32F", "NumRows": n_rows, "NumCols": n_cols, "FirstRow": 0, "FirstCol": 0,
                      "FullImage": {"NumRows": n_rows, "NumCols": n_cols},
                      "SCPPixel": np.array([n_rows // 2, n_cols // 2])},
        "GeoData": {"EarthModel": "WGS_84", "SCP": {"ECF": georef.enu_to_ecef(layout.scp_point, ref),
                                                    "LLH": georef.enu_to_geodetic(layout.scp_point, ref)},
                    "ImageCorners": np.zeros((4, 2))},              # projected by set_polygons
        "Grid": _grid(image, layout, axes),
        "Timeline": {"CollectStart": start, "CollectDuration": duration,
                     "IPP": {"Set": [{"TStart": 0.0, "TEnd": duration, "IPPStart": 0, "IPPEnd": n_pulses - 1,
                                      "IPPPoly": np.array([0.0, track.prf])}]}},
        "Position": {"ARPPoly": fit},
        "RadarCollection": {"TxFrequency": {"Min": band[0], "Max": band[1]}, "TxPolarization": pol[0],
                            "RcvChannels": {"ChanParameters": [{"TxRcvPolarization": f"{pol[0]}:{pol[1]}"}]}},
        "ImageFormation": {"RcvChanProc": {"NumChanProc": 1, "ChanIndex": [1]},
                           "TxRcvPolarizationProc": f"{pol[0]}:{pol[1]}", "TStartProc": 0.0, "TEndProc": duration,
                           "TxFrequencyProc": {"MinProc": band[0], "MaxProc": band[1]}, "ImageFormAlgo": "OTHER",
                           "STBeamComp": "NO", "ImageBeamComp": "NO", "AzAutofocus": "NO", "RgAutofocus": "NO"},
    }


def build_xml(image: SarImage, track: Track, ref: georef.GeoReference, layout: Layout,
              start: datetime.datetime | None = None, created: datetime.datetime | None = None) -> Any:
    """The SICD XML tree (lxml ElementTree) of ``image`` on ``layout``: SCPCOA computed by sarkit,
    then the polygons and Radiometric. ``start`` default :func:`collection_start`, ``created`` now."""
    import lxml.etree
    import sarkit.sicd as sksicd
    root = sksicd.ElementWrapper(lxml.etree.Element(f"{{{SICD_NAMESPACE}}}SICD"))
    root.from_dict(sicd_dict(image, track, ref, layout, collection_start(image) if start is None else start,
                             utc_now() if created is None else created))
    for parent, child in (("{*}Timeline/{*}IPP", "{*}Set"), ("{*}RadarCollection/{*}RcvChannels", "{*}ChanParameters")):
        holder = root.elem.find(parent)
        holder.set("size", str(len(holder.findall(child))))
        for index, elem in enumerate(holder.findall(child), start=1):
            elem.set("index", str(index))
    tree = lxml.etree.ElementTree(root.elem)
    root.elem.find("{*}ImageFormation").addnext(sksicd.compute_scp_coa(tree))
    set_polygons(tree)
    root["Radiometric"] = radiometric(tree)
    return tree


#: SICD grid planes :func:`write_sicd` writes: ``"slant"`` the slant plane at the SCP (the default,
#: as commercial SICDs of backprojected images), ``"image"`` the image's own plane.
PLANES = ("slant", "image")
#: Spectral weightings :func:`write_sicd` writes: ``"uniform"`` the image's own weighting taken out
#: (the default: every reader's RCS agrees, docs/physics.md (K3)), ``"image"`` the image's own.
WEIGHTINGS = ("uniform", "image")


def write_sicd(image: SarImage, path: str | os.PathLike, raw: RawData | None = None,
               ref: georef.GeoReference | None = None, plane: str = "slant", weighting: str = "uniform") -> Path:
    """Write ``image`` as a SICD 1.3.0 NITF at ``path`` (atomically), resampled onto its SICD grid.

    Parameters
    ----------
    image : SarImage
        complex64 [n_azimuth, n_range] on a uniform plane grid (local frame, m).
    path : path-like
        The ``.nitf`` file to write.
    raw : RawData, optional
        The data that were focused: their track gives ``Position``, ``Timeline`` and the band.
        Without them, the track the radar parameters in ``image.metadata["radar"]`` synthesise
        (a sarmitsuba render's images record them) stands in.
    ref : GeoReference, optional
        WGS84 origin of the local frame (default: ``geo_origin`` in ``image.metadata["radar"]``).
    plane : {"slant", "image"}, default "slant"
        ``"slant"``: a ground-plane image is resampled onto the slant plane at the SCP
        (:mod:`sarmitsuba.formats.sicd_slant`; a slant-plane image keeps its plane);
        ``"image"``: the image's own plane (``ImagePlane = GROUND`` for a ground image).
    weighting : {"uniform", "image"}, default "uniform"
        ``"uniform"``: the image's range and azimuth weighting (focusing windows, antenna
        pattern, pulse density: the ``WgtFunct`` of ``"image"``) is divided out of its spectrum
        while it is resampled, over the central part of the support where it is at least
        :data:`~sarmitsuba.formats.sicd_support.FLOOR` (-20 dB) of its peak; the rest of the
        support, where the division would gain more, is dropped and ``ImpRespBW`` is the part
        kept (all of it for the Taylor windows alone; about 63 % in azimuth where a stripmap's
        two-way pattern falls to its nulls). ``WgtType = UNIFORM``, no ``WgtFunct``,
        ``ImpRespWid = 0.8859 / ImpRespBW``; ``RCSSFPoly`` 1 at unit peak gain, and sarpy's RCS
        tool, the standard's ``BetaZeroSFPoly`` and the peak all read a point target's RCS
        (docs/physics.md (K3)). Apply a taper afterwards for low sidelobes (sarpy's
        ``apply_spectral_taper`` keeps the peak and ``BetaZeroSFPoly`` readings).
        ``"image"``: the image's own weighting as it is (``WgtFunct``), ``RCSSFPoly`` 1 at the
        peak; sarpy's ``TotalRCS`` then reads a point target ``W_row W_col`` high (K3).

    Raises SicdError naming ``path``: bistatic ``raw`` (a receiver on its own platform), no raw data
    and no radar parameters, a non-uniform grid, an
    image too small for its SICD grid, a ``collection_start`` that is no ISO 8601 time with an
    offset, corners that do not project onto the Earth; :class:`outputs.WriteError` (an OSError)
    when the file cannot be written, leaving nothing behind.
    """
    import sarkit.sicd as sksicd
    if raw is not None and raw.rx_time is None and not np.array_equal(raw.tx_position, raw.rx_position):
        raise SicdError(f"cannot write SICD file {path}: the data are bistatic (a receiver on its own platform, "
                        "docs/physics.md (B1)), and this writer describes a monostatic collection (its SCPCOA and "
                        "the grid's spatial frequencies); write the phase history with --cphd (CollectType "
                        "BISTATIC), or the image with --geotiff")
    if plane not in PLANES:
        raise SicdError(f"cannot write SICD file {path}: plane = {plane!r}; valid planes are "
                        f"{', '.join(PLANES)} (\"slant\" for the slant plane at the scene centre)")
    if weighting not in WEIGHTINGS:
        raise SicdError(f"cannot write SICD file {path}: weighting = {weighting!r}; valid weightings are "
                        f"{', '.join(WEIGHTINGS)} (\"uniform\" takes the image's weighting out)")
    try:
        start = collection_start(image, path)
        for axis in (image.range, image.azimuth):
            _check_uniform(axis)
        image = _normal_up(image)
        track = track_of(image, raw)
        own = sicd_layout(image, track, weighting)
        target = image
        if plane == "slant" and image.plane != "slant":
            target = slant_frame(image, track, own.scp_point, _mode(image) == "spotlight")
        layout = own if target is image else sicd_layout(target, track, weighting, own.kept)
        reference = _reference(image, ref)
        described = target
        if own.gains() != (None, None):
            sines = tuple(float(v[0]) for v in Aperture(image, track).sines(own.scp_point))
            described = dataclasses.replace(target, window="rect",
                                            metadata=uniform_metadata(target.metadata, own.kept, sines))
        tree = build_xml(described, track, reference, layout, start=start)
    except (SicdError, SupportError, PolygonError, SlantError) as exc:
        message = str(exc)
        raise SicdError(message if str(path) in message else f"cannot write SICD file {path}: {message}") from None
    if target is image:
        array = resample(image, layout.carrier, layout.scp, layout.rows, layout.cols, layout.removed, own.gains())
    else:
        array = resample_to_slant(image, own.carrier, own.scp, tree, layout.rows, layout.cols, layout.scp,
                                  layout.removed, reference, own.gains())
    security = sksicd.NitfSecurityFields(clas="U")
    metadata = sksicd.NitfMetadata(
        xmltree=tree, file_header_part=sksicd.NitfFileHeaderPart(ostaid="sarmitsuba", security=security),
        im_subheader_part=sksicd.NitfImSubheaderPart(isorce="sarmitsuba", security=security),
        de_subheader_part=sksicd.NitfDeSubheaderPart(security=security))

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f, sksicd.NitfWriter(f, metadata) as writer:
            writer.write_image(array)
    return atomic_write(Path(path), write, "SICD file")


def check_sicd(path: str | os.PathLike, advisory: bool = True) -> list[str]:
    """Run sarkit's SICD consistency checker (``sicdcheck``: the XML schema, the NITF headers and
    every consistency check) on ``path``; the sorted names of the checks that failed.

    ``advisory`` False leaves out the checks whose only failures are advisory ("want", severity
    Warning, such as the oversampling-ratio checks ``check_iprbw_to_ss_osr_row``/``_col``, which
    SICD wants in 1.1 to 2.2); required ("need", Error) failures are always listed. Files of
    :func:`write_sicd` give ``[]`` (their grid samples the impulse response about twice).
    Raises OSError when the file cannot be opened.
    """
    import sarkit.verification as skver
    with open(path, "rb") as f:
        con = skver.SicdConsistency.from_file(f)
        con.check()
    failed = con.failures(omit_passed_sub=True)
    return sorted(name for name, result in failed.items()
                  if advisory or any(d["severity"] == "Error" for d in result["details"]))


def read_sicd(path: str | os.PathLike) -> SarImage:
    """Read a SICD NITF with a PLANE grid into a SarImage in a local east-north-up frame.

    The image's azimuth runs along the flight: the columns of a SICD whose ``Col/UVectECF`` points
    against the antenna's velocity (left-looking) are reversed. Files written by
    :func:`write_sicd` come back in their own frame on the SICD grid (positions
    within micrometres, the pixels with the carrier the writer took out restored, metadata
    included; writing that image again changes no pixel); files of the former SICD 1.4.0 layout
    as they were written (the focused image's own grid); other tools' files in the frame of
    their SCP, their pixels as stored.

    Raises SicdError naming ``path``: missing or unreadable; empty, truncated, damaged, not a NITF
    file or a NITF without SICD XML (one line saying which, :func:`damage_message`); a grid other
    than PLANE.
    """
    import logging

    import lxml.etree
    import sarkit.sicd as sksicd
    try:
        file = open(path, "rb")
    except OSError as exc:
        raise SicdError(f"cannot read SICD file {path}: {exc}") from None
    # What jbpy and sarkit raise on a damaged or foreign file (found by cutting and overwriting files):
    # ValueError (a header field that is no number, no SICD data extension), AssertionError (jbpy's checks
    # of the segment structure), lxml's XMLSyntaxError (the XML cut), IndexError (no data extension).
    damaged = (OSError, ValueError, KeyError, AttributeError, TypeError, IndexError, AssertionError, RuntimeError,
               lxml.etree.LxmlError)
    nitf_log = logging.getLogger("jbpy")       # logs every bad field of a foreign file, with tracebacks
    level = nitf_log.level
    nitf_log.setLevel(logging.CRITICAL + 1)     # its modules' loggers inherit it
    try:
        with file, sksicd.NitfReader(file) as reader:
            array, tree = reader.read_image(), reader.metadata.xmltree
    except damaged as exc:
        raise SicdError(damage_message(path, exc)) from None
    finally:
        nitf_log.setLevel(level)
    return image_from_parts(path, tree, array)


def damage_message(path: str | os.PathLike, exc: BaseException) -> str:
    """One line on a SICD file that sarkit could not read (``exc``): ``path``, what is wrong (empty, not
    a NITF file, truncated against the file length ``FL`` of its NITF 2.1 header, or damaged or no
    SICD) and the fix."""
    size = Path(path).stat().st_size
    with open(path, "rb") as f:
        head = f.read(_NITF_FL.stop)
    again = "write it again with `render --sicd` (or `focus --sicd`), or give an intact copy"
    if size == 0:
        return f"cannot read SICD file {path}: the file is empty (an interrupted write or copy?); {again}"
    if head[:4] not in (b"NITF", b"NSIF"):
        return (f"cannot read SICD file {path}: not a NITF file (it begins with {head[:9]!r}, a SICD NITF with "
                "'NITF02.10'); give a SICD NITF, such as the image.nitf that `render --sicd` writes")
    if size < _NITF_FL.stop:
        return (f"cannot read SICD file {path}: the file is truncated: it ends inside its NITF header, after "
                f"{size} bytes; {again}")
    declared = head[_NITF_FL]
    if head[:9] in (b"NITF02.10", b"NSIF01.00") and declared.isdigit() and size < int(declared):
        return (f"cannot read SICD file {path}: the file is truncated: {size} of the {int(declared)} bytes its "
                f"NITF header declares (an interrupted write or copy?); {again}")
    reason = " ".join(str(exc).split())[:160] or "no detail"
    return (f"cannot read SICD file {path}: the file is damaged, or a NITF without SICD XML "
            f"({type(exc).__name__}: {reason}); {again}")


def image_from_parts(path: Any, tree: Any, array: np.ndarray) -> SarImage:
    """SarImage from a SICD XML tree and its array ``[NumRows, NumCols]``."""
    import sarkit.sicd as sksicd
    xml = sksicd.XmlHelper(tree)
    if xml.load("{*}Grid/{*}Type") != "PLANE":
        raise SicdError(f"{path}: only SICD PLANE grids can be read (this one is {xml.load('{*}Grid/{*}Type')})")
    params = {p.get("name"): p.text for p in tree.findall("{*}CollectionInfo/{*}Parameter")}
    grid = json.loads(params[_PARAM_GRID]) if _PARAM_GRID in params else {}
    scp_ecf = xml.load("{*}GeoData/{*}SCP/{*}ECF")
    ref = (georef.GeoReference(*grid["geo_origin"]) if "geo_origin" in grid
           else georef.GeoReference(*[float(v) for v in xml.load("{*}GeoData/{*}SCP/{*}LLH")]))
    axes = georef.enu_axes(ref)
    scp = georef.ecef_to_enu(scp_ecf, ref)
    u_rg, u_az = xml.load("{*}Grid/{*}Row/{*}UVectECF") @ axes.T, xml.load("{*}Grid/{*}Col/{*}UVectECF") @ axes.T
    scp_row, scp_col = xml.load("{*}ImageData/{*}SCPPixel")
    first_row, first_col = xml.load("{*}ImageData/{*}FirstRow"), xml.load("{*}ImageData/{*}FirstCol")
    ss_rg, ss_az = xml.load("{*}Grid/{*}Row/{*}SS"), xml.load("{*}Grid/{*}Col/{*}SS")
    origin = np.asarray(grid.get("origin", scp), float)
    rows, cols = first_row + np.arange(array.shape[0]), first_col + np.arange(array.shape[1])
    rng = (scp - origin) @ u_rg + (rows - scp_row) * ss_rg
    azi = (scp - origin) @ u_az + (cols - scp_col) * ss_az
    metadata = json.loads(params[_PARAM_METADATA]) if _PARAM_METADATA in params else {"source": str(path)}
    data = _with_carrier(array, grid.get("carrier_removed"), (rows - scp_row) * ss_rg, (cols - scp_col) * ss_az)
    velocity = xml.load("{*}SCPCOA/{*}ARPVel")
    if velocity is not None and float(xml.load("{*}Grid/{*}Col/{*}UVectECF") @ velocity) < 0:
        # columns against the flight (a left-looking SICD, Row x Col away from the Earth): the
        # SarImage's azimuth runs along the flight, as a focused image's does; the positions stay
        data, azi, u_az = data[:, ::-1], -azi[::-1], -u_az
    return SarImage(data=np.ascontiguousarray(data.T).astype(np.complex64), azimuth=azi, range=rng, origin=origin,
                    azimuth_direction=u_az, range_direction=u_rg,
                    plane="ground" if xml.load("{*}Grid/{*}ImagePlane") == "GROUND" else "slant",
                    algorithm=grid.get("algorithm", "unknown"), window=grid.get("window", "unknown"),
                    metadata=metadata)


def _with_carrier(array: np.ndarray, removed: Any, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The SICD pixels ``array`` [rows, cols] times ``exp(j 2 pi (f_row x + f_col y))``: the carrier
    ``removed`` [cycles/m] that :func:`write_sicd` took out, at the row and column coordinates
    ``x``, ``y`` [m] from the SCP (nothing for files without it, or where it is zero)."""
    if not removed or not any(float(f) for f in removed):
        return array
    cycles = np.mod(float(removed[0]) * x, 1.0)[:, None] + np.mod(float(removed[1]) * y, 1.0)[None, :]
    return array * np.exp(2j * np.pi * cycles)


def load_image(path: str | os.PathLike) -> SarImage:
    """A SarImage from ``path``: SICD (``.nitf``, ``.ntf``) through :func:`read_sicd`, anything else
    through :meth:`SarImage.load`. Raises SarImageError naming the file."""
    from ..core.image import SarImageError
    if Path(path).suffix.lower() not in (".nitf", ".ntf"):
        return SarImage.load(path)
    try:
        return read_sicd(path)
    except SicdError as exc:
        raise SarImageError(str(exc)) from None
