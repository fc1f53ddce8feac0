"""Stage 7, stacks: two or more focused images of one scene processed together.

Stage: 7 (core -> scene -> tracing -> signal -> focus -> products -> formats -> **stacks** ->
analysis). A pair of passes gives an interferogram, a pair of channels of one pass an
along-track interferogram, a stack of passes a tomogram. Measuring images against closed forms
is the stage after, :mod:`sarmitsuba.analysis`; rendering the passes of a stack is the entry
point :mod:`sarmitsuba.stack`.

Takes: ``SarImage`` and ``RawData`` of passes focused on one ground grid (in memory, or render
folders and stack folders on disk), and their ``Baseline`` (:mod:`sarmitsuba.scene.baseline`).

Gives: interferograms, coherence and heights; along-track interferograms and DPCA images;
elevation profiles, scatterers and point clouds, with the files and figures of each.

=======================  ===============================================================
:mod:`.interferometry`   interferogram, coherence, height of two renders
:mod:`.insar_products`   reading two renders, writing the interferometry products
:mod:`.along_track`      along-track interferogram and DPCA image of two channels
:mod:`.tomography`       the stack's phase model, beamforming, Capon, calibration, peaks
:mod:`.tomo_sparse`      SL1MMER, the sparse inversion of few scatterers per cell
:mod:`.tomo_pixels`      the pixels a tomographic inversion uses: window, clutter level
:mod:`.tomo_stack`       tomographic focusing of a stack in memory (``focus_elevation``)
:mod:`.tomo_products`    the tomography command's files: profiles, scatterers, point cloud
=======================  ===============================================================

Physics: (I1)-(I4) interferometry; (V6)-(V7) along-track interferometry; (TS1)-(TS7)
tomography.
"""
