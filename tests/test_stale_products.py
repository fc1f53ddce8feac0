"""Stale products (issue 28): a render owns the products it writes (sarmitsuba/core/outputs.py).

A render into a folder that holds an earlier render removes that render's files it does not
write again (other channels, bounce orders, figures, standard formats), through the list of
files the earlier render recorded in ``summary.json`` (``"files"``); a file not on that list (a
user's notes, a file merely named like a product) is never touched. Figures drawn after the
render (``--figures``) and ``focus --out`` into a render folder join the list. A failed or
interrupted render leaves the earlier one in place, and a later render still cleans up; a
folder from an older version without the list keeps its files, with one warning.
"""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from sarmitsuba.cli import main

FAST = ["--no-progress", "--max-depth", "1"]
SINGLE = {"raw.npz", "image.npz", "image.exr", "image.png", "summary.json"}


def _names(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


def _render(out: Path, *flags: str, scene: str = "trihedral") -> None:
    assert main(["render", scene, "--out", str(out), *FAST, *flags]) == 0


def _listed(out: Path) -> set[str]:
    return set(json.loads((out / "summary.json").read_text())["files"])


# ---- the command line ---------------------------------------------------------------------------

def test_single_pol_render_removes_the_quad_pol_channels_and_formats(tmp_path):
    """quad-pol with CPHD, then single-pol into the same folder: raw_HV.npz, image_VV.*,
    pauli.png, raw_HH.cphd ... are gone, the single-pol files are there; notes.txt and a file
    named like a product that no render wrote (raw_HH_order7.npz) stay."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    _render(out, "--set", "polarization=quad", "--cphd")
    first = _names(out)
    assert {"raw_HV.npz", "image_VV.png", "pauli.png", "raw_HH.cphd", "notes.txt"} <= first
    assert _listed(out) == first - {"notes.txt"}
    (out / "raw_HH_order7.npz").write_text("not written by a render")
    _render(out)
    assert _names(out) == SINGLE | {"notes.txt", "raw_HH_order7.npz"}
    assert (out / "notes.txt").read_text() == "mine"
    assert (out / "raw_HH_order7.npz").read_text() == "not written by a render"
    assert _listed(out) == SINGLE


def test_render_without_split_or_figures_removes_orders_and_figures(tmp_path):
    """--split-bounces --figures, then a plain render: *_order1/2 files, fig_*.png and
    figures.json (drawn after the render, recorded with it) are gone."""
    out = tmp_path / "out"
    assert main(["render", "trihedral", "--out", str(out), "--no-progress", "--max-depth", "2",
                 "--split-bounces", "--figures"]) == 0
    first = _names(out)
    assert {"raw_order2.npz", "image_order1.exr", "fig_bounce_orders.png", "figures.json"} <= first
    assert _listed(out) == first
    _render(out)
    assert _names(out) == SINGLE
    assert _listed(out) == SINGLE


def test_focus_into_a_render_folder_joins_its_products(tmp_path):
    """focus --geotiff into a render folder: image.tif joins the render's list, so the next
    render (which writes no GeoTIFF) removes it; raw.npz, focus's input, is kept."""
    out = tmp_path / "out"
    _render(out)
    assert main(["focus", str(out / "raw.npz"), "--out", str(out), "--geotiff", "--no-progress"]) == 0
    assert "image.tif" in _listed(out) and "raw.npz" in _listed(out)
    _render(out)
    assert _names(out) == SINGLE


def test_interrupted_render_keeps_the_earlier_one_and_a_later_render_cleans_up(tmp_path, monkeypatch, capsys):
    """Ctrl-C while the second render writes its files: exit 130, the quad-pol render is
    untouched (same files, same bytes). Ctrl-C while its commit removes the quad-pol files:
    its own files go back out and the earlier list stays, so a third render still removes
    every quad-pol file left."""
    from sarmitsuba.products import image_files
    out = tmp_path / "out"
    _render(out, "--set", "polarization=quad")
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    with monkeypatch.context() as patch:
        patch.setattr(image_files, "write_exr", interrupted)
        assert main(["render", "trihedral", "--out", str(out), *FAST]) == 130
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    real_unlink = Path.unlink

    def unlink(path, *args, **kwargs):
        if path.name == "raw_VH.npz":
            raise KeyboardInterrupt
        return real_unlink(path, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(Path, "unlink", unlink)
        assert main(["render", "trihedral", "--out", str(out), *FAST]) == 130
    left = _names(out)
    assert "raw_VH.npz" in left and not left & (SINGLE - {"summary.json"}), left
    assert not [name for name in left if name.startswith(".")]
    assert (out / "summary.json").read_bytes() == before["summary.json"]
    capsys.readouterr()
    _render(out)
    assert _names(out) == SINGLE


def test_folder_of_an_older_version_keeps_its_files_with_one_warning(tmp_path, capsys):
    """A summary.json without "files" (sarmitsuba before issue 28): nothing of it is removed,
    one warning says stale files may remain; the new render records its list."""
    out = tmp_path / "out"
    _render(out, "--set", "polarization=quad")
    summary = json.loads((out / "summary.json").read_text())
    del summary["files"]
    (out / "summary.json").write_text(json.dumps(summary))
    capsys.readouterr()
    _render(out)
    err = capsys.readouterr().err
    assert err.count("warning:") == 1 and "older sarmitsuba" in err and str(out) in err, err
    assert {"raw_HV.npz", "pauli.png"} <= _names(out)
    assert _listed(out) == SINGLE


# ---- OutputDirectory ----------------------------------------------------------------------------

MANIFEST_FILE = "summary.json"


def _run(folder: Path, names: list[str], products: str | None = "replace") -> None:
    from sarmitsuba.core.outputs import OutputDirectory
    with OutputDirectory(folder, products=products) as out:
        for name in names:
            out.write(name, lambda path, name=name: path.write_text(name))


def test_replace_removes_only_listed_files_and_keeps_the_list_safe(tmp_path):
    """Only plain names of the earlier list are removed: a listed '../outside.txt', a hidden
    name or a folder is never touched; a listed file already gone is no error."""
    from sarmitsuba.core.outputs import read_manifest
    folder = tmp_path / "run"
    _run(folder, ["a.npz", "b.npz", MANIFEST_FILE])
    assert read_manifest(folder) == ("a.npz", "b.npz", MANIFEST_FILE)
    (tmp_path / "outside.txt").write_text("keep")
    (folder / ".hidden").write_text("keep")
    (folder / "sub").mkdir()
    body = json.loads((folder / MANIFEST_FILE).read_text())
    body["files"] += ["../outside.txt", ".hidden", "sub", "gone.npz"]
    (folder / MANIFEST_FILE).write_text(json.dumps(body))
    _run(folder, ["b.npz", MANIFEST_FILE])
    assert _names(folder) == {"b.npz", MANIFEST_FILE, ".hidden", "sub"}
    assert (tmp_path / "outside.txt").read_text() == "keep"
    assert read_manifest(folder) == ("b.npz", MANIFEST_FILE)


def test_add_joins_an_existing_list_and_creates_none(tmp_path):
    from sarmitsuba.core.outputs import read_manifest
    folder = tmp_path / "run"
    _run(folder, ["a.npz", MANIFEST_FILE])
    _run(folder, ["fig.png"], products="add")
    assert read_manifest(folder) == ("a.npz", "fig.png", MANIFEST_FILE)
    plain = tmp_path / "plain"
    _run(plain, ["fig.png"], products="add")
    assert _names(plain) == {"fig.png"} and read_manifest(plain) is None


def test_unknown_products_mode(tmp_path):
    from sarmitsuba.core.outputs import OutputDirectory
    with pytest.raises(ValueError, match="products"):
        OutputDirectory(tmp_path, products="owns")
