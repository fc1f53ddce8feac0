"""Where a launch's returns are summed: the fine-grid histogram, or the ``exact`` kernel's path
list, one per polarimetric channel (docs/physics.md (D1)-(D4), (D7), (P4)).

:class:`sarmitsuba.tracing.integration.returns.Returns` computes every pulse's returns; an :class:`Accumulator`
holds what they are summed into for one launch (in the launch's context dict): ``hist`` and
``hist_hi``, the low and high fixed-point words (:data:`.fixed_point.AMPLITUDE`, int64 ``(re, im)``
pairs) of ``[spectral orders, channels x groups, pulses, fine samples]`` complex entries
(channel-major: group ``c * groups + order``), whose sums do not depend on the order of the
additions (D7); or, with ``range_kernel = exact``, path buffers of one entry per term and
channel, read back in a canonical order.
"""
from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from .fast_time import SPECTRAL_ORDERS, taps
from .fixed_point import AMPLITUDE, POWER, SOLID_ANGLE, UnrepresentableSum

__all__ = ["Accumulator", "HISTOGRAM_MIN_FLOATS", "PATH_HEADROOM", "PATH_FIELDS", "TALLIES", "WORDS_PER_ENTRY",
           "histogram_floats"]

#: The ``exact`` kernel's clutter path buffer holds at least this many scatterers, and a launch
#: that overflowed it asks for this many more than it found (slack, so a retry rarely overflows).
PATH_HEADROOM = 1024
#: The exact kernel's path fields and their NumPy dtypes.
PATH_FIELDS = dict(path_pos=np.float64, path_re=np.float32, path_im=np.float32, path_order=np.uint32,
                   path_pulse=np.uint32, path_spectral=np.uint32, path_channel=np.uint32)


#: The fine-grid histogram's device arrays hold at least this many real values (a low and a high
#: int64 word each: 8 MiB), and otherwise the next power of two: ``scatter_add(mode=Expand)`` writes the
#: array's size into its kernel, so sizes rounded to a few buckets let launches and acquisitions
#: of other pulse counts or windows reuse the kernels (compiled or from Dr.Jit's disk cache) at
#: most twice the memory.
HISTOGRAM_MIN_FLOATS = 1 << 19
#: int64 words per complex histogram entry: the low words ``(re, im)`` in ``hist``, the high ones in ``hist_hi``.
WORDS_PER_ENTRY = 4
#: The launch's tallies (in its context) and their fixed-point scales, eq. (D7): ``energy``, the
#: visible returns' ``|a|^2`` per bounce order and outside the window [m^2]; ``carried``, the tubes'
#: solid angle times their reflection losses per bounce order [sr].
TALLIES = {"energy": POWER, "carried": SOLID_ANGLE}


def histogram_floats(n: int) -> int:
    """Real values allocated for a histogram of ``n`` real values: ``max(HISTOGRAM_MIN_FLOATS,
    2^ceil(log2 n))``."""
    return max(HISTOGRAM_MIN_FLOATS, 1 << max(int(n) - 1, 0).bit_length())


def _pair_type(like):
    """The Dr.Jit type of a complex entry's low (or high) words on ``like``'s backend: a packet of
    two int64, scatter-added as one."""
    return (dr.cuda.ad if dr.backend_v(like) == dr.JitBackend.CUDA else dr.llvm.ad).Array2i64


class Accumulator:
    """The sums of one acquisition's launches (configuration fixed per acquisition).

    Parameters
    ----------
    settings : TraceSettings
        ``range_kernel`` (``exact`` keeps path lists), ``max_depth``.
    window : FastTimeWindow
        The fine grid's length, step and oversampling.
    groups : int
        Spectra per pulse and channel (bounce orders with ``split_bounces``, else 1).
    n_channels : int
        Polarimetric channels deposited (4 for ``quad``).
    apart : int
        Bounce orders :meth:`collect` returns apart (``EffectSet.deposit_groups``): when above
        ``groups``, the one histogram is read after each order's deposits (:meth:`order_done`) and
        the orders told apart by difference, so that each order's energy is measured (docs/physics.md
        (D6)) at no extra device memory.
    """

    def __init__(self, settings, window, groups: int, n_channels: int, apart: int = 1):
        self.settings, self.window, self.groups, self.n_channels = settings, window, groups, n_channels
        self.apart = max(apart, groups)
        self.exact = settings.range_kernel == "exact"
        #: The tallies' scatter-add (small arrays): ``ReduceMode.Expand`` (no atomics) unless several
        #: host threads deposit at once (:meth:`shared_by`). Either gives the same bits: the words
        #: are integers (D7).
        self.reduce = dr.ReduceMode.Expand
        #: The histogram's: ``Auto`` (Dr.Jit expands arrays of up to ``dr.expand_threshold()``
        #: entries per thread, and adds atomically into larger ones) unless several host threads
        #: deposit at once, then atomic adds (``Direct``: pairs of words at scattered places, which
        #: ``Local``'s reduction within each packet only slows, about twice in a benchmark of random
        #: deposits).
        self.deposit_mode = dr.ReduceMode.Auto

    def shared_by(self, threads: int) -> None:
        """Deposit from ``threads`` host threads at once: as :attr:`reduce` and :attr:`deposit_mode`
        say for one, atomic adds (``ReduceMode.Local`` for the tallies, ``Direct`` for the
        histogram) for several.

        Expand adds without atomics into the copy of the histogram that belongs to the Dr.Jit pool
        worker running a block (its ``pool_thread_id()``). A host thread that waits on Dr.Jit (an
        evaluation, a sync, a ray cast) runs queued blocks of any kernel, as worker 0: two host
        threads waiting at once add into copy 0 together and lose updates (measured: a few pulses
        of ``urban`` off by up to 4e-5 of their power, in 15 of 21 threaded traces)."""
        self.reduce = dr.ReduceMode.Expand if threads <= 1 else dr.ReduceMode.Local
        self.deposit_mode = dr.ReduceMode.Auto if threads <= 1 else dr.ReduceMode.Direct

    def open(self, ctx: dict) -> None:
        """Add the launch's zeroed histogram to its context ``ctx`` (nothing for ``exact``) and the
        fine grid's scale."""
        # fine bins per metre of two-way length, as a value (each scene's window has its own step)
        ctx["fine_per_length"] = {cls: dr.opaque(cls, 1.0 / self.window.fine_step_length)
                                  for cls in (mi.Float, mi.Float64)}
        if not self.exact:
            size = len(SPECTRAL_ORDERS) * self.n_channels * self.groups * ctx["n_b"] * self.window.n_fine
            ctx["hist_entries"] = size
            # the low and the high words, (re, im) packets of int64 each, eq. (D7), and one entry more,
            # whose high real word counts the terms no words hold (refused, never clamped)
            ctx["hist"] = dr.zeros(mi.Int64, histogram_floats(2 * size + 2))
            ctx["hist_hi"] = dr.zeros(mi.Int64, histogram_floats(2 * size + 2))
            ctx["hist_refused"] = dr.opaque(mi.UInt32, size)
            # the layout's sizes enter the kernels as values, not literals, so that launches and
            # acquisitions of other pulse counts or windows (same structure) share the kernels
            ctx["hist_n_b"] = dr.opaque(mi.UInt32, ctx["n_b"])
            ctx["hist_n_fine"] = dr.opaque(mi.UInt32, self.window.n_fine)
            ctx["orders_read"] = {}                             # order -> its histogram (order_done)

    @property
    def snapshots(self) -> bool:
        """Whether the orders are told apart by reading the histogram after each (:meth:`order_done`)."""
        return not self.exact and self.apart > self.groups

    def order_done(self, ctx: dict, depth: int) -> None:
        """After the deposits of bounce order ``depth + 1`` (0-based ``depth``; the orders deposit one
        after the other): keep the histogram, which holds that order's deposits alone, and start
        the next order's from zero. Nothing unless :attr:`snapshots`."""
        if not self.snapshots:
            return
        ctx["orders_read"][depth] = self.read_histogram(ctx)
        for name in ("hist", "hist_hi"):
            ctx[name] = dr.zeros(mi.Int64, dr.width(ctx[name]))

    @staticmethod
    def read_histogram(ctx: dict) -> np.ndarray:
        """The launch's histogram, complex64 ``[entries]``, its words decoded on the device
        (:meth:`.fixed_point.FixedPoint.combine`); raises UnrepresentableSum where a term was refused (D7)."""
        n = ctx["hist_entries"]
        real = dr.arange(mi.UInt32, 2 * n)
        values = AMPLITUDE.combine(dr.gather(mi.Int64, ctx["hist_hi"], real), dr.gather(mi.Int64, ctx["hist"], real))
        values = values.numpy().view(np.complex64)
        count = int(dr.gather(mi.Int64, ctx["hist_hi"], mi.UInt32(2 * n)).numpy()[0])
        if count:
            raise UnrepresentableSum(
                f"{count} return(s) of the launch were not finite or exceeded {AMPLITUDE.largest:g} "
                f"{AMPLITUDE.unit} (docs/physics.md (D7)): a defect of the tracer; please report the scene")
        return values[:n]

    def tally(self, ctx: dict, name: str, value, slot, active) -> None:
        """Add ``value`` (mi.Float, detached) into slot ``slot`` of the launch's tally ``name``
        (:data:`TALLIES`) where ``active``, in fixed point (D7)."""
        TALLIES[name].add(ctx[name], dr.detach(value), mi.UInt32(slot), active, mode=ctx["tally"])

    @staticmethod
    def tallies(max_depth: int) -> dict:
        """The launch's zeroed tallies (:data:`TALLIES`): ``energy`` ``max_depth + 1`` slots (the last:
        outside the window), ``carried`` ``max_depth``."""
        return dict(energy=POWER.zeros(max_depth + 1), carried=SOLID_ANGLE.zeros(max_depth))

    @staticmethod
    def read_tallies(ctx: dict) -> dict:
        """The launch's tallies as float64 arrays (``energy``, ``carried``), evaluated; raises
        UnrepresentableSum where a value was refused (D7)."""
        return {name: scale.read(ctx[name]) for name, scale in TALLIES.items()}

    def collect(self, ctx: dict) -> dict:
        """``{"paths": {field: array}}`` (``exact``) or ``{"hist": complex64 [orders, channels x
        apart, n_b, n_fine]}`` (spectral orders; channel-major), in NumPy (the histogram already
        evaluated). With :attr:`snapshots`, bounce order ``d``'s histogram is the one
        :meth:`order_done` kept, and what was deposited after the last reading goes to the order
        after it."""
        if self.exact:
            return {"paths": {name: np.concatenate([p[name] for p in ctx["paths"]] + [np.zeros(0, dtype)])
                              for name, dtype in PATH_FIELDS.items()}}
        hist = self.read_histogram(ctx)
        shape = (len(SPECTRAL_ORDERS), self.n_channels, ctx["n_b"], self.window.n_fine)
        if not self.snapshots:
            return {"hist": hist.reshape(shape[0], self.n_channels * self.groups, *shape[2:])}
        read = ctx["orders_read"]
        if np.any(hist):                   # deposited after the last reading
            last = len(read) if len(read) < self.apart else self.apart - 1
            read[last] = read[last] + hist if last in read else hist
        apart = np.zeros((shape[0], self.n_channels, self.apart, *shape[2:]), np.complex64)
        for depth, part in read.items():
            apart[:, :, depth] = part.reshape(shape)
        return {"hist": apart.reshape(shape[0], self.n_channels * self.apart, *shape[2:])}

    def deposit(self, ctx, pulse, depth: int, anchor, offset, values, order_index, mask, paths, slot) -> mi.Bool:
        """Deposit ``values`` (one mi.Complex2f per channel) at the two-way length ``offset`` [m]
        (float32) beyond ``anchor`` for batch pulse ``pulse``, eqs. (D1)-(D4); ``slot`` places a PO
        term in the exact kernel's path list (None: a clutter scatterer, appended). Returns whether
        the term lies inside the fast-time window. While the launch is replayed (``ctx["seed"]``,
        the histogram's gradient as (re, im) floats, :mod:`.replay`), nothing is deposited: the
        term's share of the loss's change, ``sum_taps w (g_re Re v + g_im Im v)``, is added to
        ``ctx["adjoint"]``."""
        st, win = self.settings, self.window
        per_length = ctx["fine_per_length"].get(type(offset), 1.0 / win.fine_step_length)
        position = anchor[1] + offset * per_length                          # fine bins after anchor[0]
        if self.exact:
            coarse = (mi.Float64(anchor[0]) + mi.Float64(position)) * (1.0 / win.oversample)
            if slot is None:
                slot = dr.scatter_inc(paths["count"], mi.UInt32(0), mask)
                keep = mask & (slot < paths["capacity"])
            else:
                keep = mask
            n_ch = len(values)
            for c, value in enumerate(values):
                index = slot * n_ch + c
                dr.scatter(paths["path_pos"], coarse, index, keep)
                dr.scatter(paths["path_re"], value.real, index, keep)
                dr.scatter(paths["path_im"], value.imag, index, keep)
                dr.scatter(paths["path_order"], mi.UInt32(depth + 1), index, keep)
                dr.scatter(paths["path_pulse"], pulse, index, keep)
                dr.scatter(paths["path_spectral"], order_index, index, keep)
                dr.scatter(paths["path_channel"], mi.UInt32(c), index, keep)
            return (coarse >= 0) & (coarse <= win.n_samples - 1)
        k0, tap_list, (lo, hi) = taps(position, st.range_kernel)
        k0 = k0 + anchor[0]
        n_fine = ctx["hist_n_fine"]
        inside = (k0 >= lo) & (k0 < mi.Int32(n_fine) - hi)
        group = depth if self.groups > 1 else 0
        n_groups = len(values) * self.groups               # channel-major: group c * groups + order
        seed = ctx.get("seed")
        for c, value in enumerate(values):
            base = ((order_index * n_groups + c * self.groups + group) * ctx["hist_n_b"] + pulse) * n_fine
            for offset_, w in tap_list:            # one (re, im) packet per tap
                if seed is not None:               # replayed: this term's share of dL (replay.py)
                    g = dr.gather(mi.Array2f, seed, base + mi.UInt32(k0 + offset_), mask & inside)
                    ctx["adjoint"] += w * (g[0] * value.real + g[1] * value.imag)
                    continue
                self.add(ctx, value.real * w, value.imag * w, base + mi.UInt32(k0 + offset_), mask & inside)
        return inside

    def add(self, ctx, re, im, index, active) -> None:
        """Add ``re + j im`` (mi.Float) into complex entry ``index`` of the launch's histogram where
        ``active``: its low fixed-point words as one packet and, only where either is not zero
        (``|v| >= 1/2``: rarely for clutter), its high words as another, eq. (D7). A value no words
        hold is not added but counted in the entry after the histogram's last
        (:meth:`read_histogram` raises)."""
        re_hi, re_lo, re_ok = AMPLITUDE.words(dr.detach(re))
        im_hi, im_lo, im_ok = AMPLITUDE.words(dr.detach(im))
        ok = re_ok & im_ok
        pair = _pair_type(re)
        index = dr.select(ok, index, ctx["hist_refused"])
        dr.scatter_add(ctx["hist"], pair(re_lo, im_lo), index, active, mode=self.deposit_mode)
        high = active & ((re_hi != 0) | (im_hi != 0) | ~ok)
        dr.scatter_add(ctx["hist_hi"], pair(dr.select(ok, re_hi, 1), im_hi), index, high, mode=self.deposit_mode)

    def path_buffers(self, size: int) -> dict:
        """The exact kernel's path list: ``size`` slots of one entry per channel."""
        n = size * self.n_channels
        return dict(count=dr.zeros(mi.UInt32, 1), capacity=size, path_pos=dr.zeros(mi.Float64, n),
                    path_re=dr.zeros(mi.Float, n), path_im=dr.zeros(mi.Float, n),
                    path_order=dr.zeros(mi.UInt32, n), path_pulse=dr.zeros(mi.UInt32, n),
                    path_spectral=dr.zeros(mi.UInt32, n), path_channel=dr.zeros(mi.UInt32, n))

    @staticmethod
    def keep_paths(ctx, paths: dict) -> None:
        """Move a path buffer to NumPy (filled slots only); note an overflow of the appended part."""
        names = tuple(PATH_FIELDS)
        dr.eval(paths["count"], *(paths[name] for name in names))
        count = int(paths["count"].numpy()[0])
        if count > paths["capacity"]:
            ctx["needed"] = max(ctx["needed"], count + PATH_HEADROOM)
            return
        filled = np.flatnonzero(paths["path_order"].numpy())
        found = {name: paths[name].numpy()[filled] for name in names}
        # a canonical order: the appended slots (clutter) follow the threads' timing, and the
        # binning's float sums follow the list's order (D7)
        order = np.lexsort([found[name] for name in reversed(("path_pulse", "path_pos", "path_re", "path_im",
                                                                  "path_order", "path_spectral", "path_channel"))])
        ctx["paths"].append({name: values[order] for name, values in found.items()})
