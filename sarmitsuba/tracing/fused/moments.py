"""Polygon moments on the Dr.Jit device (docs/physics.md (M2), docs/design.md section 10.1).

:func:`sarmitsuba.tracing.mesh.polygons.moments` is the readable NumPy reference: area,
centroid, second moments about the centroid and bounding-box diagonal of padded convex polygons
by Green's theorem over their edges. Here one lane per polygon runs the same arithmetic over its
corner slots (unrolled: the batch's slot count is part of the kernel, one kernel per width), and
the results agree with the reference bit for bit (tests/test_fused_moments.py):

* every float64 operation is the reference's, in its order (Dr.Jit's LLVM backend does not
  contract products and sums into FMAs);
* the reference's sums over the slots are NumPy's pairwise summation of a contiguous row
  (:func:`numpy_sum`): eight partial sums for rows of eight slots or more, combined as
  ``((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))``, the rest added in order, all added to
  the reduction's identity ``0.0``;
* the box's minima and maxima are NumPy's ``np.minimum`` / ``np.maximum`` of finite values
  (the first where they are equal); a batch with a corner that is not finite goes to the
  reference.

Batches of fewer than :data:`DEVICE_ROWS` rows go to the reference too: their kernel launch and
copies cost more than NumPy's loops. Medians on the 2-core VM (octagons, one host thread):
256 rows 0.31 ms against NumPy's 0.23 ms, 1,024 rows 0.42 against 0.90, 16,384 rows 1.8
against 12.2.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from ..device import device_array, releasing, table_array
from ..mesh import polygons

__all__ = ["moments", "lane_moments", "numpy_sum", "DEVICE_ROWS"]

#: Rows below which :func:`moments` calls the reference.
DEVICE_ROWS = 512


def numpy_sum(terms: list):
    """``np.add.reduce`` of a contiguous row of ``terms`` (one value per slot), in NumPy's order."""
    if len(terms) < 8:
        total = terms[0]
        for t in terms[1:]:
            total = total + t
        return 0.0 + total
    r = list(terms[:8])
    i = 8
    while i + 8 <= len(terms):
        r = [r[k] + terms[i + k] for k in range(8)]
        i += 8
    total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    for t in terms[i:]:
        total = total + t
    return 0.0 + total


def lane_moments(xs: list, ys: list, count):
    """The moments of one lane's polygon from its slots' coordinates ``xs``, ``ys`` (Float64
    each, the batch's width of them) and its corner count (Int32; below 3: empty, all 0):
    ``(area, cx, cy, ixx, ixy, iyy, diagonal)``, as the reference (Dr.Jit evaluates only the
    ones a caller uses)."""
    x0, y0 = xs[0], ys[0]
    twelve, twenty_four = dr.opaque(mi.Float64, 12.0), dr.opaque(mi.Float64, 24.0)   # divided, not times 1/12
    x = [v - x0 for v in xs]
    y = [v - y0 for v in ys]
    width = len(xs)
    x1 = [x[(j + 1) % width] for j in range(width)]
    y1 = [y[(j + 1) % width] for j in range(width)]
    cross = [x[j] * y1[j] - x1[j] * y[j] for j in range(width)]
    area = 0.5 * numpy_sum(cross)
    safe = dr.select(area != 0.0, area, 1.0)
    cx = numpy_sum([(x[j] + x1[j]) * cross[j] for j in range(width)]) / (6.0 * safe)
    cy = numpy_sum([(y[j] + y1[j]) * cross[j] for j in range(width)]) / (6.0 * safe)
    ixx = numpy_sum([(x[j] * x[j] + x[j] * x1[j] + x1[j] * x1[j]) * cross[j] for j in range(width)]) / twelve \
        - area * cx * cx
    iyy = numpy_sum([(y[j] * y[j] + y[j] * y1[j] + y1[j] * y1[j]) * cross[j] for j in range(width)]) / twelve \
        - area * cy * cy
    ixy = numpy_sum([(x[j] * y1[j] + 2.0 * x[j] * y[j] + 2.0 * x1[j] * y1[j] + x1[j] * y[j]) * cross[j]
                      for j in range(width)]) / twenty_four - area * cx * cy
    lo_x, hi_x, lo_y, hi_y = xs[0], xs[0], ys[0], ys[0]
    for j in range(1, width):               # np.minimum(a, b): b only where b < a
        lo_x, hi_x = dr.select(xs[j] < lo_x, xs[j], lo_x), dr.select(xs[j] > hi_x, xs[j], hi_x)
        lo_y, hi_y = dr.select(ys[j] < lo_y, ys[j], lo_y), dr.select(ys[j] > hi_y, ys[j], hi_y)
    sx, sy = hi_x - lo_x, hi_y - lo_y
    diagonal = dr.sqrt(sx * sx + sy * sy)
    empty = count < 3
    zero = dr.zeros(mi.Float64, dr.width(area))
    return tuple(dr.select(empty, zero, v) for v in (area, cx + x0, cy + y0, ixx, ixy, iyy, diagonal))


@releasing
def moments(poly: np.ndarray, count: np.ndarray):
    """:func:`sarmitsuba.tracing.mesh.polygons.moments` on the device, bit for bit.

    Parameters
    ----------
    poly : float64 [n, V, 2]
        Polygons, counter-clockwise, padded with their first corner (face coordinates, m).
    count : int [n]
        Corners of each (fewer than 3: an empty polygon, all moments 0).

    Returns
    -------
    (float64 [n], float64 [n, 2], float64 [n, 3], float64 [n])
        Area [m^2], centroid [m], second moments about the centroid ``Ixx, Ixy, Iyy`` [m^4] and
        bounding-box diagonal [m] (over every slot, as the reference).
    """
    poly = np.asarray(poly)
    count = np.asarray(count)
    n = poly.shape[0]
    if n == 0 or n < DEVICE_ROWS or poly.ndim != 3 or poly.shape[1] == 0 or poly.dtype != np.float64 \
            or not np.isfinite(poly).all():
        return polygons.moments(poly, count)
    width = poly.shape[1]
    table_x = table_array(mi.Float64, poly[..., 0].reshape(-1))
    table_y = table_array(mi.Float64, poly[..., 1].reshape(-1))
    base = dr.arange(mi.UInt32, n) * width
    xs = [dr.gather(mi.Float64, table_x, base + j) for j in range(width)]
    ys = [dr.gather(mi.Float64, table_y, base + j) for j in range(width)]
    out = lane_moments(xs, ys, device_array(mi.Int32, np.minimum(count, 3)))
    dr.eval(*out)
    area, cx, cy, ixx, ixy, iyy, diagonal = (v.numpy() for v in out)
    return area, np.stack([cx, cy], axis=1), np.stack([ixx, ixy, iyy], axis=1), diagonal
