"""Every public name of the package has a docstring: the functions and classes each module lists
in ``__all__``, and the public methods and properties of those classes (the API reference is
generated from them). A name added to ``__all__`` without one fails here, naming it."""
from __future__ import annotations

import importlib
import inspect
import pkgutil

import sarmitsuba


def _public_modules():
    for info in pkgutil.walk_packages(sarmitsuba.__path__, "sarmitsuba."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            yield importlib.import_module(info.name)


def _undocumented(obj) -> bool:
    """No docstring of its own: none, blank, or the signature a dataclass writes in its place
    (``inspect.getdoc`` would fall back to a base class's)."""
    doc = (obj.__doc__ or "").strip()
    return not doc or (inspect.isclass(obj) and doc.startswith(f"{obj.__name__}("))


def _members(cls):
    """Public methods and properties defined on ``cls`` itself (inherited ones are documented where
    they are defined)."""
    for name, value in vars(cls).items():
        if name.startswith("_"):
            continue
        function = value.fget if isinstance(value, property) else getattr(value, "__func__", value)
        if inspect.isfunction(function):
            yield name, function


def public_objects() -> dict[str, object]:
    """``{"module.name": object}`` of every public function and class, under the module that
    defines it (a name re-exported by a package is listed once, where it is defined: a
    function public at the top level, ``sarmitsuba.refocus``, is public where it is defined
    even if that module's ``__all__`` forgot it)."""
    found = {}
    for module in _public_modules():
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name, None)
            if (inspect.isfunction(obj) or inspect.isclass(obj)) and obj.__module__.startswith("sarmitsuba"):
                found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


def undocumented_names() -> list[str]:
    """``module.name`` (or ``module.Class.member``) of every public function, class, method and
    property without a docstring of its own."""
    missing = []
    for module in _public_modules():
        if not (module.__doc__ or "").strip():
            missing.append(f"{module.__name__} (module)")
        for name in getattr(module, "__all__", ()):
            obj = getattr(module, name, None)
            if not (inspect.isfunction(obj) or inspect.isclass(obj)) or obj.__module__ != module.__name__:
                continue                       # constants, and names re-exported from their own module
            if _undocumented(obj):
                missing.append(f"{module.__name__}.{name}")
            if inspect.isclass(obj):
                missing += [f"{module.__name__}.{name}.{member}" for member, function in _members(obj)
                            if not (function.__doc__ or "").strip()]
    return missing


def test_every_public_name_has_a_docstring():
    assert undocumented_names() == []


def test_the_check_finds_a_public_function_without_one(monkeypatch):
    """The check itself: a public function whose docstring is removed is named."""
    from sarmitsuba.focus import ffbp_plan
    monkeypatch.setattr(ffbp_plan.subaperture_spans, "__doc__", None)
    assert "sarmitsuba.focus.ffbp_plan.subaperture_spans" in undocumented_names()


def test_the_check_finds_a_dataclass_without_one(monkeypatch):
    """A dataclass without a docstring gets its signature as ``__doc__``: that is not documentation."""
    from sarmitsuba.core import raw
    monkeypatch.setattr(raw.RawData, "__doc__", "RawData(data: numpy.ndarray, ...)")
    assert "sarmitsuba.core.raw.RawData" in undocumented_names()


def test_the_check_finds_a_method_without_one(monkeypatch):
    from sarmitsuba.tracing.visibility import rays
    monkeypatch.setattr(rays.CastCounter.add, "__doc__", None)
    assert "sarmitsuba.tracing.visibility.rays.CastCounter.add" in undocumented_names()
