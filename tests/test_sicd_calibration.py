"""The default, uniform SICD (``write_sicd(..., weighting="uniform")``) reads one RCS in every client
(issue 55, item 4; docs/physics.md (K3), (K3')).

With the image's weighting taken out of its spectrum, a point target's peak and its integrated
power agree (``W = mean(w^2) / mean(w)^2 = 1``), so sarpy's RCS tool (``sarpy.annotation.rcs``:
``RCSSF sum |p|^2 / (OSR_row OSR_col)``), the standard's ``BetaZeroSFPoly`` integral and the peak
reading ``RCSSF |peak|^2`` all give the RCS. The trihedral sits off the SCP (tests/test_sicd_slant.py's
products: straight at 35 deg, a 3 deg circular arc at 55 deg, 50 deg looking left). Expected values:
the closed form ``4 pi a^4 / (3 lambda^2)``, ``analyze`` on the focused image, sarpy.
"""
from __future__ import annotations

import logging
import math

import numpy as np
import pytest

pytest.importorskip("sarkit.sicd")
pytest.importorskip("sarpy")

from sarmitsuba.analysis.point_target import analyze_point_target  # noqa: E402
from sarmitsuba.formats import sicd as sicd_module  # noqa: E402
from sarmitsuba.formats.sicd import SicdError, read_sicd, write_sicd  # noqa: E402

from sarmitsuba import Scene, simulate  # noqa: E402
from test_sicd_slant import APEX, CASES, FREQUENCY, closed_form_db, facing, parts, sarpy_sicd_findings, \
    trihedral  # noqa: E402

HALF = 24          # polygon half-width [SICD pixels]: +-12 uniform cells, the sinc's tails beyond hold < 2 %


def sarpy_total_rcs_db(path, fit: bool = False) -> float:
    """sarpy's RCS tool (``create_rcs_value_collection_for_reader``) over a square polygon of
    +-:data:`HALF` pixels around the brightest pixel (``fit``: the largest rectangle about it that
    the file holds, up to that): ``TotalRCS`` [dBsm]."""
    from sarpy.annotation.rcs import create_rcs_value_collection_for_reader
    from sarpy.geometry.geometry_elements import Polygon
    from sarpy.io.complex.converter import open_complex
    reader = open_complex(str(path))
    pixels = reader[:, :]
    i, j = np.unravel_index(int(np.argmax(np.abs(pixels))), pixels.shape)
    a = min(HALF, i, pixels.shape[0] - 1 - i) if fit else HALF
    b = min(HALF, j, pixels.shape[1] - 1 - j) if fit else HALF
    assert a <= i < pixels.shape[0] - a and b <= j < pixels.shape[1] - b
    ring = [[i - a, j - b], [i - a, j + b + 1], [i + a + 1, j + b + 1], [i + a + 1, j - b], [i - a, j - b]]
    values = create_rcs_value_collection_for_reader(reader, Polygon(coordinates=[ring]))
    return 10 * math.log10([e for e in values.elements if e.units == "TotalRCS"][0].value.mean)


def peak_power(pixels: np.ndarray) -> float:
    """|peak|^2 of the brightest pixel's neighbourhood, FFT-interpolated 8 times (a 32 x 32 chip)."""
    i, j = np.unravel_index(int(np.argmax(np.abs(pixels))), pixels.shape)
    chip = pixels[i - 16:i + 16, j - 16:j + 16].astype(np.complex128)
    spectrum = np.fft.fftshift(np.fft.fft2(chip))
    padded = np.zeros((256, 256), complex)
    padded[112:144, 112:144] = spectrum
    return float(np.max(np.abs(np.fft.ifft2(np.fft.ifftshift(padded))) * 64) ** 2)


@pytest.fixture(scope="module")
def uniform(tmp_path_factory):
    """{case: (simulation, uniform SICD path)}: tests/test_sicd_slant.py's off-SRP trihedral products
    on 96 x 192 ground pixels (range twice as long: the polygon of +-HALF pixels fits the slant grid)."""
    folder = tmp_path_factory.mktemp("uniform")
    out = {}
    for case, overrides in CASES.items():
        sensor = {"frequency": FREQUENCY, "bandwidth": 150e6, "sampling_rate": 180e6, "prf": 250.0,
                  "velocity": 100.0, "altitude": 1000.0, "azimuth_beamwidth": 1.2,
                  "scene_center": (0.0, 0.0, 0.0), "geo_origin": "48.1, 11.5, 520", **overrides}
        scene = Scene(meshes=[(trihedral(APEX, overrides["incidence_angle"], facing(sensor)), "pec", "tri")],
                      sensor=sensor, integrator={"max_depth": 3})
        sim = simulate(scene, image_size=(96, 192), focuser="bp")
        out[case] = (sim, write_sicd(sim.image, folder / f"{case}.nitf", raw=sim.raw, weighting="uniform"))
    return out


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
@pytest.mark.parametrize("case", list(CASES))
def test_sarpy_rcs_tool_reads_the_closed_form_on_a_uniform_sicd(uniform, case, caplog):
    """sarpy's TotalRCS over a polygon round the off-SCP trihedral: within 0.3 dB of the closed form
    and 0.2 dB of ``analyze`` on the focused image; the peak reading RCSSF |peak|^2 and the
    integral BetaZeroSF sum |p|^2 SS_row SS_col agree within 0.2 dB; sarpy's checks find no ERROR
    and no "want". Catches the weighting not taken out (W_row W_col left in: sarpy 3.7 dB high),
    taken out twice (the response inverse-tapered: peak and sums apart), RCSSF scaled by the
    weighting factors (the peak reading off by them), and Beta kept with the image's W."""
    sim, path = uniform[case]
    xml, _, pixels = parts(path)
    assert xml.load("{*}Grid/{*}Row/{*}WgtType/{*}WindowName") == "UNIFORM"
    assert xml.load("{*}Grid/{*}Col/{*}WgtFunct") is None
    reference = analyze_point_target(sim.image, APEX, chip=32).rcs_db
    total = sarpy_total_rcs_db(path)
    assert total == pytest.approx(closed_form_db(), abs=0.3)
    assert total == pytest.approx(reference, abs=0.2)
    rcssf = xml.load("{*}Radiometric/{*}RCSSFPoly")[0, 0]
    assert 10 * math.log10(rcssf * peak_power(pixels)) == pytest.approx(reference, abs=0.2)
    i, j = np.unravel_index(int(np.argmax(np.abs(pixels))), pixels.shape)
    chip = pixels[i - HALF:i + HALF + 1, j - HALF:j + HALF + 1].astype(np.complex128)
    spacing = xml.load("{*}Grid/{*}Row/{*}SS") * xml.load("{*}Grid/{*}Col/{*}SS")
    beta = xml.load("{*}Radiometric/{*}BetaZeroSFPoly")[0, 0]
    assert 10 * math.log10(beta * np.sum(np.abs(chip) ** 2) * spacing) == pytest.approx(reference, abs=0.2)
    assert sarpy_sicd_findings(path, caplog) == []


@pytest.mark.parametrize("case", ["straight", "circular"])
def test_analyze_reads_the_uniform_sicd_and_its_widths(uniform, case):
    """``analyze`` on the file read back: RCS within 0.2 dB of ``analyze`` on the focused image
    (the metadata say rect windows, no pattern, the beam kept), and the -3 dB widths 0.886 /
    ImpRespBW as ImpRespWid says (5 %). Catches the file's metadata still naming the Taylor
    windows (the RCS 3.7 dB low), a width declared from the window, the weighting left in."""
    sim, path = uniform[case]
    xml, _, _ = parts(path)
    report = analyze_point_target(read_sicd(path), APEX, chip=16)
    assert report.rcs_db == pytest.approx(analyze_point_target(sim.image, APEX, chip=32).rcs_db, abs=0.2)
    for direction in ("Row", "Col"):
        width = xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}ImpRespWid")
        assert width == pytest.approx(0.8859 / xml.load(f"{{*}}Grid/{{*}}{direction}/{{*}}ImpRespBW"), rel=1e-3)
    assert report.irw_range == pytest.approx(xml.load("{*}Grid/{*}Row/{*}ImpRespWid"), rel=0.05)
    assert report.irw_azimuth == pytest.approx(xml.load("{*}Grid/{*}Col/{*}ImpRespWid"), rel=0.05)


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_sarpy_taper_on_the_uniform_sicd_keeps_peak_and_beta(uniform, tmp_path, caplog):
    """sarpy's ``apply_spectral_taper`` (Taylor) on the uniform SICD, written by sarpy: its checks
    find no ERROR and no "want", the peak reading RCSSF |peak|^2 and the integral BetaZeroSF sum
    |p|^2 SS SS stay the RCS (0.2 dB), and sarpy's TotalRCS reads it W_row W_col high, as (K3)
    says of any weighted SICD. Catches a uniform SICD that still declares a WgtFunct (sarpy
    removes it again) and pixels whose weighting is not the declared one."""
    from sarpy.io.complex.converter import open_complex
    from sarpy.io.complex.sicd import SICDWriter
    from sarpy.processing.sicd.spectral_taper import Taper, apply_spectral_taper
    sim, path = uniform["straight"]
    data, meta = apply_spectral_taper(open_complex(str(path)), Taper("TAYLOR", {"NBAR": 4, "SLL": -35}))
    tapered = tmp_path / "tapered.nitf"
    with SICDWriter(str(tapered), meta, check_existence=False) as writer:
        writer.write_chip(data.astype(np.complex64), start_indices=(0, 0))
    assert sarpy_sicd_findings(tapered, caplog) == []
    reference = analyze_point_target(sim.image, APEX, chip=32).rcs_db
    rcssf, beta = meta.Radiometric.RCSSFPoly.Coefs[0, 0], meta.Radiometric.BetaZeroSFPoly.Coefs[0, 0]
    assert 10 * math.log10(rcssf * peak_power(data)) == pytest.approx(reference, abs=0.2)
    i, j = np.unravel_index(int(np.argmax(np.abs(data))), data.shape)
    chip = data[i - HALF:i + HALF + 1, j - HALF:j + HALF + 1]
    integral = beta * np.sum(np.abs(chip) ** 2) * meta.Grid.Row.SS * meta.Grid.Col.SS
    assert 10 * math.log10(integral) == pytest.approx(reference, abs=0.2)
    w = np.asarray(meta.Grid.Row.WgtFunct)
    factor = (np.mean(w ** 2) / np.mean(w) ** 2) ** 2
    assert sarpy_total_rcs_db(tapered) == pytest.approx(reference + 10 * math.log10(factor), abs=0.25)


def test_the_pixels_spectrum_is_flat_over_the_declared_band(uniform):
    """Power spectrum along the columns of the 16 rows through the trihedral (straight stripmap,
    whose weighting holds the two-way pattern down to -20 dB): within 1 dB peak to peak over the
    central 80 % of ImpRespBW about DeltaKCOAPoly, and 15 dB down a tenth of the band beyond it.
    Catches the weighting left in (Taylor times pattern: 20 dB across), a division centred off the
    data's spectral centre (a 1.5 % offset tilts it by 5 dB near the pattern's nulls), and the
    support beyond the kept band not dropped."""
    _, path = uniform["straight"]
    xml, _, pixels = parts(path)
    i, _ = np.unravel_index(int(np.argmax(np.abs(pixels))), pixels.shape)
    spacing = xml.load("{*}Grid/{*}Col/{*}SS")
    power = (np.abs(np.fft.fft(pixels[i - 8:i + 8].astype(np.complex128), axis=1)) ** 2).sum(axis=0)
    f = np.fft.fftfreq(pixels.shape[1], spacing)
    bandwidth = xml.load("{*}Grid/{*}Col/{*}ImpRespBW")
    centre = xml.load("{*}Grid/{*}Col/{*}DeltaKCOAPoly")[0, 0]
    offset = (f - centre + 0.5 / spacing) % (1 / spacing) - 0.5 / spacing
    inside = power[np.abs(offset) <= 0.4 * bandwidth]
    assert 10 * math.log10(inside.max() / inside.min()) < 1.0
    outside = power[np.abs(offset) >= 0.6 * bandwidth]
    assert 10 * math.log10(outside.max() / inside.mean()) < -15.0


def test_a_uniform_sicd_read_and_written_again_is_not_flattened_twice(uniform, tmp_path):
    """The image read from a uniform SICD says so (``metadata["focus"]["spectral_weighting"]``):
    written again, with either weighting, it keeps its grid and every pixel. Catches the weighting
    taken out a second time (the Taylor windows' and the pattern's division applied to pixels
    that no longer carry them)."""
    sim, path = uniform["straight"]
    image = read_sicd(path)
    _, _, pixels = parts(path)
    for weighting in ("uniform", "image"):
        again = write_sicd(image, tmp_path / f"{weighting}.nitf", raw=sim.raw, weighting=weighting)
        xml, _, pixels2 = parts(again)
        assert xml.load("{*}Grid/{*}Col/{*}WgtType/{*}WindowName") == "UNIFORM"
        np.testing.assert_array_equal(pixels2, pixels)


def test_an_unknown_weighting_is_refused_by_name(uniform, tmp_path):
    sim, _ = uniform["straight"]
    with pytest.raises(SicdError, match=r"weighting = 'taylor'; valid weightings are uniform, image"):
        write_sicd(sim.image, tmp_path / "bad.nitf", raw=sim.raw, weighting="taylor")
    assert not (tmp_path / "bad.nitf").exists()
    assert sicd_module.WEIGHTINGS == ("uniform", "image")


def test_a_hann_window_keeps_the_band_within_20_db_and_says_so(tmp_path):
    """Hann windows fall below -20 dB at the band's edges: the uniform SICD keeps the central share
    where they do not (about 80 % in range; in azimuth the two-way pattern sets it) and declares
    it. Checked by the file's own pixels: the -3 dB widths ``analyze`` measures are ImpRespWid =
    0.8859 / ImpRespBW (3 %), the sidelobes the sinc's -13.26 dB, and the RCS of ``analyze`` on the
    file (which models the narrowed band from the metadata) and of sarpy's RCS tool agree with the
    focused image's within 0.2 dB. Catches ImpRespBW left at the whole band (widths 25 % off),
    the metadata's band not narrowed (analyze's RCS 1 dB off) and the edges divided, not dropped."""
    from sarmitsuba import pipeline
    sim = pipeline.simulate("trihedral", window="hann")
    path = write_sicd(sim.image, tmp_path / "hann.nitf", raw=sim.raw)
    xml, _, _ = parts(path)
    assert xml.load("{*}Grid/{*}Row/{*}ImpRespBW") < 0.9 * 2 * sim.raw.bandwidth / 299_792_458.0
    report = analyze_point_target(read_sicd(path), (0.0, 0.0, 0.0), chip=32)
    assert report.irw_range == pytest.approx(xml.load("{*}Grid/{*}Row/{*}ImpRespWid"), rel=0.03)
    assert report.irw_azimuth == pytest.approx(xml.load("{*}Grid/{*}Col/{*}ImpRespWid"), rel=0.03)
    assert report.pslr_range_db == pytest.approx(-13.26, abs=0.5)
    reference = analyze_point_target(sim.image, (0.0, 0.0, 0.0)).rcs_db
    assert report.rcs_db == pytest.approx(reference, abs=0.2)
    assert sarpy_total_rcs_db(path) == pytest.approx(reference, abs=0.2)


def test_the_command_line_chooses_the_sicd_plane_and_weighting(tmp_path):
    """``render --sicd`` writes the slant-plane uniform file, and ``--sicd-plane image
    --sicd-weighting image`` the ground-plane weighted one, read back with sarkit (the grid and
    weighting the file declares); a bad value from Python is refused by name before tracing.
    Catches the command line's choice not reaching ``write_sicd`` (both files would read the same)."""
    import sarkit.sicd as sksicd
    from sarmitsuba.cli import main
    from sarmitsuba.core.radar import ParameterError
    from sarmitsuba.pipeline import render

    def grid(path):
        with open(path, "rb") as handle:
            xml = sksicd.XmlHelper(sksicd.NitfReader(handle).metadata.xmltree)
        return xml.load("{*}Grid/{*}ImagePlane"), xml.load("{*}Grid/{*}Row/{*}WgtType/{*}WindowName")

    base = ["render", "trihedral", "--pulses", "64", "--sicd", "--no-progress"]
    assert main(base + ["--out", str(tmp_path / "default")]) == 0
    assert grid(tmp_path / "default" / "image.nitf") == ("SLANT", "UNIFORM")
    assert main(base + ["--sicd-plane", "image", "--sicd-weighting", "image", "--out", str(tmp_path / "own")]) == 0
    plane, window = grid(tmp_path / "own" / "image.nitf")
    assert plane == "GROUND" and window != "UNIFORM", (plane, window)
    with pytest.raises(ParameterError, match="sicd_weighting = 'taylor'.*uniform and image"):
        render("trihedral", tmp_path / "bad", sicd_weighting="taylor", formats=("sicd",))
    assert not (tmp_path / "bad").exists()
