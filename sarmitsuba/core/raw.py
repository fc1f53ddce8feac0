"""Raw data: the contract between the tracer and the focusing stage (docs/design.md section 3).

:class:`RawData` is CPHD-like: slow time (pulses) on axis 0, fast time on axis 1,
complex64 samples and float64 geometry and timing. It is saved as one ``.npz``
file that loads with NumPy alone (``numpy.load(path, allow_pickle=False)``).

Signal convention (docs/design.md section 5, eq. (S2) of ``docs/physics.md``): a path
of two-way length ``L`` with complex amplitude ``a`` contributes, after range
compression, ``a * p_r(tau - L / c) * exp(-j 2 pi fc L / c)`` where ``p_r`` is the
compressed pulse with unit peak. Focusing multiplies by ``exp(+j 2 pi fc L / c)``.
"""
from __future__ import annotations

import json
import os
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .outputs import atomic_savez, json_default

__all__ = ["RawData", "RawDataError", "TRACKS", "read_npz", "refuse_non_finite"]


class RawDataError(ValueError):
    """A RawData file or array set does not honour the contract of docs/design.md section 3."""


_ARRAYS = ("data", "fast_time", "pulse_time", "tx_position", "rx_position", "velocity")
#: Optional arrays (absent or None: stop-and-hop, no separate nominal track).
_OPTIONAL = ("rx_time", "nominal_tx_position", "nominal_rx_position", "nominal_velocity")
#: Values of :meth:`RawData.on_track`.
TRACKS = ("true", "nominal")
_SCALARS = ("fc", "bandwidth", "chirp_rate", "pulse_length", "fs", "prf")


@dataclass(frozen=True)
class RawData:
    """Baseband echoes of one acquisition.

    Attributes
    ----------
    data : complex64 [n_pulses, n_samples]
        Baseband echo, range compressed when ``range_compressed`` is true. It holds the
        absolute carrier phase ``exp(-j 2 pi fc L / c)``. Units: sqrt(m^2) (normalised
        radiometry) unless ``metadata["units"]`` says otherwise.
    fast_time : float64 [n_samples], s
        Two-way delay of each sample from pulse transmission, ``t0 + i / fs``.
    pulse_time : float64 [n_pulses], s
        Transmission time of each pulse (slow time).
    tx_position, rx_position : float64 [n_pulses, 3], m
        Antenna phase centres in the world frame (z up): at transmission (``pulse_time``) and
        at reception (``rx_time``); equal for monostatic, stop-and-hop data.
    velocity : float64 [n_pulses, 3], m/s
        Platform velocity at each pulse's transmission.
    fc : float, Hz
        Carrier frequency.
    bandwidth : float, Hz
        Transmitted (chirp) bandwidth.
    chirp_rate : float, Hz/s
        LFM chirp rate ``K_r = bandwidth / pulse_length`` (sign: up-chirp positive).
    pulse_length : float, s
        Transmitted pulse duration ``T_p``.
    fs : float, Hz
        Fast-time sampling rate.
    prf : float, Hz
        Pulse repetition frequency.
    range_compressed : bool
        True when ``data`` is already range compressed.
    metadata : dict
        JSON-serialisable: scene, effects, seed, versions, timing, units.
    rx_time : float64 [n_pulses], s, optional
        Time at which ``rx_position`` is taken: the reception of the echo from the scene
        reference point (the scene centre of a render; CPHD's ``RcvTime``), on the clock of
        ``pulse_time``. None (default): ``pulse_time``, the stop-and-hop approximation. An echo
        of delay ``tau`` is received at ``rx_position + velocity (pulse_time + tau - rx_time)``
        to first order (docs/physics.md (J3)); backprojection uses that.
    nominal_tx_position, nominal_rx_position : float64 [n_pulses, 3], m, optional
        The antenna as the navigation data know it, when it differs from the true positions
        above (sensor ``motion_error``, docs/physics.md (J4)): what a processor without precise
        navigation focuses with (:meth:`on_track`). None (default): no separate nominal track.
    nominal_velocity : float64 [n_pulses, 3], m/s, optional
        The nominal track's velocity; given together with the nominal positions.

    Raises
    ------
    RawDataError
        On inconsistent shapes or dtypes (naming which array disagrees with ``data``),
        non-positive or non-finite scalars, non-finite geometry or timing, a fast-time axis
        that does not increase, or non-finite samples (their count and first (pulse, sample)).
        The sample check is one ``np.isfinite`` pass (about 25 ms for 2000 x 4000 samples).
    """

    data: np.ndarray
    fast_time: np.ndarray
    pulse_time: np.ndarray
    tx_position: np.ndarray
    rx_position: np.ndarray
    velocity: np.ndarray
    fc: float
    bandwidth: float
    chirp_rate: float
    pulse_length: float
    fs: float
    prf: float
    range_compressed: bool = True
    metadata: dict[str, Any] = field(default_factory=dict)
    rx_time: np.ndarray | None = None
    nominal_tx_position: np.ndarray | None = None
    nominal_rx_position: np.ndarray | None = None
    nominal_velocity: np.ndarray | None = None

    def __post_init__(self) -> None:
        self._check_shapes()
        self._check_values()

    def _check_shapes(self) -> None:
        """Dtypes and shapes: every array's length agrees with ``data``."""
        if self.data.ndim != 2 or self.data.dtype != np.complex64:
            hint = " (convert with .astype(numpy.complex64))" if self.data.ndim == 2 else ""
            raise RawDataError(f"data must be complex64 [n_pulses, n_samples], got {self.data.dtype} "
                               f"{list(self.data.shape)}{hint}")
        n_pulses, n_samples = self.data.shape
        _check_axis("fast_time", self.fast_time, (n_samples,), f"data has {n_samples} fast-time samples (columns)")
        for name in ("pulse_time", "tx_position", "rx_position", "velocity", *_OPTIONAL):
            if getattr(self, name) is None:
                continue
            shape = (n_pulses,) if name in ("pulse_time", "rx_time") else (n_pulses, 3)
            _check_axis(name, getattr(self, name), shape, f"data has {n_pulses} pulses (rows)")
        nominal = [getattr(self, name) is None for name in _OPTIONAL[1:]]
        if any(nominal) and not all(nominal):
            raise RawDataError("nominal_tx_position, nominal_rx_position and nominal_velocity are given together "
                               "(the nominal track) or not at all")

    def _check_values(self) -> None:
        """Positive finite scalars, finite geometry, increasing fast time, finite samples."""
        for name in ("fc", "bandwidth", "pulse_length", "fs", "prf"):
            value = float(getattr(self, name))
            if not (np.isfinite(value) and value > 0):
                raise RawDataError(f"{name} must be a finite positive number, got {value}")
        if not np.isfinite(float(self.chirp_rate)):
            raise RawDataError(f"chirp_rate must be a finite number (Hz/s), got {self.chirp_rate}")
        for name in ("fast_time", "pulse_time", "tx_position", "rx_position", "velocity", *_OPTIONAL):
            if getattr(self, name) is None:
                continue
            labels = ("sample",) if name == "fast_time" else ("pulse",) if name.endswith("_time") else ("pulse", "axis")
            refuse_non_finite(getattr(self, name), name, "value", labels, RawDataError,
                               "the geometry is corrupt: re-create the data (sarmitsuba render)")
        steps = np.diff(self.fast_time)
        if np.any(steps <= 0):
            k = int(np.argmax(steps <= 0)) + 1
            raise RawDataError(f"fast_time must be strictly increasing (t0 + i / fs), but sample {k} "
                               f"({float(self.fast_time[k])!r} s) is not after sample {k - 1}")
        refuse_non_finite(self.data, "data", "sample", ("pulse", "sample"), RawDataError,
                           "focusing would spread NaN over the whole image; re-create the data (sarmitsuba "
                           "render), or zero the bad samples (numpy.nan_to_num) if they are known to be void")

    @property
    def n_pulses(self) -> int:
        """Number of pulses (rows of ``data``)."""
        return self.data.shape[0]

    @property
    def n_samples(self) -> int:
        """Number of fast-time samples (columns of ``data``)."""
        return self.data.shape[1]

    @property
    def wavelength(self) -> float:
        """Carrier wavelength in metres, ``c / fc``."""
        from .constants import SPEED_OF_LIGHT
        return SPEED_OF_LIGHT / self.fc

    @property
    def receive_time(self) -> np.ndarray:
        """float64 [n_pulses], s: ``rx_time``, or ``pulse_time`` for stop-and-hop data."""
        return self.pulse_time if self.rx_time is None else self.rx_time

    @property
    def has_nominal_track(self) -> bool:
        """Whether the data carry a nominal track apart from the true one (motion errors)."""
        return self.nominal_tx_position is not None

    def on_track(self, track: str) -> "RawData":
        """The data with the antenna positions of ``track``: ``"true"`` (the data as they are) or
        ``"nominal"``: ``tx_position``, ``rx_position`` and ``velocity`` replaced by the nominal
        track's (what a processor without precise navigation focuses with; docs/physics.md (J4)),
        ``metadata["track"] = "nominal"``.

        Raises
        ------
        RawDataError
            ``track`` not in :data:`TRACKS`, or ``"nominal"`` for data without a nominal track
            (no sensor ``motion_error``).
        """
        if track not in TRACKS:
            raise RawDataError(f"track = {track!r}; valid values are {', '.join(repr(t) for t in TRACKS)}")
        if track == "true":
            return self
        if not self.has_nominal_track:
            raise RawDataError("track = 'nominal': these data carry no nominal track (they were simulated without "
                               "motion errors, so the nominal track is the true one); render with the sensor parameter "
                               "motion_error, or focus with track = 'true'")
        from dataclasses import replace
        return replace(self, tx_position=self.nominal_tx_position.copy(), rx_position=self.nominal_rx_position.copy(),
                       velocity=self.nominal_velocity.copy(), nominal_tx_position=None, nominal_rx_position=None,
                       nominal_velocity=None, metadata={**self.metadata, "track": "nominal"})

    def save(self, path: str | os.PathLike) -> Path:
        """Write the data to ``path`` (``.npz``) atomically: a temporary file, then a rename.

        Returns the path written. Raises ``OSError`` when the directory is not writable.
        """
        arrays = {name: getattr(self, name) for name in (*_ARRAYS, *_OPTIONAL) if getattr(self, name) is not None}
        scalars = {name: np.float64(getattr(self, name)) for name in _SCALARS}
        return atomic_savez(Path(path), **arrays, **scalars,
                             range_compressed=np.bool_(self.range_compressed),
                             metadata=np.str_(json.dumps(self.metadata, default=json_default)))

    @classmethod
    def load(cls, path: str | os.PathLike) -> "RawData":
        """Read a file written by :meth:`save` (or by any tool honouring the contract).

        Raises
        ------
        RawDataError
            Naming ``path`` and the problem: missing or unreadable file, not an ``.npz``
            archive, damaged archive (truncated, bad CRC), missing field, arrays whose
            lengths disagree, non-finite samples or geometry (count and first position).
        """
        kwargs = read_npz(path, "RawData", RawDataError, _read_raw_fields)
        try:
            return cls(**kwargs)
        except RawDataError as exc:
            raise RawDataError(f"{path}: {exc}") from None


def _read_raw_fields(f: Any) -> dict[str, Any]:
    """The keyword arguments of :class:`RawData` from an open ``NpzFile``."""
    missing = [k for k in (*_ARRAYS, *_SCALARS) if k not in f.files]
    if missing:
        raise KeyError(f"not a RawData file, missing {missing}: give a raw.npz written by RawData.save "
                       "(sarmitsuba render) or one with every field of docs/design.md section 3")
    kwargs: dict[str, Any] = {k: np.asarray(f[k]) for k in (*_ARRAYS, *_OPTIONAL) if k in f.files}
    kwargs.update({k: float(f[k]) for k in _SCALARS})
    kwargs["range_compressed"] = bool(f["range_compressed"]) if "range_compressed" in f.files else True
    kwargs["metadata"] = json.loads(str(f["metadata"])) if "metadata" in f.files else {}
    return kwargs


def _check_axis(name: str, value: np.ndarray, shape: tuple[int, ...], owner: str) -> None:
    """Raise :class:`RawDataError` unless ``value`` is float64 of ``shape``; ``owner`` says
    what fixes the length (e.g. "data has 8 pulses (rows)")."""
    if value.ndim == len(shape) and value.shape[0] != shape[0]:
        raise RawDataError(f"{owner} but {name} has {value.shape[0]} {'rows' if value.ndim == 2 else 'entries'}: "
                           "the arrays are not of one acquisition; re-create the file (RawData.save, sarmitsuba "
                           "render)")
    if value.shape != shape or value.dtype != np.float64:
        hint = " (convert with .astype(numpy.float64))" if value.shape == shape else ""
        raise RawDataError(f"{name} must be float64 {list(shape)}, got {value.dtype} {list(value.shape)}{hint}")


def refuse_non_finite(array: np.ndarray, name: str, noun: str, labels: tuple[str, ...],
                       error: type[ValueError], fix: str) -> None:
    """Raise ``error`` when ``array`` holds NaN or Inf: their count, the first index (named by
    ``labels``, C order) and ``fix``. One ``np.isfinite`` pass when all values are finite."""
    finite = np.isfinite(array)
    if finite.all():
        return
    bad = ~finite
    count = int(np.count_nonzero(bad))
    first = np.unravel_index(int(np.argmax(bad)), array.shape)
    where = ", ".join(f"{label} {'xyz'[i] if label == 'axis' else i}" for label, i in zip(labels, first))
    raise error(f"{name} has {count} non-finite {noun}{'s' if count > 1 else ''} (NaN or Inf) out of "
                f"{array.size}, the first at ({where}): {fix}")


#: First bytes of a zip archive (``.npz``): a local file header, or the end record of an empty one.
_ZIP_MAGIC = (b"PK\x03\x04", b"PK\x05\x06")


def read_npz(path: str | os.PathLike, what: str, error: type[ValueError], read: Any) -> Any:
    """``read(npz)`` on the opened ``.npz`` at ``path``, every failure raised as ``error``.

    ``what`` names the contract ("RawData", "SarImage") in messages. ``read`` may raise
    ``KeyError`` for a missing field. Truncated or corrupted archives (``zipfile.BadZipFile``,
    ``zlib.error``, ``EOFError``), files that are no ``.npz`` (text, ``.npy``, pickles) and
    unreadable members (``ValueError``, ``TypeError`` from NumPy) all become ``error`` with
    the file name, the problem and the likely fix.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(4)
    except OSError as exc:
        raise error(f"{path}: cannot read {what}: {exc.strerror or exc}") from exc
    if head not in _ZIP_MAGIC:
        found = "an empty file" if not head else f"a file starting with {head!r}"
        example = f"out/urban/{'raw' if what == 'RawData' else 'image'}.npz"
        raise error(f"{path}: cannot read {what}: not an .npz {what} file ({found}; an .npz archive starts with "
                    f"b'PK'): give the .npz that sarmitsuba wrote (e.g. {example})")
    try:
        with np.load(path, allow_pickle=False) as npz:
            return read(npz)
    except (zipfile.BadZipFile, zlib.error, EOFError) as exc:
        raise error(f"{path}: cannot read {what}: damaged .npz archive ({exc}): the file is truncated or "
                    "corrupted (an interrupted write or copy?); copy it again or re-create it") from exc
    except KeyError as exc:
        raise error(f"{path}: {exc.args[0] if exc.args else exc}") from exc
    except (OSError, ValueError, TypeError) as exc:
        reason = ("it holds a pickled Python object, which no field of the contract is"
                  if "allow_pickle" in str(exc) else str(exc))
        raise error(f"{path}: cannot read {what} ({reason}); the file is damaged or not a {what} file") from exc
