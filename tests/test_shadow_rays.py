"""The rays a render reports casting (``TraceResult.shadow_rays`` and ``rays_per_order``, the
``shadow_rays`` and ``rays_traced`` of summary.json) against the rays it casts.

Truth: a spy on the two methods that cast rays on the mesh tracer's behalf
(:meth:`~sarmitsuba.tracing.visibility.rays.PathVisibility._free`, one visibility ray per lane, and
:meth:`~sarmitsuba.tracing.visibility.rays.Rays._ray`, the host's closest-hit and shadow rays)
counts every ray as it is cast, apart from the tracer's own tallies; and the path geometry of
docs/physics.md (M4), (B2): a monostatic first bounce's one ray from the sample to the antenna is
its way out and its way back, while a bistatic one casts a second ray from each sample, to the
receiver, at every bounce. A plate alone at one bounce has nothing to hide it (no mixed pieces, no
recheck, no occluders cast) and no chains to discover: every ray cast is a visibility ray of its
samples, so ``rays_traced`` must equal the spy's count.

Deliberate bugs these tests were run against (each fails them):
  * every sample counted once as a shadow ray whatever the geometry (the count before the
    receiver's rays were told apart: a monostatic first bounce then reports twice the rays it
    casts, and a bistatic render exactly the monostatic count);
  * the receiver's rays at the first bounce not counted (only the orders past the first).
"""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba
from sarmitsuba.pipeline import simulate
from sarmitsuba.tracing.visibility import rays as rays_module

from test_bistatic import BASE, RECEIVERS, block_scene
from test_patches import rectangle

#: A level 10 m square of concrete at the scene centre: seen by every platform above it.
PLATE = rectangle((0.0, 0.0, 0.0), (5.0, 0.0, 0.0), (0.0, 5.0, 0.0))
ONE_BOUNCE = {"max_depth": 1, "diffraction": False, "polarimetry": "scalar"}


def _spied(monkeypatch, scene) -> tuple:
    """``(simulation, rays cast)``: the rays counted as the two casting methods are called."""
    import drjit as dr
    cast = [0]
    free, ray = rays_module.PathVisibility._free, rays_module.Rays._ray

    def spy_free(self, origin, target):
        cast[0] += dr.width(origin)
        return free(self, origin, target)

    def spy_ray(self, start, end, direction):
        cast[0] += len(start)
        return ray(self, start, end, direction)
    monkeypatch.setattr(rays_module.PathVisibility, "_free", spy_free)
    monkeypatch.setattr(rays_module.Rays, "_ray", spy_ray)
    sim = simulate(scene)
    monkeypatch.undo()
    return sim, cast[0]


@pytest.mark.parametrize("incidence, receiver", [(30.0, None), (60.0, None), (30.0, "beside"), (60.0, "drone")])
def test_a_plate_alone_reports_the_rays_it_casts(monkeypatch, incidence, receiver):
    """The plate at one bounce, monostatic at 30 and 60 deg incidence and received beside the track
    (14 deg) or on a drone across it (about 60 deg): ``rays_traced`` equals the rays the spy saw
    cast. Monostatic, no shadow ray of its own (the ray to each sample is both legs); bistatic,
    one per sample, to the receiver: ``shadow_rays == rays_per_order[0] > 0``."""
    sensor = {**BASE, "incidence_angle": incidence, "n_pulses": 5, **(RECEIVERS[receiver] if receiver else {})}
    sim, cast = _spied(monkeypatch, sarmitsuba.Scene([(PLATE, "concrete", "plate")], sensor=sensor,
                                                     integrator=ONE_BOUNCE))
    t = sim.trace
    assert t.rays_per_order[0] > 0
    assert int(t.rays_per_order.sum() + t.shadow_rays) == cast, (t.rays_per_order, t.shadow_rays, cast)
    assert t.shadow_rays == (t.rays_per_order[0] if receiver else 0)


def test_a_receiver_on_the_transmitters_track_adds_its_first_bounce_rays():
    """A box on the ground at two bounces, received on the transmitter's own track (stop-and-hop):
    the same pieces, samples and second-bounce chains as the monostatic render (the same rays per
    order), and the receiver's own ray from every first-bounce sample on top of the monostatic
    shadow rays: ``shadow_rays`` exceeds the monostatic count by ``rays_per_order[0]`` exactly."""
    sensor = {**BASE, "n_pulses": 16, "prf": 200.0, "heading": 20.0, "stop_and_hop": True}
    same = {"receiver_altitude": 1000.0, "receiver_incidence_angle": 45.0, "receiver_heading": 20.0,
            "receiver_velocity": 100.0}
    mono = simulate(sarmitsuba.Scene(block_scene(), sensor=sensor, integrator={"max_depth": 2})).trace
    bi = simulate(sarmitsuba.Scene(block_scene(), sensor={**sensor, **same}, integrator={"max_depth": 2})).trace
    assert np.array_equal(bi.rays_per_order, mono.rays_per_order) and mono.rays_per_order[1] > 0
    assert mono.shadow_rays > 0
    assert bi.shadow_rays == mono.shadow_rays + bi.rays_per_order[0]
