"""Stage 7, analysis: measuring images against closed forms, oracles and each other.

Stage: 7 (core -> scene -> tracing -> signal -> focus -> products -> formats -> **analysis**),
the last stage before the entry points (``api``, ``cli``, ``pipeline``, ``info``).

Takes: ``SarImage`` and ``RawData`` (in memory, npz or SICD), scenes and sensors for the cost
model.

Gives: point-target reports (IRW, PSLR, ISLR, RCS), analytic raw data that every focuser is
tested against, interferograms, coherence and heights, and the cost of a render before it runs.

=======================  ===============================================================
:mod:`.point_target`     point-target analysis (IRW, PSLR, ISLR, integrated RCS)
:mod:`.cut_metrics`      peak and 1-D cuts of a band-limited chip
:mod:`.impulse_model`    the impulse response a backprojected image should have
:mod:`.synthetic`        analytic point-target raw data: the focusers' oracle
:mod:`.reference_cases`  the standard stripmap point-target acquisitions
:mod:`.interferometry`   interferogram, coherence, height of two renders
:mod:`.cost`             rays, time and memory of a render, estimated without tracing
:mod:`.bistatic`         bistatic angle, bisector and ground-range resolution
:mod:`.along_track`      along-track interferogram and DPCA image of two channels
=======================  ===============================================================

Physics: (K), (K2) calibration and energy widths; (S2)-(S3) the oracle's echo and
backprojection; (I1)-(I4) interferometry; (NESZ); (B4) bistatic resolution;
(V6)-(V7) along-track interferometry.

``from sarmitsuba.analysis import analyze_point_target`` and the other names of the former module
``sarmitsuba.analysis`` are looked up in :mod:`.point_target`.
"""


from ..core.moved import former_module_attributes as _former_module_attributes

__getattr__ = _former_module_attributes(__name__, "point_target")
