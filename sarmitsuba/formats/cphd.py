"""CPHD 1.1.0 (NGA.STND.0068, Compensated Phase History Data) export and import of RawData.

The format is written and read by sarkit (the NGA reference implementation); this module
only maps :class:`~sarmitsuba.core.raw.RawData` onto it:

- one channel ``"1"``, ``SGN = -1``, signal format ``CF8``, in either domain (``domain``):
  ``Global/DomainType = TOA`` (default), the range-compressed fast-time samples, or ``FX``, their
  Fourier transform along fast time over the sampled band, the deramped phase history that
  vendors deliver and FX readers (FastSAR) take (:mod:`sarmitsuba.formats.cphd_fx`, docs/physics.md
  (GEO2')); :func:`read_cphd` reads both;
- PVPs per pulse in ECEF (WGS84) metres: the local east-north-up frame is placed at the
  :class:`~sarmitsuba.core.georef.GeoReference` origin, which is also written as the scene's IARP;
- the scene reference point (SRP) is the scene centre (``metadata["radar"]["scene_center"]``,
  else the mean of the pulses' closest points on the ground), and ``SceneCoordinates/ImageArea``
  (with the channel's ``ImageArea`` and the ``ImageGrid``) bounds what the data can show: the
  scene's bounding box with its layover and a margin, else the fast-time window projected to the
  ground (:mod:`sarmitsuba.formats.cphd_geometry`);
- the samples are compensated to the SRP as CPHD requires (docs/physics.md (GEO2)): sample ``s`` of vector ``v`` sits
  at ``dTOA = SC0[v] + s SCSS`` relative to the SRP delay ``tau_srp[v]`` and carries the phase
  factor ``exp(+j 2 pi fc tau_srp[v])`` (a point at the SRP reads zero phase at ``dTOA = 0``).
  :func:`read_cphd` undoes both, so the samples come back within float32 rounding;
- continuous-motion data (``RawData.rx_time``, docs/physics.md (J3)) write ``RcvTime``/``RcvPos``
  at the SRP echo's arrival, ``TxTime``/``TxPos`` at transmission (``CollectType`` MONOSTATIC: one
  antenna); stop-and-hop data write ``RcvPos = RawData.rx_position`` and ``RcvTime = TxTime + tau_srp``:
  the transmitter itself (MONOSTATIC), or a second platform's antenna (``CollectType`` BISTATIC,
  ``RcvVel`` its own velocity from the receiver positions, ``aFDOP`` from both legs, and sarkit's
  ``ReferenceGeometry/Bistatic``). Reading, a MONOSTATIC file's receiver elsewhere with the
  transmitter's velocity gives ``rx_time`` back; a BISTATIC file gives stop-and-hop data;
- range-compressed data are written as such; chirped data (``range_compressed`` false) are
  written uncompressed, in the TOA domain only (an FX vector is a deramped phase history);
- times: ``Global/Timeline/CollectionStart`` is the first pulse's UTC time,
  ``metadata["radar"]["collection_start"]`` (ISO 8601), else 2000-01-01T00:00:00Z; ``TxTime``
  counts from it. ``ProductInfo/CreationInfo/DateTime`` is the moment the file is written (UTC);
- what CPHD has no element for travels as standard ``ProductInfo/CreationInfo/Parameter``
  elements (:data:`PARAMETERS`): sarmitsuba's metadata (JSON, with any ``scene_path`` cut to its
  file name: no path of the user's machine leaves it), the first pulse time in RawData's clock,
  the PRF and whether the samples are range compressed, so that a file read back focuses exactly
  like the RawData it came from. Files written by sarmitsuba 0.1 carried the
  same four entries as non-standard file-header keys, which other readers (sarpy) refuse;
  :func:`read_cphd` still reads them.
"""
from __future__ import annotations

import datetime
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from ..core import georef
from ..core.constants import SPEED_OF_LIGHT
from ..core.outputs import atomic_write, json_default
from ..core.raw import RawData
from .cphd_fx import fx_from_toa, fx_grid, fx_layout, toa_from_fx
from .cphd_geometry import bistatic, receiver_velocity, scene_coordinates, scene_reference_point, srp_delay, unit
from .provenance import collection_start as provenance_start
from .provenance import portable_metadata, utc_now

__all__ = ["CphdError", "write_cphd", "read_cphd", "check_cphd", "CPHD_NAMESPACE", "PARAMETERS", "DOMAINS",
           "collection_start", "toa_fixed", "TOA_FIXED_TOLERANCE", "check_domain"]

#: XML namespace of the CPHD version written.
CPHD_NAMESPACE = "http://api.nsgreg.nga.mil/schema/cphd/1.1.0"
_CHANNEL = "1"
#: Signal domains :func:`write_cphd` writes (``domain``; the first is the default): time of arrival,
#: frequency (``Global/DomainType`` TOA, FX).
DOMAINS = ("toa", "fx")
#: Spread [s] of the vectors' TOA1 and TOA2 up to which the channel is TOAFixed: sarpy wants TOAFixed
#: whenever every value lies within 1e-11 s of their mean, which a larger spread rules out (2e-11 s
#: is 3 mm of range, far below a sample).
TOA_FIXED_TOLERANCE = 2e-11
_KVP_METADATA = "SARMITSUBA_METADATA"
_KVP_TIME0 = "SARMITSUBA_PULSE_TIME0"
_KVP_PRF = "SARMITSUBA_PRF"
_KVP_COMPRESSED = "SARMITSUBA_RANGE_COMPRESSED"
#: Names of the ``ProductInfo/CreationInfo/Parameter`` elements written (and, in files of
#: earlier versions, of the file-header keys read): metadata JSON, first pulse time [s] in
#: RawData's clock (zero at mid-aperture), PRF [Hz], ``"true"``/``"false"`` range compressed.
PARAMETERS = (_KVP_METADATA, _KVP_TIME0, _KVP_PRF, _KVP_COMPRESSED)
#: PVP layout in 8-byte words: (name, size, format).
_PVP_LAYOUT = (("TxTime", 1, "f8"), ("TxPos", 3, "v"), ("TxVel", 3, "v"), ("RcvTime", 1, "f8"),
               ("RcvPos", 3, "v"), ("RcvVel", 3, "v"), ("SRPPos", 3, "v"), ("aFDOP", 1, "f8"),
               ("aFRR1", 1, "f8"), ("aFRR2", 1, "f8"), ("FX1", 1, "f8"), ("FX2", 1, "f8"),
               ("TOA1", 1, "f8"), ("TOA2", 1, "f8"), ("TDTropoSRP", 1, "f8"), ("SC0", 1, "f8"),
               ("SCSS", 1, "f8"), ("SIGNAL", 1, "i8"))


class CphdError(ValueError):
    """A CPHD file cannot be written or read as RawData (names the file and the reason)."""


def pvp_dtype_xml() -> dict[str, Any]:
    """The ``PVP`` element of the XML as sarkit's dictionary form (offsets in 8-byte words)."""
    pvp, offset = {}, 0
    for name, size, kind in _PVP_LAYOUT:
        dtype = np.dtype(("<f8", (3,))) if kind == "v" else np.dtype("<" + kind)
        pvp[name] = {"Offset": offset, "Size": size, "dtype": dtype}
        offset += size
    return pvp


def check_domain(domain: str, raw: RawData | None = None, path: Any = "the CPHD file") -> None:
    """Raise :class:`CphdError` naming ``path`` unless ``domain`` is one of :data:`DOMAINS`, or when it is
    ``"fx"`` and ``raw`` holds chirped samples (``range_compressed`` false): an FX vector is the
    deramped phase history (docs/physics.md (GEO2')), which chirped echoes are not."""
    if domain not in DOMAINS:
        raise CphdError(f"cannot write CPHD file {path}: domain = {domain!r}; valid domains are "
                        f"{' and '.join(DOMAINS)} (the first is the default)")
    if domain == "fx" and raw is not None and not raw.range_compressed:
        raise CphdError(f"cannot write CPHD file {path} in the FX domain: the raw data are chirped (sensor "
                        "output=raw), and an FX vector is the deramped phase history; write the TOA domain, or render "
                        "with output=compressed")


def build_pvps(raw: RawData, ref: georef.GeoReference, dtype: np.dtype, domain: str = "toa") -> np.ndarray:
    """PVP array [n_pulses] of ``dtype``: geometry in ECEF, times from the first pulse (CPHD 1.1 sec. 6);
    the signal's sample axis (``SC0``, ``SCSS``, ``FX1``, ``FX2``) of the TOA or FX ``domain``."""
    rot = georef.enu_axes(ref)
    srp = scene_reference_point(raw)
    tau = srp_delay(raw.tx_position, raw.rx_position, srp)
    pvp = np.zeros(raw.n_pulses, dtype=dtype)
    pvp["TxTime"] = raw.pulse_time - raw.pulse_time[0]
    # continuous motion: the receiver at the SRP echo's arrival (docs/physics.md (J3)); stop-and-hop
    # data: the antenna did not move, and the SRP echo arrives tau after transmission
    pvp["RcvTime"] = pvp["TxTime"] + (tau if raw.rx_time is None else raw.rx_time - raw.pulse_time)
    pvp["TxPos"] = georef.enu_to_ecef(raw.tx_position, ref)
    pvp["RcvPos"] = georef.enu_to_ecef(raw.rx_position, ref)
    rx_velocity = receiver_velocity(raw)            # a bistatic receiver's own, else the antenna's
    pvp["TxVel"], pvp["RcvVel"] = raw.velocity @ rot, rx_velocity @ rot
    pvp["SRPPos"] = georef.enu_to_ecef(np.broadcast_to(srp, raw.tx_position.shape), ref)
    # aFDOP = -2 Rdot_avg / c, Rdot_avg the mean of the two legs' range rates to the SRP (CPHD 1.1 sec. 6)
    rdot = 0.5 * sum(np.sum(vel * unit(pos - srp), axis=1)
                     for pos, vel in ((raw.tx_position, raw.velocity), (raw.rx_position, rx_velocity)))
    pvp["aFDOP"] = -2.0 * rdot / SPEED_OF_LIGHT
    pvp["aFRR2"] = 2.0 / (SPEED_OF_LIGHT * lfm_rate(raw))
    pvp["aFRR1"] = raw.fc * pvp["aFRR2"]
    pvp["FX1"], pvp["FX2"] = raw.fc - 0.5 * raw.bandwidth, raw.fc + 0.5 * raw.bandwidth
    pvp["TOA1"] = raw.fast_time[0] - tau
    pvp["TOA2"] = pvp["TOA1"] + (raw.n_samples - 1) / raw.fs
    pvp["SC0"], pvp["SCSS"] = pvp["TOA1"], 1.0 / raw.fs
    if domain == "fx":                # the bins of the sampled band (GEO2'); FX1, FX2 the transmitted band in it
        grid = fx_grid(raw.n_samples, raw.fs)
        pvp["SC0"], pvp["SCSS"] = raw.fc + grid.bins[0] * grid.df, grid.df
        pvp["FX1"], pvp["FX2"] = grid.band(raw.fc, raw.bandwidth)
    if toa_fixed(pvp):                # a window that follows the SRP (circular track): one saved interval
        pvp["TOA1"], pvp["TOA2"] = pvp["TOA1"].max(), pvp["TOA2"].min()
    pvp["SIGNAL"] = 1
    return pvp


def toa_fixed(pvp: np.ndarray) -> bool:
    """Whether the vectors' sampled TOA intervals ``[SC0, SC0 + (n - 1) SCSS]`` (relative to the SRP)
    agree within :data:`TOA_FIXED_TOLERANCE` (a circular track about the SRP, whose fast-time window
    follows the SRP's range): then ``TOA1``/``TOA2`` are written as the one interval every vector
    samples, the latest start and the earliest end, and the channel is ``TOAFixed`` (CPHD 1.1.0 sec. 6:
    ``TOAFixed`` true when TOA1 and TOA2 are the same for every vector; sarkit's check wants them
    exactly equal, sarpy's wants ``TOAFixed`` true when they lie within 10 ps of their mean)."""
    return bool(np.ptp(pvp["TOA1"]) <= TOA_FIXED_TOLERANCE and np.ptp(pvp["TOA2"]) <= TOA_FIXED_TOLERANCE)


def sample_rate(tree: Any, pvp: np.ndarray) -> float:
    """Fast-time sampling rate [Hz]: TxRcv's SampleRate when given, else ``1 / SCSS``."""
    text = tree.findtext("{*}TxRcv/{*}RcvParameters/{*}SampleRate")
    return float(text) if text else 1.0 / float(pvp["SCSS"][0])


def lfm_rate(raw: RawData) -> float:
    """The transmitted chirp rate [Hz/s]: ``raw.chirp_rate``, or ``bandwidth / pulse_length`` when it is 0."""
    return float(raw.chirp_rate) if raw.chirp_rate else float(raw.bandwidth / raw.pulse_length)


def radar_words(raw: RawData) -> tuple[str, str, str]:
    """(ModeType, TxPol, RcvPol) from sarmitsuba's metadata, UNSPECIFIED where unknown."""
    radar = raw.metadata.get("radar", {}) if isinstance(raw.metadata, dict) else {}
    mode = {"stripmap": "STRIPMAP", "spotlight": "SPOTLIGHT"}.get(str(radar.get("mode", "")).lower(),
                                                                   "DYNAMIC STRIPMAP")
    pol = str(raw.metadata.get("polarization") or radar.get("polarization") or "")
    if len(pol) == 2 and set(pol) <= {"H", "V"}:
        return mode, pol[0], pol[1]
    return mode, "UNSPECIFIED", "UNSPECIFIED"


def cphd_dict(raw: RawData, ref: georef.GeoReference, pvp: np.ndarray, start: datetime.datetime,
              created: datetime.datetime, domain: str = "toa") -> dict[str, Any]:
    """The CPHD XML (less ReferenceGeometry) in sarkit's dictionary form (CPHD 1.1.0 sec. 5-9): the
    collection starting at ``start`` (the first pulse, UTC), the file made at ``created`` (UTC), the
    signal in the TOA or FX ``domain`` (:data:`DOMAINS`)."""
    srp = scene_reference_point(raw)
    scene, area = scene_coordinates(raw, ref, srp)
    mode, tx_pol, rcv_pol = radar_words(raw)
    tref = pvp["TxTime"] + 0.5 * (pvp["RcvTime"] - pvp["TxTime"])
    rate = lfm_rate(raw)
    scene_name = str(raw.metadata.get("scene", "scene")) if isinstance(raw.metadata, dict) else "scene"
    n_samples = raw.n_samples if domain == "toa" else fx_grid(raw.n_samples, raw.fs).n_bins
    fx1, fx2 = float(pvp["FX1"].min()), float(pvp["FX2"].max())
    # FxC, FxBW: (FX1 + FX2) / 2 and FX2 - FX1 (CPHD 1.1 sec. 7), the transmitted band unless fs cut it
    fxc, fxbw = float(raw.fc), float(raw.bandwidth)
    if (fx1, fx2) != (raw.fc - 0.5 * raw.bandwidth, raw.fc + 0.5 * raw.bandwidth):
        fxc, fxbw = 0.5 * (fx1 + fx2), fx2 - fx1
    return {
        "CollectionID": {"CollectorName": "sarmitsuba", "CoreName": scene_name or "scene",
                         # one antenna, moving during the echo or not (CPHD 1.1 sec. 2), or two
                         "CollectType": "BISTATIC" if bistatic(raw) else "MONOSTATIC",
                         "RadarMode": {"ModeType": mode}, "Classification": "UNCLASSIFIED",
                         "ReleaseInfo": "UNRESTRICTED"},
        "Global": {"DomainType": domain.upper(), "SGN": -1,
                   "Timeline": {"CollectionStart": start, "TxTime1": float(pvp["TxTime"][0]),
                                "TxTime2": float(pvp["TxTime"][-1])},
                   "FxBand": {"FxMin": fx1, "FxMax": fx2},
                   "TOASwath": {"TOAMin": float(pvp["TOA1"].min()), "TOAMax": float(pvp["TOA2"].max())}},
        "SceneCoordinates": scene,
        "Data": {"SignalArrayFormat": "CF8", "NumBytesPVP": 8 * sum(s for _, s, _ in _PVP_LAYOUT),
                 "NumCPHDChannels": 1,
                 "Channel": ({"Identifier": _CHANNEL, "NumVectors": raw.n_pulses, "NumSamples": n_samples,
                              "SignalArrayByteOffset": 0, "PVPArrayByteOffset": 0},),
                 "NumSupportArrays": 0},
        "Channel": {"RefChId": _CHANNEL, "FXFixedCPHD": True, "TOAFixedCPHD": toa_fixed(pvp), "SRPFixedCPHD": True,
                    "Parameters": ({"Identifier": _CHANNEL, "RefVectorIndex": raw.n_pulses // 2,
                                    "FXFixed": True, "TOAFixed": toa_fixed(pvp), "SRPFixed": True, "SignalNormal": True,
                                    "Polarization": {"TxPol": tx_pol, "RcvPol": rcv_pol},
                                    "FxC": fxc, "FxBW": fxbw,
                                    "TOASaved": float(pvp["TOA2"].max() - pvp["TOA1"].min()),
                                    "DwellTimes": {"CODId": "1", "DwellId": "1"}, "ImageArea": area,
                                    "TxRcv": {"TxWFId": ("tx",), "RcvId": ("rcv",)}},)},
        "PVP": pvp_dtype_xml(),
        "Dwell": {"NumCODTimes": 1, "CODTime": ({"Identifier": "1",
                                                  "CODTimePoly": np.array([[0.5 * (tref[0] + tref[-1])]])},),
                  "NumDwellTimes": 1, "DwellTime": ({"Identifier": "1",
                                                      "DwellTimePoly": np.array([[tref[-1] - tref[0]]])},)},
        "TxRcv": {"NumTxWFs": 1, "TxWFParameters": ({"Identifier": "tx", "PulseLength": float(raw.pulse_length),
                                                     "RFBandwidth": float(raw.bandwidth), "FreqCenter": float(raw.fc),
                                                     "LFMRate": rate, "Polarization": tx_pol},),
                  "NumRcvs": 1, "RcvParameters": ({"Identifier": "rcv",
                                                   "WindowLength": float(raw.n_samples / raw.fs),
                                                   "SampleRate": float(raw.fs), "IFFilterBW": float(raw.fs),
                                                   "FreqCenter": float(raw.fc), "LFMRate": rate,
                                                   "Polarization": rcv_pol},)},
        "ProductInfo": {"CreationInfo": ({"Application": application(raw), "DateTime": created,
                                          "Parameter": creation_parameters(raw)},)},
    }


def application(raw: RawData) -> str:
    """``CreationInfo/Application``: ``"sarmitsuba"`` and the version that made the data, when recorded."""
    versions = raw.metadata.get("versions") if isinstance(raw.metadata, dict) else None
    version = versions.get("sarmitsuba") if isinstance(versions, dict) else None
    return f"sarmitsuba {version}" if version else "sarmitsuba"


def creation_parameters(raw: RawData) -> list[tuple[str, str]]:
    """``ProductInfo/CreationInfo/Parameter`` entries (name, text), :data:`PARAMETERS`: what CPHD has
    no element for (the metadata as JSON, the first pulse time [s], the PRF [Hz], range compressed)."""
    text = json.dumps(portable_metadata(raw.metadata), default=json_default, ensure_ascii=True)
    return [(_KVP_METADATA, text), (_KVP_TIME0, repr(float(raw.pulse_time[0]))), (_KVP_PRF, repr(float(raw.prf))),
            (_KVP_COMPRESSED, "true" if raw.range_compressed else "false")]


def collection_start(raw: RawData, path: Any = "the CPHD file") -> datetime.datetime:
    """The first pulse's UTC time (:func:`sarmitsuba.formats.provenance.collection_start`); raises
    :class:`CphdError` naming ``path`` for a value that is no ISO 8601 time with a UTC offset."""
    try:
        return provenance_start(raw.metadata)
    except ValueError as exc:
        raise CphdError(f"cannot write CPHD file {path}: metadata radar {exc}") from None


def build_metadata(raw: RawData, ref: georef.GeoReference, start: datetime.datetime | None = None,
                   created: datetime.datetime | None = None, domain: str = "toa") -> tuple[Any, np.ndarray]:
    """(sarkit.cphd.Metadata, PVP array) for ``raw`` placed at ``ref``, its collection starting at
    ``start`` (default :func:`collection_start`), the file made at ``created`` (default now, UTC), the
    signal in the TOA or FX ``domain``."""
    import lxml.etree
    import sarkit.cphd as skcphd
    root = skcphd.ElementWrapper(lxml.etree.Element(f"{{{CPHD_NAMESPACE}}}CPHD"))
    dtype = skcphd.get_pvp_dtype(_tree_with_pvp_layout(raw))
    pvp = build_pvps(raw, ref, dtype, domain)
    start = collection_start(raw) if start is None else start
    root.from_dict(cphd_dict(raw, ref, pvp, start, utc_now() if created is None else created, domain))
    tree = lxml.etree.ElementTree(root.elem)
    refgeom = skcphd.compute_reference_geometry(tree, pvp)
    root.elem.find("{*}Dwell").addnext(refgeom)
    return skcphd.Metadata(xmltree=tree), pvp


def _tree_with_pvp_layout(raw: RawData) -> Any:
    """A minimal XML tree holding only Data/NumBytesPVP and PVP, for ``get_pvp_dtype``."""
    import lxml.etree
    import sarkit.cphd as skcphd
    root = skcphd.ElementWrapper(lxml.etree.Element(f"{{{CPHD_NAMESPACE}}}CPHD"))
    root["Data"] = {"NumBytesPVP": 8 * sum(s for _, s, _ in _PVP_LAYOUT)}
    root["PVP"] = pvp_dtype_xml()
    return lxml.etree.ElementTree(root.elem)


def write_cphd(raw: RawData, path: str | os.PathLike, ref: georef.GeoReference | None = None,
               domain: str = "toa") -> Path:
    """Write ``raw`` as a one-channel CPHD 1.1.0 file at ``path`` (atomically), placed at ``ref``.

    Parameters
    ----------
    raw : RawData
        Samples complex64 [n_pulses, n_samples] (range compressed or chirped, as simulated)
        and geometry in the local ENU frame (m, m/s, s).
    path : path-like
        The ``.cphd`` file to write.
    ref : GeoReference, optional
        WGS84 origin of the local frame (default: the ``geo_origin`` recorded in
        ``raw.metadata["radar"]``, see :func:`georef.of`).
    domain : {"toa", "fx"}, default "toa"
        ``Global/DomainType``: the fast-time samples compensated to the SRP (docs/physics.md
        (GEO2)), complex64 [n_pulses, n_samples], or their Fourier transform over the transmitted
        band (GEO2'), complex64 [n_pulses, M] (``M`` the fast-time length zero-padded by 1.25,
        :func:`sarmitsuba.formats.cphd_fx.fx_grid`).
        Monostatic and bistatic (``CollectType`` BISTATIC) data alike.

    Returns the path written. Raises :class:`outputs.WriteError` (an OSError) when the file
    cannot be written, :class:`CphdError` naming ``path`` when ``metadata["radar"]["collection_start"]``
    is not an ISO 8601 time with an offset, when ``domain`` is none of :data:`DOMAINS`, or for the
    FX domain of chirped data (:func:`check_domain`); nothing is left behind then.
    """
    import sarkit.cphd as skcphd
    check_domain(domain, raw, path)
    ref = georef.of(raw.metadata.get("radar", {}) if isinstance(raw.metadata, dict) else {}) if ref is None else ref
    metadata, pvp = build_metadata(raw, ref, collection_start(raw, path), domain=domain)
    srp = scene_reference_point(raw)
    tau = srp_delay(raw.tx_position, raw.rx_position, srp)
    if domain == "fx":
        signal = fx_from_toa(raw.data, float(raw.fast_time[0]), raw.fs, raw.fc, tau, fx_grid(raw.n_samples, raw.fs))
    else:
        signal = (raw.data * np.exp(2j * np.pi * raw.fc * tau)[:, None]).astype(np.complex64)

    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f, skcphd.Writer(f, metadata) as writer:
            writer.write_signal(_CHANNEL, signal)
            writer.write_pvp(_CHANNEL, pvp)
    return atomic_write(Path(path), write, "CPHD file")


def check_cphd(path: str | os.PathLike) -> list[str]:
    """Run sarkit's CPHD consistency checker (``cphdcheck``) on ``path``; return its failures' names."""
    import sarkit.verification as skver
    with open(path, "rb") as f:
        con = skver.CphdConsistency.from_file(f, thorough=True)
        con.check()
    return sorted(con.failures())


def read_cphd(path: str | os.PathLike) -> RawData:
    """Read a one-channel CPHD file, TOA or FX domain, into RawData in the local ENU frame of its IARP.

    Samples are decompensated from the SRP (see the module docstring); FX vectors are first
    transformed back to fast time (:func:`sarmitsuba.formats.cphd_fx.toa_from_fx`, docs/physics.md
    (GEO2')). Geometry is converted from ECEF to the local east-north-up frame at
    ``SceneCoordinates/IARP/LLH``. Files written by :func:`write_cphd` give back their RawData
    (metadata included; TOA samples within float32 rounding, FX ones within the band they keep,
    geometry within micrometres), those of earlier versions (the same entries as file-header keys)
    too; other tools' files get metadata from the XML only.

    Raises
    ------
    CphdError
        Naming ``path``: missing or unreadable file; an empty, truncated or otherwise damaged
        file, or one that is not a CPHD file (one line saying which, :func:`damage_message`); more
        than one channel; a TOA file whose fast-time axis differs between vectors, or an FX file whose
        frequency axis does (both need resampling).
    """
    import lxml.etree
    import sarkit.cphd as skcphd
    try:
        file = open(path, "rb")
    except OSError as exc:
        raise CphdError(f"cannot read CPHD file {path}: {exc}") from None
    # What sarkit's reader raises on a damaged file (found by cutting and overwriting files): ValueError
    # (a header line without " := ", UnicodeDecodeError), KeyError (a header key missing), lxml's
    # XMLSyntaxError (the XML cut or overwritten), RuntimeError (a short PVP or signal block).
    damaged = (OSError, ValueError, KeyError, AttributeError, TypeError, RuntimeError, lxml.etree.LxmlError)
    with file:
        try:
            with skcphd.Reader(file) as reader:
                channel = reader.metadata.xmltree.findtext("{*}Data/{*}Channel/{*}Identifier")
                signal, pvp = reader.read_channel(channel)
                tree, kvps = reader.metadata.xmltree, reader.metadata.file_header_part.additional_kvps
        except damaged as exc:
            raise CphdError(damage_message(path, exc)) from None
    return raw_from_parts(path, tree, kvps, signal, pvp)


def damage_message(path: str | os.PathLike, exc: BaseException) -> str:
    """One line on a CPHD file that sarkit could not read (``exc``): ``path``, what is wrong (empty,
    not a CPHD file, truncated against the block sizes its header declares, or damaged) and the fix."""
    size = Path(path).stat().st_size
    with open(path, "rb") as f:
        head = f.read(5)
        f.seek(0)
        complete, declared = declared_size(f)
    again = "write it again with `render --cphd`, or give an intact copy"
    if size == 0:
        return f"cannot read CPHD file {path}: the file is empty (an interrupted write or copy?); {again}"
    if head != b"CPHD/":
        return (f"cannot read CPHD file {path}: not a CPHD file (it begins with {head!r}, a CPHD file with "
                "'CPHD/'); give a CPHD 1.x file, such as the raw.cphd that `render --cphd` writes")
    if not complete:
        return (f"cannot read CPHD file {path}: the file is truncated: it ends inside its header, after {size} "
                f"bytes; {again}")
    if declared is not None and size < declared:
        return (f"cannot read CPHD file {path}: the file is truncated: {size} of the {declared} bytes its header "
                f"declares (an interrupted write or copy?); {again}")
    reason = " ".join(str(exc).split())[:160] or "no detail"
    return f"cannot read CPHD file {path}: the file is damaged ({type(exc).__name__}: {reason}); {again}"


def declared_size(file: Any) -> tuple[bool, int | None]:
    """(header complete, file size [bytes] its header declares) of the CPHD file open at its start
    in ``file``. The header is complete when its terminator line is found before the file ends; the
    size is the end of its last block (XML, support, PVP, signal), None when a size is unreadable."""
    keys: dict[str, str] = {}
    for line in iter(file.readline, b""):
        if line == b"\f\n":
            break
        key, sep, value = line.decode("latin-1").strip().partition(" := ")
        keys[key] = value if sep else ""
    else:
        return False, None
    blocks = [name[: -len("_SIZE")] for name in keys if name.endswith("_BLOCK_SIZE")]
    try:
        return True, max(int(keys[f"{b}_SIZE"]) + int(keys[f"{b}_BYTE_OFFSET"]) for b in blocks)
    except (KeyError, ValueError):
        return True, None


def stored_parameters(tree: Any, kvps: dict[str, str]) -> dict[str, str]:
    """sarmitsuba's :data:`PARAMETERS` found in the file: ``ProductInfo/CreationInfo/Parameter`` and
    ``ProductInfo/Parameter`` elements, else (files of earlier versions) the file-header keys ``kvps``."""
    found = {name: kvps[name] for name in PARAMETERS if name in kvps}
    for elem in tree.findall("{*}ProductInfo/{*}CreationInfo/{*}Parameter") + tree.findall(
            "{*}ProductInfo/{*}Parameter"):
        if elem.get("name") in PARAMETERS:
            found[elem.get("name")] = elem.text or ""
    return found


def raw_from_parts(path: Any, tree: Any, kvps: dict[str, str], signal: np.ndarray, pvp: np.ndarray) -> RawData:
    """RawData from one channel's XML, file-header keys, signal [n_vectors, n_samples] and PVPs."""
    import sarkit.cphd as skcphd
    xml = skcphd.XmlHelper(tree)
    domain = xml.load("{*}Global/{*}DomainType")
    if domain not in ("TOA", "FX"):
        raise CphdError(f"{path}: Global/DomainType is {domain!r}; CPHD files are TOA or FX domain")
    if xml.load("{*}Data/{*}NumCPHDChannels") != 1:
        raise CphdError(f"{path}: only one-channel CPHD files can be read")
    llh = xml.load("{*}SceneCoordinates/{*}IARP/{*}LLH")
    ref = georef.GeoReference(float(llh[0]), float(llh[1]), float(llh[2]))
    rot = georef.enu_axes(ref)
    tx, rx = georef.ecef_to_enu(pvp["TxPos"], ref), georef.ecef_to_enu(pvp["RcvPos"], ref)
    tau = srp_delay(pvp["TxPos"], pvp["RcvPos"], pvp["SRPPos"]) + pvp["TDTropoSRP"]
    fc = float(xml.load("{*}Channel/{*}Parameters/{*}FxC"))
    fs = sample_rate(tree, pvp)
    wf = tree.find("{*}TxRcv/{*}TxWFParameters")
    if domain == "FX":
        data, fast_time, fc, fs = fx_samples(path, tree, signal, pvp, tau, fc)
    else:
        start = pvp["SC0"] + tau
        if np.ptp(start) > 1e-3 * float(pvp["SCSS"][0]) or np.ptp(pvp["SCSS"]) > 0:
            raise CphdError(f"{path}: the vectors' fast-time axes differ (SC0 + TOA_SRP varies by "
                            f"{np.ptp(start):.3g} s); RawData needs one axis, resampling is not supported")
        data = (signal * np.exp(-2j * np.pi * fc * tau)[:, None]).astype(np.complex64)
        fast_time = start[0] + np.arange(signal.shape[1]) * float(pvp["SCSS"][0])
    bandwidth = float(xml.load("{*}Channel/{*}Parameters/{*}FxBW"))
    pulse_length = float(wf.findtext("{*}PulseLength")) if wf is not None else 1.0 / float(xml.load(
        "{*}Channel/{*}Parameters/{*}FxBW"))
    chirp = float(wf.findtext("{*}LFMRate")) if wf is not None and wf.find("{*}LFMRate") is not None else 0.0
    kvps = stored_parameters(tree, kvps)
    time0 = float(kvps.get(_KVP_TIME0, 0.0))
    pulse_time = pvp["TxTime"] + time0
    # one platform that moved during the echo (MONOSTATIC, same velocity, receiver elsewhere): continuous
    # motion; a BISTATIC file's receiver is a second antenna, stop-and-hop at RcvPos
    moving = (xml.load("{*}CollectionID/{*}CollectType") != "BISTATIC"
              and not np.array_equal(pvp["TxPos"], pvp["RcvPos"])
              and np.allclose(pvp["RcvVel"], pvp["TxVel"], rtol=0.0, atol=1e-6))
    prf = float(kvps[_KVP_PRF]) if _KVP_PRF in kvps else 1.0 / float(np.median(np.diff(pvp["TxTime"])))
    metadata = json.loads(kvps[_KVP_METADATA]) if _KVP_METADATA in kvps else {"source": str(path)}
    return RawData(data=data, fast_time=fast_time,
                   pulse_time=pulse_time, tx_position=tx, rx_position=rx,
                   rx_time=pvp["RcvTime"] + time0 if moving else None,
                   velocity=np.asarray(pvp["TxVel"]) @ rot.T, fc=fc, bandwidth=bandwidth, chirp_rate=chirp,
                   pulse_length=pulse_length, fs=fs, prf=prf,
                   range_compressed=kvps.get(_KVP_COMPRESSED, "true") == "true", metadata=metadata)


def fx_samples(path: Any, tree: Any, signal: np.ndarray, pvp: np.ndarray, tau: np.ndarray,
               fxc: float) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(data complex64 [n_vectors, n_samples], fast_time float64 [n_samples] s, fc [Hz], fs [Hz]) of the
    FX vectors ``signal`` [n_vectors, n_bins] with their PVPs, SRP delays ``tau`` [s] and ``FxC`` [Hz]
    (:func:`sarmitsuba.formats.cphd_fx.fx_layout`, :func:`~sarmitsuba.formats.cphd_fx.toa_from_fx`);
    raises :class:`CphdError` naming ``path`` when they need resampling."""
    text = tree.findtext("{*}TxRcv/{*}RcvParameters/{*}SampleRate")
    try:
        layout = fx_layout(pvp["SC0"], pvp["SCSS"], signal.shape[1], fxc, float(text) if text else None)
        data, fast_time = toa_from_fx(signal, layout, pvp["TOA1"], pvp["TOA2"], tau)
    except ValueError as exc:
        raise CphdError(f"{path}: {exc}") from None
    return data, fast_time, layout.fc, layout.fs
