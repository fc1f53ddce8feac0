"""Stage 4, focusing: range-compressed :class:`~sarmitsuba.core.raw.RawData` to a :class:`~sarmitsuba.core.image.SarImage`.

Stage: 4 (core -> scene -> tracing -> signal -> **focus** -> products -> formats -> stacks -> analysis).

Takes: ``RawData`` from :mod:`sarmitsuba.signal` (or any file honouring the contract,
docs/design.md section 3), and optionally the scene for its ground grid (:mod:`.scene_grid`).

Gives: a ``SarImage`` on a ground or slant grid, weighted and normalised as the render's own.

Physics: (S1)-(S3) signal model and backprojection; (A) antenna pattern; (K), (K2)
calibration and energy widths; (F1)-(F9) fast factorised backprojection; (PGA)-(PGA8) phase
gradient autofocus, on the pulses' echoes of point-like targets and from the clutter. docs/design.md
section 8; conventions and precision in docs/design.md section 5, validation targets in
section 9.

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
                                    precision, vectorised and threaded (the fast path);
                                    any track, stripmap and spotlight.
:func:`backproject_reference`       Plain float64 loop over pulses; the test oracle.
:func:`ffbp`                        Fast factorised backprojection (Ulander et al. 2003):
                                    sub-aperture polar images, then the grid; same options
                                    and normalisation as :func:`backproject`, any track
                                    (monostatic), interpolation error set by its knobs.
:func:`omega_k`                     Accurate omega-K with Stolt interpolation (straight track,
                                    squinted too; Cumming and Wong ch. 8).
:func:`range_doppler`               Range-Doppler with RCMC and optional SRC (ch. 6).
==================================  =========================================================

Phase gradient autofocus
------------------------
==================================  =========================================================
:mod:`.autofocus`                   ``pga``: PGA of a focused image (PGA)-(PGA5).
:mod:`.autofocus_pulses`            ``pga_focus``: the rounds through the pulses (PGA6).
:mod:`.pga_kernel`                  Wahl's kernel: centre, window, gradient, iterate (PGA).
:mod:`.pga_lines`                   Which range lines PGA learns from (PGA3), (PGA4).
:mod:`.pga_deramp`                  The deramp of a backprojected image (PGA2).
:mod:`.pga_pulses`                  The pulses' echoes read at the targets (PGA7).
:mod:`.pga_clutter`                 The error read from every range bin of the clutter (PGA8).
==================================  =========================================================

One call
--------
:func:`focus` (also ``sarmitsuba.refocus``) focuses any RawData with a named algorithm
(:data:`ALGORITHMS`), on the scene's ground grid when the metadata record it, as the ``focus``
command does (:mod:`sarmitsuba.focus.dispatch`).

Range processing and geometry
-----------------------------
==================================  =========================================================
:func:`range_compress`              Matched filter of chirped raw data, with a window.
:func:`apply_range_window`          Window compressed data over the band.
:func:`stripmap_geometry`           Straight-track geometry, Doppler centroid, checks.
:func:`slant_output_grid`           The slant-plane grid of the FFT focusers.
==================================  =========================================================
"""
from .backprojection import backproject, backproject_reference
from .dispatch import ALGORITHMS, focus
from .ffbp import ffbp
from .grid import ImageGrid
from .omegak import omega_k
from .range_compression import apply_range_window, range_compress
from .rda import range_doppler
from .stripmap import StripmapGeometry, slant_output_grid, stripmap_geometry

__all__ = ["focus", "ALGORITHMS", "ImageGrid", "backproject", "backproject_reference", "ffbp", "omega_k", "range_doppler", "range_compress",
           "apply_range_window", "StripmapGeometry", "stripmap_geometry", "slant_output_grid"]

