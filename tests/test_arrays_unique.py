"""``core.arrays.sorted_unique`` against NumPy's own ``np.unique`` (a second method)."""
import numpy as np
import pytest

from sarmitsuba.core.arrays import sorted_unique, unique_rows


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


def _rows(seed: int, n: int, k: int, low: int, high: int) -> np.ndarray:
    return np.random.default_rng(seed).integers(low, high, (n, k))


@pytest.mark.parametrize("keys", [
    np.zeros((0, 3), np.int64), np.array([[2, -1]]), np.array([[1, 2], [1, 2], [1, 2]]),
    _rows(3, 4000, 2, -3, 3), _rows(4, 3000, 4, -(1 << 40), 1 << 40), _rows(5, 2000, 6, 0, 2),
    np.array([[1, 9, 0], [1, -9, 0], [0, 9, 5], [1, 9, 0]], np.int32)])
def test_unique_rows_is_numpys_unique_on_rows(keys):
    """Rows, inverse and counts as ``np.unique(keys, axis=0, ...)`` gives them: lexicographic
    order on signed columns (a reversed ``lexsort`` key order, or an unsigned view, breaks the
    order); the inverse scattered back through the sort (indexing it by the sorted positions
    instead breaks it); the counts of each run."""
    rows, inverse, counts = unique_rows(keys, return_inverse=True, return_counts=True)
    e_rows, e_inverse, e_counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    assert rows.dtype == e_rows.dtype
    np.testing.assert_array_equal(rows, e_rows)
    np.testing.assert_array_equal(inverse, e_inverse.reshape(-1))
    np.testing.assert_array_equal(counts, e_counts)
    np.testing.assert_array_equal(unique_rows(keys), e_rows)
    np.testing.assert_array_equal(rows[inverse], keys)
