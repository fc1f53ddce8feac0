"""Weighted images by default and RCS independent of the window, end to end.

``simulate`` / ``render`` focus with a Taylor window (nbar 4, -35 dB) in range and azimuth and
divide out the sensor's azimuth pattern; ``window="rect"`` gives the unweighted sinc response.
Truth: the range IRW broadens by the Taylor window's closed-form factor (1.337, Carrara et al.
1995 appendix D; :mod:`sarmitsuba.focus.windows`) and its range PSLR is the window's -35 dB
design level, while the RCS read by integrated energy stays the same (docs/physics.md (K2)).
"""
from __future__ import annotations

import numpy as np
import pytest

import sarmitsuba  # noqa: F401
from sarmitsuba.analysis import point_target as analysis
from sarmitsuba import pipeline
from sarmitsuba.cli import main
from sarmitsuba.focus import windows
from sarmitsuba.core.radar import ParameterError

TAYLOR = {"name": "taylor", "nbar": 4, "sll": -35.0}


@pytest.fixture(scope="module")
def trihedral():
    return {window: pipeline.simulate("trihedral", window=window) for window in ("rect", "taylor")}


def test_default_window_is_taylor_and_recorded(trihedral):
    image, p = trihedral["taylor"].image, trihedral["taylor"].loaded.params
    focus = image.metadata["focus"]
    assert focus["window_range"] == TAYLOR and focus["window_azimuth"] == TAYLOR
    assert focus["azimuth_pattern"] == pytest.approx(p.pattern_length / p.wavelength)
    assert image.window == "range=taylor(nbar=4, sll=-35), azimuth=taylor(nbar=4, sll=-35)"
    assert pipeline.window_title(image) == "taylor"
    rect = trihedral["rect"].image
    assert rect.window == "rect" and rect.metadata["focus"]["window_range"] == {"name": "rect"}
    assert pipeline.window_title(rect) == "rect"
    import inspect
    assert inspect.signature(pipeline.simulate).parameters["window"].default == "taylor"
    assert inspect.signature(pipeline.render).parameters["window"].default == "taylor"


def test_taylor_image_has_the_window_response_and_the_same_rcs(trihedral):
    reports = {w: analysis.analyze_point_target(s.image, (0.0, 0.0, 0.0)) for w, s in trihedral.items()}
    rect, taylor = reports["rect"], reports["taylor"]
    assert taylor.irw_range / rect.irw_range == pytest.approx(windows.broadening_factor("taylor"), rel=0.03)
    assert taylor.pslr_range_db == pytest.approx(windows.pslr_theory("taylor"), abs=1.5)
    assert rect.pslr_range_db == pytest.approx(-13.26, abs=0.5)
    assert taylor.peak_magnitude == pytest.approx(rect.peak_magnitude, rel=0.03)   # unit peak gain both
    readings = [r.rcs_db for r in reports.values()]
    readings += [10 * np.log10(analysis.integrated_rcs(s.image)) for s in trihedral.values()]
    assert np.ptp(readings) < 0.3, readings


def test_refocus_bp_takes_an_azimuth_window_and_reproduces_the_render(trihedral):
    """Refocused with the render's focuser (fast factorised backprojection) and windows, the raw
    data give the render's image; direct backprojection gives it to its interpolation error
    (-36 dB of the peak measured: docs/physics.md (F7))."""
    sim = trihedral["taylor"]
    assert sim.image.metadata["focus"]["implementation"] == "ffbp"
    image = pipeline.refocus(sim.raw, "ffbp", window_range="taylor", window_azimuth="taylor")
    assert image.data.shape == sim.image.data.shape
    assert np.abs(image.data - sim.image.data).max() < 1e-4 * np.abs(sim.image.data).max()
    direct = pipeline.refocus(sim.raw, "bp", window_range="taylor", window_azimuth="taylor")
    assert direct.metadata["focus"]["implementation"] != "ffbp"
    assert np.abs(direct.data - sim.image.data).max() < 1e-2 * np.abs(sim.image.data).max()


def test_bad_window_fails_before_tracing(monkeypatch):
    monkeypatch.setattr(pipeline, "trace", lambda *a, **k: pytest.fail("traced despite a bad window"))
    for window in ("triangle", ("taylor", {"sll": -5.0}), 3):
        with pytest.raises(ParameterError, match="window"):
            pipeline.simulate("trihedral", window=window)


def test_render_window_option(tmp_path, capsys, monkeypatch):
    titles = []
    original = pipeline.image_files.write_quicklook
    monkeypatch.setattr(pipeline.image_files, "write_quicklook",
                        lambda image, path, **kw: titles.append(kw.get("title")) or original(image, path, **kw))
    assert main(["render", "trihedral", "--out", str(tmp_path), "--no-progress", "--window", "hamming"]) == 0
    image = analysis.SarImage.load(tmp_path / "image.npz")
    assert image.metadata["focus"]["window_azimuth"] == {"name": "hamming", "alpha": 0.54}
    assert titles and "window hamming" in titles[0]
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["render", "trihedral", "--out", str(tmp_path), "--window", "triangle"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--window" in err and "triangle" in err


@pytest.mark.parametrize("beta", [2.0, 6.0])
def test_refocus_takes_a_window_with_parameters_in_range(trihedral, beta):
    """``refocus(raw, window=("kaiser", {"beta": b}))`` weights range too. Truth: Kaiser's design
    relation between beta and the sidelobe level A (Kaiser and Schafer, IEEE TASSP 28(1), 1980,
    eq. for 13.26 < A < 60 dB), beta = 0.76609 (A - 13.26)^0.4 + 0.09834 (A - 13.26), solved for A."""
    from scipy.optimize import brentq
    level = brentq(lambda a: 0.76609 * (a - 13.26) ** 0.4 + 0.09834 * (a - 13.26) - beta, 13.27, 60.0)
    raw = trihedral["rect"].raw
    image = pipeline.refocus(raw, "bp", window=("kaiser", {"beta": beta}))
    assert image.metadata["focus"]["window_range"] == {"name": "kaiser", "beta": beta}
    report = sarmitsuba.analyze(image, (0.0, 0.0, 0.0), raw=raw)
    assert report.pslr_range_db == pytest.approx(-level, abs=1.0)
