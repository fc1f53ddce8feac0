"""SICD (NGA.STND.0024, Sensor Independent Complex Data) export and import of focused images.

The NITF container and the XML are written and read by sarkit (the NGA reference
implementation); this module maps a :class:`~sarmitsuba.core.image.SarImage` onto SICD 1.4.0:

- **Array.** SICD's first index is the row. Rows are range (ground or slant range, increasing
  away from the sensor), columns azimuth, so the SICD array is ``image.data.T``
  (``[n_range, n_azimuth]``); a file read back is transposed again. Signs: rows increase away
  from the sensor, columns along the flight direction, so ``Row x Col`` points up (away from
  the Earth) for a right-looking image and down for a left-looking one.
- **Grid** (``Type = PLANE``, ``ImagePlane = GROUND`` or ``SLANT``; standard vol. 1, sec. 4):
  ``Row/UVectECF`` is the image's range direction, ``Col/UVectECF`` its azimuth direction,
  both in ECEF through the geographic reference (docs/physics.md (G1), (G3)); ``SS`` the pixel
  spacings; the SCP is the centre pixel. Spatial-frequency support of the two-way phase:
  in range ``KCtr = 2 fc sin(theta) / c`` and ``ImpRespBW = 2 B sin(theta) / c`` on the ground
  (``theta`` the incidence angle at the SCP; ``2 fc / c`` and ``2 B / c`` in the slant plane), in
  azimuth ``ImpRespBW = 2 (s2 - s1) / lambda`` over the sines ``s1 .. s2`` off broadside that
  both the processed beam and the track's span seen from the SCP cover (a short track, not the
  beam, bounds the aperture of a few-pulse render). ``ImpRespWid`` is the focusing window's -3 dB
  width over ``ImpRespBW`` (:func:`sarmitsuba.focus.windows.impulse_response_width`; 0.8859 /
  ImpRespBW for ``UNIFORM``); when the track cuts the beam's window short, the width of the part
  kept (:func:`segment_irw`), ``WgtType`` still naming the window. ``Sgn = -1``.
  ``TimeCOAPoly`` is the time at which each column's ground point is broadside (stripmap; the
  middle of the aperture in spotlight).
- **Geometry.** ``Position/ARPPoly`` is a quadratic fit of the antenna positions in ECEF against
  time from the first pulse: the raw data's transmit positions, else the track the image's
  radar parameters synthesise (:func:`track_of`); ``Timeline`` one IPP set at the PRF;
  ``SCPCOA`` is sarkit's own computation (``compute_scp_coa``); ``GeoData/ImageCorners`` the
  corner pixels projected along their R/Rdot contours onto the SCP's height above the ellipsoid
  by sarkit (``image_to_constant_hae_surface``; NGA.STND.0024-3, Image Projections), which
  for a slant-plane image is not the corner's own latitude and longitude.
- **Radar.** ``RadarCollection`` carries the band, the polarization and one receive channel;
  ``ImageFormation/ImageFormAlgo = OTHER`` (backprojection is neither PFA, RMA nor RGAZCOMP).
- **sarmitsuba's own metadata** (JSON, with the geographic origin of the local frame and the
  image grid's origin) travel as ``CollectionInfo/Parameter`` elements, so that :func:`read_sicd`
  gives back the SarImage (grid within micrometres, samples exactly); other tools' PLANE-grid
  SICDs are read in the east-north-up frame of their SCP.
- **Checks.** :func:`check_sicd` runs sarkit's ``sicdcheck`` (schema, NITF headers, every
  consistency check). sarmitsuba's default grids sample the impulse response more than 2.2
  times, which draws only the advisory oversampling-ratio warnings (SICD wants 1.1 to 2.2); a
  grid inside that range passes every check.
"""
from __future__ import annotations

import datetime
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core import georef
from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage
from ..core.outputs import atomic_write, json_default
from ..core.raw import RawData

__all__ = ["SicdError", "write_sicd", "read_sicd", "check_sicd", "load_image", "SICD_NAMESPACE"]

#: XML namespace of the SICD version written.
SICD_NAMESPACE = "urn:SICD:1.4.0"
_PARAM_METADATA = "SARMITSUBA_METADATA"
_PARAM_GRID = "SARMITSUBA_GRID"
#: A fixed collection start keeps the files reproducible (times count from the first pulse).
_COLLECTION_START = datetime.datetime(2000, 1, 1, tzinfo=datetime.timezone.utc)
#: Bytes of the file length FL in a NITF 2.1 / NSIF 1.0 file header (MIL-STD-2500C: every field before
#: it has a fixed length).
_NITF_FL = slice(342, 354)
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


@dataclass(frozen=True)
class Track:
    """The collection a SICD describes: per-pulse times [s] (float64 [n]), antenna positions and
    velocities (float64 [n, 3], local frame, m and m/s), carrier ``fc`` [Hz], ``bandwidth`` [Hz], ``prf`` [Hz]."""

    pulse_time: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    fc: float
    bandwidth: float
    prf: float


def track_of(image: SarImage, raw: RawData | None) -> Track:
    """The :class:`Track` of ``raw`` (its transmit positions), else the one the radar parameters in
    ``image.metadata["radar"]`` synthesise (:func:`sarmitsuba.core.radar.acquisition_geometry`, world frame).

    Raises SicdError when neither is available.
    """
    if raw is not None:
        return Track(raw.pulse_time, raw.tx_position, raw.velocity, raw.fc, raw.bandwidth, raw.prf)
    from ..core.radar import ParameterError, RadarParameters, acquisition_geometry
    radar = image.metadata.get("radar") if isinstance(image.metadata, dict) else None
    try:
        params = RadarParameters.from_mapping({k: v for k, v in radar.items() if v is not None})
        geometry = acquisition_geometry(params)
    except (AttributeError, TypeError, ValueError, KeyError, ParameterError):
        raise SicdError("writing SICD needs the raw data that were focused, or an image whose metadata record "
                        "the resolved radar parameters (metadata['radar'] of a sarmitsuba render): pass raw=") from None
    return Track(geometry.pulse_time, geometry.positions, geometry.velocity, params.frequency, params.bandwidth,
                 params.prf)


def grid_direction(unit_ecef: np.ndarray, spacing: float, bandwidth: float, kctr: float,
                   window: tuple[str, dict], width: float | None = None) -> dict[str, Any]:
    """One ``Grid/Row`` or ``Grid/Col`` element (sarkit's dictionary form); ``width`` is the
    impulse-response width in units of ``1 / bandwidth`` (default: the window's own)."""
    from ..focus.windows import impulse_response_width
    name, params = window
    half = min(0.5 * bandwidth, 0.5 / spacing)           # a support wider than the sampling wraps
    weight = {"WindowName": _WINDOW_NAMES.get(name, name.upper())}
    if params:
        weight["Parameter"] = [(k.upper(), str(v)) for k, v in params.items()]
    width = impulse_response_width(name, **params) if width is None else width
    return {"UVectECF": unit_ecef, "SS": float(spacing), "ImpRespWid": width / bandwidth,
            "Sgn": -1, "ImpRespBW": float(bandwidth), "KCtr": float(kctr), "DeltaK1": -half, "DeltaK2": half,
            "WgtType": weight}


def segment_irw(window: tuple[str, dict], u0: float, u1: float, samples: int = 512, fft: int = 1 << 17) -> float:
    """-3 dB width of ``|p|^2``, in units of ``1 / B``, of the window ``w(u - 1/2)`` kept over
    ``u0 <= u <= u1`` only (0 <= u0 < u1 <= 1) and spread over a support ``B``: the weighting left
    when the track, not the beam, bounds the aperture. 0.8859 for ``rect``."""
    from ..focus.windows import spectral_window
    u = u0 + (np.arange(samples) + 0.5) / samples * (u1 - u0)
    power = np.abs(np.fft.rfft(spectral_window(window[0], u - 0.5, 1.0, **window[1]), fft)) ** 2
    power /= power[0]
    k = int(np.argmax(power < 0.5))
    half = k - 1 + (power[k - 1] - 0.5) / (power[k - 1] - power[k])
    return 2.0 * half * samples / fft


def azimuth_support(image: SarImage, track: Track, scp: np.ndarray, wavelength: float,
                    window: tuple[str, dict]) -> tuple[float, float, float | None]:
    """(bandwidth, centre) [cycles/m] of the azimuth spatial frequencies ``2 s / lambda`` seen at the
    SCP (``s`` the sine off broadside, over the image's beam sines and the track's span, whichever
    is narrower), and the impulse-response width in units of ``1 / bandwidth`` (None: the window's)."""
    focus = image.metadata.get("focus", {}) if isinstance(image.metadata, dict) else {}
    beam = focus.get("beam_sines") if isinstance(focus, dict) else None
    heading = track.velocity.mean(axis=0) / np.linalg.norm(track.velocity.mean(axis=0))
    rel = scp - track.position[[0, -1]]
    lo, hi = np.sort(rel @ heading / np.linalg.norm(rel, axis=1))
    width = None
    if beam and min(hi, beam[1]) > max(lo, beam[0]):
        b0, b1 = float(beam[0]), float(beam[1])
        u0, u1 = (max(lo, b0) - b0) / (b1 - b0), (min(hi, b1) - b0) / (b1 - b0)
        if u1 - u0 < 1.0 - 1e-9:                       # the track, not the beam, bounds the aperture
            width = segment_irw(window, u0, u1)
        lo, hi = max(lo, b0), min(hi, b1)
    return 2.0 * float(hi - lo) / wavelength, float(hi + lo) / wavelength, width


def closest_approach_time(track: Track, point: np.ndarray) -> float:
    """Time [s] from the first pulse at which the antenna passes broadside of ``point`` (straight track)."""
    velocity = track.velocity.mean(axis=0)
    along = (point - track.position[0]) @ velocity / float(velocity @ velocity)
    return float(np.clip(along, 0.0, track.pulse_time[-1] - track.pulse_time[0]))


def sicd_dict(image: SarImage, track: Track, ref: georef.GeoReference) -> dict[str, Any]:
    """The SICD XML (less SCPCOA, ImageCorners zero) in sarkit's dictionary form."""
    axes = georef.enu_axes(ref)
    (scp_row, scp_col), scp = scene_centre_point(image)
    scp_ecf = georef.enu_to_ecef(scp, ref)
    times, n_pulses = track.pulse_time - track.pulse_time[0], len(track.pulse_time)
    duration = n_pulses / track.prf                  # IPP count n at TEnd: IPPEnd = n - 1 (vol. 1, Timeline)
    t_scp = closest_approach_time(track, scp)
    antenna = track.position[int(np.argmin(np.abs(times - t_scp)))]
    sin_inc = float(np.hypot(*(antenna - scp)[:2]) / np.linalg.norm(antenna - scp))
    ground = image.plane == "ground"
    projection = sin_inc if ground else 1.0
    wavelength = SPEED_OF_LIGHT / track.fc
    az_window = _window(image, "window_azimuth")
    az_bw, az_ctr, az_width = azimuth_support(image, track, scp, wavelength, az_window)
    velocity = track.velocity.mean(axis=0)
    mode = str(image.metadata.get("radar", {}).get("mode", "stripmap")) if isinstance(image.metadata, dict) else ""
    slope = 0.0 if mode == "spotlight" else float(np.asarray(image.azimuth_direction) @ velocity / (velocity @ velocity))
    pol = _polarization(image)
    fit = np.polynomial.polynomial.polyfit(times, georef.enu_to_ecef(track.position, ref), 2 if len(times) > 2 else 1)
    n_az, n_rg = image.data.shape
    band = (track.fc - 0.5 * track.bandwidth, track.fc + 0.5 * track.bandwidth)
    return {
        "CollectionInfo": {"CollectorName": "sarmitsuba", "CoreName": str(image.metadata.get("scene", "scene")) or
                           "scene", "CollectType": "MONOSTATIC",
                           "RadarMode": {"ModeType": "SPOTLIGHT" if mode == "spotlight" else "STRIPMAP"},
                           "Classification": "UNCLASSIFIED", "Parameter": _parameters(image, ref)},
        "ImageCreation": {"Application": "sarmitsuba", "DateTime": _COLLECTION_START},
        "ImageData": {"PixelType": "RE32F_IM32F", "NumRows": n_rg, "NumCols": n_az, "FirstRow": 0, "FirstCol": 0,
                      "FullImage": {"NumRows": n_rg, "NumCols": n_az}, "SCPPixel": np.array([scp_row, scp_col])},
        "GeoData": {"EarthModel": "WGS_84", "SCP": {"ECF": scp_ecf, "LLH": georef.enu_to_geodetic(scp, ref)},
                    "ImageCorners": np.zeros((4, 2))},              # projected by project_corners
        "Grid": {"ImagePlane": "GROUND" if ground else "SLANT", "Type": "PLANE",
                 "TimeCOAPoly": np.array([[t_scp, slope]]),
                 "Row": grid_direction(np.asarray(image.range_direction) @ axes, _spacing(image.range),
                                       2.0 * track.bandwidth * projection / SPEED_OF_LIGHT,
                                       2.0 * track.fc * projection / SPEED_OF_LIGHT, _window(image, "window_range")),
                 "Col": grid_direction(np.asarray(image.azimuth_direction) @ axes, _spacing(image.azimuth), az_bw,
                                       az_ctr, az_window, az_width)},
        "Timeline": {"CollectStart": _COLLECTION_START, "CollectDuration": duration,
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


def build_xml(image: SarImage, track: Track, ref: georef.GeoReference) -> Any:
    """The SICD XML tree (lxml ElementTree) of ``image``, SCPCOA computed by sarkit."""
    import lxml.etree
    import sarkit.sicd as sksicd
    root = sksicd.ElementWrapper(lxml.etree.Element(f"{{{SICD_NAMESPACE}}}SICD"))
    root.from_dict(sicd_dict(image, track, ref))
    for parent, child in (("{*}Timeline/{*}IPP", "{*}Set"), ("{*}RadarCollection/{*}RcvChannels", "{*}ChanParameters")):
        holder = root.elem.find(parent)
        holder.set("size", str(len(holder.findall(child))))
        for index, elem in enumerate(holder.findall(child), start=1):
            elem.set("index", str(index))
    tree = lxml.etree.ElementTree(root.elem)
    root.elem.find("{*}ImageFormation").addnext(sksicd.compute_scp_coa(tree))
    project_corners(tree)
    return tree


def project_corners(tree: Any) -> None:
    """Set ``GeoData/ImageCorners``: the corner pixels (first row and column,
    then clockwise in (row, col)) projected along their R/Rdot contours onto the WGS84 surface of
    the SCP's height, by sarkit (``image_to_constant_hae_surface``, the image-to-scene projection).
    A slant-plane corner lies off the Earth, so its own latitude and longitude would be wrong."""
    import sarkit.sicd as sksicd
    import sarkit.wgs84
    xml = sksicd.XmlHelper(tree)
    n_rows, n_cols = xml.load("{*}ImageData/{*}NumRows"), xml.load("{*}ImageData/{*}NumCols")
    rowcol = np.array([[0, 0], [0, n_cols - 1], [n_rows - 1, n_cols - 1], [n_rows - 1, 0]])
    rowcol += np.array([xml.load("{*}ImageData/{*}FirstRow"), xml.load("{*}ImageData/{*}FirstCol")])
    hae = xml.load("{*}GeoData/{*}SCP/{*}LLH")[2]
    points, _, success = sksicd.image_to_constant_hae_surface(tree, sksicd.rowcol_to_xrowycol(tree, rowcol), hae)
    if not success or not np.all(np.isfinite(points)):
        raise SicdError("the image's corners do not project onto the Earth (is the track above the scene?)")
    xml.set("{*}GeoData/{*}ImageCorners", sarkit.wgs84.cartesian_to_geodetic(points)[:, :2])


def write_sicd(image: SarImage, path: str | os.PathLike, raw: RawData | None = None,
               ref: georef.GeoReference | None = None) -> Path:
    """Write ``image`` as a SICD 1.4.0 NITF at ``path`` (atomically).

    Parameters
    ----------
    image : SarImage
        complex64 [n_azimuth, n_range] on a uniform plane grid (local frame, m).
    path : path-like
        The ``.nitf`` file to write.
    raw : RawData, optional
        The data that were focused: their track gives ``Position``, ``Timeline`` and the band.
        Without them, the track the radar parameters in ``image.metadata["radar"]`` synthesise
        (a sarmitsuba render's images record them) stands in (:func:`track_of`).
    ref : GeoReference, optional
        WGS84 origin of the local frame (default: ``geo_origin`` in ``image.metadata["radar"]``).

    Raises SicdError without ``raw`` and without radar parameters, or on a non-uniform grid; :class:`outputs.WriteError`
    (an OSError) when the file cannot be written, leaving nothing behind.
    """
    import sarkit.sicd as sksicd
    tree = build_xml(image, track_of(image, raw), _reference(image, ref))
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


def check_sicd(path: str | os.PathLike, advisory: bool = True) -> list[str]:
    """Run sarkit's SICD consistency checker (``sicdcheck``: the XML schema, the NITF headers and
    every consistency check) on ``path``; the sorted names of the checks that failed.

    ``advisory`` False leaves out the checks whose only failures are advisory ("want", severity
    Warning, such as the oversampling-ratio checks ``check_iprbw_to_ss_osr_row``/``_col``, which
    SICD wants in 1.1 to 2.2); required ("need", Error) failures are always listed. A file whose
    grid samples the impulse response 1.1 to 2.2 times in both directions gives ``[]``.
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

    Files written by :func:`write_sicd` come back in their own frame (grid within micrometres,
    samples exactly, metadata included); other tools' files in the frame of their SCP.

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
    return SarImage(data=np.ascontiguousarray(array.T).astype(np.complex64), azimuth=azi, range=rng, origin=origin,
                    azimuth_direction=u_az, range_direction=u_rg,
                    plane="ground" if xml.load("{*}Grid/{*}ImagePlane") == "GROUND" else "slant",
                    algorithm=grid.get("algorithm", "unknown"), window=grid.get("window", "unknown"),
                    metadata=metadata)


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
