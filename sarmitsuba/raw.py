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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["RawData", "RawDataError"]


class RawDataError(ValueError):
    """A RawData file or array set does not honour the contract of docs/design.md section 3."""


_ARRAYS = ("data", "fast_time", "pulse_time", "tx_position", "rx_position", "velocity")
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
        Antenna phase centres in the world frame (z up); equal for monostatic data.
    velocity : float64 [n_pulses, 3], m/s
        Platform velocity at each pulse.
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

    Raises
    ------
    RawDataError
        On inconsistent shapes, dtypes or non-positive scalars.
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

    def __post_init__(self) -> None:
        if self.data.ndim != 2 or self.data.dtype != np.complex64:
            raise RawDataError(
                f"data must be complex64 [n_pulses, n_samples], got {self.data.dtype} {self.data.shape}")
        n_pulses, n_samples = self.data.shape
        expected = {
            "fast_time": (n_samples,), "pulse_time": (n_pulses,),
            "tx_position": (n_pulses, 3), "rx_position": (n_pulses, 3), "velocity": (n_pulses, 3),
        }
        for name, shape in expected.items():
            value = getattr(self, name)
            if value.shape != shape or value.dtype != np.float64:
                raise RawDataError(
                    f"{name} must be float64 {list(shape)}, got {value.dtype} {list(value.shape)}")
        for name in ("fc", "bandwidth", "pulse_length", "fs", "prf"):
            value = float(getattr(self, name))
            if not (np.isfinite(value) and value > 0):
                raise RawDataError(f"{name} must be a finite positive number, got {value}")
        if n_samples > 1 and not np.all(np.diff(self.fast_time) > 0):
            raise RawDataError("fast_time must be strictly increasing")

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

    def save(self, path: str | os.PathLike) -> Path:
        """Write the data to ``path`` (``.npz``) atomically: a temporary file, then a rename.

        Returns the path written. Raises ``OSError`` when the directory is not writable.
        """
        arrays = {name: getattr(self, name) for name in _ARRAYS}
        scalars = {name: np.float64(getattr(self, name)) for name in _SCALARS}
        return _atomic_savez(Path(path), **arrays, **scalars,
                             range_compressed=np.bool_(self.range_compressed),
                             metadata=np.str_(json.dumps(self.metadata, default=_json_default)))

    @classmethod
    def load(cls, path: str | os.PathLike) -> "RawData":
        """Read a file written by :meth:`save` (or by any tool honouring the contract).

        Raises
        ------
        RawDataError
            When the file is missing a field, is not an ``.npz`` or has wrong shapes.
        """
        try:
            with np.load(path, allow_pickle=False) as f:
                missing = [k for k in (*_ARRAYS, *_SCALARS) if k not in f.files]
                if missing:
                    raise RawDataError(f"{path}: not a RawData file, missing {missing}")
                kwargs: dict[str, Any] = {k: f[k] for k in _ARRAYS}
                kwargs.update({k: float(f[k]) for k in _SCALARS})
                kwargs["range_compressed"] = bool(f["range_compressed"]) if "range_compressed" in f.files else True
                kwargs["metadata"] = json.loads(str(f["metadata"])) if "metadata" in f.files else {}
        except (OSError, ValueError, EOFError) as exc:
            if isinstance(exc, RawDataError):
                raise
            raise RawDataError(f"{path}: cannot read RawData ({exc})") from exc
        return cls(**kwargs)


def _json_default(obj: Any) -> Any:
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"metadata value of type {type(obj).__name__} is not JSON-serialisable")


def _atomic_savez(path: Path, **arrays: Any) -> Path:
    """``np.savez`` to ``path`` through a temporary name in the same directory, then rename."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.partial")
    try:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
        os.replace(tmp, path)
    except BaseException:              # Ctrl-C or a full disk: no half-written file is left
        tmp.unlink(missing_ok=True)
        raise
    return path
