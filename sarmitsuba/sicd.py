"""SICD (NGA.STND.0024, Sensor Independent Complex Data) export and import of focused images.

The NITF container and the XML are written and read by sarkit (the NGA reference
implementation); this module maps a :class:`~sarmitsuba.image.SarImage` onto SICD 1.4.0:

- **Array.** SICD's first index is the row. Rows are range (ground or slant range, increasing
  away from the sensor), columns azimuth, so the SICD array is ``image.data.T``
  (``[n_range, n_azimuth]``); a file read back is transposed again.
- **Grid** (``Type = PLANE``, ``ImagePlane = GROUND`` or ``SLANT``; standard vol. 1, sec. 4):
  ``Row/UVectECF`` is the image's range direction, ``Col/UVectECF`` its azimuth direction,
  both in ECEF through the geographic reference (docs/physics.md (G1), (G3)); ``SS`` the pixel
  spacings; the SCP is the centre pixel. Spatial-frequency support of the two-way phase:
  in range ``KCtr = 2 fc sin(theta) / c`` and ``ImpRespBW = 2 B sin(theta) / c`` on the ground
  (``theta`` the incidence angle at the SCP; ``2 fc / c`` and ``2 B / c`` in the slant plane), in
  azimuth ``ImpRespBW = 2 (s2 - s1) / lambda`` over the processed beam sines ``s1 .. s2`` (the
  track's span seen from the SCP when the image records no beam). ``ImpRespWid`` is the focusing
  window's -3 dB width over ``ImpRespBW`` (:func:`sarmitsuba.focus.windows.impulse_response_width`;
  0.8859 / ImpRespBW for ``UNIFORM``). ``Sgn = -1``. ``TimeCOAPoly`` is the time at which each
  column's ground point is broadside (stripmap; the middle of the aperture in spotlight).
- **Geometry.** ``Position/ARPPoly`` is a quadratic fit of the antenna positions in ECEF against
  time from the first pulse; ``Timeline`` one IPP set at the PRF; ``SCPCOA`` is sarkit's own
  computation (``compute_scp_coa``).
- **Radar.** ``RadarCollection`` carries the band, the polarization and one receive channel;
  ``ImageFormation/ImageFormAlgo = OTHER`` (backprojection is neither PFA, RMA nor RGAZCOMP).
- **sarmitsuba's own metadata** (JSON, with the geographic origin of the local frame and the
  image grid's origin) travel as ``CollectionInfo/Parameter`` elements, so that :func:`read_sicd`
  gives back the SarImage (grid within micrometres, samples exactly); other tools' PLANE-grid
  SICDs are read in the east-north-up frame of their SCP.
"""
from __future__ import annotations

import datetime
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from . import georef
from .constants import SPEED_OF_LIGHT
from .image import SarImage
from .outputs import atomic_write, json_default
from .raw import RawData

__all__ = ["SicdError", "write_sicd", "read_sicd", "check_sicd", "load_image", "SICD_NAMESPACE"]

#: XML namespace of the SICD version written.
SICD_NAMESPACE = "urn:SICD:1.4.0"
_PARAM_METADATA = "SARMITSUBA_METADATA"
_PARAM_GRID = "SARMITSUBA_GRID"
#: A fixed collection start keeps the files reproducible (times count from the first pulse).
_COLLECTION_START = datetime.datetime(2000, 1, 1, tzinfo=datetime.timezone.utc)
#: sarmitsuba window name -> SICD WgtType/WindowName.
_WINDOW_NAMES = {"rect": "UNIFORM", "taylor": "TAYLOR", "hamming": "HAMMING", "hann": "HANNING", "kaiser": "KAISER"}


class SicdError(ValueError):
    """A SICD file cannot be written from, or read into, a SarImage (names the file and the reason)."""


def _reference(image: SarImage, ref: georef.GeoReference | None) -> georef.GeoReference:
    radar = image.metadata.get("radar", {}) if isinstance(image.metadata, dict) else {}
    return georef.of(radar if isinstance(radar, dict) else {}) if ref is None else ref


def scene_centre_point(image: SarImage) -> tuple[tuple[int, int], np.ndarray]:
    """((row, col) of the SCP in the SICD array, its local position [3] m): the centre pixel."""
    n_az, n_rg = image.data.shape
    i, j = n_az // 2, n_rg // 2
    point = (np.asarray(image.origin, float) + image.azimuth[i] * np.asarray(image.azimuth_direction, float)
             + image.range[j] * np.asarray(image.range_direction, float))
    return (j, i), point


def _window(image: SarImage, key: str) -> tuple[str, dict]:
    focus = image.metadata.get("focus", {}) if isinstance(image.metadata, dict) else {}
    spec = focus.get(key) if isinstance(focus, dict) else None
    if not isinstance(spec, dict) or "name" not in spec:
        return "rect", {}
    return str(spec["name"]), {k: v for k, v in spec.items() if k != "name"}


def grid_direction(unit_ecef: np.ndarray, spacing: float, bandwidth: float, kctr: float,
                   window: tuple[str, dict]) -> dict[str, Any]:
    """One ``Grid/Row`` or ``Grid/Col`` element (sarkit's dictionary form)."""
    from .focus.windows import impulse_response_width
    name, params = window
    half = min(0.5 * bandwidth, 0.5 / spacing)           # a support wider than the sampling wraps
    weight = {"WindowName": _WINDOW_NAMES.get(name, name.upper())}
    if params:
        weight["Parameter"] = [(k.upper(), str(v)) for k, v in params.items()]
    return {"UVectECF": unit_ecef, "SS": float(spacing), "ImpRespWid": impulse_response_width(name, **params) / bandwidth,
            "Sgn": -1, "ImpRespBW": float(bandwidth), "KCtr": float(kctr), "DeltaK1": -half, "DeltaK2": half,
            "WgtType": weight}


def azimuth_support(image: SarImage, raw: RawData, scp: np.ndarray, wavelength: float) -> tuple[float, float]:
    """(bandwidth, centre) [cycles/m] of the azimuth spatial frequencies ``2 s / lambda``, ``s`` the
    sine of the angle off broadside: over the image's beam sines, else the track seen from the SCP."""
    focus = image.metadata.get("focus", {}) if isinstance(image.metadata, dict) else {}
    sines = focus.get("beam_sines") if isinstance(focus, dict) else None
    if not sines:
        track = raw.velocity.mean(axis=0) / np.linalg.norm(raw.velocity.mean(axis=0))
        rel = raw.tx_position[[0, -1]] - scp
        sines = np.sort(rel @ track / np.linalg.norm(rel, axis=1))
    s1, s2 = float(sines[0]), float(sines[1])
    return 2.0 * (s2 - s1) / wavelength, (s1 + s2) / wavelength


def closest_approach_time(raw: RawData, point: np.ndarray) -> float:
    """Time [s] from the first pulse at which the antenna passes broadside of ``point`` (straight track)."""
    velocity = raw.velocity.mean(axis=0)
    along = (point - raw.tx_position[0]) @ velocity / float(velocity @ velocity)
    return float(np.clip(along, 0.0, raw.pulse_time[-1] - raw.pulse_time[0]))


def sicd_dict(image: SarImage, raw: RawData, ref: georef.GeoReference) -> dict[str, Any]:
    """The SICD XML (less SCPCOA) in sarkit's dictionary form."""
    import sarkit.wgs84
    axes = georef.enu_axes(ref)
    (scp_row, scp_col), scp = scene_centre_point(image)
    scp_ecf = georef.enu_to_ecef(scp, ref)
    times = raw.pulse_time - raw.pulse_time[0]
    duration = raw.n_pulses / raw.prf                  # IPP count n at TEnd: IPPEnd = n - 1 (vol. 1, Timeline)
    t_scp = closest_approach_time(raw, scp)
    antenna = raw.tx_position[int(np.argmin(np.abs(times - t_scp)))]
    sin_inc = float(np.hypot(*(antenna - scp)[:2]) / np.linalg.norm(antenna - scp))
    ground = image.plane == "ground"
    projection = sin_inc if ground else 1.0
    wavelength = SPEED_OF_LIGHT / raw.fc
    az_bw, az_ctr = azimuth_support(image, raw, scp, wavelength)
    velocity = raw.velocity.mean(axis=0)
    mode = str(image.metadata.get("radar", {}).get("mode", "stripmap")) if isinstance(image.metadata, dict) else ""
    slope = 0.0 if mode == "spotlight" else float(np.asarray(image.azimuth_direction) @ velocity / (velocity @ velocity))
    pol = _polarization(image)
    fit = np.polynomial.polynomial.polyfit(times, georef.enu_to_ecef(raw.tx_position, ref), 2 if len(times) > 2 else 1)
    n_az, n_rg = image.data.shape
    rows, cols = np.array([0, 0, n_rg - 1, n_rg - 1]), np.array([0, n_az - 1, n_az - 1, 0])
    corners = (scp + ((rows - scp_row) * _spacing(image.range))[:, None] * np.asarray(image.range_direction)
               + ((cols - scp_col) * _spacing(image.azimuth))[:, None] * np.asarray(image.azimuth_direction))
    band = (raw.fc - 0.5 * raw.bandwidth, raw.fc + 0.5 * raw.bandwidth)
    return {
        "CollectionInfo": {"CollectorName": "sarmitsuba", "CoreName": str(image.metadata.get("scene", "scene")) or
                           "scene", "CollectType": "MONOSTATIC",
                           "RadarMode": {"ModeType": "SPOTLIGHT" if mode == "spotlight" else "STRIPMAP"},
                           "Classification": "UNCLASSIFIED", "Parameter": _parameters(image, ref)},
        "ImageCreation": {"Application": "sarmitsuba", "DateTime": _COLLECTION_START},
        "ImageData": {"PixelType": "RE32F_IM32F", "NumRows": n_rg, "NumCols": n_az, "FirstRow": 0, "FirstCol": 0,
                      "FullImage": {"NumRows": n_rg, "NumCols": n_az}, "SCPPixel": np.array([scp_row, scp_col])},
        "GeoData": {"EarthModel": "WGS_84", "SCP": {"ECF": scp_ecf, "LLH": georef.enu_to_geodetic(scp, ref)},
                    "ImageCorners": sarkit.wgs84.cartesian_to_geodetic(georef.enu_to_ecef(corners, ref))[:, :2]},
        "Grid": {"ImagePlane": "GROUND" if ground else "SLANT", "Type": "PLANE",
                 "TimeCOAPoly": np.array([[t_scp, slope]]),
                 "Row": grid_direction(np.asarray(image.range_direction) @ axes, _spacing(image.range),
                                       2.0 * raw.bandwidth * projection / SPEED_OF_LIGHT,
                                       2.0 * raw.fc * projection / SPEED_OF_LIGHT, _window(image, "window_range")),
                 "Col": grid_direction(np.asarray(image.azimuth_direction) @ axes, _spacing(image.azimuth), az_bw,
                                       az_ctr, _window(image, "window_azimuth"))},
        "Timeline": {"CollectStart": _COLLECTION_START, "CollectDuration": duration,
                     "IPP": {"Set": [{"TStart": 0.0, "TEnd": duration, "IPPStart": 0, "IPPEnd": raw.n_pulses - 1,
                                      "IPPPoly": np.array([0.0, raw.prf])}]}},
        "Position": {"ARPPoly": fit},
        "RadarCollection": {"TxFrequency": {"Min": band[0], "Max": band[1]}, "TxPolarization": pol[0],
                            "RcvChannels": {"ChanParameters": [{"TxRcvPolarization": f"{pol[0]}:{pol[1]}"}]}},
        "ImageFormation": {"RcvChanProc": {"NumChanProc": 1, "ChanIndex": [1]},
                           "TxRcvPolarizationProc": f"{pol[0]}:{pol[1]}", "TStartProc": 0.0, "TEndProc": duration,
                           "TxFrequencyProc": {"MinProc": band[0], "MaxProc": band[1]}, "ImageFormAlgo": "OTHER",
                           "STBeamComp": "NO", "ImageBeamComp": "NO", "AzAutofocus": "NO", "RgAutofocus": "NO"},
    }


def _spacing(axis: np.ndarray) -> float:
    """The step [m] of a uniform image axis; SicdError otherwise (a PLANE grid is uniform)."""
    steps = np.diff(np.asarray(axis, dtype=np.float64))
    if steps.size == 0 or np.ptp(steps) > 1e-6 * abs(steps.mean()):
        raise SicdError("a SICD PLANE grid needs uniformly sampled image axes with at least two samples")
    return float(steps.mean())


def _polarization(image: SarImage) -> tuple[str, str]:
    """(transmit, receive) of the image's channel: ``"V"``/``"H"``, ``"OTHER"`` when unknown."""
    pol = str(image.metadata.get("polarization", "")) if isinstance(image.metadata, dict) else ""
    return (pol[0], pol[1]) if len(pol) == 2 and set(pol) <= {"H", "V"} else ("OTHER", "OTHER")


def _parameters(image: SarImage, ref: georef.GeoReference) -> list[tuple[str, str]]:
    """CollectionInfo/Parameter entries: the metadata (JSON) and the local frame and grid origin."""
    grid = {"geo_origin": ref.as_tuple(), "origin": np.asarray(image.origin, float).tolist(),
            "azimuth0": float(image.azimuth[0]), "range0": float(image.range[0]),
            "algorithm": image.algorithm, "window": image.window}
    return [(_PARAM_GRID, json.dumps(grid)), (_PARAM_METADATA, json.dumps(image.metadata, default=json_default))]


def build_xml(image: SarImage, raw: RawData, ref: georef.GeoReference) -> Any:
    """The SICD XML tree (lxml ElementTree) of ``image``, SCPCOA computed by sarkit."""
    import lxml.etree
    import sarkit.sicd as sksicd
    root = sksicd.ElementWrapper(lxml.etree.Element(f"{{{SICD_NAMESPACE}}}SICD"))
    root.from_dict(sicd_dict(image, raw, ref))
    for parent, child in (("{*}Timeline/{*}IPP", "{*}Set"), ("{*}RadarCollection/{*}RcvChannels", "{*}ChanParameters")):
        holder = root.elem.find(parent)
        holder.set("size", str(len(holder.findall(child))))
        for index, elem in enumerate(holder.findall(child), start=1):
            elem.set("index", str(index))
    tree = lxml.etree.ElementTree(root.elem)
    root.elem.find("{*}ImageFormation").addnext(sksicd.compute_scp_coa(tree))
    return tree


def write_sicd(image: SarImage, path: str | os.PathLike, raw: RawData | None = None,
               ref: georef.GeoReference | None = None) -> Path:
    """Write ``image`` as a SICD 1.4.0 NITF at ``path`` (atomically).

    Parameters
    ----------
    image : SarImage
        complex64 [n_azimuth, n_range] on a uniform plane grid (local frame, m).
    path : path-like
        The ``.nitf`` file to write.
    raw : RawData
        The data that were focused: their track gives ``Position``, ``Timeline`` and the band.
    ref : GeoReference, optional
        WGS84 origin of the local frame (default: ``geo_origin`` in ``image.metadata["radar"]``).

    Raises SicdError without ``raw`` or on a non-uniform grid; :class:`outputs.WriteError`
    (an OSError) when the file cannot be written, leaving nothing behind.
    """
    import sarkit.sicd as sksicd
    if raw is None:
        raise SicdError("writing SICD needs the raw data that were focused (their track and band)")
    tree = build_xml(image, raw, _reference(image, ref))
    security = sksicd.NitfSecurityFields(clas="U")
    metadata = sksicd.NitfMetadata(
        xmltree=tree, file_header_part=sksicd.NitfFileHeaderPart(ostaid="sarmitsuba", security=security),
        im_subheader_part=sksicd.NitfImSubheaderPart(isorce="sarmitsuba", security=security),
        de_subheader_part=sksicd.NitfDeSubheaderPart(security=security))
    array = np.ascontiguousarray(image.data.T.astype(np.complex64))

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f, sksicd.NitfWriter(f, metadata) as writer:
            writer.write_image(array)
    return atomic_write(Path(path), write, "SICD file")


def check_sicd(path: str | os.PathLike) -> dict[str, str]:
    """Run sarkit's SICD consistency checker (``sicdcheck``) on ``path``.

    Returns the failed checks' names mapped to their severity: ``"Error"`` when a required
    ("need") assertion failed, else ``"Warning"`` (only advisory "want" assertions failed).
    """
    import sarkit.verification as skver
    with open(path, "rb") as f:
        con = skver.SicdConsistency.from_file(f)
        con.check()
    failed = con.failures(omit_passed_sub=True)
    return {name: "Error" if any(d["severity"] == "Error" for d in result["details"]) else "Warning"
            for name, result in sorted(failed.items())}


def read_sicd(path: str | os.PathLike) -> SarImage:
    """Read a SICD NITF with a PLANE grid into a SarImage in a local east-north-up frame.

    Files written by :func:`write_sicd` come back in their own frame (grid within micrometres,
    samples exactly, metadata included); other tools' files in the frame of their SCP.

    Raises SicdError naming ``path``: unreadable, not a SICD, or a grid other than PLANE.
    """
    import logging

    import sarkit.sicd as sksicd
    nitf_log = logging.getLogger("jbpy")       # logs every bad field of a foreign file, with tracebacks
    level = nitf_log.level
    nitf_log.setLevel(logging.CRITICAL + 1)     # its modules' loggers inherit it
    try:
        with open(path, "rb") as f, sksicd.NitfReader(f) as reader:
            array, tree = reader.read_image(), reader.metadata.xmltree
    except (OSError, ValueError, KeyError, AttributeError, TypeError, IndexError) as exc:
        raise SicdError(f"cannot read SICD file {path}: {exc} (is it a SICD NITF?)") from None
    finally:
        nitf_log.setLevel(level)
    return image_from_parts(path, tree, array)


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
    return SarImage(data=np.ascontiguousarray(array.T).astype(np.complex64), azimuth=azi, range=rng, origin=origin,
                    azimuth_direction=u_az, range_direction=u_rg,
                    plane="ground" if xml.load("{*}Grid/{*}ImagePlane") == "GROUND" else "slant",
                    algorithm=grid.get("algorithm", "unknown"), window=grid.get("window", "unknown"),
                    metadata=metadata)


def load_image(path: str | os.PathLike) -> SarImage:
    """A SarImage from ``path``: SICD (``.nitf``, ``.ntf``) through :func:`read_sicd`, anything else
    through :meth:`SarImage.load`. Raises SarImageError naming the file."""
    from .image import SarImageError
    if Path(path).suffix.lower() not in (".nitf", ".ntf"):
        return SarImage.load(path)
    try:
        return read_sicd(path)
    except SicdError as exc:
        raise SarImageError(str(exc)) from None
