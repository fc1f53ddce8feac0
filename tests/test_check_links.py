"""The manual's link and image checker (docs/tools/check_links.py) against a hand-built site whose
broken links, missing anchors, network resources and bad images are known."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _checker():
    spec = importlib.util.spec_from_file_location("check_links", ROOT / "docs" / "tools" / "check_links.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _site(tmp_path: Path, body: str) -> Path:
    from PIL import Image
    (tmp_path / "guide").mkdir()
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(tmp_path / "ok.png")
    (tmp_path / "empty.png").write_bytes(b"")
    (tmp_path / "text.png").write_bytes(b"not a png at all")
    (tmp_path / "guide" / "page.html").write_text('<html><body><h1 id="eq-m5">M5</h1><a name="old"></a></body></html>')
    (tmp_path / "index.html").write_text(f"<html><head></head><body>{body}</body></html>")
    return tmp_path


def test_a_clean_site_has_no_problems(tmp_path):
    body = ('<a href="guide/page.html#eq-m5">ok</a><a href="guide/page.html#old">name</a>'
            '<a href="https://example.org/">external link</a><img src="ok.png"><a href="#">top</a>')
    assert _checker().check(_site(tmp_path, body)) == []


def test_each_kind_of_problem_is_found_once(tmp_path):
    body = ('<a href="guide/missing.html">a</a>'
            '<a href="guide/page.html#eq-m6">b</a>'
            '<script src="https://cdn.example.org/mathjax.js"></script>'
            '<img src="empty.png"><img src="text.png"><img src="gone.png">')
    problems = _checker().check(_site(tmp_path, body))
    assert len(problems) == 6, problems
    expected = ["missing.html: no such file", "no id 'eq-m6'", "from the network", "empty image",
                "unreadable image", "gone.png: no such file"]
    for text in expected:
        assert sum(text in p for p in problems) == 1, (text, problems)


def test_the_command_line_exits_2_without_a_manual(tmp_path, capsys):
    assert _checker().main([str(tmp_path)]) == 2
    assert "make docs" in capsys.readouterr().err


def test_an_example_page_without_its_figure_is_found(tmp_path):
    checker = _checker()
    site = _site(tmp_path, "")
    (site / "gallery").mkdir()
    (site / "gallery" / "plot_a.html").write_text('<img src="../ok.png"><img src="../sphx_glr_plot_a_001.png">')
    (site / "gallery" / "plot_b.html").write_text('<img src="../sphx_glr_plot_a_001.png">')    # another's figure
    assert checker.gallery_problems(site) == ["gallery/plot_b.html: the example left no figure"]


def test_a_same_page_anchor_is_checked_and_the_command_line_fails_on_problems(tmp_path, capsys):
    """``#eq-m5`` on the page that holds it passes and ``#eq-m6`` on a page without it is found;
    the command line exits 1 on a site with problems (that ``make docs`` then fails) and 0 on a
    clean one. (Caught: every same-page anchor skipped; problems printed with exit 0.)"""
    checker = _checker()
    site = _site(tmp_path, '<h2 id="here">h</h2><a href="#here">ok</a><a href="#nowhere">broken</a>')
    problems = checker.check(site)
    assert len(problems) == 1 and "no id 'nowhere'" in problems[0], problems
    (site / "gallery").mkdir()
    (site / "gallery" / "plot_a.html").write_text('<img src="../sphx_glr_plot_a_001.png">')
    from PIL import Image
    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(site / "sphx_glr_plot_a_001.png")
    assert checker.main([str(site)]) == 1
    (site / "index.html").write_text('<html><body><h2 id="here">h</h2><a href="#here">ok</a></body></html>')
    assert checker.main([str(site)]) == 0
