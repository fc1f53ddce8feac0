"""The contract shared by the backprojection focusers: input checks, metadata and the output image.

:func:`~sarmitsuba.focus.backproject`, :func:`~sarmitsuba.focus.backproject_reference` and
:func:`~sarmitsuba.focus.ffbp` accept the same :class:`~sarmitsuba.core.raw.RawData` (range
compressed, uniform fast time) and return a :class:`~sarmitsuba.core.image.SarImage` on the given
:class:`~sarmitsuba.focus.ImageGrid` with the same ``metadata["focus"]`` record
(docs/design.md section 3).
"""
from __future__ import annotations

import copy
import os
from typing import Any

import numpy as np

from ..core.image import SarImage
from ..core.raw import RawData
from .beam import BeamWeighting, sine_scale
from .grid import ImageGrid
from .range_lines import MAX_OVERSAMPLE
from .windows import check_window, window_label

__all__ = ["check_inputs", "range_window_of", "focus_metadata", "make_image", "progress_bar", "available_cpus",
           "receiver_motion"]


def receiver_motion(raw: RawData) -> tuple[np.ndarray, np.ndarray] | None:
    """``(velocity, rx_delay)`` of continuous-motion data, or None for stop-and-hop data.

    ``velocity`` float64 [n_pulses, 3] m/s and ``rx_delay = rx_time - pulse_time`` float64
    [n_pulses] s: the echo of a point ``X`` arrives at ``rx_position + velocity (L / c - rx_delay)``,
    ``L`` its two-way length (docs/physics.md (J3)).
    """
    if raw.rx_time is None:
        return None
    return np.asarray(raw.velocity, float), np.asarray(raw.rx_time - raw.pulse_time, float)


def available_cpus() -> int:
    """CPUs this process may run on (the default number of worker threads)."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def check_inputs(raw: RawData, grid: ImageGrid, oversample: Any, pulse_block: Any,
                 workers: Any) -> tuple[float, int, int, int]:
    """Check the data, the grid and the common options; returns ``(t0, oversample, pulse_block, workers)``.

    Raises
    ------
    TypeError
        When ``raw`` is not a RawData or ``grid`` not an ImageGrid.
    ValueError
        When the data are not range compressed, have no pulse or fewer than 2 samples, the
        fast-time axis is not ``t0 + i / fs``, an antenna position is not finite, or
        ``oversample`` (1 .. 64), ``pulse_block`` (>= 1) or ``workers`` (>= 1, None: all CPUs)
        is not an integer in its range.
    """
    if not isinstance(raw, RawData):
        raise TypeError(f"raw must be a sarmitsuba.core.raw.RawData, got {type(raw).__name__}")
    if not isinstance(grid, ImageGrid):
        raise TypeError(f"grid must be a sarmitsuba.focus.ImageGrid, got {type(grid).__name__}")
    if not raw.range_compressed:
        raise ValueError("backprojection needs range-compressed data, but raw.range_compressed is False; "
                         "range-compress the raw chirps first (matched filter)")
    if raw.n_pulses < 1 or raw.n_samples < 2:
        raise ValueError(f"raw.data must have >= 1 pulse and >= 2 fast-time samples, got shape {raw.data.shape}")
    t0 = float(raw.fast_time[0])
    step = np.diff(raw.fast_time)
    if not np.allclose(step, 1.0 / raw.fs, rtol=1e-6, atol=0.0):
        raise ValueError(f"raw.fast_time must be t0 + i / fs with fs = raw.fs = {raw.fs} Hz; its steps span "
                         f"[{step.min()!r}, {step.max()!r}] s instead of {1.0 / raw.fs!r} s")
    for name, value in (("tx_position", raw.tx_position), ("rx_position", raw.rx_position)):
        if not np.all(np.isfinite(value)):
            raise ValueError(f"raw.{name} must be finite")
    checked = []
    for name, value, low, high in (("oversample", oversample, 1, MAX_OVERSAMPLE),
                                   ("pulse_block", pulse_block, 1, None),
                                   ("workers", workers, 1, None)):
        if name == "workers" and value is None:
            value = available_cpus()
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
                or value < low or (high is not None and value > high):
            bound = f"{low} .. {high}" if high is not None else f">= {low}"
            raise ValueError(f"{name} must be an integer in {bound}, got {value!r}")
        checked.append(int(value))
    return (t0, *checked)  # type: ignore[return-value]


def range_window_of(raw: RawData) -> tuple[str, dict[str, float]]:
    """The range window the data were compressed with: ``raw.metadata["range_window"]`` when it
    names a window of :mod:`.windows`, else rect (the tracer's ``sinc(B t)`` pulses)."""
    spec = raw.metadata.get("range_window") if isinstance(raw.metadata, dict) else None
    if isinstance(spec, dict) and isinstance(spec.get("name"), str):
        params = {k: v for k, v in spec.items() if k != "name"}
        try:
            return check_window(spec["name"], **params)
        except ValueError:
            pass
    return "rect", {}


def focus_metadata(raw: RawData, grid: ImageGrid, seconds: float, beam: BeamWeighting,
                   **params: Any) -> dict[str, Any]:
    """``image.metadata["focus"]`` of a backprojected image: ``params`` (the focuser's options),
    the windows, pattern, beam sines, straight-track reference ``track`` (mid-aperture transmitter,
    unit velocity, first-to-last length), ``sine_scale`` (:func:`~.beam.sine_scale` at the grid's
    centre: the target-side sines per beam sine, 1 on a straight track), normalisation, radar figures, ``seconds`` and
    ``pixel_pulses_per_second`` (grid pixels x pulses / seconds: the rate of a direct
    backprojection of every pulse onto every pixel)."""
    pixel_pulses = grid.shape[0] * grid.shape[1] * raw.n_pulses
    w_rg, w_az = range_window_of(raw), beam.window
    label = "rect" if w_rg[0] == w_az[0] == "rect" else \
        f"range={window_label(*w_rg)}, azimuth={window_label(*w_az)}"
    mid = raw.n_pulses // 2
    velocity = np.asarray(raw.velocity[mid], float)
    speed = float(np.linalg.norm(velocity))
    track = {"position": [float(v) for v in raw.tx_position[mid]],
             "direction": [float(v) for v in velocity / speed] if speed > 0 else None,
             "length": float(np.linalg.norm(raw.tx_position[-1] - raw.tx_position[0]))}
    normalisation = ("1/n_pulses" if beam.sines is None and beam.is_rect else "1/sum(w)" if beam.sines is None
                     else f"per range column: 1/max sum(w g{'^2' if beam.power == 2 else ''})")
    return {"algorithm": "backprojection", "window": label, **params,
            "window_range": {"name": w_rg[0], **w_rg[1]}, "window_azimuth": {"name": w_az[0], **w_az[1]},
            "azimuth_pattern": beam.pattern, "pattern_power": beam.power,
            "beam_sines": None if beam.sines is None else list(beam.sines), "track": track,
            "sine_scale": sine_scale(raw, grid.origin + grid.azimuth[grid.shape[0] // 2] * grid.azimuth_direction
                                     + grid.range[grid.shape[1] // 2] * grid.range_direction, beam.sines),
            "interpolation": "fft-upsample + linear", "normalisation": normalisation,
            "n_pulses": raw.n_pulses, "grid_shape": list(grid.shape), "plane": grid.plane,
            "fc": raw.fc, "bandwidth": raw.bandwidth, "fs": raw.fs, "prf": raw.prf,
            "seconds": seconds, "pixel_pulses_per_second": pixel_pulses / max(seconds, 1e-12)}


def make_image(raw: RawData, grid: ImageGrid, data: np.ndarray, focus: dict[str, Any]) -> SarImage:
    """The SarImage of ``data`` on ``grid``: a deep copy of ``raw.metadata`` plus ``"focus"``."""
    metadata = copy.deepcopy(raw.metadata)
    metadata["focus"] = focus
    return SarImage(data=data, azimuth=np.array(grid.azimuth), range=np.array(grid.range),
                    origin=np.array(grid.origin), azimuth_direction=np.array(grid.azimuth_direction),
                    range_direction=np.array(grid.range_direction), plane=grid.plane,
                    algorithm="backprojection", window=focus["window"], metadata=metadata)


def progress_bar(enabled: bool, total: int, desc: str = "backprojection", unit: str = "pulse") -> Any:
    """A :mod:`tqdm` bar (disabled unless ``enabled``)."""
    from tqdm.auto import tqdm
    return tqdm(total=total, desc=desc, unit=unit, disable=not enabled)
