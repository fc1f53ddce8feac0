"""Straight-track stripmap geometry (sarmitsuba.focus.stripmap) and the shared test helpers.

The point-target cases (:class:`Case`, :data:`CASES`, :data:`AIRBORNE_X`, :data:`SPACEBORNE_C`,
:data:`CW_LOW`, :data:`CW_HIGH`), their analytic raw data and the squint deskew live in
:mod:`sarmitsuba.analysis.reference_cases` (geometry, targets, sources and the deskew convention are
described there); this module re-exports them for ``test_omegak.py`` and ``test_rda.py``
and adds the cached per-name data and geometry (:func:`simulate`, :func:`geometry`) and the
analysis helpers the focusing tests share (:func:`analyse`, :func:`chip`, :func:`correlation`).
"""
from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest

from sarmitsuba.analysis import synthetic
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C
from sarmitsuba.focus.stripmap import (StripmapGeometry, estimate_doppler_centroid, slant_output_grid,
                                       stripmap_geometry)
from sarmitsuba.core.image import SarImage
from sarmitsuba.core.raw import RawData
# cases and helpers of sarmitsuba.analysis.reference_cases, re-exported for test_omegak.py and test_rda.py
from sarmitsuba.analysis.reference_cases import (AIRBORNE_X, CASES, CW_HIGH, CW_LOW, SPACEBORNE_C, Case, deskew,
                                                 focused_carrier, phase_error_deg, simulate_case)


# ============================================================================ cached data of the cases
@functools.lru_cache(maxsize=8)
def simulate(name: str, range_window: str = "rect") -> RawData:
    """Range-compressed analytic data of case ``name`` (cached: tests share it)."""
    return simulate_case(CASES[name], range_window)


def geometry(name: str) -> StripmapGeometry:
    case = CASES[name]
    return stripmap_geometry(simulate(name), scene_centre=case.scene_centre)


# ============================================================================ analysis helpers
def analyse(image: SarImage, geo: StripmapGeometry, fc: float, target: synthetic.PointTarget, **kw):
    """Point-target report (deskewed for squint) and the predicted (azimuth, range)."""
    az, rg = geo.zero_doppler(target.position)
    return analyze_point_target(deskew(image, geo, rg), (az, rg), carrier=focused_carrier(geo, fc), **kw), (az, rg)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """|<a, b>| / (|a| |b|) of two complex chips."""
    a = a.astype(np.complex128).ravel()
    b = b.astype(np.complex128).ravel()
    return float(abs(np.vdot(a, b)) / np.sqrt(np.vdot(a, a).real * np.vdot(b, b).real))


def chip(image: SarImage, az: float, rg: float, half: int = 12) -> np.ndarray:
    i = int(round((az - image.azimuth[0]) / (image.azimuth[1] - image.azimuth[0])))
    j = int(round((rg - image.range[0]) / (image.range[1] - image.range[0])))
    assert half <= i < image.data.shape[0] - half and half <= j < image.data.shape[1] - half, "chip off the image"
    return image.data[i - half:i + half + 1, j - half:j + half + 1]


# ============================================================================ tests
@pytest.mark.parametrize("name", list(CASES))
def test_geometry_of_cases(name):
    """Velocity, R_ref, squint and Doppler centroid come out of the data as simulated."""
    case = CASES[name]
    geo = geometry(name)
    assert geo.velocity == pytest.approx(case.speed, rel=1e-12)
    assert geo.pulse_spacing == pytest.approx(case.speed / case.prf, rel=1e-12)
    np.testing.assert_allclose(geo.azimuth_direction, [1.0, 0.0, 0.0], atol=1e-12)
    # range direction: perpendicular to the track, toward the scene centre (-y, down)
    expect = np.array([0.0, -case.track_offset, -case.altitude]) / case.closest_range
    np.testing.assert_allclose(geo.range_direction, expect, atol=1e-9)
    assert geo.squint == pytest.approx(case.squint, abs=1e-12)
    assert geo.doppler_source == "metadata"  # the generator records the beam squint
    assert geo.doppler_centroid == pytest.approx(2 * case.speed * np.sin(case.squint) / case.wavelength, rel=1e-9)
    # R_ref: closest approach of the mid-swath beam centre (window centred on beam_range +- half a sample)
    assert geo.reference_range == pytest.approx(case.closest_range, abs=C / (2 * case.fs))
    assert geo.max_cross_track_error < 1e-6 and geo.max_along_track_error < 1e-6
    # prediction: the target's closest approach
    for t in case.targets():
        az, rg = geo.zero_doppler(t.position)
        assert rg == pytest.approx(np.hypot(t.position[1] - case.track_offset, case.altitude), rel=1e-12)
        assert az == pytest.approx(t.position[0] - geo.origin[0], abs=1e-9)


@pytest.mark.parametrize("name", list(CASES))
def test_doppler_centroid_estimated_from_data(name):
    """Madsen fraction + range-walk ambiguity give the absolute centroid within 2 % of the PRF."""
    case = CASES[name]
    raw = simulate(name)
    f_dc = 2 * case.speed * np.sin(case.squint) / case.wavelength
    assert estimate_doppler_centroid(raw) == pytest.approx(f_dc, abs=0.02 * case.prf)
    bare = dataclasses.replace(raw, metadata={})
    geo = stripmap_geometry(bare, scene_centre=case.scene_centre)
    assert geo.doppler_source == "data"
    assert geo.doppler_centroid == pytest.approx(f_dc, abs=0.02 * case.prf)


def test_flat_earth_default_scene_centre():
    """Without a stated scene centre: the ground point (z = 0) on the right at the mid-swath range."""
    case = CW_HIGH
    geo = stripmap_geometry(simulate(case.name))
    np.testing.assert_allclose(geo.scene_centre, case.scene_centre, atol=2.0)
    np.testing.assert_allclose(geo.range_direction, geometry(case.name).range_direction, atol=1e-4)


def test_slant_grid_convention():
    """Origin on the track at the scene centre's closest approach (azimuth 0 = the scene centre),
    range absolute, azimuth centred on the mid-aperture antenna's coordinate + R_ref tan(squint)."""
    case = CW_HIGH
    raw = simulate(case.name)
    geo = geometry(case.name)
    grid = slant_output_grid(geo, raw)
    assert grid.plane == "slant" and grid.shape == raw.data.shape
    mid = raw.tx_position.mean(axis=0)  # track along +x: the origin is the track point at the centre's x
    np.testing.assert_allclose(geo.origin, [case.scene_centre[0], mid[1], mid[2]], atol=1e-9)
    assert grid.range[case.n_samples // 2] == pytest.approx(geo.reference_range, rel=1e-15)
    assert np.diff(grid.range).mean() == pytest.approx(C / (2 * case.fs), rel=1e-12)
    assert grid.azimuth[case.n_pulses // 2] == pytest.approx(
        mid[0] - case.scene_centre[0] + geo.reference_range * np.tan(case.squint), abs=1e-6)
    assert np.diff(grid.azimuth).mean() == pytest.approx(case.speed / case.prf, rel=1e-12)
    # a pixel's world position is at its range from the track line, at its zero-Doppler azimuth
    i, j = 17, 101
    p = geo.slant_position(grid.azimuth[i], grid.range[j])
    az, rg = geo.zero_doppler(p)
    assert az == pytest.approx(grid.azimuth[i], abs=1e-6) and rg == pytest.approx(grid.range[j], abs=1e-6)


def _with_positions(raw: RawData, positions: np.ndarray) -> RawData:
    return dataclasses.replace(raw, tx_position=positions, rx_position=positions.copy())


def test_curved_or_uneven_track_is_rejected():
    """Deviations beyond lambda/16 across or along the track raise ValueError naming bp and ffbp."""
    raw = simulate(AIRBORNE_X.name)
    n = raw.n_pulses
    tol = raw.wavelength / 16
    k = np.linspace(-1.0, 1.0, n)
    bent = raw.tx_position.copy()
    bent[:, 2] += 2 * tol * (1 - k**2)  # a 2 lambda/16 sag
    with pytest.raises(ValueError, match="not straight.*use bp or ffbp"):
        stripmap_geometry(_with_positions(raw, bent))
    uneven = raw.tx_position.copy()
    uneven[:, 0] += 3 * tol * np.sin(np.pi * k)
    with pytest.raises(ValueError, match="uniformly spaced.*use bp or ffbp"):
        stripmap_geometry(_with_positions(raw, uneven))
    # within tolerance: accepted, and the deviation is reported
    wobble = raw.tx_position.copy()
    wobble[:, 1] += 0.5 * tol * np.sin(7 * np.pi * k)
    geo = stripmap_geometry(_with_positions(raw, wobble), scene_centre=(0, 0, 0))
    assert 0.3 * tol < geo.max_cross_track_error < tol  # the line fit absorbs a little of the wobble
    # an explicit tolerance relaxes the check
    geo = stripmap_geometry(_with_positions(raw, bent), scene_centre=(0, 0, 0), tolerance=3 * tol)
    assert geo.max_cross_track_error == pytest.approx(4 / 3 * tol, rel=0.01)  # sag minus its fitted mean


def test_bistatic_and_bad_prf_are_rejected():
    raw = simulate(AIRBORNE_X.name)
    with pytest.raises(ValueError, match="monostatic"):
        stripmap_geometry(dataclasses.replace(raw, rx_position=raw.tx_position + [0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="uniform PRF"):
        stripmap_geometry(dataclasses.replace(raw, prf=raw.prf * 1.01))
    with pytest.raises(ValueError, match="velocity disagrees"):
        stripmap_geometry(dataclasses.replace(raw, velocity=raw.velocity * 1.05))
    with pytest.raises(ValueError, match="squint"):
        stripmap_geometry(raw, squint=85.0)


@pytest.mark.parametrize("parameter", ["n_azimuth", "n_range"])
def test_slant_output_grid_sizes_are_counts_of_at_least_two(parameter):
    """``slant_output_grid``'s n_azimuth / n_range: 0 and 1 (and non-integers) raise ValueError
    naming the parameter; 2 and 3 give a grid of that many samples, spaced as the default's."""
    case = CW_LOW
    raw, geo = simulate(case.name), geometry(case.name)
    for bad in (0, 1, -3, 2.0, True):
        with pytest.raises(ValueError, match=parameter):
            slant_output_grid(geo, raw, **{parameter: bad})
    full = slant_output_grid(geo, raw)
    for n in (2, 3):
        grid = slant_output_grid(geo, raw, **{parameter: n})
        axis, other = (grid.azimuth, grid.range) if parameter == "n_azimuth" else (grid.range, grid.azimuth)
        ref, ref_other = (full.azimuth, full.range) if parameter == "n_azimuth" else (full.range, full.azimuth)
        assert axis.shape == (n,) and other.shape == ref_other.shape
        assert np.diff(axis) == pytest.approx(np.diff(ref).mean(), rel=1e-12)
