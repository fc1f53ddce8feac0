"""Small faults that reached the user as a traceback, a misleading line or silence.

Each must give one clear line naming the parameter or file and the fix (exit 2 where it is an
error): a Latin-1 byte in a shape id, a raw/image file given to ``info``, a derivative with
respect to a PEC material, a UTM-sized scene with ``scene_center`` at the origin, ``info``'s
time estimates (for which machine), and a ``scene_center`` far from every shape.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.cli import main
from sarmitsuba.scene.loader import builtin_scenes
from test_input_errors import one_line_error          # tests/ is on sys.path (conftest.py)

DIHEDRAL = builtin_scenes()["dihedral"]


# ---- a Latin-1 byte in a shape id -----------------------------------------------------------------

def _dihedral_bytes() -> bytes:
    return Path(DIHEDRAL).read_bytes()


def test_latin1_shape_id_without_declaration_names_the_file_and_the_fix(tmp_path, capsys):
    """0xE9 in an id, no encoding declared: Mitsuba reads the file as UTF-8 and keeps the byte,
    which Python cannot decode; one line naming the file, the id and both fixes."""
    scene = tmp_path / "latin.xml"
    scene.write_bytes(_dihedral_bytes().replace(b'id="wall"', b'id="mur_\xe9t\xe9"'))
    assert main(["info", str(scene)]) == 2
    err = one_line_error(capsys)
    assert str(scene) in err and "mur_été" in err
    assert 'encoding="ISO-8859-1"' in err and "UTF-8" in err


def _utm(data: bytes) -> bytes:
    """The scene moved to UTM-sized coordinates (traced in a shifted local frame, whose XML the
    loader rewrites), scene_center with it."""
    return (data.replace(b"</transform>", b'    <translate x="691000" y="5334000"/>\n        </transform>')
            .replace(b'name="scene_center" value="0, 0, 0"', b'name="scene_center" value="691000, 5334000, 0"'))


@pytest.mark.parametrize("utm", [False, True])
@pytest.mark.parametrize("variant", ["declared", "utf16", "comment", "comment_version_only"])
def test_latin1_that_is_declared_or_in_a_comment_works(tmp_path, capsys, variant, utm):
    """The same id with encoding="ISO-8859-1" declared, the file in UTF-16, and a Latin-1 byte
    in a comment only (with or without a declaration naming no encoding), as Mitsuba takes them:
    all load, also far from the origin, and the id arrives as written."""
    data = _utm(_dihedral_bytes()) if utm else _dihedral_bytes()
    text = data.replace(b'id="wall"', b'id="mur_\xe9t\xe9"').decode("latin-1")
    scene = tmp_path / f"{variant}.xml"
    if variant == "declared":
        scene.write_bytes(('<?xml version="1.0" encoding="ISO-8859-1"?>\n' + text).encode("latin-1"))
    elif variant == "utf16":
        scene.write_bytes(('<?xml version="1.0" encoding="UTF-16"?>\n' + text).encode("utf-16"))
    else:
        head = b'<?xml version="1.0"?>\n' if variant == "comment_version_only" else b""
        scene.write_bytes(head + data.replace(b"Dihedral:", b"Di\xe8dre:"))
    from sarmitsuba.scene.loader import load_scene
    from sarmitsuba.scene.meshcheck import shape_label
    loaded = load_scene(str(scene))
    labels = {shape_label(shape, k) for k, shape in enumerate(loaded.scene.shapes())}
    assert labels == ({"floor", "wall"} if variant.startswith("comment") else {"floor", "mur_été"})
    assert bool(np.any(loaded.offset)) == utm


# ---- info of a product file -----------------------------------------------------------------------

@pytest.mark.parametrize("name, head", [("raw.npz", None), ("raw.cphd", b"CPHD/1.1.0\n"),
                                        ("image.nitf", b"NITF02.10"), ("renamed.xml", None)])
def test_info_of_raw_or_image_file_says_it_takes_a_scene(tmp_path, capsys, name, head):
    """info of raw.npz (a zip; also under an .xml name), a CPHD or a NITF file: not Mitsuba's
    "No document element found" but one line saying it is not a scene, and where it goes."""
    import numpy as np
    path = tmp_path / name
    if head is None:
        with open(path, "wb") as f:
            np.savez(f, data=np.zeros(4))
    else:
        path.write_bytes(head + b"\0" * 64)
    assert main(["info", str(path)]) == 2
    err = one_line_error(capsys)
    assert str(path) in err and "not a scene" in err and "info" in err
    assert "focus" in err and "analyze" in err
    assert "No document element" not in err


# ---- a derivative with respect to a PEC material --------------------------------------------------

@pytest.mark.parametrize("api", ["gradients", "raw_gradient"])
def test_pec_material_parameter_is_refused_before_any_tracing(monkeypatch, api):
    """dihedral's "metal" is pec: it has no permittivity or conductivity to move. The refusal
    must come before the forward render (gradients) or the adjoint trace (raw_gradient): both
    are replaced by a failure here, so a late refusal fails the test."""
    import numpy as np
    from sarmitsuba import derivatives
    from sarmitsuba.core.radar import ParameterError

    def traced(*args, **kwargs):
        raise AssertionError("traced before the parameters were checked")
    monkeypatch.setattr(derivatives, "_values", traced)
    monkeypatch.setattr(derivatives, "trace", traced)
    parameter = derivatives.MaterialParameter("metal", "conductivity")
    with pytest.raises(ParameterError, match="(?i)pec") as caught:
        if api == "gradients":
            derivatives.gradients("dihedral", derivatives.AmplitudeLoss(np.zeros((8, 8))), [parameter],
                                  image_size=(8, 8), sensor_overrides={"n_pulses": 8})
        else:
            derivatives.raw_gradient("dihedral", np.zeros((8, 8)), [parameter], sensor_overrides={"n_pulses": 8})
    assert "metal" in str(caught.value)


def test_an_amplitude_loss_of_the_wrong_shape_is_refused_before_any_tracing(monkeypatch):
    """A target of 8 x 6 pixels for an 8 x 8 image: refused before the forward render (which is
    replaced by a failure here), naming both shapes and ``image_size``; the transposed shape too
    (azimuth by range, not range by azimuth)."""
    import numpy as np
    from sarmitsuba import derivatives
    from sarmitsuba.core.radar import ParameterError

    def traced(*args, **kwargs):
        raise AssertionError("traced before the loss was checked")
    monkeypatch.setattr(derivatives, "_values", traced)
    monkeypatch.setattr(derivatives, "trace", traced)
    monkeypatch.setattr(derivatives, "_raw", traced)
    for target, size in (((8, 6), (8, 8)), ((6, 8), (8, 6))):
        with pytest.raises(ParameterError, match=r"image_size") as caught:
            derivatives.gradients("dihedral", derivatives.AmplitudeLoss(np.zeros(target)), [],
                                  image_size=size, sensor_overrides={"n_pulses": 8})
        assert f"{target}" in str(caught.value) and f"{size}" in str(caught.value)


# ---- scene_center far from the shapes -------------------------------------------------------------
# The dihedral's shapes span x -10..10, y 0..10, z 0..5 m (scenes/dihedral.xml): middle (0, 5, 2.5).

def _dihedral_moved(tmp_path, x: float = 0.0, y: float = 0.0, center: str = "0, 0, 0") -> Path:
    text = Path(DIHEDRAL).read_text()
    if x or y:
        text = text.replace("</transform>", f'    <translate x="{x}" y="{y}"/>\n        </transform>')
    path = tmp_path / "moved.xml"
    path.write_text(text.replace('name="scene_center" value="0, 0, 0"', f'name="scene_center" value="{center}"'))
    return path


def test_utm_scene_with_scene_center_at_the_origin_leads_with_scene_center(tmp_path, capsys):
    """Shapes at UTM coordinates (691 km, 5334 km), scene_center left at 0: the fix named first
    is scene_center = the shapes' middle, as numbers; raising the altitude (to 5334 km) second."""
    path = _dihedral_moved(tmp_path, 691000.0, 5334000.0)
    assert main(["info", str(path)]) == 2
    err = one_line_error(capsys)
    fix = "set scene_center = 691000.0, 5334005.0, 2.5"
    assert fix in err and "raise altitude" in err
    assert err.index(fix) < err.index("raise altitude")


def _acquisition_warnings(path: Path) -> list[str]:
    import warnings
    from sarmitsuba.scene.loader import load_scene
    from sarmitsuba.scene.planning import AcquisitionWarning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_scene(str(path))
    return [str(w.message) for w in caught if issubclass(w.category, AcquisitionWarning)]


def test_scene_center_400_m_from_every_shape_warns_with_the_middle(tmp_path):
    """scene_center 400 m off (390 m from the box's nearest face y = 10): one warning naming
    scene_center, the distance and the shapes' middle as the fix."""
    found = [m for m in _acquisition_warnings(_dihedral_moved(tmp_path, center="0, 400, 0")) if "scene_center" in m]
    assert len(found) == 1, found
    assert "390.0 m" in found[0] and "set scene_center = 0.0, 5.0, 2.5" in found[0]
    assert "track" not in found[0]          # across track: the automatic track barely grows (219 -> 255 pulses)


def test_scene_center_400_m_along_track_also_names_the_longer_track(tmp_path):
    """Along track (x, heading 0) the automatic track grows tenfold (219 -> 2219 pulses, info):
    the warning says so; with n_pulses given, the track is the user's and is not mentioned."""
    path = _dihedral_moved(tmp_path, center="400, 0, 0")
    found = [m for m in _acquisition_warnings(path) if "scene_center" in m]
    assert len(found) == 1 and "390.0 m" in found[0] and "automatic track longer" in found[0]
    from sarmitsuba.scene.loader import load_scene
    import warnings
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_scene(str(path), sensor_overrides={"n_pulses": 2400})
    given = [str(w.message) for w in caught if "scene_center" in str(w.message)]
    assert len(given) == 1 and "track" not in given[0]


@pytest.mark.parametrize("center", ["0, 5, 2.5", "0, 12, 0", "0, 30, 0", "25, 0, 0"])
def test_scene_center_near_the_shapes_does_not_warn(tmp_path, center):
    """Inside the box, or outside by less than 16 ground-range cells (16 x 1.41 m = 22.6 m at
    150 MHz and 45 deg; the box's half diagonal is 11.5 m): no warning."""
    assert not [m for m in _acquisition_warnings(_dihedral_moved(tmp_path, center=center)) if "scene_center" in m]


def test_scene_center_just_beyond_the_margin_warns(tmp_path):
    """40 m beyond the box's face (y = 50): past the 22.6 m margin."""
    assert [m for m in _acquisition_warnings(_dihedral_moved(tmp_path, center="0, 50, 0")) if "scene_center" in m]


# ---- info's time estimates: for which machine -----------------------------------------------------

def test_info_says_its_times_are_for_an_idle_two_core_machine(capsys, monkeypatch):
    """The rates are calibrated on 2 threads of a 2-core VM (analysis/cost.py, CAST_RATE_ANCHORS)
    and not scaled: info says so in text and JSON, with this machine's cores and load."""
    import json
    import os
    monkeypatch.setattr(os, "cpu_count", lambda: 7)
    monkeypatch.setattr(os, "getloadavg", lambda: (5.25, 0.0, 0.0))
    assert main(["info", "dihedral"]) == 0
    text = capsys.readouterr().out
    cost = text.split("Estimated cost", 1)[1].split("Warnings", 1)[0]
    line = next(line for line in cost.splitlines() if "idle" in line)
    assert "idle 2-core" in line and "this machine: 7 cores, load average 5.2" in line
    assert main(["info", "dihedral", "--json"]) == 0
    basis = json.loads(capsys.readouterr().out)["cost"]["time_basis"]
    assert "idle 2-core" in basis and "7 cores" in basis
