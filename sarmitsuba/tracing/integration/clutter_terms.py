"""Clutter scatterers in the kernel: per pulse, every scatterer of a rough surface's own lattice
inside a recorded hit's footprint, its amplitude, second-order two-way length and hashed phase,
deposited on the fast-time grid (docs/physics.md (C), the bistatic sigma nought (C2), the
polarimetric channels of (P7) and, after mirrors, both orderings of the path (P9)); a part of
:class:`sarmitsuba.tracing.integration.returns.Returns`. The lattice's steps are
:mod:`sarmitsuba.tracing.integration.clutter_lattice`'s.
"""
from __future__ import annotations

import functools

import drjit as dr
import mitsuba as mi

from ...core.radar import CHANNELS
from ..deposit.accumulate import PATH_HEADROOM
from .clutter_lattice import footprint_cells, lattice_frame, length_expansion, scatterer, shortened_footprint, surface_key
from ..deposit.fast_time import SPECTRAL_ORDERS
from . import jones as pol
from .rough_sigma import azimuth_cosine, bistatic_sigma0_table, mono_sigma0
from .pulse_view import receive_leg
from ..loops import loop_mode

__all__ = ["ClutterTerms", "bistatic_sigma0"]

# flag of kernel.Flags (repeated here: the kernel imports this module through returns)
_BACK = 128


def bistatic_sigma0(kind, value, cos_i, cos_b, r_in, r_out):
    """Sigma nought of a rough surface's scatterer met at ``cos_i`` (the incidence cosine, from
    the facet's normal) and leaving at ``cos_b`` (the scattering cosine), docs/physics.md (C2):
    the geometric mean of the two monostatic (C) values, ``sqrt(sigma0_mono(theta_i)
    sigma0_mono(theta_b))`` (Willis, *Bistatic Radar*, 2nd ed., 2005: the bistatic constant-gamma
    model). ``kind`` 1 (constant gamma, ``value = gamma``): ``gamma sqrt(cos_i cos_b)``; ``kind``
    2 (Lambertian, ``value = 4 S^2``): ``4 S^2 |r(cos_i)| |r(cos_b)| cos_i cos_b`` with ``r_in``,
    ``r_out`` the facet's reflection coefficient at the two angles; 0 for any other kind.
    Symmetric in the two directions (swap ``cos_i, r_in`` with ``cos_b, r_out``); equal to (C)
    where they coincide. Drjit arrays of one width (``kind`` mi.UInt32, the rest mi.Float,
    ``r_*`` mi.Complex2f), cosines in [0, 1]; returns mi.Float, dimensionless (m^2 / m^2)."""
    lambert = value * dr.sqrt(dr.squared_norm(r_in) * dr.squared_norm(r_out)) * cos_i * cos_b
    return dr.select(kind == 1, value * dr.sqrt(cos_i * cos_b), dr.select(kind == 2, lambert, 0.0))


class ClutterTerms:
    """The clutter methods of :class:`sarmitsuba.tracing.integration.returns.Returns` (which provides the tables,
    the footprint, ``_pulse``, ``_folded``, ``_in_beam``, ``_d_first``, ``_arriving``,
    ``reciprocal``, ``weight``, ``anchor``, ``carrier_phase``, the reflection tables and the
    accumulator)."""

    def clutter(self, ctx, rec, depth: int, lattice: dict | None = None) -> None:
        """Per pulse, every scatterer of the surface's own lattice inside the footprint, eq. (C).

        The lattice lies in the plane of the hit (frame ``u, v`` from the surface normal, origin
        at a point fixed to the shape), cells ``c`` wide; cell ``(iu, iv)`` of a shape holds one
        scatterer at a hashed position inside it with a hashed phase (an integer hash of the shape,
        the plane, the cell and the seed). Its amplitude is ``sqrt(sigma0) c prod(r_1 .. r_{k-1})``;
        its two-way length is the pulse's length to the tube's hit point expanded to second order in
        the offset. The footprints (the reference position's) tile a plane, so every scatterer is
        counted once per pulse: the same scatterers, with the same phases and positions, for every
        pulse, bounce order and pass. The lattice's steps are :mod:`sarmitsuba.tracing.integration.clutter_lattice`'s.
        """
        lattice = lattice or self._clutter_lattice(ctx, rec, depth)
        count = dr.gather(mi.UInt32, ctx["count"], rec.sub)
        paths = self.sums.path_buffers(max(ctx["capacity"], PATH_HEADROOM)) if self.exact else None

        def pulse_body(q):
            self._clutter_pulse(ctx, rec, depth, lattice, q, paths)
            return (q + 1,)

        dr.while_loop((mi.UInt32(0),), lambda q: q < count, pulse_body, mode=loop_mode(), label="pulses")
        if paths is not None:
            self.sums.keep_paths(ctx, paths)

    def _clutter_lattice(self, ctx, rec, depth: int) -> dict:
        """The pulse-independent part of eq. (C) per hit: the (shortened) footprint's cells on the
        surface's lattice, the lattice's frame and hash key, the clutter model and sigma0's raise."""
        t, c = self.tables, self.fp.scatterer_spacing
        back = (rec.flags & _BACK) != 0
        n_geo = dr.select(back, -rec.n, rec.n)                          # the surface's own normal
        d_ref = self._folded(rec, dr.normalize(rec.unfolded - dr.gather(mi.Array3f64, ctx["reference"], rec.sub)),
                             depth)
        e1, e2, raise_by = shortened_footprint(rec.e1, rec.e2, rec.n, n_geo, d_ref)
        axes = tuple(dr.gather(mi.Vector3f, a, rec.shape) for a in t.shape_axes)   # the shape's own frame
        u_axis, v_axis = lattice_frame(n_geo, axes)
        # the hit from the shape's origin (float64 difference, then float32)
        local = mi.Vector3f(rec.p64 - dr.gather(mi.Array3f64, t.shape_origin, rec.shape))
        return dict(kind=dr.gather(mi.UInt32, t.clutter_kind, rec.row),
                    value=t.read("clutter_value", rec.row), raise_by=raise_by, axes=(u_axis, v_axis), cells=footprint_cells(local, e1, e2, u_axis, v_axis, c),
                    key0=surface_key(dr.gather(mi.UInt32, t.shape_key, rec.shape), back, n_geo, local, axes, c,
                                     self.settings.seed))

    def _clutter_pulse(self, ctx, rec, depth: int, lattice: dict, q, paths) -> None:
        """Pulse ``q`` of the hits' sub-apertures: sigma0 and the amplitude ``a_c`` at the hit, then
        each scatterer of the footprint at its second-order length ``L_c``, deposited, eq. (C)."""
        c, n, kind, value = self.fp.scatterer_spacing, rec.n, lattice["kind"], lattice["value"]
        pulse, antenna, lref, view = self._pulse(ctx, rec.sub, q)
        incoming = rec.unfolded - antenna                                    # unfolded first leg
        s = dr.norm(incoming)
        outgoing, dist = receive_leg(view, antenna, rec.p64, s)             # to the antenna at reception (J3)
        d, b = self._folded(rec, incoming / s, depth), mi.Vector3f(outgoing / dist)
        cos_i, cos_b = dr.maximum(-dr.dot(n, d), 0.0), dr.maximum(dr.dot(n, b), 0.0)
        co, cross, level = self.rough_returns(rec, d, b, n, (cos_i, cos_b), (kind, value * lattice["raise_by"]), depth)
        rough = (level > 0) & (self._in_beam(rec.aim, antenna, view) if self.aim_mask else True)
        weight = self.weight(self._d_first(depth, d, rec.first_hit, antenna), b, s, dist, lref, view)
        rel = s + dist - lref
        anchor = self.anchor(rel, lref)
        amplitude = rec.gamma * self.carrier_phase(rel) * (c * weight)
        expansion = length_expansion(d, b, s, dist, *lattice["axes"], c)
        n_cells = dr.select(rough, lattice["cells"].cells, 0)
        mid = mi.UInt32(SPECTRAL_ORDERS.index(0))

        def step(i, found, outside):
            own, dl, phase, phase_x = scatterer(i, lattice["cells"], lattice["key0"], expansion, n_cells, self.k,
                                                cross=cross is not None, inside=lattice.get("inside"))
            sn, cs = dr.sincos(phase)
            here = amplitude * mi.Complex2f(cs, sn)
            values = [here * a for a in co]
            if cross is not None:
                sn, cs = dr.sincos(phase_x)
                there = amplitude * mi.Complex2f(cs, sn)
                values = [v + there * a for v, a in zip(values, cross)]
            inside = self.sums.deposit(ctx, pulse, depth, anchor, dl, values, mid, own, paths, None)
            return i + 1, found + mi.UInt32(own), outside + mi.UInt32(own & ~inside)

        _, found, outside = dr.while_loop((mi.UInt32(0), mi.UInt32(0), mi.UInt32(0)),
                                          lambda i, *_: i < n_cells, step, mode=loop_mode(), label="scatterers")
        power = dr.squared_norm(amplitude) * level
        self.sums.tally(ctx, "energy", mi.Float(found) * power, depth, rough)
        self.sums.tally(ctx, "energy", mi.Float(outside) * power, self.settings.depth, rough)
        dr.scatter_add(ctx["scatterers"], found, mi.UInt32(depth), rough, mode=ctx["tally"])

    def rough_returns(self, rec, d, b, n, cosines: tuple, model: tuple, depth: int):
        """Per channel, the co-polarised and the cross-polarised factor of a rough surface's
        scatterer (its own phases aside), for the pulse's incidence ``d`` and return ``b`` (unit
        mi.Vector3f), the facet normal ``n`` on the side met, ``cosines = (cos_i, cos_b)`` and
        ``model = (kind, value)`` of :func:`bistatic_sigma0`; ``rec`` gives the material ``row``
        and, after bounces, the tube's ``jones``.

        A single bounce returns the one path traced: ``sqrt(sigma0)`` of (C2) (scalar), or
        ``S = B^T C J`` of (P7) with ``C`` of :func:`sarmitsuba.tracing.integration.jones.scatter_rough`,
        ``a_te = sqrt(sigma0(r_te))``, ``a_tm = sqrt(sigma0(r_tm))``, ``a_x = sqrt(q (a_te^2 +
        a_tm^2) / 2)``. After mirrors (``depth > 0``) the reverse ordering of the path (scatterer
        first, mirrors after; not traced, of the same length) is added, eq. (P9):
        ``S_direct + S_reverse^T`` with the reverse's amplitudes (C2) at the swapped directions.
        Returns ``(co, cross, level)``: lists of mi.Complex2f (or mi.Float, scalar) in the order
        of the requested channels, ``cross`` None unless polarimetric, and ``level`` (mi.Float)
        the mean co-polarised power factor times ``1 + q`` (the energy tally)."""
        cos_i, cos_b = cosines
        both = depth > 0
        # a rough surface's tables (RS6): monostatic for a direct return to the transmitter
        rough = None if self.tables.rough_mono is None else \
            (rec.row, azimuth_cosine(d, b, n), depth == 0 and not self.bistatic)
        sigma0 = functools.partial(self._sigma0, model, rough)
        if not self.polarimetric:
            r_in, r_out = self.reflection_at(rec.row, cos_i, True), self.reflection_at(rec.row, cos_b, True)
            channel = 1 if self.vv_sign else 0
            # safe_sqrt: sqrt's derivative is infinite at 0 (a smooth row's sigma0); the same values
            a = dr.safe_sqrt(sigma0(cos_i, cos_b, r_in, r_out, channel))
            if both:                 # the reverse ordering: met along -b, leaving along -d
                a = a + dr.safe_sqrt(sigma0(cos_b, cos_i, r_out, r_in, channel))
            return [a], None, a * a
        pair_in, pair_out = self.reflection_pair(rec.row, cos_i, True), self.reflection_pair(rec.row, cos_b, True)
        q = dr.gather(mi.Float, self.tables.cross_pol, rec.row)

        def amplitudes(c_1, c_2, into, out):     # (a_te, a_tm, a_x) of one ordering, eq. (P7)
            s_te, s_tm = (sigma0(c_1, c_2, into[j], out[j], j) for j in (0, 1))
            s_x = q * 0.5 * (s_te + s_tm)
            if rough is not None:
                s_x = dr.select(model[0] == 3, model[1] * self._rough_cross(rough, c_1, c_2), s_x)
            return dr.safe_sqrt(s_te), dr.safe_sqrt(s_tm), dr.safe_sqrt(s_x)

        direct = amplitudes(cos_i, cos_b, pair_in, pair_out)
        reverse = amplitudes(cos_b, cos_i, pair_out, pair_in) if both else None
        one, zero = mi.Complex2f(1.0, 0.0), mi.Complex2f(0.0, 0.0)
        track, arriving = mi.Vector3f(*self.track), self._arriving(rec, d, depth)
        needed = tuple(c for c in CHANNELS if c in self.channels or (both and c[::-1] in self.channels))
        unit = [dict(zip(needed, pol.receive(pol.scatter_rough(arriving, d, b, n, *a), -b, track, needed)))
                for a in ((one, zero, None), (zero, one, None), (zero, zero, one))]

        def channels(parts):                  # sum over the parts of a S(M) (+ a_rev S(M)^T)
            out = []
            for name in self.channels:
                swap = name[::-1]
                value = sum((m[name] * direct[j] for j, m in parts), zero)
                if reverse is not None:
                    value = value + sum((m[swap] * reverse[j] for j, m in parts), zero)
                out.append(value)
            return out
        co, cross = channels([(0, unit[0]), (1, unit[1])]), channels([(2, unit[2])])
        a_te, a_tm = (direct[j] + (reverse[j] if both else 0.0) for j in (0, 1))
        return co, cross, 0.5 * (a_te * a_te + a_tm * a_tm) * (1.0 + q)

    def _sigma0(self, model, rough, cos_1, cos_2, r_1, r_2, channel: int):
        """Sigma nought met at ``cos_1`` and leaving at ``cos_2``: (C2) of :func:`bistatic_sigma0`,
        or for clutter kind 3 the rough surface's table (RS6) of ``channel`` (0 HH, 1 VV), times
        ``model``'s value (sigma0's raise near grazing). ``rough = (row, cos_phi, monostatic)``, or
        None when no material is a rough surface."""
        kind, value = model
        base = bistatic_sigma0(kind, value, cos_1, cos_2, r_1, r_2)
        if rough is None:
            return base
        row, cos_phi, monostatic = rough
        read, active = self.tables.read, kind == 3
        table = mono_sigma0(read, row, channel, cos_1, active) if monostatic else \
            bistatic_sigma0_table(read, row, channel, cos_1, cos_2, cos_phi, active)
        return dr.select(kind == 3, value * table, base)

    def _rough_cross(self, rough, cos_1, cos_2):
        """A rough surface's sigma0_HV (RS6): the monostatic table's, or after a mirror the
        geometric mean of its values at the two angles (the model has no bistatic HV)."""
        row, _, monostatic = rough
        read = self.tables.read
        if monostatic:
            return mono_sigma0(read, row, 2, cos_1)
        return dr.safe_sqrt(mono_sigma0(read, row, 2, cos_1) * mono_sigma0(read, row, 2, cos_2))
