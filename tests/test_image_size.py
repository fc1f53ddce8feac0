"""``simulate(..., image_size=, image_spacing=)``: an exact ground grid, checked before tracing."""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.analysis import point_target as analysis
from sarmitsuba import pipeline
from sarmitsuba.core.radar import ParameterError


def test_exact_image_size_and_spacing_keep_the_target_in_place():
    sim = pipeline.simulate("trihedral", sensor_overrides={"n_pulses": 64}, image_size=(64, 48), image_spacing=0.25)
    assert sim.image.data.shape == (64, 48)
    np.testing.assert_allclose(np.diff(sim.image.azimuth), 0.25)
    np.testing.assert_allclose(np.diff(sim.image.range), 0.25)
    rep = analysis.analyze_point_target(sim.image, [0.0, 0.0, 0.0], chip=32)
    assert abs(rep.azimuth_error_cells) < 0.05 and abs(rep.range_error_cells) < 0.05


@pytest.mark.parametrize("size, spacing", [((1, 64), None), ((64, 0), None), ((64, 64), 0.0), ((64, 64), -1.0)])
def test_bad_image_size_fails_before_tracing(monkeypatch, size, spacing):
    monkeypatch.setattr(pipeline, "trace", lambda *a, **k: pytest.fail("traced despite a bad image size"))
    with pytest.raises(ParameterError, match="image_s"):
        pipeline.simulate("trihedral", image_size=size, image_spacing=spacing)
