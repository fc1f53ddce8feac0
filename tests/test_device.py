"""NumPy arrays copied onto the device (:func:`sarmitsuba.tracing.device.device_array`).

A kernel that loads an array mapped from NumPy's buffer carries the buffer's alignment in its
code (LLVM ``align 1`` where the allocator gave less than 64 bytes), so the same kernel hashes
differently from render to render and compiles again each time (measured: 15 s per render of the
owned-region kernels on the smooth block, 1.3 s once they are cached). The truth here is the
kernel's own code (Dr.Jit's kernel history), not the helper.
"""
import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (sets the variant before Dr.Jit loads)
import drjit as dr
import mitsuba as mi
from sarmitsuba.tracing.device import device_array


def _loads(array) -> list[str]:
    """The vector loads of the kernel that computes ``array + 1``."""
    dr.kernel_history()                                   # clear
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.eval(array + 1)
        kernels = [k for k in dr.kernel_history() if "ir" in k]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    assert len(kernels) == 1
    return [line for line in kernels[0]["ir"].getvalue().splitlines() if " = load <" in line]


@pytest.mark.skipif(not mi.variant().startswith("llvm"), reason="the alignment is LLVM's IR")
@pytest.mark.parametrize("cls, dtype", [(mi.Float64, np.float64), (mi.UInt32, np.uint32), (mi.Float, np.float32)])
def test_an_array_from_an_unaligned_numpy_buffer_is_loaded_aligned(cls, dtype):
    buffer = np.arange(41, dtype=dtype)
    unaligned = buffer[1:]                                # one element past an allocation: never 64-byte aligned
    assert any("align 1," in line for line in _loads(cls(unaligned))), "premise: the mapped buffer loads unaligned"
    loads = _loads(device_array(cls, unaligned))
    assert loads and all("align 1," not in line for line in loads)


def test_the_copy_keeps_its_values_and_does_not_follow_the_numpy_buffer():
    values = np.linspace(-3.0, 7.0, 13)
    out = device_array(mi.Float64, values[1:])
    values[5] = 1e9                                        # a mapped array would see this
    np.testing.assert_array_equal(out.numpy(), np.linspace(-3.0, 7.0, 13)[1:])
    vectors = np.arange(15, dtype=np.float64).reshape(3, 5)
    out3 = device_array(mi.Array3f64, vectors)
    vectors[:] = -1
    np.testing.assert_array_equal(out3.numpy(), np.arange(15, dtype=np.float64).reshape(3, 5))
