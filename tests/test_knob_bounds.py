"""Every integrator knob bounded by its physics (docs/physics.md (M1), (T1), (T3)).

No value of ``patch_size``, ``ray_spacing``, ``oversample``, ``pulses_per_trace`` or ``max_depth``
may give a render whose raw data are not finite, or whose energy is more than 20 dB off the
automatic setting's, without a ParameterError naming the knob. Before these bounds, the dihedral
at ``patch_size = 10`` returned raw data 440 times too strong (a split edge end's ``1 / (u . a)``
crossing zero), and a plate with a box 1e27 times; tubes wider than ``pi`` of quadratic phase gave
non-finite samples.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from sarmitsuba.core.constants import SPEED_OF_LIGHT
from sarmitsuba.core.geometry import acquisition_geometry
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.core.raw import RawDataError
from sarmitsuba.pipeline import render, simulate
from sarmitsuba.scene import planning
from sarmitsuba.scene.loader import load_scene
from sarmitsuba.signal import binning

IMAGE = {"image_size": (16, 16), "image_spacing": 1.0}


def _energy(sim) -> float:
    return float(np.sum(np.abs(sim.raw.data.astype(np.complex128)) ** 2))


def _run(integrator: dict):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate("dihedral", integrator_overrides=integrator, **IMAGE)


@pytest.mark.parametrize(("frequency", "near"), [(9.6e9, 1400.0), (1.27e9, 700e3)])
def test_phase_limited_size_reaches_the_phase_exactly(frequency, near):
    """At ``P = phase_limited_size``, the exact two-way spherical path to a patch corner
    (``r = P / sqrt 2`` off the line of sight) departs from the straight one by ``phi / k``: the
    quadratic phase (M1) is the spherical wave's leading term (a second method, not the formula)."""
    from sarmitsuba.core.radar import RadarParameters
    params = RadarParameters(frequency=frequency)
    k = 2.0 * math.pi * frequency / SPEED_OF_LIGHT
    for phi in (planning.PATCH_PHASE, planning.PATCH_PHASE_MAX, planning.TUBE_PHASE_MAX):
        size = planning.phase_limited_size(params, near, phi)
        r = size / math.sqrt(2.0)
        exact = k * 2.0 * (math.hypot(near, r) - near)        # two-way: 2 (sqrt(R^2 + r^2) - R)
        assert exact == pytest.approx(phi, rel=1e-4), (frequency, near, phi, size)


def test_patch_size_refused_beyond_its_bound_and_accepted_up_to_it():
    """The dihedral (X band, R_near about 1404 m): the largest valid patch is the whole number of
    scatterer cells below sqrt(2 R_near (pi / 4) / k) (about 3.3 m), as the message says."""
    loaded = load_scene("dihedral")
    p, lo, hi = loaded.params, loaded.bbox_lo, loaded.bbox_hi
    geometry = acquisition_geometry(p)
    cell = planning.scatterer_spacing(p, loaded.settings)
    near = float(np.min(np.linalg.norm(np.clip(geometry.positions, lo, hi) - geometry.positions, axis=1)))
    k = 2.0 * math.pi * p.frequency / SPEED_OF_LIGHT
    largest = cell * math.floor(math.sqrt(2.0 * near * (math.pi / 4) / k) / cell)
    assert 2.5 < largest < 3.4
    settings = lambda size: loaded.settings.__class__(patch_size=size)    # noqa: E731
    assert planning.patch_size(p, geometry, lo, hi, settings(largest), cell) == pytest.approx(largest)
    with pytest.raises(ParameterError, match=r"patch_size = 10 m.*patch_size <= (\d+\.\d+) m") as info:
        planning.patch_size(p, geometry, lo, hi, settings(10.0), cell)
    assert float(str(info.value).split("patch_size <= ")[1].split(" m")[0]) == pytest.approx(largest, rel=1e-3)
    assert "patch_size = 0 (automatic)" in str(info.value)


#: Each knob over decades (the cheap end of each range).
SWEEPS = {
    "patch_size": (0.01, 0.1, 1.0, 3.0, 10.0, 100.0, 1000.0),
    "ray_spacing": (0.1, 1.0, 10.0, 100.0, 1000.0),
    "oversample": (1, 4, 16, 64),
    "pulses_per_trace": (1, 16, 256, 4096, 65536),
    "max_depth": (2, 4, 16, 64),
}


def _sweep(name: str, values, base: dict, reference: float) -> list:
    accepted = []
    for value in values:
        try:
            sim = _run({**base, name: value})
        except ParameterError as exc:
            assert name in str(exc), (name, value, str(exc))
            continue
        data = sim.raw.data
        assert np.all(np.isfinite(data)), (name, value)
        ratio = 10.0 * math.log10(max(_energy(sim), 1e-300) / reference)
        assert abs(ratio) < 20.0, (name, value, ratio)
        accepted.append(value)
    return accepted


def test_every_knob_swept_over_decades_is_refused_or_within_20_db():
    """Dihedral, full aperture, patches (the default) and the tube preview (where the ray spacing
    shapes the lit regions): each value raises a ParameterError naming the knob, or gives finite
    raw data within 20 dB of the automatic setting's energy. ``max_depth = 1`` is left out of the
    energy comparison: a dihedral at 45 deg returns almost only its double bounce (-60 dB without it)."""
    reference = _energy(_run({}))
    accepted = {name: _sweep(name, values, {}, reference) for name, values in SWEEPS.items()}
    assert accepted["patch_size"][-1] == 3.0 and 10.0 not in accepted["patch_size"]
    assert 10.0 not in accepted["ray_spacing"]
    assert accepted["oversample"] == list(SWEEPS["oversample"])
    assert accepted["pulses_per_trace"] == list(SWEEPS["pulses_per_trace"])
    assert np.all(np.isfinite(_run({"max_depth": 1}).raw.data))
    tiles = {"lit_regions": "tiles"}
    tile_reference = _energy(_run(tiles))
    assert _sweep("ray_spacing", (0.3, 1.0, 4.0, 10.0, 100.0, 1000.0), tiles, tile_reference) == [0.3, 1.0, 4.0]


def test_non_finite_raw_data_are_refused_and_nothing_is_written(tmp_path, monkeypatch):
    """A fault that makes the traced samples overflow (injected here into the range compression)
    raises RawDataError before RawData exists; ``render`` leaves no file behind."""
    real = binning.range_compress

    def overflowing(*args, **kwargs):
        data = real(*args, **kwargs)
        data[0, 0] = 1e30
        return data
    monkeypatch.setattr(binning, "range_compress", overflowing)
    with pytest.raises(RawDataError, match="not finite or exceed"):
        _run({})
    out = tmp_path / "out"
    with pytest.raises(RawDataError):
        render("dihedral", out, progress=False)
    assert not out.exists() or not any(out.iterdir())


def test_split_ends_stay_bounded_beyond_the_patch_bound(monkeypatch):
    """With the bound lifted, 10 m patches on the dihedral (6.8 rad of quadratic phase) are wrong
    but bounded: a split end whose own ``u . a`` crossed zero is held at ``|alpha| = 0.25``
    (edge_terms.MIN_END_ALPHA). With the old 1e-30 floor: 37 dB too much energy, peak 440 times."""
    monkeypatch.setattr(planning, "PATCH_PHASE_MAX", 1e9)
    reference = _energy(_run({}))
    sim = _run({"patch_size": 10.0})
    assert sim.loaded.settings.patch_size == 10.0
    assert abs(10.0 * math.log10(_energy(sim) / reference)) < 10.0
