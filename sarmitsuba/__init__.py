"""sarmitsuba: ray-traced synthetic aperture radar simulation of urban scenes on Mitsuba 3 / Dr.Jit.

Importing the package finds a libLLVM >= 16 for Dr.Jit's LLVM backend, sets the Mitsuba
variant (``llvm_ad_mono``) and registers the plugins (``sar`` sensor, ``sbr`` integrator,
``radar`` and ``itu-radio-material`` BSDFs).

Pipeline (DESIGN.md section 2), one module per stage:

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
products               :mod:`~sarmitsuba.products` -- EXR, PNG quicklook
orchestration          :mod:`~sarmitsuba.pipeline` -- ``render``; :mod:`~sarmitsuba.cli`
=====================  ====================================================================
"""
from ._variant import activate as _activate

__version__ = "0.1.0"

VARIANT = _activate()

__all__ = ["VARIANT", "__version__"]
