"""Mitsuba plugins of sarmitsuba, installed as the ``sarmitsuba_plugins`` package.

==========================  ===========  =====================================================
plugin name                 type         module
==========================  ===========  =====================================================
``sar``                     sensor       :mod:`sarmitsuba_plugins.sar_sensor`
``sbr``                     integrator   :mod:`sarmitsuba_plugins.sbr_integrator`
``radar``                   bsdf         :mod:`sarmitsuba_plugins.radar_material`
``itu-radio-material``      bsdf         :mod:`sarmitsuba_plugins.radar_material` (Sionna RT scenes)
==========================  ===========  =====================================================

Each module registers its plugin at import time for the Mitsuba variant that is active
then; :mod:`sarmitsuba.tracing._variant` imports (and on a variant change reloads) them. Do not
import these modules before a variant is set.
"""

#: Plugin modules, in registration order.
MODULES = ("sar_sensor", "sbr_integrator", "radar_material")
