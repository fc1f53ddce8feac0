"""Stage 5, products: the image files and figures a render writes, and the scene's ground truth.

Stage: 5 (core -> scene -> tracing -> signal -> focus -> **products** -> formats -> stacks -> analysis).

Takes: a ``SarImage`` (and ``RawData`` for the raw figure) from the earlier stages, or the
saved ``raw.npz``/``image.npz``; the scene for ground truth and preview.

Gives: files: OpenEXR and PNG images, explanatory figures, Pauli RGB, the optical preview,
layover/shadow/double-bounce masks.

=======================  ===============================================================
:mod:`.image_files`      OpenEXR channels and PNG quicklooks
:mod:`.figures`          figures from saved files (:mod:`.figures_raw`, :mod:`.figures_point`)
:mod:`.figures_pol`      the Pauli RGB of a quad-pol set
:mod:`.groundtruth`      layover, shadow, footprints and double-bounce lines from the scene
:mod:`.preview`          optical preview of scene and acquisition, before tracing
:mod:`.plotting`         dB scale, multilooks, axes: the display conventions
=======================  ===============================================================

Physics: (G1)-(G3) of "Geometry of the image" (double bounce, layover, shadow); (P5) Pauli
basis.

``sarmitsuba.products.write_exr`` and the other names of the former module
``sarmitsuba.products`` are looked up in :mod:`.image_files`.
"""


from ..core.moved import former_module_attributes as _former_module_attributes

__getattr__ = _former_module_attributes(__name__, "image_files")
