"""sarmitsuba: ray-traced synthetic aperture radar simulation of urban scenes on Mitsuba 3 / Dr.Jit.

Importing the package finds a libLLVM >= 16 for Dr.Jit's LLVM backend, sets the Mitsuba
variant (``llvm_ad_mono``) and registers the plugins (``sar`` sensor, ``sbr`` integrator,
``radar`` and ``itu-radio-material`` BSDFs).

Pipeline (docs/design.md section 2), one module per stage:

=====================  ====================================================================
stage                  module / main entry points
=====================  ====================================================================
scene                  :mod:`~sarmitsuba.scene` -- ``load_scene``; :mod:`~sarmitsuba.radar`
                       -- ``RadarParameters``, ``acquisition_geometry``;
                       :mod:`~sarmitsuba.materials` -- ITU-R P.2040, Fresnel, slab
plan                   :mod:`~sarmitsuba.planning` -- fast-time window, ray footprint
trace                  :mod:`~sarmitsuba.trace` -- ``trace`` (Dr.Jit SBR + PO kernel)
raw data               :mod:`~sarmitsuba.binning` -- ``to_raw_data``; :mod:`~sarmitsuba.raw`
                       -- ``RawData``
focus                  :mod:`~sarmitsuba.focus` -- ``backproject``, ``ImageGrid``;
                       :mod:`~sarmitsuba.image` -- ``SarImage``
                       :func:`~sarmitsuba.focus.omega_k`, :func:`~sarmitsuba.focus.range_doppler`
radiometry             :mod:`~sarmitsuba.radiometry` -- radar equation, noise, calibration
products               :mod:`~sarmitsuba.products` -- EXR, PNG quicklook;
                       :mod:`~sarmitsuba.figures` -- explanatory figures from saved files;
                       :mod:`~sarmitsuba.groundtruth` -- layover/shadow masks from the scene;
                       :mod:`~sarmitsuba.preview` -- optical preview of scene and acquisition
analysis               :mod:`~sarmitsuba.analysis` -- point-target analysis;
                       :mod:`~sarmitsuba.synthetic` -- analytic point targets;
                       :mod:`~sarmitsuba.reference_cases` -- standard stripmap point-target acquisitions;
                       :mod:`~sarmitsuba.canonical` -- canonical radar targets
checks                 :mod:`~sarmitsuba.meshcheck` -- mesh defect warnings;
                       :mod:`~sarmitsuba.effects` -- which optional effects a run simulates, and why;
                       :mod:`~sarmitsuba.info` -- ``info``: radar summary and cost estimate, no tracing
orchestration          :mod:`~sarmitsuba.pipeline` -- ``simulate``, ``render``, ``refocus``;
                       :mod:`~sarmitsuba.cli`
=====================  ====================================================================
"""
from ._variant import activate as _activate

__version__ = "0.1.0"

VARIANT = _activate()

__all__ = ["VARIANT", "__version__"]
