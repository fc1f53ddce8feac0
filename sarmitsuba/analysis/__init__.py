"""Stage 8, analysis: measuring images against closed forms, oracles and each other.

Stage: 8 (core -> scene -> tracing -> signal -> focus -> products -> formats -> stacks -> **analysis**),
the last stage before the entry points (``api``, ``cli``, ``pipeline``, ``info``).

Takes: ``SarImage`` and ``RawData`` (in memory, npz or SICD), scenes and sensors for the cost
model.

Gives: point-target reports (IRW, PSLR, ISLR, RCS), analytic raw data that every focuser is
tested against, and the cost of a render before it runs. Interferometry and tomography, which
process two or more images of one scene, are the stage before: :mod:`sarmitsuba.stacks`.

=======================  ===============================================================
:mod:`.point_target`     point-target analysis (IRW, PSLR, ISLR, integrated RCS)
:mod:`.cut_metrics`      peak and 1-D cuts of a band-limited chip
:mod:`.impulse_model`    the impulse response a backprojected image should have
:mod:`.synthetic`        analytic point-target raw data: the focusers' oracle
:mod:`.reference_cases`  the standard stripmap point-target acquisitions
:mod:`.cost`             rays, time and memory of a render, estimated without tracing
:mod:`.memory`           whether a render fits in memory, checked before tracing
:mod:`.bistatic`         bistatic angle, bisector and ground-range resolution
:mod:`.ambiguities`      azimuth and range ambiguity-to-signal ratios (AASR, RASR)
:mod:`.orders`           each bounce order's share of a render's energy, the depth warning
:mod:`.reach`            the mesh tracer's work per sub-aperture, for the cost model
=======================  ===============================================================

Physics: (K), (K2) calibration and energy widths; (S2)-(S3) the oracle's echo and
backprojection; (NESZ); (B4) bistatic resolution.

``from sarmitsuba.analysis import analyze_point_target`` and the other names of the former module
``sarmitsuba.analysis`` are looked up in :mod:`.point_target`.
"""


from ..core.moved import former_module_attributes as _former_module_attributes

__getattr__ = _former_module_attributes(__name__, "point_target")
