"""Forward-mode derivatives of the raw data with respect to material parameters (issue 57),
against central finite differences of full renders and of the NumPy Fresnel reference.

Each test names the plausible bug it catches.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from sarmitsuba.core.constants import VACUUM_PERMITTIVITY
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.derivatives import MaterialParameter, raw_derivative
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene import materials
from sarmitsuba.scene.fresnel import fresnel_half_space
from sarmitsuba.tracing.derivatives.tangents import material_tangent, reflection_table_ad

REPO = Path(__file__).resolve().parents[1]
EPS_R, SIGMA = 5.0, 0.05            # a dielectric trihedral (S/m)
PULSES = {"n_pulses": 16}
FREQUENCY = 9.6e9


def _trihedral(folder: Path, eps_r: float, sigma: float, extra: str = "") -> str:
    """The built-in trihedral made of a half-space of ``eps_r``, ``sigma``, written beside its mesh."""
    xml = (REPO / "scenes" / "trihedral.xml").read_text()
    material = (f'<bsdf type="radar" id="metal"><string name="model" value="half_space"/>'
                f'<float name="relative_permittivity" value="{eps_r!r}"/>'
                f'<float name="conductivity" value="{sigma!r}"/></bsdf>')
    xml = re.sub(r'<bsdf type="radar" id="metal">.*?</bsdf>', material, xml, flags=re.S)
    xml = xml.replace('value="meshes/trihedral.obj"', f'value="{REPO / "scenes" / "meshes" / "trihedral.obj"}"')
    xml = xml.replace("</scene>", extra + "</scene>")
    path = folder / f"trihedral_{eps_r!r}_{sigma!r}_{len(extra)}.xml"
    path.write_text(xml)
    return str(path)


def _raw(path: str) -> np.ndarray:
    return simulate(path, sensor_overrides=PULSES).raw.data.astype(np.complex128)


@pytest.mark.parametrize("eta", [4.0 - 0.1j, 20.0 - 5.0j, 2.5 - 0.0j])
@pytest.mark.parametrize("polarization", ["HH", "VV"])
def test_half_space_table_is_the_fresnel_reference(eta, polarization):
    """The Dr.Jit table the derivatives flow through against the NumPy reference. Catches TE and
    TM swapped, the TM sign convention (``r_tm`` is minus P.2040's) lost, the wrong root branch."""
    import mitsuba as mi
    n = 257
    table = reflection_table_ad(mi.Float64(eta.real), mi.Float64(eta.imag), n, polarization)
    mine = np.asarray(table.real) + 1j * np.asarray(table.imag)
    r_te, r_tm = fresnel_half_space(np.linspace(0.0, 1.0, n), eta)
    np.testing.assert_allclose(mine, r_te if polarization == "HH" else r_tm, rtol=0, atol=1e-12)


@pytest.mark.parametrize("parameter", ["relative_permittivity", "conductivity"])
@pytest.mark.parametrize("polarization", ["HH", "VV"])
def test_half_space_tangent_is_the_reference_tables_difference(parameter, polarization):
    """``dT/dp`` by AD against a central difference of the NumPy reference table. Catches the sign
    of ``d eta / d sigma = -j / (omega eps_0)`` and a derivative taken with respect to the wrong part."""
    omega_eps0 = 2.0 * math.pi * FREQUENCY * VACUUM_PERMITTIVITY
    material = materials.Material("m", complex(EPS_R, -SIGMA / omega_eps0), "half_space", None)
    tangent = material_tangent(material, parameter, FREQUENCY, polarization, 257)
    h = 1e-6 * (EPS_R if parameter == "relative_permittivity" else 1.0)
    step = h if parameter == "relative_permittivity" else -1j * h / omega_eps0
    cos = np.linspace(0.0, 1.0, 257)
    pick = 0 if polarization == "HH" else 1
    plus = fresnel_half_space(cos, material.relative_permittivity + step)[pick]
    minus = fresnel_half_space(cos, material.relative_permittivity - step)[pick]
    np.testing.assert_allclose(tangent, (plus - minus) / (2 * h), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("parameter, step", [("relative_permittivity", 5e-3), ("conductivity", 1e-3)])
def test_raw_derivative_matches_central_differences_of_renders(tmp_path, parameter, step):
    """``d raw / dp`` (forward-mode AD through the tracing kernels) against ``(raw(p + h) - raw(p -
    h)) / 2h`` of two full renders, within 1 % (the issue's bound; measured 3e-5 and 1e-4). Catches
    a tangent that misses the Jones model's second (TM) table, the earlier bounces' coefficients
    (the trihedral's third order carries most of its return), or a histogram collected before
    the tangent is propagated."""
    derivative = raw_derivative(_trihedral(tmp_path, EPS_R, SIGMA), MaterialParameter("metal", parameter),
                                sensor_overrides=PULSES)
    if parameter == "relative_permittivity":
        plus, minus = _trihedral(tmp_path, EPS_R + step, SIGMA), _trihedral(tmp_path, EPS_R - step, SIGMA)
    else:
        plus, minus = _trihedral(tmp_path, EPS_R, SIGMA + step), _trihedral(tmp_path, EPS_R, SIGMA - step)
    fd = (_raw(plus) - _raw(minus)) / (2 * step)
    assert np.linalg.norm(fd) > 0
    assert np.linalg.norm(derivative.data - fd) <= 1e-2 * np.linalg.norm(fd)
    assert derivative.metadata["derivative"]["parameter"] == parameter


@pytest.mark.parametrize("incidence", [60.0])
def test_scalar_polarimetry_derivatives_take_their_channels_table(tmp_path, incidence):
    """With ``polarimetry = scalar`` the one reflection table is the channel's: ``r_te`` for HH,
    ``r_tm`` for VV (flat_tangents). ``d raw / d eps_r`` of each channel against central
    differences of two renders, within 1 %, at 60 deg incidence, where the two Fresnel
    coefficients' derivatives differ (the two channels' differences are checked to differ by more
    than 5 %). Catches the HH and VV tangents swapped, which no Jones-model test sees."""
    step, fds = 5e-3, {}
    for polarization in ("HH", "VV"):
        sensor = {**PULSES, "incidence_angle": incidence, "polarization": polarization}
        integrator = {"polarimetry": "scalar"}
        derivative = raw_derivative(_trihedral(tmp_path, EPS_R, SIGMA), MaterialParameter("metal", "relative_permittivity"),
                                    sensor_overrides=sensor, integrator_overrides=integrator)
        renders = [simulate(_trihedral(tmp_path, EPS_R + sign * step, SIGMA), sensor_overrides=sensor,
                            integrator_overrides=integrator).raw.data.astype(np.complex128) for sign in (1, -1)]
        fd = (renders[0] - renders[1]) / (2 * step)
        assert np.linalg.norm(fd) > 0
        assert np.linalg.norm(derivative.data - fd) <= 1e-2 * np.linalg.norm(fd), polarization
        fds[polarization] = fd
    assert np.linalg.norm(fds["HH"] - fds["VV"]) > 0.05 * np.linalg.norm(fds["VV"])


def test_a_material_no_return_touches_has_zero_derivative(tmp_path):
    """A plate of its own material 300 m along the track, far outside the beam: its parameters do
    not enter the raw data, so the derivative is exactly 0. Catches a tangent set on every table
    row instead of the material's own."""
    plate = ('<bsdf type="radar" id="far"><string name="model" value="half_space"/>'
             '<float name="relative_permittivity" value="3.0"/></bsdf>'
             '<shape type="rectangle" id="far_plate"><transform name="to_world"><translate x="300"/></transform>'
             '<ref id="far"/></shape>')
    path = _trihedral(tmp_path, EPS_R, SIGMA, plate)
    derivative = raw_derivative(path, MaterialParameter("far", "relative_permittivity"), sensor_overrides=PULSES)
    assert np.count_nonzero(derivative.data) == 0


def test_bad_parameters_are_named(tmp_path):
    path = _trihedral(tmp_path, EPS_R, SIGMA)
    with pytest.raises(ParameterError, match="'brick' is not in the scene"):
        raw_derivative(path, MaterialParameter("brick", "conductivity"), sensor_overrides=PULSES)
    with pytest.raises(ParameterError, match="valid: relative_permittivity, conductivity, thickness"):
        MaterialParameter("metal", "roughness")
    with pytest.raises(ParameterError, match="is a half_space: it has no thickness"):
        raw_derivative(path, MaterialParameter("metal", "thickness"), sensor_overrides=PULSES)
    with pytest.raises(ParameterError, match="is a 'pec'"):
        raw_derivative("trihedral", MaterialParameter("metal", "relative_permittivity"), sensor_overrides=PULSES)
    import sarmitsuba
    with pytest.raises(ParameterError, match="focuser = 'omegak'.*'bp' or 'ffbp'"):
        sarmitsuba.gradients(path, None, [], focuser="omegak")


def test_reverse_mode_is_the_forward_mode_transposed(tmp_path):
    """For ``L = Re <w, raw>`` (random ``w``), reverse mode's ``dL/dp`` (the loss's gradient carried
    back through the binning's adjoint and the kernels) equals ``Re <w, d raw / dp>`` from forward
    mode, for both parameters and two materials at once. Catches a conjugate missing in the binning's
    adjoint, the seed laid into the histogram in the wrong pulse order, and gradients of one
    material's row credited to another. Its expected value comes from the same kernels' forward
    mode: it checks the two modes against each other (since reverse mode replays the kernels in
    symbolic loops and forward mode runs them evaluated, two different passes), not against
    truth; the central differences of renders above and in tests/test_geometry_gradients.py do
    that."""
    from sarmitsuba.derivatives import raw_gradient
    plate = ('<bsdf type="radar" id="ground"><string name="model" value="half_space"/>'
             '<float name="relative_permittivity" value="8.0"/><float name="conductivity" value="0.2"/></bsdf>'
             '<shape type="rectangle" id="ground_plate"><transform name="to_world"><scale x="6" y="6"/>'
             '<translate z="-0.5"/></transform><ref id="ground"/></shape>')
    path = _trihedral(tmp_path, EPS_R, SIGMA, plate)
    parameters = [MaterialParameter(m, n) for m in ("metal", "ground") for n in ("relative_permittivity", "conductivity")]
    forward = {p: raw_derivative(path, p, sensor_overrides=PULSES).data.astype(np.complex128) for p in parameters}
    shape = next(iter(forward.values())).shape
    rng = np.random.default_rng(12)
    w = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    reverse = raw_gradient(path, w, parameters, sensor_overrides=PULSES)       # dL/dRe + j dL/dIm = w
    for p in parameters:
        expected = float(np.real(np.vdot(w, forward[p])))
        assert np.linalg.norm(forward[p]) > 0, p
        assert reverse[p] == pytest.approx(expected, rel=1e-3), p


@pytest.mark.parametrize("eta, thickness", [(5.3 - 0.4j, 0.3), (4.0 - 0.02j, 0.05), (12.0 - 3.0j, 0.2)])
@pytest.mark.parametrize("polarization", ["HH", "VV"])
def test_slab_table_is_the_reference(eta, thickness, polarization):
    """The Dr.Jit slab (P.2040 eqs. (43a), (44)) against the NumPy reference. Catches ``exp(+2jq)``
    for ``exp(-2jq)`` (a growing wave), ``q`` without the thickness, ``1 - R'`` for ``1 - R'^2``."""
    import mitsuba as mi
    from sarmitsuba.scene.fresnel import slab_reflection
    n = 257
    table = reflection_table_ad(mi.Float64(eta.real), mi.Float64(eta.imag), n, polarization, mi.Float64(thickness),
                                FREQUENCY)
    mine = np.asarray(table.real) + 1j * np.asarray(table.imag)
    r_te, r_tm = slab_reflection(np.linspace(0.0, 1.0, n), eta, thickness, FREQUENCY)
    np.testing.assert_allclose(mine, r_te if polarization == "HH" else r_tm, rtol=0, atol=1e-9)


@pytest.mark.parametrize("parameter", ["relative_permittivity", "conductivity", "thickness"])
def test_slab_tangent_is_the_reference_tables_difference(parameter):
    """A slab's ``dT/dp`` by AD against central differences of the NumPy reference. Catches the
    thickness derivative's missing ``2 pi f / c`` and the slab's resonance phase read backwards."""
    from sarmitsuba.scene.fresnel import slab_reflection
    omega_eps0 = 2.0 * math.pi * FREQUENCY * VACUUM_PERMITTIVITY
    eta, d = complex(5.3, -0.2 / omega_eps0), 0.3
    material = materials.Material("wall", eta, "slab", d)
    tangent = material_tangent(material, parameter, FREQUENCY, "VV", 257)
    h = {"relative_permittivity": 1e-6, "conductivity": 1e-7, "thickness": 1e-8}[parameter]
    shift = {"relative_permittivity": (h, 0.0), "conductivity": (-1j * h / omega_eps0, 0.0), "thickness": (0.0, h)}[parameter]
    cos = np.linspace(0.0, 1.0, 257)
    plus = slab_reflection(cos, eta + shift[0], d + shift[1].real, FREQUENCY)[1]
    minus = slab_reflection(cos, eta - shift[0], d - shift[1].real, FREQUENCY)[1]
    fd = (plus - minus) / (2 * h)
    np.testing.assert_allclose(tangent, fd, rtol=1e-4, atol=1e-6 * np.abs(fd).max())


def test_slab_thickness_derivative_matches_central_differences(tmp_path):
    """A trihedral of a 5 cm slab: ``d raw / d thickness`` against renders 10 micrometres apart
    (the slab's resonances are 7 mm apart in thickness). Catches the slab's table not the one the
    kernels read (the half-space's taken instead)."""
    xml = Path(_trihedral(tmp_path, EPS_R, SIGMA)).read_text()
    paths = {}
    for tag, d in (("0", 0.05), ("p", 0.05 + 1e-5), ("m", 0.05 - 1e-5)):
        paths[tag] = tmp_path / f"slab_{tag}.xml"
        paths[tag].write_text(xml.replace('<string name="model" value="half_space"/>',
                                          f'<string name="model" value="slab"/><float name="thickness" value="{d!r}"/>'))
    derivative = raw_derivative(str(paths["0"]), MaterialParameter("metal", "thickness"), sensor_overrides=PULSES)
    fd = (_raw(str(paths["p"])) - _raw(str(paths["m"]))) / 2e-5
    assert np.linalg.norm(fd) > 0
    assert np.linalg.norm(derivative.data - fd) <= 1e-2 * np.linalg.norm(fd)


def test_urban_ground_permittivity_derivative_matches_central_differences(tmp_path):
    """The built-in urban scene (rough ground and facades, slabs, a metal roof; 16 pulses), its
    ground made of explicit concrete (ITU-R P.2040 at the carrier): ``d raw / d eps_r`` of the
    ground against renders 0.05 apart (measured 4e-5). The double bounce off the walls carries
    the ground's coefficient: catches a derivative lost in the earlier bounces' coefficients."""
    eta = materials.itu_permittivity("concrete", FREQUENCY)
    sigma = -eta.imag * 2.0 * math.pi * FREQUENCY * VACUUM_PERMITTIVITY
    source = (REPO / "scenes" / "urban.xml").read_text()
    source = source.replace('value="meshes/', f'value="{REPO / "scenes" / "meshes"}/')
    paths = {}
    for tag, eps in (("0", eta.real), ("p", eta.real + 0.05), ("m", eta.real - 0.05)):
        xml = source.replace('<bsdf type="radar" id="soil">\n        <string name="material" value="concrete"/>',
                             f'<bsdf type="radar" id="soil"><float name="relative_permittivity" value="{eps!r}"/>'
                             f'<float name="conductivity" value="{sigma!r}"/>')
        assert "soil\"><float" in xml
        paths[tag] = tmp_path / f"urban_{tag}.xml"
        paths[tag].write_text(xml)
    derivative = raw_derivative(str(paths["0"]), MaterialParameter("soil", "relative_permittivity"),
                                sensor_overrides=PULSES)
    fd = (_raw(str(paths["p"])) - _raw(str(paths["m"]))) / 0.1
    assert np.linalg.norm(fd) > 1e-3 * np.linalg.norm(_raw(str(paths["0"])))
    assert np.linalg.norm(derivative.data - fd) <= 1e-2 * np.linalg.norm(fd)


@pytest.mark.parametrize("focuser", ["bp", "ffbp"])
def test_gradients_of_an_image_loss_match_central_differences(tmp_path, focuser):
    """``sarmitsuba.gradients``: an amplitude loss between the trihedral's image at ``eps_r`` 5 and
    a target imaged at 6, differentiated in reverse mode through the adjoint of direct or fast
    factorised backprojection, the binning's and the kernels', against central differences of the
    loss itself (renders 0.01 apart), for permittivity and conductivity at once. Catches the image
    gradient carried to the raw data by the forward map instead of its adjoint, a loss gradient
    with the wrong sign, and ``focuser`` ignored (the target is focused with the other one)."""
    import sarmitsuba
    from sarmitsuba.derivatives import AmplitudeLoss
    size = {"image_size": (24, 24), "image_spacing": 0.3, "sensor_overrides": PULSES, "focuser": focuser}
    target = sarmitsuba.gradients(_trihedral(tmp_path, 6.0, SIGMA), AmplitudeLoss(np.zeros((24, 24))), [], **size).image
    loss = AmplitudeLoss(target)
    parameters = [MaterialParameter("metal", "relative_permittivity"), MaterialParameter("metal", "conductivity")]
    result = sarmitsuba.gradients(_trihedral(tmp_path, EPS_R, SIGMA), loss, parameters, **size)
    assert result.loss > 0 and result.image.shape == (24, 24)
    if focuser == "ffbp":          # the factorised image: close to the direct one, not equal to it
        direct = sarmitsuba.gradients(_trihedral(tmp_path, EPS_R, SIGMA), loss, [], **{**size, "focuser": "bp"}).image
        assert 1e-6 < np.linalg.norm(result.image - direct) / np.linalg.norm(direct) < 0.05
    for parameter, h in zip(parameters, (1e-2, 1e-3)):
        shift = (h, 0.0) if parameter.name == "relative_permittivity" else (0.0, h)
        plus = sarmitsuba.gradients(_trihedral(tmp_path, EPS_R + shift[0], SIGMA + shift[1]), loss, [], **size).loss
        minus = sarmitsuba.gradients(_trihedral(tmp_path, EPS_R - shift[0], SIGMA - shift[1]), loss, [], **size).loss
        fd = (plus - minus) / (2 * h)
        assert abs(fd) > 0
        assert result.gradient[parameter] == pytest.approx(fd, rel=1e-2), parameter


def _dihedral_with_wall(folder: Path, eps_r: float) -> str:
    """The built-in dihedral (metal ground) with its wall made of a half-space of ``eps_r``."""
    xml = (REPO / "scenes" / "dihedral.xml").read_text()
    wall = (f'<bsdf type="radar" id="wall_material"><string name="model" value="half_space"/>'
            f'<float name="relative_permittivity" value="{eps_r!r}"/><float name="conductivity" value="0.05"/></bsdf>')
    xml = xml.replace("</bsdf>", "</bsdf>" + wall, 1)
    xml = re.sub(r'(<shape type="rectangle" id="wall">.*?)<ref id="metal"/>', r'\1<ref id="wall_material"/>', xml,
                 flags=re.S)
    path = folder / f"dihedral_{eps_r!r}.xml"
    path.write_text(xml)
    return str(path)


def test_gradient_descent_recovers_a_walls_permittivity_from_30_percent_off(tmp_path):
    """The inverse problem end to end: a dihedral whose wall has ``eps_r`` 5 is imaged; starting
    from 6.5, L-BFGS-B (scipy) on the amplitude loss and ``sarmitsuba.gradients`` finds the wall's
    permittivity within 2 % (measured: 5.0000 after 9 iterations). Catches any gradient whose
    sign or size is wrong enough to stall the descent."""
    import scipy.optimize
    import sarmitsuba
    from sarmitsuba.derivatives import AmplitudeLoss
    size = {"image_size": (32, 32), "image_spacing": 0.5, "sensor_overrides": {"n_pulses": 32}}
    target = sarmitsuba.gradients(_dihedral_with_wall(tmp_path, 5.0), AmplitudeLoss(np.zeros((32, 32))), [],
                                  **size).image
    loss, parameter = AmplitudeLoss(target), MaterialParameter("wall_material", "relative_permittivity")

    def value_and_gradient(x):
        result = sarmitsuba.gradients(_dihedral_with_wall(tmp_path, float(x[0])), loss, [parameter], **size)
        return result.loss, np.array([result.gradient[parameter]])

    found = scipy.optimize.minimize(value_and_gradient, [6.5], jac=True, method="L-BFGS-B", bounds=[(1.5, 20.0)],
                                    options={"maxiter": 20})
    assert abs(found.x[0] - 5.0) <= 0.02 * 5.0


def test_scattering_coefficient_derivative_matches_central_differences(tmp_path):
    """A trihedral of Sionna's rough concrete (``itu-radio-material``, ``scattering_coefficient``
    0.3): ``d raw / dS`` through the specular factor ``sqrt(1 - S^2)`` and the Lambertian
    clutter ``4 S^2 |r|^2 cos^2`` against renders 1e-3 apart. Catches either path left out (the
    clutter's speckle and the specular returns both move) or the specular factor's sign."""
    xml = Path(_trihedral(tmp_path, EPS_R, SIGMA)).read_text()
    paths = {}
    for tag, s in (("0", 0.3), ("p", 0.301), ("m", 0.299)):
        material = (f'<bsdf type="itu-radio-material" id="metal"><string name="type" value="concrete"/>'
                    f'<float name="thickness" value="0.2"/><float name="scattering_coefficient" value="{s!r}"/></bsdf>')
        paths[tag] = tmp_path / f"rough_{tag}.xml"
        paths[tag].write_text(re.sub(r'<bsdf type="radar" id="metal">.*?</bsdf>', material, xml, flags=re.S))
    derivative = raw_derivative(str(paths["0"]), MaterialParameter("metal", "scattering_coefficient"),
                                sensor_overrides=PULSES)
    fd = (_raw(str(paths["p"])) - _raw(str(paths["m"]))) / 2e-3
    assert np.linalg.norm(fd) > 0
    assert np.linalg.norm(derivative.data - fd) <= 1e-2 * np.linalg.norm(fd)
    with pytest.raises(ParameterError, match="has no scattering_coefficient"):
        raw_derivative(_trihedral(tmp_path, EPS_R, SIGMA), MaterialParameter("metal", "scattering_coefficient"),
                       sensor_overrides=PULSES)


def test_quad_pol_reverse_mode_is_the_forward_mode_transposed(tmp_path):
    """Quad-pol: forward mode gives each channel's ``d raw / dp``, reverse mode takes a gradient per
    channel; ``Re sum_c <w_c, d raw_c / dp>`` must agree. Catches the seeds of the four channels
    laid into the histogram in another order than the kernel deposits them."""
    from sarmitsuba.derivatives import raw_gradient
    sensor, first = {**PULSES, "polarization": "quad"}, {"max_depth": 1}      # (one bounce: fewer kernels to compile)
    path = _trihedral(tmp_path, EPS_R, SIGMA)
    parameter = MaterialParameter("metal", "relative_permittivity")
    forward = raw_derivative(path, parameter, sensor_overrides=sensor, integrator_overrides=first)
    assert set(forward) == {"HH", "HV", "VH", "VV"}
    rng = np.random.default_rng(5)
    w = {c: (1.0 + 3.0 * k) * (rng.standard_normal(forward[c].data.shape) + 1j * rng.standard_normal(forward[c].data.shape))
         for k, c in enumerate(("HH", "HV", "VH", "VV"))}
    reverse = raw_gradient(path, w, [parameter], sensor_overrides=sensor, integrator_overrides=first)[parameter]
    expected = sum(float(np.real(np.vdot(w[c], forward[c].data.astype(np.complex128)))) for c in w)
    assert reverse == pytest.approx(expected, rel=1e-3)
    with pytest.raises(ParameterError, match="needs the gradient per channel"):
        raw_gradient(path, w["HH"], [parameter], sensor_overrides=sensor, integrator_overrides=first)


def test_evaluated_loops_collect_once_then_pause_the_collector():
    """The derivative traces' kernels repeat only if nothing but reference counts frees AD
    variables inside them (Dr.Jit schedules the gradients pending at a loop boundary in the order
    of their AD indices, which reuse the lowest free slot; docs/design.md section 10). Measured
    on urban, two heights, 64 pulses, eight evaluations at one point from an empty kernel cache:
    with the collector running, five of the last six compiled again for about 55 s each; paused,
    none did. Catches the pause or the collection on entry removed, and the collector left off
    after the block (or after an error in it)."""
    import gc
    import weakref
    from sarmitsuba.tracing.loops import evaluated_loops, loop_mode

    class Cyclic:
        pass

    gc.enable()
    garbage = Cyclic()
    garbage.me = garbage                        # freed only by the cyclic collector
    alive = weakref.ref(garbage)
    del garbage
    with evaluated_loops():
        assert alive() is None                  # collected on entry
        assert not gc.isenabled() and loop_mode() == "evaluated"
    assert gc.isenabled() and loop_mode() is None
    with pytest.raises(RuntimeError):
        with evaluated_loops():
            raise RuntimeError("a failed trace")
    assert gc.isenabled()
    gc.disable()                                # a caller that paused it keeps it paused
    try:
        with evaluated_loops():
            pass
        assert not gc.isenabled()
    finally:
        gc.enable()
