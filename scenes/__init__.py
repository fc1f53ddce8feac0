"""Built-in scenes of sarmitsuba (installed as ``sarmitsuba_scenes``; data only).

=============  ===========================================================================
name           what it holds
=============  ===========================================================================
``urban``      the default: concrete ground, buildings of different heights, one tall
               tower, a long brick wall facing the sensor
``dihedral``   a metal wall standing on a metal ground plate, fold line along x
``trihedral``  a triangular metal trihedral corner reflector on absorbing-free open space
=============  ===========================================================================

Every scene has a ``sar`` sensor (X-band, 45 degrees incidence) and an ``sbr`` integrator;
frame: z up, the sensor on the +y side looking toward -y.
"""
