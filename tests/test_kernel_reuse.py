"""Kernels shared across launches, acquisitions and scenes of the same structure (issue 56).

Dr.Jit hashes a kernel's code; anything that enters it as a literal (a histogram's size, a pulse
count, a buffer's alignment) makes a new kernel, compiled again (seconds for the large ones) and
written to the disk cache again. The truth here is Dr.Jit's own: its kernel history (the code of
every kernel) and the files of a fresh disk cache (``DRJIT_CACHE_DIR``).
"""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (sets the variant before Dr.Jit loads)
import drjit as dr
import mitsuba as mi
from sarmitsuba.tracing.deposit.accumulate import HISTOGRAM_MIN_FLOATS, histogram_floats
from sarmitsuba.tracing.device import ALIGNMENT, aligned_copy, device_array, gather_table, table_array

llvm_only = pytest.mark.skipif(not mi.variant().startswith("llvm"), reason="the alignment is LLVM's IR")


def _kernel(compute) -> dict:
    """Dr.Jit's record of the one kernel that evaluates ``compute()``."""
    dr.kernel_history()                                   # clear
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.eval(compute())
        kernels = [k for k in dr.kernel_history() if "ir" in k]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    assert len(kernels) == 1
    return {"hash": kernels[0]["hash"], "ir": kernels[0]["ir"].getvalue()}


def _in_drjit_memory(cls, values):
    """``values`` copied by a Dr.Jit kernel into memory Dr.Jit allocated (the former device_array)."""
    mapped = cls(np.ascontiguousarray(values))
    out = dr.empty(cls, len(values))
    dr.scatter(out, mapped, dr.arange(mi.UInt32, len(values)))
    dr.eval(out)
    dr.sync_thread()
    return out


def test_aligned_copy_is_aligned_private_and_equal():
    for dtype in (np.float64, np.float32, np.uint32, np.bool_):
        for n in (0, 1, 5, 1000):
            values = np.arange(n + 1)[1:].astype(dtype)
            out = aligned_copy(values, dtype)
            assert out.dtype == dtype and out.flags.c_contiguous and (n == 0 or out.ctypes.data % ALIGNMENT == 0)
            np.testing.assert_array_equal(out, values)
            assert not np.shares_memory(out, values)


@llvm_only
@pytest.mark.parametrize("n", [1, 3, 40])
@pytest.mark.parametrize("cls, dtype", [(mi.Float64, np.float64), (mi.Float, np.float32), (mi.UInt32, np.uint32)])
def test_device_array_makes_the_kernel_of_drjit_memory(cls, dtype, n):
    """The mapped aligned copy gives the very kernel an array in Dr.Jit's own memory gives, for
    any offset of the source buffer (the kernel a one-entry array makes, a scalar load, included)."""
    buffer = np.arange(n + 3, dtype=dtype)
    in_drjit = _in_drjit_memory(cls, buffer[:n])
    reference = _kernel(lambda: in_drjit + 1)["hash"]
    for start in (0, 1, 3):
        values = buffer[start:start + n]
        got = device_array(cls, values)
        assert _kernel(lambda: got + 1)["hash"] == reference
        np.testing.assert_array_equal(got.numpy(), values)


def test_device_array_converts_like_the_type_and_nests():
    out = device_array(mi.Float, np.array([0.1, 2.5, -3.0]))         # float64 in, float32 kept
    np.testing.assert_array_equal(out.numpy(), np.array([0.1, 2.5, -3.0], np.float32))
    vectors = np.arange(12, dtype=np.float64).reshape(3, 4)
    out3 = device_array(mi.Array3f64, vectors)
    np.testing.assert_array_equal(out3.numpy(), vectors)
    assert dr.width(device_array(mi.UInt32, np.zeros(0, np.int64))) == 0


@llvm_only
def test_a_one_entry_table_gathers_like_a_wider_one():
    """A one-entry table is padded to two (same gathers), so a scene with one material shares the
    kernel of a scene with several: the kernel does not depend on the table's width or buffer."""
    index = dr.arange(mi.UInt32, 7) % 1
    one = mi.Float(np.array([0.25, 9.0], np.float32)[1:])             # NumPy's buffer, offset
    padded = gather_table(one)
    assert dr.width(padded) == 2
    np.testing.assert_array_equal(dr.gather(mi.Float, padded, index).numpy(), np.full(7, 9.0, np.float32))
    wide = gather_table(mi.Float(np.array([9.0, 1.0, 2.0], np.float32)))
    assert (_kernel(lambda: dr.gather(mi.Float, padded, index) * 2)["hash"]
            == _kernel(lambda: dr.gather(mi.Float, wide, index) * 2)["hash"])
    nested = gather_table((mi.Vector3f(np.array([1.0], np.float32), np.array([2.0], np.float32),
                                       np.array([3.0], np.float32)),))
    assert dr.width(nested[0]) == 2 and nested[0].numpy().tolist() == [[1, 1], [2, 2], [3, 3]]
    assert gather_table(None) is None and gather_table(5) == 5


@llvm_only
def test_a_launch_of_one_sub_aperture_gathers_like_a_wider_one():
    """Per-launch tables (one row per pulse or sub-aperture) of one entry are padded too, so a
    launch of a single sub-aperture runs the kernel of any other launch."""
    index = dr.arange(mi.UInt32, 9) % 1
    one = table_array(mi.Array3f64, np.array([[1.5], [2.5], [3.5]]))
    three = table_array(mi.Array3f64, np.array([[1.5, 0, 0], [2.5, 0, 0], [3.5, 0, 0]]))
    assert dr.width(one) == 2 and dr.width(table_array(mi.UInt32, np.array([7, 8]))) == 2
    got = dr.gather(mi.Array3f64, one, index)
    np.testing.assert_array_equal(got.numpy(), np.tile([[1.5], [2.5], [3.5]], 9))
    assert (_kernel(lambda: dr.gather(mi.Array3f64, one, index) * 2)["hash"]
            == _kernel(lambda: dr.gather(mi.Array3f64, three, index) * 2)["hash"])


def test_histogram_sizes_fall_into_few_buckets():
    assert histogram_floats(1) == HISTOGRAM_MIN_FLOATS == histogram_floats(HISTOGRAM_MIN_FLOATS)
    for n in (HISTOGRAM_MIN_FLOATS + 1, 3 * HISTOGRAM_MIN_FLOATS, 1 << 23, (1 << 23) + 2):
        size = histogram_floats(n)
        assert n <= size < 2 * n and size & (size - 1) == 0


def _render(cache: Path, out: Path, pulses: int) -> set[str]:
    env = dict(os.environ, DRJIT_CACHE_DIR=str(cache))
    subprocess.run([sys.executable, "-m", "sarmitsuba", "render", "trihedral", "--pulses", str(pulses),
                    "--max-depth", "3", "--out", str(out), "--no-progress"],
                   check=True, capture_output=True, env=env,
                   cwd=Path(__file__).resolve().parents[1])
    return set(os.listdir(cache))


@llvm_only
def test_a_second_pulse_count_compiles_no_new_kernel(tmp_path):
    """Rendering the trihedral with 60 pulses after 40 (launches of other sizes, a histogram of
    another size) writes no new kernel to a fresh disk cache: every kernel is shared."""
    cache = tmp_path / "cache"
    cache.mkdir()
    first = _render(cache, tmp_path / "a", 40)
    assert first, "premise: the first render writes its kernels to the cache"
    second = _render(cache, tmp_path / "b", 60)
    assert second == first
