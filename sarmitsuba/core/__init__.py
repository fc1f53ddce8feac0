"""The foundation every stage stands on: constants, array checks, all-or-nothing files, and the contracts.

Stage: 0, before the pipeline (core -> scene -> tracing -> signal -> focus -> products ->
formats -> stacks -> analysis). Every stage may import it; it imports no stage.

Takes: nothing from the other stages.

Gives: the three records that pass between stages (frozen dataclasses, docs/design.md
section 3), and the primitives they are built from:

=======================  ===============================================================
:mod:`.radar`            ``RadarParameters``: the sensor and platform, every stage's input;
                         ``acquisition_geometry``: antenna positions per pulse
:mod:`.sensor_checks`    the checks a new ``RadarParameters`` runs, the named values' choices
:mod:`.raw`              ``RawData``: range-compressed echoes, the tracer's output and the
                         focusers' input (``raw.npz``)
:mod:`.image`            ``SarImage``: a focused image on its grid (``image.npz``)
:mod:`.georef`           ``GeoReference``: the scene's local ENU frame on the WGS84 ellipsoid
:mod:`.outputs`          output directories that are written whole or not at all
:mod:`.arrays`           the array checks of every frozen dataclass
:mod:`.constants`        physical constants with their sources
=======================  ===============================================================

Physics: (S1) (the carrier phase RawData's samples carry), (GEO1) (local frame to ECEF).
"""
