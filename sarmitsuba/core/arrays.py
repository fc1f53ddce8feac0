"""Array validation shared by every stage's frozen dataclasses (docs/design.md section 2).

=====================  ==============================================================
:func:`vector3`        a finite 3-vector (float64, shape ``(3,)``) or a clear ValueError
:func:`readonly`       a float64 copy whose ``writeable`` flag is off
=====================  ==============================================================

Frozen dataclasses between stages hold their arrays read-only, so no stage can change another
stage's data in place.
"""
from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["readonly", "vector3"]


def vector3(name: str, value: Any) -> np.ndarray:
    """``value`` as a float64 array of shape ``(3,)``.

    Raises
    ------
    ValueError
        Naming ``name``: ``value`` is not 3 finite numbers.
    """
    arr = np.array(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be 3 finite numbers (x, y, z in metres), got {value!r}")
    return arr


def readonly(arr: Any) -> np.ndarray:
    """A float64 copy of ``arr`` (any shape) that cannot be written to."""
    out = np.array(arr, dtype=np.float64, copy=True)
    out.flags.writeable = False
    return out
