"""Every word of a drawn figure is on the figure and legible: no title, label, tick label or
annotation crosses the figure's edge or another text (sarmitsuba.products).

The judge is matplotlib's own renderer: each visible text artist's window extent after drawing,
against the figure's bounding box and against every other text's. The cases are those where
text was cut off or piled up: the point-target figure's one-line title (wider than the figure),
and the slant-plane omega-K / RDA images of a spaceborne track, 25 times longer in azimuth than
in range, whose equal-aspect axes became a sliver with its range ticks, offset text, axis label
and near/far range notes on top of each other.
"""
from __future__ import annotations

import itertools

import pytest

from sarmitsuba.analysis.point_target import analyze_point_target
from sarmitsuba.pipeline import refocus, simulate
from sarmitsuba.products import figures
from sarmitsuba.products.figures_point import point_target_figure
from sarmitsuba.products.image_files import write_quicklook

#: The spaceborne trihedral of benchmarks/trajectory.py: X band, 514 km, a 0.3 deg beam.
SPACEBORNE = {"altitude": 514e3, "velocity": 7600.0, "prf": 4000.0, "azimuth_beamwidth": 0.3, "n_pulses": 1501}


def _axes_tree(fig):
    stack, seen = list(fig.axes), []
    while stack:
        ax = stack.pop()
        if ax not in seen:
            seen.append(ax)
            stack.extend(ax.child_axes)
    return seen


def visible_texts(fig):
    """``(text, window extent)`` of every drawn, non-empty text artist of ``fig``: figure texts,
    titles, axis labels, offset texts, tick labels in view, annotations, of every axes and inset."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    artists = list(fig.texts)                                 # the suptitle among them
    for ax in _axes_tree(fig):
        if not ax.get_visible():
            continue
        artists += [ax.title, ax._left_title, ax._right_title, ax.xaxis.label, ax.yaxis.label,
                    ax.xaxis.offsetText, ax.yaxis.offsetText, *ax.texts]
        for axis in (ax.xaxis, ax.yaxis):
            lo, hi = sorted(axis.get_view_interval())
            artists += [tick.label1 for tick in axis.get_major_ticks()
                        if tick.label1.get_visible() and lo <= tick.get_loc() <= hi]
    out = []
    for text in dict.fromkeys(artists):                        # each once, in order
        if text.get_visible() and text.get_text().strip():
            out.append((text, text.get_window_extent(renderer)))
    return out


def check_layout(fig) -> None:
    """Every visible text inside the figure and clear of every other (1 px slack)."""
    box = fig.bbox
    texts = visible_texts(fig)
    assert texts
    for text, extent in texts:
        assert (extent.x0 >= box.x0 - 1 and extent.y0 >= box.y0 - 1 and extent.x1 <= box.x1 + 1
                and extent.y1 <= box.y1 + 1), f"cut off at the figure's edge: {text.get_text()!r}"
    for (a, ea), (b, eb) in itertools.combinations(texts, 2):
        overlap = min(ea.x1, eb.x1) - max(ea.x0, eb.x0) > 1 and min(ea.y1, eb.y1) - max(ea.y0, eb.y0) > 1
        assert not overlap, f"texts overlap: {a.get_text()!r} and {b.get_text()!r}"


@pytest.fixture(scope="module")
def airborne():
    return simulate("trihedral")


@pytest.fixture(scope="module")
def spaceborne():
    raw = simulate("trihedral", sensor_overrides=SPACEBORNE).raw
    return {"omega-k": refocus(raw, "omegak"), "rda": refocus(raw, "rda")}


@pytest.mark.parametrize("algorithm", ["omega-k", "rda"])
def test_slant_plane_quicklook_and_figure_of_a_spaceborne_track(spaceborne, algorithm, tmp_path, drawn):
    """Catches an equal-aspect sliver (2850 m by 112 m) whose labels pile up, and range ticks of
    726 km written with an offset that lands on the axis label."""
    image = spaceborne[algorithm]
    write_quicklook(image, tmp_path / "image.png")
    check_layout(drawn[-1])
    figures.image_figure(image, tmp_path / "figure.png")
    check_layout(drawn[-1])


def test_comparison_figure_of_ground_and_slant_images(airborne, spaceborne, tmp_path, drawn):
    figures.comparison_figure({"ffbp (ground)": airborne.image, **spaceborne}, tmp_path / "compare.png")
    check_layout(drawn[-1])


def test_point_target_figure_title_fits(airborne, tmp_path, drawn):
    """Catches the one-line title with the window and the errors and RCS, wider than the figure
    (cut off at both edges)."""
    report = analyze_point_target(airborne.image, (0.0, 0.0, 0.0))
    point_target_figure(airborne.image, report, tmp_path / "pta.png")
    check_layout(drawn[-1])


def test_quicklook_colour_bar_says_what_its_decibels_are_relative_to(airborne, tmp_path, drawn):
    """Catches a colour bar labelled plain "dB": the scale is relative to the 99.5th percentile
    of the intensities (a lone target's sidelobes sit near 0 dB on it), not to 1 m^2."""
    write_quicklook(airborne.image, tmp_path / "image.png")
    labels = [ax.yaxis.label.get_text() for ax in _axes_tree(drawn[-1])]
    assert any("99.5th percentile" in label for label in labels), labels
