"""Stage 3, the signal: the tracer's returns become raw data, with the receiver and radiometry.

Stage: 3 (core -> scene -> tracing -> **signal** -> focus -> products -> formats -> stacks -> analysis).

Takes: a ``TraceResult`` from :mod:`sarmitsuba.tracing` and the scene's ``RadarParameters``.

Gives: ``RawData`` (:mod:`sarmitsuba.core.raw`): range-compressed (or chirped) echoes on the
fast-time x slow-time grid, in normalised or absolute units, with thermal noise when the
sensor asks for it.

=======================  ===============================================================
:mod:`.binning`          ``to_raw_data``: spectra to samples, absolute scaling, noise
:mod:`.signal_model`     the chirp's spectrum and the receiver's response
:mod:`.radiometry`       thermal noise, image calibration, effective pulses
:mod:`.bandlimited`      exact band-limited (DFT) interpolation
=======================  ===============================================================

Physics: (S1)-(S2) signal model; (R4) thermal noise; (K) image calibration; (D1)-(D5)
deposit grid to samples.
"""
