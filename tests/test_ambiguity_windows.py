"""The azimuth window in the AASR and its warning (docs/physics.md (AMB1), :mod:`sarmitsuba.analysis.ambiguities`).

Truth: (AMB1) integrated here on its own, in the along-track sine ``s`` over the traced beam
``[sin_lo, sin_hi]``: the two-way power pattern ``sinc^4(L sin(asin(s) - squint) / lambda)`` (zero
beyond the beam), its aliases shifted by ``m prf lambda / (2 v)`` in ``s``, weighted by the window
squared, the window sampled by ``scipy.signal.windows.taylor`` (``norm=False``: its own sampling
``x_k = (k - (n - 1) / 2) / n`` of the cells' centres, so the sum is the midpoint rule) or 1 for
rect. The Taylor weight falls toward the band's edges, where the aliases are strongest, so its
ratio lies several dB below rect's.

Deliberate bugs these tests were run against (each fails them):
  * the window left out of the ratio (``ambiguities`` calling ``azimuth_ambiguity_ratio(p)``, its
    default Taylor, whatever window it is given): the rect ratios and the rect warning;
  * the window mapped onto half the band (``x = (s - sin_lo) / (sin_hi - sin_lo) - 1``): every
    Taylor ratio;
  * ``simulate`` warning of the ratio of the default window, not of its ``window`` argument.
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.signal.windows

from sarmitsuba.analysis.ambiguities import LIMIT_DB, ambiguities, azimuth_ambiguity_ratio
from sarmitsuba.core.radar import RadarParameters

#: Two beams: broadside at 180 Hz, and squinted 4 deg at 150 Hz with a 1 deg beam.
CASES = {"broadside": dict(prf=180.0, azimuth_beamwidth=1.2), "squinted": dict(prf=150.0, azimuth_beamwidth=1.0,
                                                                            squint=4.0)}
SAMPLES = 20001


def aasr(p: RadarParameters, window: str, prf: float | None = None) -> float:
    """(AMB1) by the midpoint rule in ``s`` (the module docstring)."""
    prf = p.prf if prf is None else prf
    lo, hi = p.beam_sines
    x = (np.arange(SAMPLES) - (SAMPLES - 1) / 2) / SAMPLES               # scipy's sample positions
    s = lo + (x + 0.5) * (hi - lo)
    w2 = (scipy.signal.windows.taylor(SAMPLES, nbar=4, sll=35, norm=False) if window == "taylor"
          else np.ones(SAMPLES)) ** 2
    squint = math.radians(p.squint)

    def power(sine):
        inside = (sine >= lo) & (sine <= hi)
        look = np.sin(np.arcsin(np.clip(sine, -1, 1)) - squint)
        return np.where(inside, np.sinc(p.pattern_length / p.wavelength * look) ** 4, 0.0)
    step = prf * p.wavelength / (2.0 * p.velocity)                      # one PRF in along-track sine
    orders = math.ceil((hi - lo) / step)
    alias = sum(np.sum(w2 * (power(s + m * step) + power(s - m * step))) for m in range(1, orders + 1))
    return float(alias / np.sum(w2 * power(s)))


@pytest.mark.parametrize("case", list(CASES))
def test_the_ratio_weighs_the_aliases_by_the_window(case):
    """Rect and Taylor, each within 0.3 % of the independent integral, and Taylor's below rect's by
    the integral's own margin (more than 3 dB here), in ``azimuth_ambiguity_ratio`` and in
    ``ambiguities``' AASR for the window it is given."""
    p = RadarParameters(**CASES[case])
    truth = {w: aasr(p, w) for w in ("rect", "taylor")}
    assert 10 * math.log10(truth["rect"] / truth["taylor"]) > 3.0
    for window, expected in truth.items():
        assert azimuth_ambiguity_ratio(p, (window, {})) == pytest.approx(expected, rel=3e-3)
        assert ambiguities(p, (window, {})).aasr == pytest.approx(expected, rel=3e-3)


@pytest.mark.parametrize("case", list(CASES))
def test_the_prf_named_reaches_the_limit_with_the_window_given(case):
    """``ambiguities``' PRF from which the AASR is at most -20 dB, for each window: there the
    independent integral with that window reads -20 dB (within 0.05 dB); the two PRFs differ, and
    between them rect warns and Taylor does not."""
    p = RadarParameters(**CASES[case])
    found = {w: ambiguities(p, (w, {})) for w in ("rect", "taylor")}
    for window, a in found.items():
        assert 10 * math.log10(aasr(p, window, a.prf_min_aasr_hz)) == pytest.approx(LIMIT_DB, abs=0.05)
    low, high = found["taylor"].prf_min_aasr_hz, found["rect"].prf_min_aasr_hz
    assert high > 1.02 * low
    between = RadarParameters(**{**CASES[case], "prf": math.sqrt(low * high)})
    assert "AASR" in (ambiguities(between, ("rect", {})).warning or "")
    assert ambiguities(between, ("taylor", {})).warning is None


def test_simulate_warns_of_the_window_it_focuses_with(monkeypatch):
    """The trihedral in stripmap at a PRF between the two windows' limits (from the independent
    integral): ``simulate`` with ``window="rect"`` warns of the AASR before it traces (the trace is
    replaced by a failure here), with the default Taylor window it does not."""
    from sarmitsuba import pipeline
    from sarmitsuba.scene.loader import load_scene
    from sarmitsuba.scene.planning import AcquisitionWarning
    p = load_scene("trihedral", {"mode": "stripmap", "n_pulses": 64}).params
    limit = 10 ** (LIMIT_DB / 10)
    first = {}
    for window in ("rect", "taylor"):            # the integral's PRF at the limit, by bisection
        lo, hi = 100.0, 400.0
        for _ in range(16):
            lo, hi = (lo, math.sqrt(lo * hi)) if aasr(p, window, math.sqrt(lo * hi)) <= limit else (math.sqrt(lo * hi), hi)
        first[window] = hi
    prf = math.sqrt(first["rect"] * first["taylor"])
    assert aasr(p, "rect", prf) > limit > aasr(p, "taylor", prf)

    def traced(*args, **kwargs):
        raise AssertionError("traced")
    monkeypatch.setattr(pipeline, "trace", traced)
    for window, warned in (("rect", True), ("taylor", False)):
        with warnings.catch_warnings(record=True) as caught, pytest.raises(AssertionError, match="traced"):
            warnings.simplefilter("always")
            pipeline.simulate("trihedral", sensor_overrides={"mode": "stripmap", "n_pulses": 64, "prf": prf},
                              window=window)
        issued = [str(w.message) for w in caught if issubclass(w.category, AcquisitionWarning)
                  and str(w.message).startswith("AASR")]
        assert bool(issued) == warned, (window, issued)
