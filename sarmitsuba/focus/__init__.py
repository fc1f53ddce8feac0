"""Focusing stage: range-compressed :class:`~sarmitsuba.raw.RawData` to a :class:`~sarmitsuba.image.SarImage`.

DESIGN.md section 8; conventions, precision and validation targets in
``../shared/notes/focusing.md``.

Grids
-----
=========================  ==================================================================
:class:`ImageGrid`         Pixel lattice (origin, two unit directions, axes in metres, plane).
:meth:`ImageGrid.ground`   Horizontal grid centred on a point: rows along track, columns in
                           ground range away from the sensor.
=========================  ==================================================================

Algorithms
----------
==================================  =========================================================
:func:`backproject`                 Time-domain backprojection, hybrid float64/float32
                                    precision, vectorised and threaded (the fast path).
:func:`backproject_reference`       Plain float64 loop over pulses; the test oracle.
==================================  =========================================================
"""
from .backprojection import backproject, backproject_reference
from .grid import ImageGrid

__all__ = ["ImageGrid", "backproject", "backproject_reference"]
