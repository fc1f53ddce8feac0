"""Where returns are summed: the fine fast-time grid, and how it becomes a band-limited spectrum.

Takes: each term's pulse, two-way length relative to the pulse's reference length [m], complex
amplitude and polarimetric channel.

Gives: per pulse the spectrum of the path sum over the sampling band
(:func:`~.fast_time.reduce_deposit`), or the ``exact`` range kernel's path list.

==========================  ===============================================================
:mod:`.fast_time`           the deposit kernel and its reduction to a spectrum
:mod:`.accumulate`          one histogram or path list per polarimetric channel
==========================  ===============================================================

Physics: docs/physics.md (D1)-(D5), (P4).
"""
