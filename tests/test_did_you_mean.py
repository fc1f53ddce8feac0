"""A misspelt name gets the closest valid names ("did you mean ...?") before the full list:
sar sensor and sbr integrator parameters, materials (ITU names in XML and in Python scenes),
material overrides, built-in and Sionna RT scene names. The expected suggestions are written
by hand; a name far from every valid one gets the list alone."""
from __future__ import annotations

import pytest

from sarmitsuba.cli import main
from sarmitsuba.core.valid_ranges import unknown_name

TRIHEDRAL_XML = """<scene version="3.0.0">
  <sensor type="sar"/>
  <integrator type="sbr"/>
  <bsdf type="itu-radio-material" id="m"><string name="type" value="{material}"/></bsdf>
  <shape type="rectangle"><ref id="m"/></shape>
</scene>
"""


@pytest.mark.parametrize("argv, question", [
    (["info", "trihedral", "--set", "bandwith=1e8"], "did you mean 'bandwidth'?"),
    (["info", "trihedral", "--set", "incidence=30"], "did you mean 'incidence_angle'?"),
    (["info", "trihedral", "--integrator-set", "max_dept=2"], "did you mean 'max_depth'?"),
    (["info", "trihedral", "--material-set", "gama_db=-10"], "did you mean 'gamma_db'?"),
    (["info", "trihedal"], "did you mean 'trihedral'"),
    (["info", "sionna:munch"], "did you mean 'munich'?"),
])
def test_cli_suggests_the_closest_name(argv, question, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and question in err and "valid: " in err
    assert err.index("did you mean") < err.index("valid: ")


def test_xml_material_typo_suggests_the_itu_name(tmp_path, capsys):
    path = tmp_path / "plate.xml"
    path.write_text(TRIHEDRAL_XML.format(material="concret"))
    assert main(["info", str(path)]) == 2
    err = capsys.readouterr().err
    assert "did you mean 'concrete'" in err and "metal" in err


def test_python_scene_material_typo_suggests_the_itu_name():
    import trimesh

    import sarmitsuba
    from sarmitsuba.core.radar import ParameterError
    with pytest.raises(ParameterError, match="did you mean 'glass'"):
        sarmitsuba.Scene([(trimesh.creation.box((1, 1, 1)), "glas")])


def test_no_suggestion_for_a_name_far_from_all():
    message = unknown_name("sar sensor parameter", "zzzz", ["altitude", "bandwidth"])
    assert "did you mean" not in message and message.endswith("valid: altitude, bandwidth")
    assert unknown_name("material", "Glass", ["concrete", "glass"]).count("'glass'") == 1
