"""Figures from saved containers: written atomically, expected pixel size, not blank, right numbers,
and redrawn from a render's files without tracing again."""
from __future__ import annotations

import json
import math

import matplotlib.image
import numpy as np
import pytest

import sarmitsuba  # noqa: F401  (variant and plugins)
from sarmitsuba.products import figures, figures_raw
from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.signal.bandlimited import dft_rows
from sarmitsuba.core.image import SarImage
from sarmitsuba.pipeline import render, simulate
from sarmitsuba.core.raw import RawData


def check_png(path, size: tuple[int, int], min_std: float = 0.02) -> np.ndarray:
    """The file exists, is ``size`` = (width, height) pixels and not blank; returns its pixels."""
    assert path.is_file() and not any(p.name.endswith(".partial") for p in path.parent.iterdir())
    pixels = matplotlib.image.imread(path)
    assert pixels.shape[:2] == (size[1], size[0]), pixels.shape
    assert pixels[..., :3].mean(axis=2).std() > min_std, "blank figure"
    return pixels


@pytest.fixture(scope="module")
def dihedral():
    """The dihedral traced once, with per-bounce-order products (about 1 s)."""
    return simulate("dihedral", integrator_overrides={"split_bounces": True})


def sinc_image(shape=(96, 96), d_az=0.25, d_rg=0.4, rho=(0.6, 1.2), peak=(0.3, -0.55)) -> SarImage:
    """A closed-form point target: separable unit-peak sinc response with a carrier ramp."""
    az = (np.arange(shape[0]) - shape[0] // 2) * d_az
    rg = (np.arange(shape[1]) - shape[1] // 2) * d_rg
    response = np.sinc((az[:, None] - peak[0]) / rho[0]) * np.sinc((rg[None, :] - peak[1]) / rho[1])
    data = (2.0 * response * np.exp(1j * (0.8 * az[:, None] / d_az + 1.9 * rg[None, :] / d_rg))).astype(np.complex64)
    return SarImage(data=data, azimuth=az, range=rg, origin=np.zeros(3), azimuth_direction=np.array([1.0, 0, 0]),
                    range_direction=np.array([0.0, -1, 0]), metadata={"scene": "sinc"})


# ============================================================================ single figures
def test_raw_figure(dihedral, tmp_path):
    path = figures.raw_figure(dihedral.raw, tmp_path / "raw.png", figsize=(12.0, 9.0), dpi=80)
    check_png(path, (960, 720))


def test_raw_figure_of_chirped_data(tmp_path):
    """Chirped echoes are range compressed for the zoom; a point's broadside pulse is found."""
    fc, bandwidth, tp, fs, prf, v = 9.6e9, 20e6, 2e-6, 24e6, 250.0, 100.0
    n_p, n_s = 64, 160
    tx = np.zeros((n_p, 3))
    tx[:, 0] = (np.arange(n_p) - 40) * v / prf                 # target broadside at pulse 40
    tx[:, 1], tx[:, 2] = 1000.0, 1000.0
    r = np.linalg.norm(tx, axis=1)
    t = 2 * 1400.0 / 3e8 + np.arange(n_s) / fs
    tau = t[None, :] - 2 * r[:, None] / 299792458.0
    data = ((np.abs(tau) <= tp / 2) * np.exp(1j * np.pi * bandwidth / tp * tau**2)
            * np.exp(-4j * np.pi * fc * r[:, None] / 299792458.0)).astype(np.complex64)
    raw = RawData(data=data, fast_time=t, pulse_time=np.arange(n_p) / prf, tx_position=tx, rx_position=tx.copy(),
                  velocity=np.tile([v, 0.0, 0.0], (n_p, 1)), fc=fc, bandwidth=bandwidth, chirp_rate=bandwidth / tp,
                  pulse_length=tp, fs=fs, prf=prf, range_compressed=False,
                  metadata={"scene": "chirp", "radar": {"azimuth_beamwidth": 1.0}})
    lag = ((np.arange(n_s) + n_s // 2) % n_s - n_s // 2) / fs                 # circular delay, s
    chirp = (np.abs(lag) <= tp / 2) * np.exp(1j * np.pi * bandwidth / tp * lag**2)
    compressed = np.fft.ifft(np.fft.fft(data, axis=1) * np.conj(np.fft.fft(chirp)), axis=1)   # matched filter
    echo = figures_raw.pick_echo(raw, compressed.astype(np.complex64), 299792458.0 * t / 2)
    assert abs(echo.pulse - 40) <= 1 and echo.point_like
    check_png(figures.raw_figure(raw, tmp_path / "chirp.png", figsize=(8.0, 6.0), dpi=50), (400, 300))


def test_image_figure(dihedral, tmp_path):
    check_png(figures.image_figure(dihedral.image, tmp_path / "image.png", figsize=(9.0, 7.5), dpi=80), (720, 600))


def test_bounce_orders_figure(dihedral, tmp_path):
    images = dihedral.images_per_order
    assert len(images) == 2
    path = figures.bounce_orders_figure(images, tmp_path / "orders.png", dpi=60, panel_size=(5.0, 5.0))
    check_png(path, (600, 300))
    labelled = figures.bounce_orders_figure({"single": images[0], "double": images[1], "all": dihedral.image},
                                            tmp_path / "labelled.png", dpi=50, panel_size=(4.0, 4.0))
    check_png(labelled, (600, 200))


def test_comparison_figure_stripmap_vs_spotlight(tmp_path):
    """Any labelled images side by side; the annotated resolutions are the closed forms:
    L / 2 in stripmap (the tapered beam's aperture, L = 0.443 lambda / sin(beta / 2) for a
    3 dB width beta), lambda / (2 dtheta) in spotlight, c / (2 B sin(theta))."""
    strip = simulate("trihedral")
    spot = simulate("trihedral", sensor_overrides={"mode": "spotlight"})
    p, q = strip.loaded.params, spot.loaded.params
    wavelength = 299792458.0 / p.frequency
    rho_gr = 299792458.0 / (2 * p.bandwidth * math.sin(math.radians(p.incidence_angle)))
    aperture = 0.44294647 * wavelength / math.sin(math.radians(p.azimuth_beamwidth) / 2)
    assert figures.image_resolution(strip.image) == pytest.approx((aperture / 2, rho_gr))
    assert figures.image_resolution(spot.image) == pytest.approx(
        (wavelength / (2 * q.n_pulses * q.velocity / (q.prf * q.slant_range)), rho_gr))
    path = figures.comparison_figure({"stripmap": strip.image, "spotlight": spot.image}, tmp_path / "cmp.png",
                                     dpi=60, panel_size=(5.0, 5.0))
    check_png(path, (600, 300))
    assert figures.image_resolution(sinc_image()) is None


def test_overlay_figure_numbers(dihedral, tmp_path):
    stats = figures.overlay_figure(dihedral.image, dihedral.loaded, tmp_path / "overlay.png", dpi=60,
                                   figsize=(13.0, 5.4))
    check_png(stats["path"], (780, 324))
    assert stats["double_bounce_pixels"] > 0 and stats["layover_pixels"] > 0
    assert stats["double_bounce_bright"] == 1.0, "the fold line is the brightest thing in a dihedral image"
    assert 0.0 <= stats["layover_overlap"] <= 1.0
    assert stats["shadow_dark"] is None, "the dihedral has no ground behind its wall: no shadow in the scene area"


def test_point_target_figure(tmp_path):
    """Drawn from an analysis report and from a plain dict; its cuts' -3 dB width is the IRW."""
    image = sinc_image()
    report = analyze_point_target(image, (0.3, -0.55))
    assert report.irw_azimuth == pytest.approx(0.886 * 0.6, rel=0.01)
    assert report.irw_range == pytest.approx(0.886 * 1.2, rel=0.01)
    check_png(figures.point_target_figure(image, report, tmp_path / "pt.png", dpi=60), (780, 276))
    plain = {"row": report.row, "column": report.column, "irw_azimuth": report.irw_azimuth,
             "irw_range": report.irw_range, "pslr_azimuth_db": -13.26, "pslr_range_db": -13.26}
    check_png(figures.point_target_figure(image, plain, tmp_path / "pt_dict.png", dpi=50), (650, 230))
    # the drawn range cut (exact band-limited interpolation, ramp estimated) has the report's IRW
    chip = image.data.astype(np.complex128)
    n = np.arange(chip.shape[0])
    w_az = float(np.angle(np.sum(chip[1:] * np.conj(chip[:-1]))))
    w_rg = float(np.angle(np.sum(chip[:, 1:] * np.conj(chip[:, :-1]))))
    spectrum = np.fft.fft2(chip * np.exp(-1j * (w_az * n[:, None] + w_rg * n[None, :])))
    t = np.arange(-10 * 64, 10 * 64) / 64
    cut = np.abs(dft_rows(96, [report.row]) @ spectrum @ dft_rows(96, report.column + t).T)[0]
    above = t[cut ** 2 >= cut.max() ** 2 / 2]
    assert (above[-1] - above[0]) * 0.4 == pytest.approx(report.irw_range, abs=2 * 0.4 / 64)
    with pytest.raises(ValueError, match="lacks"):
        figures.point_target_figure(image, {"row": 1.0}, tmp_path / "bad.png")


# ============================================================================ batch and redraw
def test_write_figures_and_redraw_without_tracing(tmp_path, monkeypatch):
    """render writes the containers; redraw draws every figure from them, tracing nothing."""
    out = tmp_path / "dihedral"
    render("dihedral", out, integrator_overrides={"split_bounces": True}, progress=False)

    def no_tracing(*args, **kwargs):
        raise AssertionError("redraw must not trace")

    import sarmitsuba.pipeline
    import sarmitsuba.tracing.driver.trace
    monkeypatch.setattr(sarmitsuba.tracing.driver.trace, "trace", no_tracing)
    monkeypatch.setattr(sarmitsuba.pipeline, "trace", no_tracing)
    monkeypatch.setattr(sarmitsuba.pipeline, "simulate", no_tracing)
    paths = figures.redraw(out)
    assert set(paths) == {"raw", "image", "bounce_orders", "overlay", "stats"}
    for role in ("raw", "image", "bounce_orders", "overlay"):
        check_png(paths[role], matplotlib.image.imread(paths[role]).shape[1::-1])
        assert paths[role].name == figures.FIGURE_FILES[role]
    stats = json.loads(paths["stats"].read_text())
    assert stats["overlay"]["double_bounce_bright"] == 1.0
    assert math.isfinite(stats["overlay"]["layover_overlap"])
    # without the scene: no overlay, the rest still drawn
    paths = figures.redraw(out, scene=False)
    assert "overlay" not in paths and paths["image"].is_file()


def test_bad_dynamic_range(dihedral, tmp_path):
    with pytest.raises(ValueError, match="dynamic_range_db"):
        figures.image_figure(dihedral.image, tmp_path / "x.png", dynamic_range_db=0)


# ============================================================================ issue 13: what the figures say
C = 299792458.0
#: A side-looking X-band stripmap: 160 pulses of 1/3 m, 3 deg beam (74 m footprint, wider than the track).
STRIP = dict(fc=9.6e9, bandwidth=100e6, fs=120e6, prf=300.0, speed=100.0, n_pulses=160,
             center=(0.0, 1000.0, 1000.0), beamwidth=3.0, metadata={"radar": {"azimuth_beamwidth": 3.0}})


def texts(fig) -> list[str]:
    """Every text of a figure: titles, labels, annotations, legend entries."""
    from matplotlib.text import Text
    return [t.get_text() for t in fig.findobj(Text)]


def line_of_points(spacing=0.1, amplitude=0.2):
    """A line along azimuth (x) much longer than the track and its beam footprint (an extended target:
    its echo has no azimuth chirp), as closely spaced points (spacing << azimuth resolution)."""
    from sarmitsuba.analysis.synthetic import PointTarget
    return [PointTarget((x, 0.0, 0.0), amplitude) for x in np.arange(-80.0, 80.0, spacing)]


def test_raw_figure_draws_the_phase_history_of_a_true_point(tmp_path, drawn):
    """Analytic data of one point: it is found where it is, and the drawn parabola is the
    closed-form phase history -4 pi |A_p - X| / lambda (up to a constant)."""
    from sarmitsuba.analysis.synthetic import PointTarget, stripmap
    target = np.array([5.0, 0.0, 0.0])
    raw = stripmap(PointTarget(target), **STRIP)
    figures.raw_figure(raw, tmp_path / "raw.png", figsize=(8.0, 6.0), dpi=50)
    fig = drawn[-1]
    ax_c, ax_d = fig.axes[2], fig.axes[3]            # (a), (b), then the zoom panels (colour bars after)
    assert "point target" in ax_c.get_title() and "no point-like" not in ax_c.get_title()
    measured, model = ax_d.get_lines()
    pulses = np.asarray(model.get_xdata(), int)
    truth = -4 * np.pi * STRIP["fc"] / C * np.linalg.norm(raw.tx_position[pulses] - target, axis=1)
    drawn_model = np.asarray(model.get_ydata())
    ok = np.isfinite(drawn_model)
    assert ok.sum() > 100 and np.ptp(drawn_model[ok]) > 100, "a 3 deg X-band aperture: a 190 rad parabola"
    offset = drawn_model[ok] - truth[ok]
    assert np.ptp(offset) < 0.05, "the drawn point-target phase history is not the point's"
    assert np.nanmax(np.abs(np.asarray(measured.get_ydata()) - drawn_model)) < 0.05
    echo = figures_raw.pick_echo(raw, raw.data, C * raw.fast_time / 2)
    broadside = int(np.argmin(np.linalg.norm(raw.tx_position - target, axis=1)))
    assert abs(echo.pulse - broadside) <= 1
    assert echo.r0 == pytest.approx(np.linalg.norm(raw.tx_position[broadside] - target), abs=0.3)


def test_raw_figure_of_an_extended_target_finds_no_point(tmp_path, drawn):
    """A line of points along the track (a wall-like echo, no azimuth chirp) and the traced dihedral:
    no point-like target, no parabola drawn, and the figure says so."""
    from sarmitsuba.analysis.synthetic import stripmap
    raw = stripmap(line_of_points(), **STRIP)
    echo = figures_raw.pick_echo(raw, raw.data, C * raw.fast_time / 2)
    assert not echo.point_like and echo.rms > 5.0
    figures.raw_figure(raw, tmp_path / "line.png", figsize=(8.0, 6.0), dpi=50)
    sim = simulate("dihedral")
    figures.raw_figure(sim.raw, tmp_path / "dihedral.png", figsize=(8.0, 6.0), dpi=50)
    for fig in drawn[-2:]:
        assert "no point-like target found" in fig.axes[2].get_title()
        assert len(fig.axes[3].get_lines()) == 1, "only the measured phase: no point-target parabola"
        assert not any("point target" in t and "lambda" in t for t in texts(fig))


def test_raw_figure_prefers_a_weak_point_to_a_bright_wall(tmp_path):
    """A point 60 m further in range, weaker in the raw data than the line: the point is shown."""
    from sarmitsuba.analysis.synthetic import PointTarget, stripmap
    target = np.array([5.0, -60.0, 0.0])
    raw = stripmap(line_of_points() + [PointTarget(target, 0.5)], **STRIP)
    slant = C * raw.fast_time / 2
    brightest = np.unravel_index(int(np.argmax(np.abs(raw.data))), raw.data.shape)
    assert abs(slant[brightest[1]] - np.hypot(1000.0, 1000.0)) < 3.0, "the line is the brightest echo"
    echo = figures_raw.pick_echo(raw, raw.data, slant)
    assert echo.point_like and echo.rms < 0.5
    broadside = int(np.argmin(np.linalg.norm(raw.tx_position - target, axis=1)))
    assert abs(echo.pulse - broadside) <= 1
    assert echo.r0 == pytest.approx(np.linalg.norm(raw.tx_position[broadside] - target), abs=0.6)


def all_axes(fig):
    """The figure's axes and their inset axes (where colour bars sized to an image live)."""
    return [a for ax in fig.axes for a in (ax, *ax.child_axes)]


def colour_bars(fig):
    return [ax for ax in all_axes(fig) if hasattr(ax, "_colorbar")]


def image_axes(fig):
    """(image axes, colour-bar axes) of a one-image figure."""
    bars = colour_bars(fig)
    images = [ax for ax in fig.axes if ax.get_images() and ax not in bars]
    return images[0], bars[0]


def check_orientation(fig, ax, x_from: str = "from scene centre") -> None:
    """Axis labels say what they are measured from; near/far range and the flight arrow are marked,
    clear of the x label and of each other."""
    renderer = fig.canvas.get_renderer()
    assert x_from in ax.get_xlabel() and "azimuth from" in ax.get_ylabel()
    marks = {t.get_text(): t for t in ax.texts}
    near = [t for s, t in marks.items() if "near range" in s]
    far = [t for s, t in marks.items() if "far range" in s]
    assert near and far and any("flight" in s for s in marks)
    label = ax.xaxis.label.get_window_extent(renderer)
    near_box, far_box = near[0].get_window_extent(renderer), far[0].get_window_extent(renderer)
    assert not near_box.overlaps(label) and not far_box.overlaps(label) and not near_box.overlaps(far_box)
    assert near_box.x0 < far_box.x0, "near range (the sensor side) is on the left, where range is small"


def check_colorbar_height(fig, ax, bar) -> None:
    renderer = fig.canvas.get_renderer()
    image_h = ax.get_window_extent(renderer).height
    assert bar.get_window_extent(renderer).height == pytest.approx(image_h, rel=0.05)


def test_image_figure_marks_sensor_side_flight_and_sizes_the_colour_bar(dihedral, tmp_path, drawn):
    figures.image_figure(dihedral.image, tmp_path / "image.png", figsize=(9.0, 7.5), dpi=60)
    fig = drawn[-1]
    ax, bar = image_axes(fig)
    check_orientation(fig, ax)
    check_colorbar_height(fig, ax, bar)
    figures.bounce_orders_figure(dihedral.images_per_order, tmp_path / "orders.png", dpi=40)
    fig = drawn[-1]
    check_colorbar_height(fig, fig.axes[0], colour_bars(fig)[0])


def test_overlay_legend_clear_of_axis_labels(dihedral, tmp_path, drawn):
    figures.overlay_figure(dihedral.image, dihedral.loaded, tmp_path / "overlay.png", dpi=60)
    fig = drawn[-1]
    renderer = fig.canvas.get_renderer()
    legend = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None][0]
    box = legend.get_window_extent(renderer)
    for ax in fig.axes:
        for label in (ax.xaxis.label, ax.yaxis.label, ax.title):
            if label.get_text():
                assert not box.overlaps(label.get_window_extent(renderer)), label.get_text()
    ax, bar = image_axes(fig)
    check_orientation(fig, ax)
    check_colorbar_height(fig, ax, bar)


def test_focus_progress_bars_are_labelled(capsys):
    """render --split-bounces: one labelled bar per focused image, not four identical ones."""
    simulate("dihedral", integrator_overrides={"split_bounces": True}, progress=True)
    err = capsys.readouterr().err
    for label in ("focus all orders", "focus order 1", "focus order 2"):
        assert f"{label}:" in err, label
    simulate("dihedral", progress=True, focuser="bp")           # direct backprojection, one image
    err = capsys.readouterr().err
    assert "focus:" in err and "focus order" not in err


def test_unwritable_figure_names_the_path_given(tmp_path, unwritable_paths):
    image = sinc_image()
    report = analyze_point_target(image, (0.3, -0.55))
    from sarmitsuba.products.image_files import WriteError
    for target in unwritable_paths:
        with pytest.raises(OSError) as caught:
            figures.point_target_figure(image, report, target, dpi=30)
        assert isinstance(caught.value, WriteError)
        message = str(caught.value)
        assert message.startswith(f"cannot write figure {target}: ") and ".partial" not in message
        assert not list(tmp_path.rglob("*.partial"))


def test_analyze_figure_to_an_unwritable_path_exits_2(tmp_path, capsys, unwritable_paths):
    from sarmitsuba.cli import main
    sinc_image().save(tmp_path / "image.npz")
    for target in unwritable_paths:
        assert main(["analyze", str(tmp_path / "image.npz"), "--target", "0.3,-0.55", "--figure", str(target)]) == 2
        err = capsys.readouterr().err
        assert f"cannot write figure {target}" in err and ".partial" not in err and "Traceback" not in err
        assert not list(tmp_path.rglob("*.partial"))
