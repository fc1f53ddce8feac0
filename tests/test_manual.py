"""The manual (``make docs``) builds from the repository with no warning, in its quick form (the
gallery's pages without running their scripts: ``-D plot_gallery=0``; ``make docs`` runs them); its
API reference holds every public function and class (docs/conf.py, docs/api), and every internal
link, anchor and image of the result resolves, with nothing loaded from the network
(docs/tools/check_links.py)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from test_docstrings import public_objects          # tests/ is on sys.path (conftest.py)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> Path:
    """The HTML manual, built as ``make docs`` builds it (warnings are errors), the gallery not run."""
    out = tmp_path_factory.mktemp("manual")
    done = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
                           "-D", "plot_gallery=0", str(ROOT / "docs"), str(out)], capture_output=True, text=True,
                          cwd=ROOT)
    assert done.returncode == 0 and not done.stderr.strip(), done.stderr[-4000:]
    return out


def test_the_manual_builds_without_warnings(built):
    for page in ("index.html", "physics.html", "design.html", "reading-sar-images.html", "api/index.html",
                 "getting-started.html", "guide/index.html", "guide/rendering.html", "gallery/index.html",
                 "benchmarks/index.html", "plugins.html"):
        assert (built / page).is_file(), page


def test_every_public_function_and_class_is_in_the_api_reference(built):
    from sphinx.util.inventory import InventoryFile
    with open(built / "objects.inv", "rb") as stream:
        inventory = InventoryFile.load(stream, "", lambda base, uri: uri)
    documented = {name for kind in ("py:function", "py:class", "py:exception") for name in inventory.get(kind, {})}
    missing = sorted(name for name in public_objects() if name not in documented)
    assert not missing, f"{len(missing)} public names missing from the API reference: {missing[:20]}"


def test_every_internal_link_and_image_resolves(built):
    from test_check_links import _checker                   # docs/tools/check_links.py as a module
    check_links = _checker()
    problems = check_links.check(built)
    assert not problems, problems[:20]


def test_every_sensor_and_integrator_parameter_is_in_the_plugin_reference(built):
    """The plugin reference's tables name every parameter the ``sar`` sensor and the ``sbr``
    integrator take: each field of RadarParameters and TraceSettings, and each ``receiver_*``
    parameter. (Caught: the receiver's fourteen parameters and ``orbit_pass_time``, absent.)"""
    import dataclasses
    import re
    from sarmitsuba.core.radar import RadarParameters
    from sarmitsuba.core.receiver import RECEIVER_FIELDS, RECEIVER_PREFIX
    from sarmitsuba.scene.trace_inputs import TraceSettings
    text = re.sub(r"<[^>]+>", " ", (built / "plugins.html").read_text())
    names = [n for n in RadarParameters.names() if n != "receiver"] + [RECEIVER_PREFIX + f for f in RECEIVER_FIELDS]
    names += [f.name for f in dataclasses.fields(TraceSettings)]
    missing = [n for n in names if not re.search(rf"(?<![\w]){n}(?![\w])", text)]
    assert not missing, missing
