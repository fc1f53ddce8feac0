"""sarmitsuba: ray-traced synthetic aperture radar simulation of urban scenes on Mitsuba 3 / Dr.Jit.

Importing the package finds a libLLVM >= 16 for Dr.Jit's LLVM backend, sets the Mitsuba
variant (``llvm_ad_mono``) and registers the plugins (``sar`` sensor, ``sbr`` integrator,
``radar`` and ``itu-radio-material`` BSDFs).

Python API: the command line's steps, one call each (imported on first use, so ``import
sarmitsuba`` stays as cheap as the variant set-up)::

    import sarmitsuba
    sim = sarmitsuba.simulate("trihedral")                         # in memory: sim.raw, sim.image
    summary = sarmitsuba.render("trihedral", "out/trihedral")      # files
    image = sarmitsuba.refocus(sim.raw, "omegak")                  # any RawData
    report = sarmitsuba.analyze(sim.image, (0.0, 0.0, 0.0))        # point target at the apex

===============================  =====================================================================
name                             what it is
===============================  =====================================================================
``simulate(scene, ...)``         :func:`sarmitsuba.pipeline.simulate`: load, trace, bin and focus in
                                 memory; returns a ``Simulation`` (``.raw``, ``.image``, ...)
``render(scene, out_dir, ...)``  :func:`sarmitsuba.pipeline.render`: the same, writing raw.npz,
                                 image.npz/.exr/.png and summary.json
``refocus(raw, algorithm)``      :func:`sarmitsuba.pipeline.refocus`: focus any RawData with ``bp``,
                                 ``ffbp``, ``omegak`` or ``rda`` (the ``focus`` command)
``focus``                        the focusing subpackage (:mod:`sarmitsuba.focus`: ``backproject``,
                                 ``ffbp``, ``omega_k``, ...); ``sarmitsuba.focus.focus(raw, ...)`` is
                                 ``refocus``
``analyze(image, target)``       :func:`sarmitsuba.api.analyze`: point-target report (IRW, PSLR,
                                 ISLR, RCS) of a SarImage or image.npz (the ``analyze`` command)
``Scene(meshes, sensor, ...)``   :class:`sarmitsuba.scene.builder.Scene`: a scene built in Python from
                                 trimesh meshes and materials, accepted wherever a scene path is
``gradients(scene, loss, [p])``  :func:`sarmitsuba.derivatives.gradients`: a loss on the image and its
                                 gradient with respect to material parameters (reverse mode)
===============================  =====================================================================

``scene`` is an XML path, a built-in name (``urban``, ``dihedral``, ``trihedral``),
``sionna:NAME`` or a :class:`Scene`. Why ``refocus`` and not ``focus``: ``sarmitsuba.focus``
is the focusing subpackage, and importing it rebinds the package attribute ``focus`` to it,
so a top-level function of that name would be replaced by the module as soon as any code
imports ``sarmitsuba.focus``; the subpackage therefore keeps the name and offers the entry
as ``sarmitsuba.focus.focus``, and the top level as ``refocus``.

Pipeline (docs/design.md section 0): one package per stage, each importing only the ones
before it (``tests/test_architecture.py``):

=====================  =====================================================================
package                stage: main entry points
=====================  =====================================================================
:mod:`~.core`          the contracts every stage sees: ``RadarParameters``, ``RawData``,
                       ``SarImage``, ``GeoReference``; constants, all-or-nothing files
:mod:`~.scene`         1 scene: ``load_scene``, ``Scene``, materials, effects, planning
:mod:`~.tracing`       2 tracing: ``trace`` (Dr.Jit SBR + PO kernel), Dask distribution
:mod:`~.signal`        3 raw data: ``to_raw_data``, signal model, radiometry
:mod:`~.focus`         4 focusing: ``backproject``, ``ffbp``, ``omega_k``, ``range_doppler``
:mod:`~.products`      5 products: EXR/PNG, figures, ground truth, preview
:mod:`~.formats`       6 standard formats: CPHD, SICD, GeoTIFF
:mod:`~.analysis`      7 analysis: point targets, oracles, interferometry, cost model
``pipeline``, ``api``  entry points: ``simulate``, ``render``, ``refocus``, ``analyze``;
``info``, ``cli``      ``sarmitsuba info`` and the command line
=====================  =====================================================================

Modules that sat at the top level before the stage packages (``sarmitsuba.raw``,
``sarmitsuba.image``, ``sarmitsuba.radar``, ...) still import, from their new place
(:data:`MOVED_MODULES`), with a DeprecationWarning that names it.
"""
import importlib as _importlib
import os as _os
import signal as _signal
import sys as _sys


def _interrupted_while_starting(signum, frame) -> None:
    """SIGINT handler of the command line until it runs a command: Ctrl-C while the package and
    Mitsuba import exits at once with the command line's one line and code 130. Raising
    KeyboardInterrupt there instead printed tracebacks, or surfaced as an ImportError or
    SystemError from the extension being loaded (read as "needs an NVIDIA GPU"); nothing has been
    written yet, so there is nothing to clean up. :func:`sarmitsuba.cli.main` takes over for the
    command itself."""
    _os.write(2, b"interrupted: no output file was left half-written\n")
    _os._exit(130)


def _run_as_command() -> bool:
    """Whether this process is sarmitsuba's command line (``python [options] -m sarmitsuba`` or the
    ``sarmitsuba`` script), not another program importing the package: ``sys.argv[0]`` is ``-m``
    while any ``-m`` package imports, so the interpreter's own arguments decide."""
    original = list(getattr(_sys, "orig_argv", []))
    if "-m" in original[:-1] and original[original.index("-m") + 1] == "sarmitsuba":
        return True
    return _sys.argv[0].endswith(("/sarmitsuba", "sarmitsuba/__main__.py"))


if _run_as_command() and _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler:
    _signal.signal(_signal.SIGINT, _interrupted_while_starting)

from .core.moved import MOVED_MODULES
from .core.moved import install as _install_moved_modules
from .tracing._variant import VariantError as _VariantError
from .tracing._variant import activate as _activate

__version__ = "0.1.0"

#: Why the variant could not start (``SARMITSUBA_VARIANT`` unusable, libLLVM missing), when the
#: package was imported by the command line; None otherwise. The command line still answers
#: ``--help`` and ``--version``, and reports this error (exit 2) before any other command.
STARTUP_ERROR: Exception | None = None
try:
    VARIANT = _activate()
except (_VariantError, RuntimeError) as _error:
    if not _run_as_command():
        raise                                              # a library import: the caller sees the exception
    VARIANT, STARTUP_ERROR = None, _error

#: Top-level names imported on first use: name -> (module, attribute; None for the module itself).
_LAZY = {"simulate": ("pipeline", "simulate"), "render": ("pipeline", "render"),
         "refocus": ("pipeline", "refocus"), "analyze": ("api", "analyze"), "Scene": ("scene.builder", "Scene"),
         "focus": ("focus", None), "gradients": ("derivatives", "gradients")}

__all__ = ["VARIANT", "__version__", "simulate", "render", "refocus", "focus", "analyze", "Scene", "gradients"]


_install_moved_modules()


def __getattr__(name: str):
    if name not in _LAZY:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module_name, attribute = _LAZY[name]
    module = _importlib.import_module(f".{module_name}", __name__)
    value = module if attribute is None else getattr(module, attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
