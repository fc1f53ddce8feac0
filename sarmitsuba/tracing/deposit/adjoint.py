"""Reads whose reverse-mode sums do not depend on the order of the additions (docs/physics.md
(D7), (AD3)).

Dr.Jit differentiates a gather ``y = x[i]`` in reverse mode by scatter-adding ``dL/dy`` into
``dL/dx`` at ``i``. Where many lanes read one entry (a material's reflection table, a lit piece's
centroid read by each of its lanes), those float adds race between threads and the gradient's
last bits follow the threads' timing. :func:`read` is the same gather, with its adjoint added in
fixed point (:data:`.fixed_point.GRADIENT`) into an :class:`AdjointSink` instead: integer adds,
any order, the same bits. After the pass the sink's sums are handed to the source as its
gradient (:meth:`AdjointSink.gradient`). Without a sink, or in forward mode, :func:`read` is a
plain gather.

The reverse pass is seeded with the loss's gradient scaled by a power of two
(:func:`seed_scale`), so that the adjoints lie in the fixed-point range whatever the loss's
units; the gradient is scaled back exactly.
"""
from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi

from .fixed_point import GRADIENT

__all__ = ["AdjointSink", "read", "seed_scale"]


def _components(x) -> list:
    """The flat Dr.Jit arrays of ``x`` (itself if flat; a nested array's leaves in order)."""
    if dr.depth_v(x) <= 1:
        return [x]
    out = []
    for c in x:
        out.extend(_components(c))
    return out


class AdjointSink:
    """The fixed-point sums of ``dL/dx`` of one differentiable source ``x`` (a flat or nested
    float array): one slot per entry and component (:data:`.fixed_point.GRADIENT`)."""

    def __init__(self, source):
        self.type = type(source)
        self.width = dr.width(source)
        self.words = [GRADIENT.zeros(self.width) for _ in _components(source)]

    def add(self, grad, index, active) -> None:
        """Add ``grad`` (of the source's type, one entry per lane) into entries ``index`` where ``active``."""
        for words, g in zip(self.words, _components(grad)):
            GRADIENT.add(words, dr.detach(g), index, active)

    def sums(self) -> list:
        """The sums, float64 [width] per component of the source; raises UnrepresentableSum where
        an adjoint was not finite or too large for the words."""
        return [GRADIENT.read(words) for words in self.words]

    def gradient(self):
        """The sums (:meth:`sums`) as the source's type."""
        flat = [dr.leaf_t(self.type)(v) for v in self.sums()]
        return flat[0] if dr.depth_v(self.type) <= 1 else _assemble(self.type, flat)


def _assemble(cls, flat: list):
    """A nested array of type ``cls`` from its flat leaves in order."""
    parts, at = [], 0
    for i in range(dr.size_v(cls)):
        inner = dr.value_t(cls)
        n = len(_components(dr.zeros(inner, 1)))
        parts.append(flat[at] if n == 1 and dr.depth_v(inner) <= 1 else _assemble(inner, flat[at:at + n]))
        at += n
    return cls(*parts)


class _Read(dr.CustomOp):
    """``source[index]``, whose adjoint goes to a sink in fixed point."""

    def eval(self, source, index, active, sink):
        self.index, self.active, self.sink = index, active, sink
        return dr.gather(type(source), source, index, active)

    def forward(self):
        g = self.grad_in("source")
        self.set_grad_out(dr.gather(type(g), g, self.index, self.active))

    def backward(self):
        self.sink.add(self.grad_out(), self.index, self.active)

    def name(self):
        return "read (fixed-point adjoint)"


def read(source, index, active=True, sink: AdjointSink | None = None):
    """``dr.gather(type(source), source, index, active)``; with a ``sink`` and a differentiable
    ``source``, its reverse-mode adjoint is added to the sink in fixed point (module docstring)."""
    if sink is None or not dr.grad_enabled(source):
        return dr.gather(type(source), source, index, active)
    return dr.custom(_Read, source, index, mi.Bool(active) if isinstance(active, bool) else active, sink)


def seed_scale(largest: float) -> float:
    """The power of two ``2^e`` nearest above ``largest`` (the seed's largest magnitude; 1 for 0):
    dividing a seed by it is exact and puts its magnitudes in ``(1/2, 1]``."""
    if not largest > 0 or not math.isfinite(largest):
        return 1.0
    return 2.0 ** math.ceil(math.log2(largest))
