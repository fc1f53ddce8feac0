"""NumPy arrays on the Dr.Jit device, in memory Dr.Jit allocates (docs/design.md section 10).

``mi.Float64(ndarray)`` maps NumPy's buffer without copying it. A kernel that loads such an array
element by element (an array as wide as the kernel, not a table it gathers from) takes the
buffer's alignment into its code: LLVM ``align 64`` where the allocator happened to give 64-byte
aligned memory, ``align 1`` where it did not. The kernel's hash then changes from one render to
the next, and Dr.Jit compiles it again (seconds for a large kernel, every render). Memory that
Dr.Jit allocates is always aligned, so copying into it makes the kernel, and its cache entry,
the same every time.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

__all__ = ["device_array"]


def device_array(cls, values) -> object:
    """``values`` as a Dr.Jit array of type ``cls``, copied into Dr.Jit's own (aligned) memory.

    Parameters
    ----------
    cls
        A flat Dr.Jit array type (``mi.UInt32``, ``mi.Float64``, ...) or a nested one
        (``mi.Array3f64``, ...).
    values : array_like
        Shape ``(n,)`` for a flat type; ``(components, n)`` for a nested one. Converted to the
        type's dtype by ``cls`` itself, as ``cls(values)`` would.

    Returns
    -------
    cls
        Evaluated, of width ``n``.
    """
    values = np.asarray(values)
    if dr.depth_v(cls) > 1:
        mapped = cls(*(np.ascontiguousarray(v) for v in values))
        n = values.shape[1]
    else:
        mapped = cls(np.ascontiguousarray(values))
        n = values.shape[0]
    out = dr.empty(cls, n)
    dr.scatter(out, mapped, dr.arange(mi.UInt32, n))
    dr.eval(out)
    dr.sync_thread()          # the copy kernel runs asynchronously: finish it before the NumPy buffer may change
    return out
