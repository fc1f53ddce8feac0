"""Sums whose bits do not depend on the order of their additions (docs/physics.md (D7)).

Kernels add their returns from many threads at once. Float additions do not associate, so a
float sum's last bits depend on which thread added what first, and a render repeated on a busy
machine differed in its last bits (about -140 dB). Integer additions associate, even where they
wrap around, so every value here is added as an integer: ``round(v 2^F)``, a two's-complement
fixed-point number with ``F`` fraction bits (quantum ``2^-F``), held in two ``int64`` words
``(hi, lo)`` with ``v 2^F = hi 2^K + lo``:

* ``hi = trunc(v 2^(F - K))`` and ``lo = round(v 2^F - hi 2^K)``, ``|lo| <= 2^K``, both formed
  exactly in ``v``'s own precision, float32 or float64 (a power-of-two scaling, a truncation and
  a subtraction of two multiples of ``v``'s last place, :meth:`FixedPoint.words`);
* the words are scatter-added as integers, wrapping modulo ``2^64`` (a slot's two as one packet
  here; the fine histogram keeps its low and high words in two arrays,
  :mod:`.accumulate`): only the final sums must fit, ``|sum v| < 2^(62 + K - F)`` for ``hi`` and at
  most ``2^(63 - K)`` terms per slot for ``lo``;
* the slot's value is ``(hi_sum 2^K + lo_sum) 2^-F``, read in float64.

Each term is rounded once, by at most half a quantum, so a slot of ``N`` terms is within
``N 2^-(F + 1)`` of their exact sum, whatever the order, the thread count or the device. A
term that is not finite or too large for the words is not added but counted (in an extra slot
of the same array, so the count costs no further scatter), and reading the sums raises
UnrepresentableSum: nothing is clamped.

The scales (:data:`AMPLITUDE`, :data:`POWER`, :data:`SOLID_ANGLE`, :data:`GRADIENT`) are fixed by the quantities'
units and physical ranges, never by a launch's own data, so the same term is the same integer
in any launch, batch or process: renders agree bit for bit across Dr.Jit thread counts and Dask
workers too, wherever the terms themselves do.

:func:`encode` and :func:`decode` are the NumPy reference of the device's :meth:`FixedPoint.words`.
"""
from __future__ import annotations

from dataclasses import dataclass

import drjit as dr
import mitsuba as mi
import numpy as np

__all__ = ["FixedPoint", "AMPLITUDE", "POWER", "SOLID_ANGLE", "GRADIENT", "encode", "decode", "UnrepresentableSum"]


class UnrepresentableSum(RuntimeError):
    """A launch produced a term that no fixed-point slot holds: not finite, or larger than
    :attr:`FixedPoint.largest`. A defect of the tracer (or a scene of absurd size), never rounding."""


@dataclass(frozen=True)
class FixedPoint:
    """A fixed-point scale: ``fraction_bits`` ``F`` (quantum ``2^-F`` of ``unit``) and the split
    ``split_bits`` ``K`` between the words (module docstring).

    Attributes
    ----------
    fraction_bits, split_bits : int
        ``F`` and ``K``; ``0 < K <= 52``.
    unit : str
        The unit of the values summed (documentation only).
    """

    fraction_bits: int
    split_bits: int
    unit: str

    @property
    def quantum(self) -> float:
        """``2^-F``: the step of the values held, in :attr:`unit`."""
        return 2.0 ** -self.fraction_bits

    @property
    def largest(self) -> float:
        """``2^(62 + K - F)``: a term's (and a slot's final sum's) magnitude stays below this."""
        return 2.0 ** (62 + self.split_bits - self.fraction_bits)

    @property
    def terms_per_slot(self) -> int:
        """``2^(63 - K)``: the most terms one slot adds up while its ``lo`` word's sum stays in range."""
        return 1 << (63 - self.split_bits)

    def words(self, value) -> tuple:
        """``(hi, lo, ok)`` of ``value`` (mi.Float or mi.Float64, any width): mi.Int64 words and
        whether the value is finite and below :attr:`largest` (the words are 0 where it is not).

        Formed in the value's own precision: the scaling by ``2^F`` and ``2^-K`` is exact, ``hi 2^K``
        and the scaled value are multiples of its last place, and their difference, below ``2^K``,
        has no more significant bits than the value (for a float32 value whose last place is below
        ``2^(K - 23)``, ``hi`` is 0 and the difference is the value itself); every float that is
        rounded is integer-valued, so the conversions to int64 are exact."""
        s = value * (2.0 ** self.fraction_bits)
        ok = dr.abs(s) < 2.0 ** (62 + self.split_bits)        # False for NaN and +-inf too
        s = dr.select(ok, s, 0.0)
        hi = dr.trunc(s * (2.0 ** -self.split_bits))
        lo = dr.round(s - hi * (2.0 ** self.split_bits))
        return mi.Int64(hi), mi.Int64(lo), ok

    def zeros(self, slots: int):
        """A device array of ``slots`` zero slots and one more that counts refused values
        (mi.Int64 of width ``2 (slots + 1)``: slot ``i`` at ``2 i, 2 i + 1``)."""
        return dr.zeros(mi.Int64, 2 * (slots + 1))

    def add(self, target, value, index, active, mode=dr.ReduceMode.Auto) -> None:
        """Add ``value`` into slot ``index`` of ``target`` (:meth:`zeros`) where ``active``, as
        one packet of its two words; a value that is not finite or too large is not added but
        counted in the last slot (:meth:`read` raises)."""
        hi, lo, ok = self.words(value)
        refused = mi.UInt32(dr.width(target) // 2 - 1)
        dr.scatter_add(target, _pair_type(hi)(dr.select(ok, hi, 1), lo), dr.select(ok, mi.UInt32(index), refused),
                       active, mode=mode)

    def combine(self, hi, lo):
        """mi.Float values of the words' sums ``hi``, ``lo`` (mi.Int64, one per value), on the
        device: ``(hi 2^K + lo) 2^-F`` rounded once to float64 (``hi 2^(K - F)`` is exact, or
        rounded once where ``|hi| >= 2^53``), then to float32; the same bits for the same words."""
        return mi.Float(mi.Float64(hi) * (2.0 ** (self.split_bits - self.fraction_bits))
                        + mi.Float64(lo) * (2.0 ** -self.fraction_bits))

    def read(self, words) -> np.ndarray:
        """The float64 values of a device array of slots (:meth:`zeros`), its refusal slot left
        out; raises UnrepresentableSum where a value was refused."""
        pairs = np.asarray(words.numpy(), np.int64).reshape(-1, 2)
        if pairs[-1, 0]:
            raise UnrepresentableSum(f"{int(pairs[-1, 0])} value(s) were not finite or exceeded {self.largest:g} "
                                     f"{self.unit} (docs/physics.md (D7)): a defect of the tracer; please report "
                                     "the scene")
        return decode(pairs[:-1], self)


def _pair_type(like):
    """The Dr.Jit type of a slot's two words on ``like``'s backend: a packet scatter-added as one."""
    return (dr.cuda.ad if dr.backend_v(like) == dr.JitBackend.CUDA else dr.llvm.ad).Array2i64


def encode(values, scale: FixedPoint) -> np.ndarray:
    """NumPy reference of :meth:`FixedPoint.words`: int64 ``[..., 2]`` ``(hi, lo)`` of float
    ``values`` (finite, below ``scale.largest``; ValueError otherwise)."""
    s = np.asarray(values, np.float64) * 2.0 ** scale.fraction_bits
    if not np.all(np.abs(s) < 2.0 ** (62 + scale.split_bits)):
        raise ValueError(f"values must be finite and below {scale.largest:g} {scale.unit} in magnitude")
    hi = np.trunc(s * 2.0 ** -scale.split_bits)
    lo = np.round(s - hi * 2.0 ** scale.split_bits)
    return np.stack([hi, lo], axis=-1).astype(np.int64)


def decode(words: np.ndarray, scale: FixedPoint) -> np.ndarray:
    """float64 ``[...]`` values of int64 ``words [..., 2]`` (sums of :func:`encode`'s words,
    wrapped modulo ``2^64``): ``(hi 2^K + lo) 2^-F``."""
    words = np.asarray(words, np.int64)
    return (words[..., 0].astype(np.float64) * 2.0 ** (scale.split_bits - scale.fraction_bits)
            + words[..., 1].astype(np.float64) * 2.0 ** -scale.fraction_bits)


#: Deposited amplitudes, sqrt(m^2) (normalised radiometry, docs/physics.md (R1)): quantum
#: ``2^-40`` (9.1e-13, an RCS of 8.3e-25 m^2), terms and slots below ``2^61``, up to ``2^24``
#: terms in one fast-time bin of one pulse. A term below 1/2 has no high word.
AMPLITUDE = FixedPoint(fraction_bits=40, split_bits=39, unit="sqrt(m^2)")
#: Energy tallies, m^2: quantum ``2^-40`` (9.1e-13 m^2), below ``2^54`` (1.8e16 m^2) per launch.
POWER = FixedPoint(fraction_bits=40, split_bits=32, unit="m^2")
#: Power carried by ray tubes, sr (solid angle times reflection losses): quantum ``2^-80``
#: (8.3e-25 sr), below ``2^14`` sr per launch.
SOLID_ANGLE = FixedPoint(fraction_bits=80, split_bits=32, unit="sr")
#: Reverse-mode adjoints (:mod:`.adjoint`), for a seed scaled to magnitudes at most 1: a term's
#: ``dL/dx`` is its amplitude's derivative, up to ``k`` times the amplitude (sqrt(m^2) per m)
#: for a position. Quantum ``2^-48`` (3.6e-15), below ``2^46`` (7e13).
GRADIENT = FixedPoint(fraction_bits=48, split_bits=32, unit="sqrt(m^2) per unit of the source")
