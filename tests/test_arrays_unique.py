"""``core.arrays.sorted_unique`` against NumPy's own ``np.unique`` (a second method)."""
import numpy as np
import pytest

from sarmitsuba.core.arrays import sorted_unique


@pytest.mark.parametrize("values", [
    np.zeros(0, np.int64), np.array([7]), np.array([3, 3, 3]), np.array([5, -2, 5, 9, -2, 0]),
    np.random.default_rng(1).integers(-1000, 1000, 5000), np.random.default_rng(2).integers(0, 1 << 60, 3000),
    np.array([0.5, -0.0, 0.0, 2.5, 0.5]), np.array([[4, 1], [1, 4]], np.int32)])
def test_sorted_unique_is_numpys_unique(values):
    """Same values, order and dtype as ``np.unique``; a bug keeping the last repeat's neighbour or
    comparing against the unsorted input would give extra or missing values."""
    got, expected = sorted_unique(values), np.unique(values)
    assert got.dtype == expected.dtype
    np.testing.assert_array_equal(got, expected)
