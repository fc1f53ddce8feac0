"""The one place where the Dr.Jit/Mitsuba variant is chosen and the plugins are registered.

Importing :mod:`sarmitsuba` calls :func:`activate`: it finds a working libLLVM (see
:mod:`sarmitsuba.tracing._llvm`) before Dr.Jit is imported, sets the variant (``llvm_ad_mono`` by
default, ``SARMITSUBA_VARIANT`` to override, e.g. ``cuda_ad_mono``), and imports the
plugin modules of :mod:`sarmitsuba_plugins`, which register themselves for that variant.
A later ``mi.set_variant(...)`` re-registers them through a variant callback.
"""
from __future__ import annotations

import importlib
import os

DEFAULT_VARIANT = "llvm_ad_mono"


class VariantError(ImportError):
    """``SARMITSUBA_VARIANT`` names no usable variant (unknown, not ``*_mono``, or CUDA without a GPU)."""


def activate() -> str:
    """Set the variant and register the plugins; returns the variant name. Idempotent."""
    variant = os.environ.get("SARMITSUBA_VARIANT", DEFAULT_VARIANT)
    if variant.startswith("llvm"):
        from ._llvm import ensure_libllvm
        ensure_libllvm()
    import mitsuba as mi

    if mi.variant() is None:
        _set(mi, variant)
    if not mi.variant().endswith("_mono"):
        raise RuntimeError(
            f"sarmitsuba needs a *_mono Mitsuba variant, but {mi.variant()!r} is active "
            "(was sionna imported first? keep Sionna RT out of the simulator process)")
    mi.set_log_level(mi.LogLevel.Warn)
    _fit_threads_to_affinity()
    _register_plugins(reload=False)
    if not getattr(_register_on_change, "installed", False):
        mi.detail.add_variant_callback(_register_on_change)
        _register_on_change.installed = True
    return mi.variant()


def _fit_threads_to_affinity() -> None:
    """Dr.Jit's threads at most the cores this process may run on (``taskset``; Dr.Jit counts the
    machine's): two threads on one core traced Munich's 512 central pulses in 47.8 s, one in 37.0 s."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return
    import drjit as dr
    if 0 < cores < dr.thread_count():
        dr.set_thread_count(cores)


def _register_on_change(old: str | None, new: str | None) -> None:
    if new is not None and new.endswith("_mono"):
        _register_plugins(reload=True)


def _register_plugins(reload: bool) -> None:
    import sarmitsuba_plugins

    for name in sarmitsuba_plugins.MODULES:
        module_name = f"sarmitsuba_plugins.{name}"
        module = importlib.import_module(module_name)
        if reload:
            importlib.reload(module)


def _set(mi, variant: str) -> None:
    """``mi.set_variant(variant)``, or VariantError saying what ``SARMITSUBA_VARIANT`` may be."""
    usable = [v for v in mi.variants() if v.endswith("_mono")]
    if variant not in usable:
        raise VariantError(f"SARMITSUBA_VARIANT = {variant!r} is not a usable variant of this Mitsuba build; "
                           f"valid: {', '.join(usable)} (unset it for {DEFAULT_VARIANT!r}, the CPU)")
    try:
        mi.set_variant(variant)
    except (ImportError, RuntimeError) as exc:
        raise VariantError(f"SARMITSUBA_VARIANT = {variant!r} cannot start on this machine ({exc}); a cuda variant "
                           f"needs an NVIDIA GPU and driver: unset it for {DEFAULT_VARIANT!r}, the CPU") from None
