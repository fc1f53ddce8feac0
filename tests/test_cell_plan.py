"""The cell plan's bookkeeping (docs/physics.md (T6)): its fast lookups against their readable
references."""
from __future__ import annotations

import numpy as np
import pytest

from sarmitsuba.cell_plan import across_sizes, across_sizes_reference, lane_grid
from sarmitsuba.kernel import Blocks


@pytest.mark.parametrize("reach", [1, 2])
def test_bucketed_lookup_across_tube_sizes_finds_what_the_cell_by_cell_one_finds(reach):
    """Two sub-apertures of coarse tubes with blocks 7, 3 and 5 times finer (sizes that do and do
    not divide each other), a tenth of the lanes untraced. Truth: the reference, which looks up
    every cell of each lane's neighbourhood on the other lattice. The bucketed lookup gives the
    same pairs, and with a signature the same (lane, signature) pairs, one lane per signature and
    cell. A finer cell bucketed only by the coarse cell of its first corner, or a neighbourhood one
    cell short, loses pairs."""
    rng = np.random.default_rng(3)
    blocks = Blocks.of([(0, 0, 0, 40, 40, 1), (0, 10, 20, 28, 21, 7), (0, 30, 5, 6, 9, 3),
                        (0, 31, 7, 10, 5, 5), (1, 0, 0, 40, 40, 1), (1, 12, 21, 10, 10, 5)])
    grid = lane_grid(blocks, blocks.n_lanes)
    traced = rng.random(blocks.n_lanes) > 0.1
    sub = blocks.sub.astype(np.int64)[grid[0]]
    lanes = np.flatnonzero(traced)
    rows, found = across_sizes_reference(lanes, traced, grid, sub, reach=reach)
    assert rows.size > 1000
    fast = across_sizes(lanes, traced, grid, sub, reach=reach)
    assert set(zip(*fast)) == set(zip(rows.tolist(), found.tolist()))
    signature = rng.integers(0, 3, blocks.n_lanes)
    rows_s, found_s = across_sizes(lanes, traced, grid, sub, reach=reach, signature=signature)
    assert rows_s.size < rows.size / 2
    assert set(zip(rows_s.tolist(), signature[found_s].tolist())) == set(zip(rows.tolist(), signature[found].tolist()))
