"""A recessed window's edges at the second bounce, traced by sub-apertures (docs/physics.md (M8), (E4), (E6)).

A PEC wall with one window recessed 0.15 m (sill, head, two reveals, a pane at the back) is the
regression scene of a deliberate bug: a sub-aperture moves its segments' ends with the antenna
(M8), and a 1.4 mm segment on the pane's bottom edge, cut by a mirrored window's line at the
second bounce, shrinks to exactly zero length at one of its pulses. The fringe (E4) and double
(E6) terms took the edge's tangent as ``normalize(edge)``, NaN there, and deposited NaN times the
segment's zero line integral: the render raised UnrepresentableSum (D7) at 35 and 50 deg (not at
45). :func:`sarmitsuba.tracing.integration.edge_terms.edge_tangent` takes the wedge's own
direction where the segment has no length; the term is then zero, the shrinking segment's limit.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import sarmitsuba as sm
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.facades import FacadeLayout, wall_with_windows


def _nrmse_db(a: np.ndarray, b: np.ndarray) -> float:
    error = float(np.sum(np.abs(a - b) ** 2))
    return 10.0 * math.log10(error / np.sum(np.abs(b) ** 2)) if error > 0 else float("-inf")


def _recessed_window(incidence: float) -> sm.Scene:
    layout = FacadeLayout(floor_height=6.0, window_width=1.2, window_height=1.5, window_spacing=12.0,
                          sill_height=3.0, recess_depth=0.15)
    v, f, pv, pf = wall_with_windows((6, 0), (-6, 0), 0.0, 6.0, 6.0, 0.0, 6.0, layout)
    shapes = [(trimesh.Trimesh(v, f, process=False), "pec", "wall"),
              (trimesh.Trimesh(pv, pf, process=False), "pec", "pane")]
    sensor = {"bandwidth": 150e6, "azimuth_beamwidth": 0.5, "prf": 250, "scene_center": (0.0, 0.0, 0.0),
              "incidence_angle": incidence}
    return sm.Scene(shapes, name="recessed window", sensor=sensor, integrator={"max_depth": 2})


@pytest.mark.parametrize("incidence", [35.0, 50.0])
def test_recessed_window_edges_are_finite_and_image_like_per_pulse_tracing(incidence):
    """Before the fix the sub-aperture render raised UnrepresentableSum (a NaN fringe term of a
    moved segment of zero length). Now the image is finite and agrees with per-pulse tracing,
    which moves nothing, as test_subaperture.py's sub-apertures do (measured -64.5 dB at 35 deg and
    -69.5 dB at 50 deg; the limit is the trihedral's there)."""
    many = simulate(_recessed_window(incidence))
    one = simulate(_recessed_window(incidence), integrator_overrides={"pulses_per_trace": 1})
    assert many.trace.pulses_per_trace > 1 and one.trace.pulses_per_trace == 1
    assert np.all(np.isfinite(many.image.data))
    assert np.any(many.image.data != 0)
    error = _nrmse_db(many.image.data, one.image.data)
    assert error < -50.0, f"image NRMSE {error:.1f} dB against per-pulse tracing"
