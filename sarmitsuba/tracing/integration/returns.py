"""Every pulse's return from the recorded hits of a sub-aperture's ray tubes (docs/physics.md
(T3), (PO1)-(PO5), (C), (A), (R1), (D1)-(D4)).

:class:`sarmitsuba.tracing.driver.kernel.Kernel` traces the tubes of a sub-aperture once, from its reference
position, and records every visible hit (:class:`sarmitsuba.tracing.driver.kernel.Record`). This module turns
the records of one bounce order into returns: :meth:`Returns.terms`, the footprint's PO integral
as 1, 2 or 4 point terms (PO2), less those that neighbouring tubes cancel exactly (PO5);
:meth:`Returns.po`, per pulse, each term at its own point with that pulse's antenna position
(exact float64 legs, phase gradient and amplitude there, (PO4)), deposited on the fast-time grid;
:meth:`Returns.clutter`, per pulse, the rough surface's scatterers in the footprint, eq. (C)
(:mod:`.clutter_terms`). With ``lit_regions = patches`` the tubes return only the chains that meet a
shape that is not a mesh (a sphere); the patches return the rest (:mod:`..driver.mesh_trace`).
The footprints and the visibility are the sub-aperture's; everything that carries phase is the
pulse's own.
"""
from __future__ import annotations

import dataclasses
import math

import drjit as dr
import mitsuba as mi
import numpy as np

from ...core.constants import SPEED_OF_LIGHT
from ..deposit.accumulate import Accumulator
from ..deposit.fast_time import SPECTRAL_ORDERS
from . import jones as pol
from ...core.radar import CHANNELS
from .physical_optics import SINC_REGIME, split_threshold
from .clutter_terms import ClutterTerms
from ..device import gather_table, table_array
from .pulse_view import PulseView, receive_leg, receiver_axes
from ..loops import loop_mode

__all__ = ["Returns", "footprint_edges"]

#: A tile corner seen this close to grazing (cos of the incidence angle) by a pulse returns nothing
#: (as kernel.COS_GRAZING for the tube's centre).
COS_GRAZING = 1e-6
#: Below this ``|x|`` a sinc is taken as 1: the neglected ``x^2 / 6 < 2e-9`` is far below float32's
#: resolution (6e-8), and it avoids the 0 / 0 at ``x = 0``.
SINC_SMALL_ARGUMENT = 1e-4
_INVALID = 0xFFFFFFFF
# flags of kernel.Flags (repeated here: the kernel imports this module)
_HAS_I_LO, _HAS_I_HI, _HAS_J_LO, _HAS_J_HI, _INTERIOR, _SPLIT_1, _SPLIT_2, _BACK = 1, 2, 4, 8, 16, 32, 64, 128
_UNDECIDED_1, _UNDECIDED_2, _MESH_ONLY = 256, 512, 1024
#: Flags two tubes must share for their PO terms at a common point to cancel (PO5).
_MATCH = _INTERIOR | _SPLIT_1 | _SPLIT_2 | _BACK | _UNDECIDED_1 | _UNDECIDED_2 | _MESH_ONLY


def footprint_edges(t1, t2, n: mi.Vector3f, d: mi.Vector3f, s, cos_i) -> tuple:
    """The tube's footprint edges on the facet where its ray of direction ``d`` meets it at unfolded
    length ``s``: ``e_j' = e_j + d (n . e_j) / cos_i`` with ``e_j = s t_j``, eq. (T1)."""
    out = []
    for t in (t1, t2):
        e = t * s
        out.append(e + d * (dr.dot(n, e) / cos_i))
    return tuple(out)


def _sinc(x):
    """sin(x) / x, 1 at 0."""
    return dr.select(dr.abs(x) < SINC_SMALL_ARGUMENT, 1.0, dr.sin(x) / x)


class Returns(ClutterTerms):
    """Per-pulse returns of recorded hits: configuration fixed per acquisition.

    Parameters
    ----------
    params : RadarParameters
    window : FastTimeWindow
    footprint : RayFootprint
    settings : TraceSettings
    tables : kernel tables (materials, clutter models)
    effects : EffectSet
        Which effects to compile in (:class:`sarmitsuba.scene.effects.EffectSet`: clutter, antenna
        pattern, absolute radiometry, spotlight steering, per-order spectra).
    beam_sines : (float, float)
        Along-track sines bounding the traced beam.
    """

    cos_grazing = COS_GRAZING
    sinc = staticmethod(_sinc)

    def __init__(self, params, window, footprint, settings, tables, effects, beam_sines):
        # tables in aligned memory, two entries at least: one kernel for every scene's tables (the
        # launch's per-pulse and per-sub-aperture tables likewise, in context)
        if dataclasses.is_dataclass(tables):
            tables = dataclasses.replace(tables, **{f.name: gather_table(getattr(tables, f.name))
                                                   for f in dataclasses.fields(tables)})
        self.settings, self.window, self.fp, self.tables = settings, window, footprint, tables
        self.k = 2.0 * math.pi * params.frequency / SPEED_OF_LIGHT
        self.lam = params.wavelength
        self.beam_sines = beam_sines
        self.spotlight = effects.spotlight
        self.continuous = effects.continuous_motion      # the receive leg from the moving antenna (J3)
        self.curved = effects.curved_track               # per-pulse antenna axes (A)
        self.exact = settings.range_kernel == "exact"
        self.groups = effects.groups
        self.clutter_on = effects.clutter
        self.diffraction = effects.diffraction           # edge currents on the mesh's wedges (E1)-(E6)
        self.cancel_interior = settings.cancel_interior
        # polarimetry, docs/physics.md (P1)-(P7): the channels deposited, and whether the records
        # carry Jones matrices (a single co-polarised channel: the scalar model (R), (P6))
        self.channels = effects.channels
        self.polarimetric = effects.polarimetric
        self.track = footprint.track.tolist()             # H where z x look vanishes (never, for a SAR)
        # the scalar VV channel takes the sign (-1)^(k+1) of a k-bounce chain in the plane of the look (P6)
        self.vv_sign = self.channels == ("VV",)
        self.sums = Accumulator(settings, window, self.groups, len(self.channels), apart=effects.deposit_groups)
        self.split_at = split_threshold(params.bandwidth, params.frequency)
        # absolute radiometry: spreading R_ref^2 / (s R_rx) relative to the pulse's R_ref^2, eq. (R1)
        self.radiometry = effects.radiometry
        # antenna pattern, eq. (A): the tapered default beam or the antenna's dimensions
        self.pattern = effects.pattern
        if self.pattern:
            boresight = footprint.look * params.ground_range - np.array([0.0, 0.0, params.altitude])
            boresight /= np.linalg.norm(boresight)
            squint = math.radians(params.squint) if params.mode == "stripmap" else 0.0
            self.aperture_axis = (math.cos(squint) * footprint.track - math.sin(squint) * boresight).tolist()
            self.elevation_axis = np.cross(footprint.track, boresight).tolist()
            self.length_in_wavelengths = params.pattern_length / params.wavelength
            self.height_in_wavelengths = params.antenna_height / params.wavelength
        # the azimuth pattern's main lobe bounds every pulse's beam continuously (the gain is zero at
        # its first nulls, where the traced beam ends): no tube needs cutting per pulse. A uniform
        # (hard-edged) beam is cut per pulse at the aim points, as each pulse's own lattice would be.
        self.aim_mask = not (self.pattern and self.length_in_wavelengths > 0)
        # bistatic (B1)-(B3): the receiver's platform and, when it has an antenna, its pattern
        self.bistatic = effects.bistatic
        self.rx_length = self.rx_height = 0.0
        if self.bistatic:
            from ...core.receiver import receiver_parameters
            rp = receiver_parameters(params)
            self.rx_length, self.rx_height = rp.antenna_length / params.wavelength, rp.antenna_height / params.wavelength

    # ------------------------------------------------------------------ per launch
    def context(self, launch, capacity: int = 0) -> dict:
        """Buffers and per-pulse inputs of one launch: counters, the fine-grid histogram (or the
        path list of the ``exact`` kernel), antenna positions, reference lengths, sub-apertures."""
        st = self.settings
        n_b = launch.n_pulses
        a64, f64 = mi.Array3f64, mi.Float64
        ctx = dict(**self.sums.tallies(st.depth), rays=dr.zeros(mi.UInt32, st.depth + 1),
                   scatterers=dr.zeros(mi.UInt32, st.depth),
                   antenna=table_array(a64, launch.antenna.T), lref=table_array(f64, launch.lref),
                   first=table_array(mi.UInt32, launch.first), count=table_array(mi.UInt32, launch.count),
                   reference=table_array(a64, launch.reference.T),
                   middle=table_array(f64, launch.lref[launch.first + launch.count // 2]),
                   block_nj=table_array(mi.UInt32, launch.blocks.n_j),
                   block_m=table_array(mi.UInt32, launch.blocks.m),
                   launch=launch,
                   max_count=int(launch.count.max()), n_b=n_b, capacity=capacity, paths=[], needed=0, evaluated=0,
                   # the counters above, added to as the histogram is (Accumulator.shared_by): small
                   # arrays that ReduceMode.Auto would expand per pool worker, and lose updates to
                   # launches on several host threads
                   tally=self.sums.reduce)
        axis = np.broadcast_to(self.fp.track, launch.antenna.shape) if launch.axes is None else launch.axes[:, 0]
        if self.spotlight:
            to_c = np.asarray(self.fp.origin, float) - launch.antenna
            ctx["steer"] = table_array(mi.Float, np.sum(to_c * axis, axis=1) / np.linalg.norm(to_c, axis=1))
        if self.curved:
            ctx["axis"] = table_array(mi.Array3f64, launch.axes[:, 0].T)
            ctx["aperture"], ctx["elevation"] = (table_array(mi.Vector3f, launch.axes[:, k].T) for k in (1, 2))
        if self.continuous:
            ctx["velocity"] = table_array(mi.Array3f64, launch.velocity.T)
            ctx["acceleration"] = table_array(mi.Array3f64, launch.acceleration.T)
        if self.bistatic:
            ctx["receiver"] = table_array(mi.Array3f64, launch.receiver.T)
            if self.rx_length > 0 or self.rx_height > 0:
                axis, elevation, steer = receiver_axes(launch.receiver, launch.receiver_axis, self.fp.origin)
                ctx["rx_axis"], ctx["rx_elevation"] = (table_array(mi.Vector3f, a.T) for a in (axis, elevation))
                ctx["rx_steer"] = table_array(mi.Float, steer)
        self.sums.open(ctx)
        return ctx

    def collect(self, ctx) -> dict | None:
        """NumPy results of a launch (None when the exact kernel's clutter buffer overflowed)."""
        st = self.settings
        if self.exact and ctx["needed"]:
            return None
        names = ["energy", "rays", "carried", "scatterers"] + ([] if self.exact else ["hist"])
        dr.eval(*(ctx[name] for name in names))
        tallies = self.sums.read_tallies(ctx)
        energy = tallies["energy"]
        rays = ctx["rays"].numpy().astype(np.int64)
        out = dict(energy=energy[:st.depth], outside=float(energy[st.depth]), rays=rays[:st.depth],
                   shadow=int(rays[st.depth]), carried=tallies["carried"],
                   scatterers=ctx["scatterers"].numpy().astype(np.int64))
        out["evaluated"] = ctx["evaluated"] + int(out["scatterers"].sum())
        out.update(self.sums.collect(ctx))
        return out

    # ------------------------------------------------------------------ geometry helpers
    def aim_sine(self, aim, antenna, axis=None):
        """Along-track sine of the direction from ``antenna`` to ``aim`` (float64 points), relative
        to the direction of the scene centre in spotlight (the steered beam); along the pulse's own
        ``axis`` on a curved track."""
        track = mi.Array3f64(*self.fp.track.tolist()) if axis is None else axis
        to_p = aim - antenna
        sine = dr.dot(to_p, track) / dr.norm(to_p)
        if self.spotlight:
            to_c = mi.Array3f64(*self.fp.origin.tolist()) - antenna
            sine -= dr.dot(to_c, track) / dr.norm(to_c)
        return sine

    def reflection_at(self, row: mi.UInt32, cos_i: mi.Float, active: mi.Bool) -> mi.Complex2f:
        """``r(cos_i)`` of material ``row``, linear in its 257-point table, eq. (R)."""
        t = self.tables
        x = dr.clip(cos_i, 0.0, 1.0) * (t.n_cos - 1)
        i0 = mi.UInt32(dr.minimum(dr.floor(x), t.n_cos - 2))
        w = x - mi.Float(i0)
        idx = row * t.n_cos + i0
        re = dr.lerp(t.read("re", idx, active), t.read("re", idx + 1, active), w)
        im = dr.lerp(t.read("im", idx, active), t.read("im", idx + 1, active), w)
        return mi.Complex2f(re, im)

    def reflection_pair(self, row: mi.UInt32, cos_i: mi.Float, active: mi.Bool) -> tuple:
        """``(r_te, r_tm)`` of material ``row`` at ``cos_i``, linear in its tables (polarimetric runs
        only), eqs. (R), (P3')."""
        t = self.tables
        x = dr.clip(cos_i, 0.0, 1.0) * (t.n_cos - 1)
        i0 = mi.UInt32(dr.minimum(dr.floor(x), t.n_cos - 2))
        w = x - mi.Float(i0)
        idx = row * t.n_cos + i0
        out = []
        for re_, im_ in (("re", "im"), ("re_tm", "im_tm")):
            re = dr.lerp(t.read(re_, idx, active), t.read(re_, idx + 1, active), w)
            im = dr.lerp(t.read(im_, idx, active), t.read(im_, idx + 1, active), w)
            out.append(mi.Complex2f(re, im))
        return tuple(out)

    def po_channels(self, rec, d, b, n, cos_i, depth: int) -> list:
        """The reflection factor of a PO term per channel (docs/physics.md (PO1), (P4)): the scalar
        ``r(cos_i)`` of the one co-polarised channel (with the VV sign of (P6)), or, with Jones
        matrices, ``S[rx, tx] = b_rx . E'`` with ``E'`` of (P4') for the pulse's own incidence ``d``
        and return ``b``, made reciprocal after more than one bounce (P8)."""
        if not self.polarimetric:
            r = self.reflection_at(rec.row, cos_i, True)
            return [-r if self.vv_sign and depth % 2 else r]
        r_te, r_tm = self.reflection_pair(rec.row, cos_i, True)
        field = pol.scatter(self._arriving(rec, d, depth), d, b, n, r_te, r_tm)
        return self.reciprocal(pol.receive(field, -b, mi.Vector3f(*self.track), CHANNELS), depth)

    def _arriving(self, rec, d, depth: int):
        """The Jones matrix arriving at a term's point for the pulse: at the first bounce the
        pulse's own ``[h v]`` of its incoming direction ``d`` (P1), after it the tube's (from the
        sub-aperture's reference position, as its reflection coefficients, eq. (T3))."""
        return pol.launch(d, mi.Vector3f(*self.track)) if depth == 0 else rec.jones

    def reciprocal(self, entries: list, depth: int) -> list:
        """The requested channels of ``S`` (entries in :data:`CHANNELS` order), made reciprocal
        after more than one bounce: ``(S + S^T) / 2``, docs/physics.md (P8). Only the entries the
        channels need are compiled."""
        s_full = dict(zip(CHANNELS, entries))
        if depth > 0:
            s_full["HV"] = s_full["VH"] = 0.5 * (s_full["HV"] + s_full["VH"])
        return [s_full[c] for c in self.channels]

    def gain(self, v, view: PulseView):
        """One-way field pattern of the uniform aperture toward unit direction ``v`` (antenna -> scene):
        ``sinc(L sin(phi_az) / lambda) sinc(H_a sin(phi_el) / lambda)``, eq. (A). In spotlight the
        beam is steered at the scene centre, as a phased array steers: ``sin(phi_az)`` is taken
        relative to the centre's, ``sin(phi) - sin(phi_c)``. On a curved track the axes are the
        pulse's own (``view``)."""
        steer = view.steer
        axis = mi.Vector3f(*self.aperture_axis) if view.aperture is None else view.aperture
        along = dr.dot(v, axis)
        gain = mi.Float(1.0)
        if self.length_in_wavelengths > 0:          # the main lobe, zero beyond its first nulls
            x = self.length_in_wavelengths * (along - steer if steer is not None else along)
            gain *= dr.select(dr.abs(x) < 1.0, _sinc(math.pi * x), 0.0)
        if self.height_in_wavelengths > 0:
            across = dr.normalize(v - axis * along)
            elevation = mi.Vector3f(*self.elevation_axis) if view.elevation is None else view.elevation
            gain *= _sinc(math.pi * self.height_in_wavelengths * dr.dot(across, elevation))
        return gain

    def rx_gain(self, v, view: PulseView):
        """Bistatic: the receiver's one-way field pattern toward unit direction ``v`` (receiver ->
        scene), eq. (B3): its uniform aperture ``receiver_antenna_length`` x ``receiver_antenna_height``
        staring at the scene centre, ``sinc(L_r (sin(phi_az) - sin(phi_c)) / lambda) sinc(H_r
        sin(phi_el) / lambda)`` about its along-track and elevation axes."""
        axis, elevation = view.rx_axes
        along = dr.dot(v, axis)
        gain = mi.Float(1.0)
        if self.rx_length > 0:
            x = self.rx_length * (along - view.rx_steer)
            gain *= dr.select(dr.abs(x) < 1.0, _sinc(math.pi * x), 0.0)
        if self.rx_height > 0:
            gain *= _sinc(math.pi * self.rx_height * dr.dot(dr.normalize(v - axis * along), elevation))
        return gain

    def weight(self, d_first, b, s, dist, lref, view: PulseView):
        """Antenna pattern (A) and radiometric spreading (R1) of a return reached along ``d_first`` on
        its first leg and leaving toward the antenna along ``b``, ``dist`` away, at unfolded length
        ``s`` (float64 lengths): the two-way pattern ``g(d_first) g(-b)`` and ``R_ref^2 / (s R_rx)``;
        1 when neither effect is on."""
        weight = mi.Float(1.0)
        if self.pattern:
            weight *= self.gain(d_first, view) * (self.gain(-b, view) if not self.bistatic else 1.0)
        if view.rx_steer is not None:                 # the receiver's own pattern, eq. (B3)
            weight *= self.rx_gain(-b, view)
        if self.radiometry:
            rref = mi.Float(0.5 * lref)
            weight *= rref * rref / (mi.Float(s) * mi.Float(dist))
        return weight

    def carrier_phase(self, rel) -> mi.Complex2f:
        """``exp(-j k rel)`` for a float64 length ``rel`` (reduced mod 2 pi in float64 first), eq. (S1)."""
        phase = -self.k * rel
        phase = mi.Float(phase - (2.0 * math.pi) * dr.round(phase * (1.0 / (2.0 * math.pi))))
        sn, cs = dr.sincos(phase)
        return mi.Complex2f(cs, sn)

    def anchor(self, rel, lref) -> tuple[mi.Int32, mi.Float]:
        """A delay on the fine grid, from ``L - L_ref`` (float64): ``(bin, frac)``, ``bin + frac`` fine
        bins after ``t0``, ``frac`` in [0, 1). Offsets from it are added in float32."""
        if not hasattr(self, "_fine_grid"):   # the window's start and step as values, not literals (one kernel for any window)
            self._fine_grid = (dr.opaque(mi.Float64, SPEED_OF_LIGHT * self.window.t0),
                               dr.opaque(mi.Float64, 1.0 / self.window.fine_step_length))
        start, per_length = self._fine_grid
        position = (rel + (lref - start)) * per_length
        first = dr.floor(position)
        return mi.Int32(first), mi.Float(position - first)

    def _pulse(self, ctx, sub, q):
        """Pulse ``first[sub] + q`` of a lane's sub-aperture: its batch index, antenna position,
        reference length and :class:`PulseView` (beam steering, axes, motion)."""
        pulse = dr.gather(mi.UInt32, ctx["first"], sub) + q
        antenna = dr.gather(mi.Array3f64, ctx["antenna"], pulse)
        lref = dr.gather(mi.Float64, ctx["lref"], pulse)
        return pulse, antenna, lref, self.view(ctx, pulse)

    def view(self, ctx, pulse) -> PulseView:
        """The :class:`PulseView` of batch pulse ``pulse``: only what the acquisition's effects need."""
        view = PulseView(steer=dr.gather(mi.Float, ctx["steer"], pulse) if self.spotlight else None)
        if self.curved:
            view.axis = dr.gather(mi.Array3f64, ctx["axis"], pulse)
            view.aperture = dr.gather(mi.Vector3f, ctx["aperture"], pulse)
            view.elevation = dr.gather(mi.Vector3f, ctx["elevation"], pulse)
        if self.continuous:
            view.velocity = dr.gather(mi.Array3f64, ctx["velocity"], pulse)
            view.acceleration = dr.gather(mi.Array3f64, ctx["acceleration"], pulse)
        if self.bistatic:
            view.receiver = dr.gather(mi.Array3f64, ctx["receiver"], pulse)
            if "rx_steer" in ctx:
                view.rx_steer = dr.gather(mi.Float, ctx["rx_steer"], pulse)
                view.rx_axes = (dr.gather(mi.Vector3f, ctx["rx_axis"], pulse),
                                dr.gather(mi.Vector3f, ctx["rx_elevation"], pulse))
        return view

    @staticmethod
    def _folded(rec, v, depth: int):
        """A vector of the unfolded path in the scene: ``M v`` (the mirror chain's linear part)."""
        if depth == 0:
            return mi.Vector3f(v)
        v = mi.Vector3f(v)
        return rec.m1 * v.x + rec.m2 * v.y + rec.m3 * v.z

    def _in_beam(self, aim, antenna, view: PulseView):
        """Whether the pulse at ``antenna`` casts the tube aimed at ``aim`` (its traced beam)."""
        sine = self.aim_sine(aim, antenna, view.axis)
        return (sine >= self.beam_sines[0]) & (sine <= self.beam_sines[1])

    def _d_first(self, depth, d, first_hit, antenna):
        """The first leg's direction: the term's own incoming direction at the first bounce, the
        direction to the tube's first hit after it (transmit pattern, eq. (A))."""
        if depth == 0:
            return d
        return mi.Vector3f(dr.normalize(first_hit - antenna))

    # ------------------------------------------------------------------ tallies at the reference
    def tally(self, ctx, rec, hit, d, alpha, specular, r, count, depth: int, vis) -> None:
        """Energy of the visible returns (each tube's whole PO value at the carrier, at the
        sub-aperture's reference position, times its pulses) and of those outside the window;
        ``d`` is the tube's direction at the hit."""
        st = self.settings
        lref = dr.gather(mi.Float64, ctx["middle"], rec.sub)
        antenna = dr.gather(mi.Array3f64, ctx["reference"], rec.sub)
        middle = dr.gather(mi.UInt32, ctx["first"], rec.sub) + dr.gather(mi.UInt32, ctx["count"], rec.sub) // 2
        view = self.view(ctx, middle)
        if self.spotlight:                   # steered from the reference position
            track = mi.Array3f64(*self.fp.track.tolist()) if view.axis is None else view.axis
            to_c = mi.Array3f64(*self.fp.origin.tolist()) - antenna
            view.steer = mi.Float(dr.dot(to_c, track) / dr.norm(to_c))
        weight = self.weight(self._d_first(depth, d, rec.first_hit, antenna), hit.b, hit.s, hit.dist, lref, view)
        scale = (math.sqrt(math.pi) / self.lam) * (hit.cos_i + hit.cos_b) * specular * weight
        area = dr.norm(dr.cross(rec.e1, rec.e2))
        carrier = rec.gamma * r * (scale * area * _sinc(alpha[0]) * _sinc(alpha[1]))
        power = dr.squared_norm(carrier) * count
        self.sums.tally(ctx, "energy", power, depth, vis)
        rel = hit.s + hit.dist - lref
        bin_, frac = self.anchor(rel, lref)
        outside = (bin_ < 0) | (bin_ >= self.window.n_fine - 1)
        self.sums.tally(ctx, "energy", power, st.depth, vis & outside)

    # ------------------------------------------------------------------ the returns of one order
    def deposit(self, ctx, rec, depth: int, n_lanes: int) -> None:
        """Deposit the returns of one bounce order's records for every pulse of their sub-apertures."""
        index, code = self.terms(ctx, rec, n_lanes)
        if dr.width(index):
            ctx["evaluated"] += int(dr.sum(dr.gather(mi.UInt32, ctx["count"], dr.gather(mi.UInt32, rec.sub, index)))[0])
            undecided = (dr.gather(mi.UInt32, rec.flags, index) & (_UNDECIDED_1 | _UNDECIDED_2)) != 0
            for per_pulse in (False, True):
                part = dr.compress(undecided if per_pulse else ~undecided)
                if dr.width(part):
                    terms, codes = dr.gather(type(rec), rec, dr.gather(mi.UInt32, index, part)), dr.gather(mi.UInt32, code, part)
                    dr.eval(terms, codes)
                    self.po(ctx, terms, codes, depth, per_pulse)
        if self.clutter_on:
            kind = dr.gather(mi.UInt32, self.tables.clutter_kind, rec.row)
            rough = dr.compress((kind > 0) & ((rec.flags & _MESH_ONLY) == 0))     # the patches' own (M7)
            if dr.width(rough):
                hits = dr.gather(type(rec), rec, rough)
                dr.eval(hits)
                self.clutter(ctx, hits, depth)

    def terms(self, ctx, rec, n_lanes: int):
        """The PO terms of the records that survive cancellation, eqs. (PO2), (PO5).

        A footprint's edge that is split has a term at each end (``sigma = -1, +1``), an unsplit
        one a term on its centre line (``sigma = 0``); an edge whose split depends on the pulse
        (undecided over the sub-aperture, (T3)) has all three candidates, and each pulse keeps the
        ones its own split says. Where the tubes sharing a term's point (the lattice neighbours
        across the split edges) all hit the same facet plane after the same facets, are all
        visible, split the same edges for every pulse and lie inside the beam of every pulse of
        the sub-aperture, their terms are the same function of the pulse with signs that sum to
        zero: they cancel at every frequency, and none is evaluated. Returns the term list: record
        index and term code ``3 (sigma_1 + 1) + (sigma_2 + 1)``.
        """
        n_rec = dr.width(rec.flags)
        lane = dr.arange(mi.UInt32, 9 * n_rec)
        r_i = lane // 9
        c = lane - 9 * r_i
        sig1, sig2 = mi.Int32(c // 3) - 1, mi.Int32(c % 3) - 1
        flags = dr.gather(mi.UInt32, rec.flags, r_i)
        split1, split2 = (flags & _SPLIT_1) != 0, (flags & _SPLIT_2) != 0
        open1, open2 = (flags & _UNDECIDED_1) != 0, (flags & _UNDECIDED_2) != 0
        survive = (open1 | dr.select(split1, sig1 != 0, sig1 == 0)) & (open2 | dr.select(split2, sig2 != 0, sig2 == 0))
        survive &= (flags & _MESH_ONLY) == 0       # chains of mesh parts: the patches return them (M5)
        if self.cancel_interior:
            where = dr.full(mi.UInt32, _INVALID, n_lanes)
            dr.scatter(where, dr.arange(mi.UInt32, n_rec), rec.lattice)
            key = dr.gather(mi.UInt32, rec.key, r_i)
            lattice = dr.gather(mi.UInt32, rec.lattice, r_i)
            has_i = (flags & dr.select(sig1 > 0, _HAS_I_HI, _HAS_I_LO)) != 0
            has_j = (flags & dr.select(sig2 > 0, _HAS_J_HI, _HAS_J_LO)) != 0
            stride = mi.Int32(dr.gather(mi.UInt32, ctx["block_nj"], dr.gather(mi.UInt32, rec.block, r_i)))

            def compatible(step_i, step_j, exists):
                other = dr.gather(mi.UInt32, where, mi.UInt32(mi.Int32(lattice) + step_i * stride + step_j), exists)
                ok = exists & (other != _INVALID)
                return ok & (dr.gather(mi.UInt32, rec.key, other, ok) == key) \
                    & ((dr.gather(mi.UInt32, rec.flags, other, ok) & _MATCH) == (flags & _MATCH))

            zero = mi.Int32(0)
            cancelled = ((flags & _INTERIOR) != 0) & (split1 | split2) & ~open1 & ~open2
            cancelled &= ~split1 | compatible(sig1, zero, has_i)
            cancelled &= ~split2 | compatible(zero, sig2, has_j)
            cancelled &= ~(split1 & split2) | compatible(sig1, sig2, has_i & has_j)
            survive &= ~cancelled
        dr.eval(survive)
        index = dr.compress(survive)      # (empty where every term is cancelled or the patches')
        return (index // 9, index - 9 * (index // 9)) if dr.width(index) else (index, index)

    def _cell(self, ctx, block):
        """The aim cell's edge vectors (along track, ground range) of the tubes of ``block``, float64."""
        scale = 1.0 / mi.Float64(dr.gather(mi.UInt32, ctx["block_m"], block))
        return [mi.Array3f64(*self.fp.track.tolist()) * (self.fp.spacing_azimuth * scale),
                mi.Array3f64(*self.fp.look.tolist()) * (self.fp.spacing_range * scale)]

    def _alpha(self, rec, reference, antenna, cell, depth: int):
        """Half the phase across each of the sub-aperture's tile's edges at its centre,
        ``k (d - b) . e_j / 2``, as the pulse at ``antenna`` sees it (float32 pair)."""
        centre, _, d, edges = self._tile(rec, reference, antenna, rec.aim, cell, mi.Array3f64(rec.n_unfolded), depth)
        u = d - mi.Vector3f(dr.normalize(antenna - centre))
        return [0.5 * self.k * dr.dot(u, e) for e in edges]

    def splits(self, ctx, rec, reference, depth: int):
        """Which footprint edges split (PO2): ``alpha`` at the reference position (for the energy
        tally), and per edge whether it splits for every pulse of the sub-aperture or only for
        some, eq. (T3). Over the sub-aperture (its first, middle and last pulse) an edge keeps its
        sinc when ``|alpha|`` stays below the split threshold (:func:`split_threshold`), splits when
        it reaches it somewhere and stays at least :data:`SINC_REGIME` with one sign (both forms
        hold in between), and is decided per pulse otherwise. With one pulse per trace an edge
        splits at the threshold."""
        cell = self._cell(ctx, rec.block)
        first = dr.gather(mi.UInt32, ctx["first"], rec.sub)
        last = first + dr.gather(mi.UInt32, ctx["count"], rec.sub) - 1
        alpha = self._alpha(rec, reference, reference, cell, depth)
        ends = [self._alpha(rec, reference, dr.gather(mi.Array3f64, ctx["antenna"], p), cell, depth) for p in (first, last)]
        split, undecided = [], []
        for j in range(2):
            values = (alpha[j], ends[0][j], ends[1][j])
            low = dr.minimum(dr.abs(values[0]), dr.minimum(dr.abs(values[1]), dr.abs(values[2])))
            high = dr.maximum(dr.abs(values[0]), dr.maximum(dr.abs(values[1]), dr.abs(values[2])))
            same = (values[0] * values[1] > 0) & (values[0] * values[2] > 0)
            sinc = high < self.split_at
            split.append(~sinc & (low >= SINC_REGIME) & same)
            undecided.append(~split[j] & ~sinc)
        return alpha, split, undecided

    def pulse_split(self, rec, reference, antenna, cell, nu, depth: int, decided, undecided):
        """The tile's two split flags for the pulse at ``antenna`` (``decided``, or where ``undecided``
        its own ``|alpha|`` at the tile's centre, (T3)), that centre and ``u = d - b`` there."""
        centre, _, d_c, edges_c = self._tile(rec, reference, antenna, rec.aim, cell, nu, depth)
        u_c = d_c - mi.Vector3f(dr.normalize(antenna - centre))
        return [dr.select(o, dr.abs(0.5 * self.k * dr.dot(u_c, e)) >= self.split_at, s_)
                for o, s_, e in zip(undecided, decided, edges_c)], centre, u_c

    def _tile(self, rec, reference, antenna, corner, cell, nu, depth: int):
        """A point ``corner`` of the aim cell on the facet, where the unfolded ray from ``reference``
        meets its unfolded plane (``x_u``, fixed on the surface for the sub-aperture), as the pulse
        at ``antenna`` reaches it, eq. (T3): the scene point (float64), the unfolded length
        ``|x_u - A_p|``, the direction ``d`` there and the tile's local edges."""
        w = corner - reference
        nw = dr.dot(nu, w)
        t = dr.dot(nu, rec.unfolded - reference) / nw
        unfolded = reference + w * t                    # x_u
        point = rec.p64 + mi.Array3f64(self._folded(rec, unfolded - rec.unfolded, depth))
        edges = [self._folded(rec, (v - w * (dr.dot(nu, v) / nw)) * t, depth) for v in cell]
        leg = unfolded - antenna
        return point, dr.norm(leg), self._folded(rec, leg / dr.norm(leg), depth), edges

    def po(self, ctx, rec, code, depth: int, per_pulse: bool) -> None:
        """Per pulse, the PO terms at their own points, eqs. (PO1)-(PO4), (T3).

        A term belongs to a corner, edge midpoint or the centre of the tube's aim cell ``c``
        (world-fixed on the aim plane), at the tile's point ``x`` where the unfolded ray from
        ``A_ref`` through ``c`` meets the facet (:meth:`_tile`: fixed on the surface for the
        sub-aperture, as its membership is). For each pulse at ``A``: the unfolded length ``s``
        and ``R = |A - x|`` (float64), the directions, obliquity, reflection coefficient, pattern
        and spreading, and the phase gradient ``(d - b) . e_j`` along the tile's local edges
        ``e_j``: ``j sigma / (k (d - b) . e_j)`` for a split edge's end, ``sinc(k (d - b) . e_j /
        2)`` for an unsplit edge. Tubes that share a corner compute it alike, so their terms there cancel
        (PO5). ``per_pulse``: the records' splits are undecided over the sub-aperture; each
        pulse decides them at the tube's centre, as its own trace would.
        """
        k = self.k
        flags = rec.flags
        decided = [(flags & _SPLIT_1) != 0, (flags & _SPLIT_2) != 0]
        sigma = [mi.Float(code // 3) - 1.0, mi.Float(code % 3) - 1.0]
        n, nu = rec.n, mi.Array3f64(rec.n_unfolded)
        cell = self._cell(ctx, rec.block)
        reference = dr.gather(mi.Array3f64, ctx["reference"], rec.sub)
        corner = rec.aim + cell[0] * mi.Float64(0.5 * sigma[0]) + cell[1] * mi.Float64(0.5 * sigma[1])
        specular = self.tables.read("specular", rec.row)
        count, term = dr.gather(mi.UInt32, ctx["count"], rec.sub), dr.arange(mi.UInt32, dr.width(code))
        paths = self.sums.path_buffers(dr.width(code) * ctx["max_count"]) if self.exact else None
        open_ = [(flags & _UNDECIDED_1) != 0, (flags & _UNDECIDED_2) != 0]

        def body(q):
            pulse, antenna, lref, view = self._pulse(ctx, rec.sub, q)
            split, active = decided, self._in_beam(rec.aim, antenna, view) if self.aim_mask else mi.Bool(True)
            if per_pulse:                     # the pulse's own split at the tube's centre
                split = self.pulse_split(rec, reference, antenna, cell, nu, depth, decided, open_)[0]
                for s_, sg in zip(split, sigma):
                    active &= dr.select(s_, sg != 0.0, sg == 0.0)
            point, s, d, edges = self._tile(rec, reference, antenna, corner, cell, nu, depth)
            outgoing, dist = receive_leg(view, antenna, point, s)
            b = mi.Vector3f(outgoing / dist)
            cos_i, cos_b = -dr.dot(n, d), dr.dot(n, b)
            scale = (math.sqrt(math.pi) / self.lam) * (cos_i + cos_b) * specular * dr.norm(dr.cross(*edges)) \
                * self.weight(self._d_first(depth, d, rec.first_hit, antenna), b, s, dist, lref, view)
            value = mi.Complex2f(0.0, scale) * rec.gamma
            u = d - b
            for j, e in enumerate(edges):
                g = dr.dot(u, e)
                value = value * dr.select(split[j], mi.Complex2f(0.0, sigma[j] / (k * g)),
                                          mi.Complex2f(_sinc(0.5 * k * g), 0.0))
            rel = s + dist - lref
            # a tile corner the pulse sees from behind the facet, or edge-on (the unfolded ray in the
            # facet's plane): no return. A property of the corner and the pulse, so the tubes sharing
            # the corner agree and cancellation (PO5) is unaffected.
            active &= (cos_i > COS_GRAZING) & (s > 0)
            order_index = mi.UInt32(SPECTRAL_ORDERS.index(1)) - mi.UInt32(split[0]) - mi.UInt32(split[1])
            value = value * self.carrier_phase(rel)
            values = [value * c for c in self.po_channels(rec, d, b, n, cos_i, depth)]
            self.sums.deposit(ctx, pulse, depth, self.anchor(rel, lref), 0.0, values,
                          order_index, active, paths, term * ctx["max_count"] + q)
            return (q + 1,)

        dr.while_loop((mi.UInt32(0),), lambda q: q < count, body, mode=loop_mode(), label="pulses")
        if paths is not None:
            self.sums.keep_paths(ctx, paths)
