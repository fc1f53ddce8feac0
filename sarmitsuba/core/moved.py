"""Import paths from before the stage packages (docs/design.md section 0): they keep working.

Two kinds of old path:

- a former top-level module (``sarmitsuba.raw``) that now lives in a stage package
  (``sarmitsuba.core.raw``): :class:`MovedModuleFinder`, installed by ``import sarmitsuba``,
  imports it as the new module itself (the same object, so classes compare equal) with a
  DeprecationWarning that names the new path;
- a former module whose name a stage package took (``sarmitsuba.scene``,
  ``sarmitsuba.analysis``, ``sarmitsuba.products``): :func:`former_module_attributes` gives
  the package a module ``__getattr__`` that finds the old module's names in the module that
  holds them now (``sarmitsuba.scene.load_scene`` is ``sarmitsuba.scene.loader.load_scene``).
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings
from pathlib import Path
from typing import Any, Callable

__all__ = ["MOVED_MODULES", "TRACING", "STACKS", "MovedModuleFinder", "install", "former_module_attributes"]

PACKAGE = __name__.split(".")[0]

#: The tracing package's former flat modules -> their module in its parts (docs/design.md section 0).
#: Three took a part's name and cannot point anywhere else: ``tracing.visibility`` (now
#: ``tracing.visibility.rays``), ``tracing.integration`` (``tracing.integration.patch_terms``) and
#: ``tracing.deposit`` (``tracing.deposit.fast_time``).
TRACING: dict[str, str] = {
    f"tracing.{m}": f"tracing.{part}.{m}" for part, modules in (
        ("mesh", ("facets", "covers", "polygons", "polygon_kernels", "patches", "piece_cuts")),
        ("discovery", ("chains",)),
        ("visibility", ("lit_pieces", "occlusion", "motion", "motion_reference")),
        ("integration", ("term_lanes", "patch_reference", "edges", "edge_terms", "surface_clutter", "jones",
                         "polarimetry", "pulse_view", "physical_optics", "returns", "clutter_lattice", "clutter_terms")),
        ("deposit", ("accumulate",)),
        ("derivatives", ("tangents", "geometry_tangents", "lane_pairs")),
        ("driver", ("trace", "mesh_trace", "kernel", "launches", "stages", "threads", "distributed")))
    for m in modules}

#: The multi-pass modules that analysis once held -> their module in the stacks stage.
STACKS: dict[str, str] = {f"analysis.{m}": f"stacks.{m}" for m in (
    "interferometry", "insar_products", "along_track", "tomography", "tomo_sparse", "tomo_stack", "tomo_products")}

#: Former top-level modules -> their module in the stage packages.
MOVED_MODULES: dict[str, str] = {
    **{m: f"core.{m}" for m in ("constants", "arrays", "outputs", "georef", "radar", "raw", "image")},
    **{m: f"scene.{m}" for m in ("materials", "fresnel", "meshcheck", "canonical", "effects", "baseline",
                                 "planning", "trace_inputs")},
    "pyscene": "scene.builder",
    **{m: f"tracing.{m}" for m in ("_llvm", "_variant", "device")},
    "deposit": "tracing.deposit.fast_time",
    **{m: TRACING[f"tracing.{m}"] for m in ("accumulate", "physical_optics", "jones", "polarimetry", "facets",
                                            "clutter_lattice", "returns", "kernel", "trace", "distributed")},
    **TRACING,
    **{m: f"signal.{m}" for m in ("binning", "signal_model", "radiometry", "bandlimited")},
    **{m: f"products.{m}" for m in ("figures", "figures_point", "figures_pol", "figures_raw", "plotting", "preview",
                                    "groundtruth")},
    **{m: f"formats.{m}" for m in ("cphd", "sicd", "geotiff")},
    **{m: f"analysis.{m}" for m in ("impulse_model", "synthetic", "reference_cases", "cut_metrics", "cost")},
    "interferometry": "stacks.interferometry",
    **STACKS,
}


class MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports ``sarmitsuba.<old>`` as ``sarmitsuba.<MOVED_MODULES[old]>``, warning once per import."""

    def find_spec(self, fullname: str, path: Any = None, target: Any = None):
        """A spec for ``fullname`` when it names a moved module (``sarmitsuba.<old name>``), else
        None (the other finders then look for it)."""
        package, _, name = fullname.partition(".")
        if package != PACKAGE or name not in MOVED_MODULES:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        """None: the default module creation."""
        return None

    def exec_module(self, module) -> None:
        """Warn (DeprecationWarning) that the module moved, and put the new module in its place in
        ``sys.modules`` (the import returns the new module)."""
        new = f"{PACKAGE}.{MOVED_MODULES[module.__name__.partition('.')[2]]}"
        warnings.warn(f"{module.__name__} moved to {new} (docs/design.md section 0); import it from there",
                      DeprecationWarning, stacklevel=2)
        sys.modules[module.__name__] = importlib.import_module(new)   # the import returns the new module


def install() -> None:
    """Put one :class:`MovedModuleFinder` at the end of ``sys.meta_path`` (after the real modules)."""
    if not any(isinstance(finder, MovedModuleFinder) for finder in sys.meta_path):
        sys.meta_path.append(MovedModuleFinder())


def former_module_attributes(package: str, module: str) -> Callable[[str], Any]:
    """A module ``__getattr__`` for stage package ``package`` that looks a missing name up in its
    module ``module``, where the former module of the package's name now lives; a submodule's
    name is left to the import system (AttributeError, then the import).

    Raises
    ------
    AttributeError
        From the returned function, for a name neither the package nor ``module`` has.
    """
    folder = Path(sys.modules[package].__file__).parent

    def __getattr__(name: str) -> Any:
        if name.startswith("__") or (folder / f"{name}.py").exists():
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        try:
            return getattr(importlib.import_module(f"{package}.{module}"), name)
        except AttributeError:
            raise AttributeError(f"module {package!r} has no attribute {name!r}") from None

    return __getattr__
