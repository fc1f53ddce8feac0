"""Reverse mode by replay: each pulse's terms differentiated where they are evaluated, with the
loss's gradient at hand (docs/physics.md (AD3)).

The values of a launch's terms are deposited into its fine histogram ``h`` by a scatter-add
(:meth:`~.accumulate.Accumulator.deposit`). Given the loss's gradient ``g = B^H G`` with respect to
that histogram, ``dL = <g, dh>`` is a sum over the terms: each term ``v`` deposited with tap
weights ``w_b`` at bins ``b`` adds ``sum_b w_b (g_re,b Re v + g_im,b Im v)``. The replay evaluates
every pulse's terms again inside the kernels' pulse loop and, in the same loop iteration, gathers
``g`` where the deposit would have scattered, forms that sum and propagates it backward to the
lane inputs (Dr.Jit's ``backward_from`` inside the loop body, as Mitsuba's path replay does):
the derivative of the weights ``w_b`` (the range position moving) and of ``v`` both follow. The
lane inputs are read through gathers from detached leaves, so the backward pass adds into the
leaves' gradients with scatter-adds; nothing of an iteration's graph outlives it, and the loop
stays one symbolic kernel. The area terms' sum over a piece's boundary, a loop of its own in a
plain trace (M5), is unrolled to the upload's longest boundary: Dr.Jit 1.5 does not reverse a
symbolic loop nested in a symbolic loop on the LLVM backend (measured: invalid code with the
trajectory or sum-loop hints, zero gradients of the inner loop's invariants), and an evaluated
pulse loop cost 8,000 kernel launches, 2.5 s of urban's 64 pulses.

After the loop, what each leaf received is carried to the array it was detached from (a table
lookup, an earlier bounce's reflection factor), one backward pass per upload.

:func:`run_pulses` is the pulse loop of the term and scatterer kernels, plain or replayed;
:func:`replaying` says which.
"""
from __future__ import annotations

import dataclasses

import drjit as dr
import mitsuba as mi

from ..loops import loop_mode
from .adjoint import AdjointSink, read

__all__ = ["replaying", "run_pulses", "carry", "shared_read"]


def replaying(ctx: dict) -> bool:
    """Whether the launch of context ``ctx`` replays its terms against a seed (the histogram's
    gradient, ``ctx["seed"]``) rather than depositing them."""
    return ctx.get("seed") is not None


def _rebuilt(x, leaf):
    """``x`` (a dict, list, tuple, dataclass or Dr.Jit array) with ``leaf(array)`` in place of each
    floating-point Dr.Jit array that carries derivatives."""
    if isinstance(x, dict):
        return {key: _rebuilt(value, leaf) for key, value in x.items()}
    if isinstance(x, (list, tuple)):
        return type(x)(_rebuilt(value, leaf) for value in x)
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return dataclasses.replace(x, **{f.name: _rebuilt(getattr(x, f.name), leaf) for f in dataclasses.fields(x)})
    if dr.is_array_v(x) and dr.is_float_v(x) and dr.grad_enabled(x):
        return leaf(x)
    return x


def carry(pairs: list) -> None:
    """For each ``(leaf, source)``: add ``dL/d leaf`` (its gradient now) to ``source``'s and carry it
    on to what ``source`` was computed from, in one backward traversal. The leaves' gradients
    are read, not cleared."""
    if not pairs:
        return
    for leaf, source in pairs:
        dr.accum_grad(source, dr.grad(leaf))
        dr.enqueue(dr.ADMode.Backward, source)
    # not ADFlag.ClearInput: a source that is itself a leaf (a geometric lane input) keeps what it got
    dr.traverse(dr.ADMode.Backward, flags=dr.ADFlag.ClearEdges | dr.ADFlag.ClearInterior | dr.ADFlag.AllowNoGrad)


def run_pulses(ctx: dict, data: dict, count, pulse, label: str, shared=()) -> None:
    """Run ``pulse(data, q)`` for the pulses ``q < count`` of every lane (``count`` mi.UInt32, one
    per lane): a Dr.Jit loop of ``label``, plain (``loop_mode()``) or, while :func:`replaying`,
    replayed (module docstring).

    Parameters
    ----------
    ctx : dict
        The launch's context; while replaying, ``ctx["adjoint"]`` is the iteration's sum that
        :meth:`~.accumulate.Accumulator.deposit` adds its terms' share of ``dL`` to.
    data : dict
        The upload: Dr.Jit arrays by name, one entry per lane except the names in ``shared``
        (per piece or per segment, read by gathers).
    count : mi.UInt32
        Each lane's pulses.
    pulse : callable
        ``pulse(data, q)``: one pulse's terms of every lane, deposited (while replaying, ``data``
        has ``"replayed": True``: an inner loop of the terms, a sum over a piece's boundary, is
        then unrolled).
    label : str
        The loop's name in Dr.Jit's kernel history.
    shared : iterable of str
        The entries of ``data`` that are not per lane.
    """
    if not replaying(ctx):
        dr.while_loop((mi.UInt32(0),), lambda q: q < count, lambda q: (pulse(data, q), q + 1)[1:],
                      mode=loop_mode(), label=label)
        return
    pairs = []

    def detached(x):
        leaf = dr.detach(x)
        dr.enable_grad(leaf)
        pairs.append((leaf, x))
        return leaf
    leaves = _rebuilt(data, detached)
    n = dr.width(count)
    lane, first = dr.arange(mi.UInt32, n), dr.zeros(mi.UInt32, n)
    # entries many lanes read: their adjoints are summed in fixed point (D7), in a sink each
    sinks, constants = {key: _sinks(leaves[key]) for key in shared if key in leaves}, {}

    def constant(x):
        if dr.width(x) != n:
            constants[id(x)] = (x, AdjointSink(x))
        return x
    _rebuilt({key: value for key, value in leaves.items() if key not in shared}, constant)

    def per_lane(x):
        # one entry per lane (its own: nothing races), or one for all (a constant such as the
        # first bounce's unit factor, whose adjoint adds up every lane's: summed in its sink).
        # Not ReduceMode.Permute for the lanes: its adjoint writes instead of adding, and each
        # pulse of the loop would overwrite the one before (measured: gradients a sixth of the truth)
        if dr.width(x) == n:
            return dr.gather(type(x), x, lane)
        return read(x, first, True, constants[id(x)][1])

    def body(q):
        with dr.resume_grad():
            local = {key: value if key in shared else _rebuilt(value, per_lane) for key, value in leaves.items()}
            local["replayed"] = True          # an inner loop of the terms is then unrolled
            local["sinks"] = sinks            # shared_read's sinks
            ctx["adjoint"] = mi.Float(0.0)
            pulse(local, q)
            dr.backward_from(ctx.pop("adjoint"), flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)
        return (q + 1,)

    with dr.suspend_grad():
        dr.while_loop((mi.UInt32(0),), lambda q: q < count, body, label=f"{label} (replay)")
    for leaf, sink in [*_pairs(leaves, sinks), *constants.values()]:
        dr.accum_grad(leaf, sink.gradient())
    carry(pairs)


def shared_read(data: dict, name: str, index, active=True):
    """``data[name]`` (a Dr.Jit array, or a list of them) at ``index``: a gather, whose adjoint
    goes to the entry's sink in fixed point while :func:`run_pulses` replays (D7)."""
    value, sink = data[name], data.get("sinks", {}).get(name)
    if isinstance(value, (list, tuple)):
        return [read(v, index, active, s) for v, s in zip(value, sink or [None] * len(value))]
    return read(value, index, active, sink)


def _sinks(x):
    """An :class:`~.adjoint.AdjointSink` for each differentiable array of ``x`` (an array or a list
    of them; None for the others), in ``x``'s structure."""
    if isinstance(x, (list, tuple)):
        return [_sinks(v) for v in x]
    return AdjointSink(x) if dr.is_array_v(x) and dr.is_float_v(x) and dr.grad_enabled(x) else None


def _pairs(leaves: dict, sinks: dict) -> list:
    """``(leaf, sink)`` of every shared entry that has a sink."""
    out = []

    def walk(x, s):
        if isinstance(x, (list, tuple)):
            for v, t in zip(x, s):
                walk(v, t)
        elif s is not None:
            out.append((x, s))
    for key, sink in sinks.items():
        walk(leaves[key], sink)
    return out
