"""The -3 dB width of a sampled peak, measured directly on the samples: the independent
resolution oracle that tests use where the library's own measure (``analyze_point_target``)
is not to be trusted to judge itself."""
from __future__ import annotations

import numpy as np


def minus_3db_width(axis: np.ndarray, values: np.ndarray) -> tuple[float, float]:
    """``(width, peak)`` [axis units]: the -3 dB width of ``|values|^2`` sampled on ``axis``
    (linear interpolation at the half-power crossings either side of the largest sample) and
    the position of that sample."""
    power = np.abs(np.asarray(values)) ** 2
    power = power / power.max()
    k = int(np.argmax(power))
    left, right = k, k
    while power[left] > 0.5:
        left -= 1
    while power[right] > 0.5:
        right += 1
    x_left = np.interp(0.5, [power[left], power[left + 1]], [axis[left], axis[left + 1]])
    x_right = np.interp(0.5, [power[right], power[right - 1]], [axis[right], axis[right - 1]])
    return float(x_right - x_left), float(axis[k])
