"""NumPy arrays on the Dr.Jit device, in aligned memory (docs/design.md section 10).

``mi.Float64(ndarray)`` maps NumPy's buffer without copying it. A kernel that loads such an array
element by element (an array as wide as the kernel, not a table it gathers from) takes the
buffer's alignment into its code: LLVM ``align 128`` where the buffer is aligned to a full
vector of lanes, ``align 1`` where it is not. The kernel's hash then changes from one render to
the next, and Dr.Jit compiles it again (seconds for a large kernel, every render). A copy into a
NumPy buffer aligned to :data:`ALIGNMENT` bytes, mapped like any other, gives the kernel (and
its cache entry) that Dr.Jit's own aligned memory gives, every time, without a copy kernel, an
evaluation or a wait for the device.
"""
from __future__ import annotations

import functools

import drjit as dr
import numpy as np

__all__ = ["ALIGNMENT", "aligned_copy", "device_array", "gather_table", "releasing", "table_array"]

#: Bytes a mapped buffer's start is aligned to: at least a full vector of the widest lanes (16 x 8).
ALIGNMENT = 256

_DTYPES = {dr.VarType.Float32: np.float32, dr.VarType.Float64: np.float64, dr.VarType.UInt32: np.uint32,
           dr.VarType.Int32: np.int32, dr.VarType.UInt64: np.uint64, dr.VarType.Int64: np.int64,
           dr.VarType.Bool: np.bool_, dr.VarType.Float16: np.float16}


def aligned_copy(values, dtype) -> np.ndarray:
    """A C-contiguous copy of ``values`` as ``dtype`` whose buffer starts at a multiple of
    :data:`ALIGNMENT` bytes (owned by the copy alone: nothing else writes to it)."""
    values = np.asarray(values)
    dtype = np.dtype(dtype)
    nbytes = values.size * dtype.itemsize
    raw = np.empty(nbytes + ALIGNMENT, np.uint8)
    start = (-raw.ctypes.data) % ALIGNMENT
    out = raw[start:start + nbytes].view(dtype).reshape(values.shape)
    out[...] = values
    return out


def device_array(cls, values) -> object:
    """``values`` as a Dr.Jit array of type ``cls``, mapped from an aligned private copy.

    Parameters
    ----------
    cls
        A flat Dr.Jit array type (``mi.UInt32``, ``mi.Float64``, ...) or a nested one
        (``mi.Array3f64``, ...).
    values : array_like
        Shape ``(n,)`` for a flat type; ``(components, n)`` for a nested one. Converted to the
        type's dtype (as ``cls(values)`` would) in NumPy, before it is mapped.

    Returns
    -------
    cls
        Of width ``n``; its kernels are those of an array in Dr.Jit's own memory.
    """
    values = np.asarray(values)
    dtype = _DTYPES[dr.type_v(cls)]
    if dr.depth_v(cls) > 1:
        return cls(*(dr.leaf_t(cls)(aligned_copy(v, dtype)) for v in values))
    return cls(aligned_copy(values, dtype))


def gather_table(table):
    """``table`` (a Dr.Jit array that kernels gather from; nested arrays and tuples of them
    component by component) in aligned memory and at least two entries wide.

    Dr.Jit reads a one-entry table as a scalar load whose alignment follows the buffer (NumPy's,
    for a table made from an ndarray): the kernel's code then changes with the allocation, and
    differs from that of a scene whose table has several entries. A second entry (a copy of the
    first, never gathered: indices stay below the original width) makes every scene's gather
    the same instruction. Anything that is not a Dr.Jit array (None, ints, flags) comes back as is.
    """
    if isinstance(table, tuple):
        return tuple(gather_table(t) for t in table)
    if not dr.is_array_v(table) or dr.depth_v(table) == 0:
        return table
    cls = type(table)
    if dr.depth_v(cls) > 1:
        return cls(*(gather_table(c) for c in table))
    return table_array(cls, table.numpy())


def table_array(cls, values) -> object:
    """:func:`device_array` of a table that kernels gather from, at least two entries wide (a
    one-entry table is read as a scalar, a different kernel: see :func:`gather_table`); the
    padding repeats the last entry and is never gathered."""
    values = np.asarray(values)
    if values.shape[-1] == 1:
        values = np.repeat(values, 2, axis=-1)
    return device_array(cls, values)


def releasing(function):
    """``function`` (a kernel that takes and returns NumPy arrays), then Dr.Jit's cache of freed
    device memory handed back (``dr.flush_malloc_cache``). Dr.Jit keeps every freed array for
    reuse by size; the kernels' temporaries, of sizes that change from call to call, would
    otherwise stay cached until the trace ends: 150 MiB more peak memory on a 100 k-triangle
    city's sub-aperture, 680 MiB on the 1 M-triangle city (``benchmarks/scaling.py``)."""
    @functools.wraps(function)
    def released(*args, **kwargs):
        try:
            return function(*args, **kwargs)
        finally:
            dr.flush_malloc_cache()
    return released
