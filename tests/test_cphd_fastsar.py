"""Other processors form sarmitsuba's frequency-domain (FX) CPHD: FastSAR, and a backprojection of what
sarpy reads.

A trihedral (1 m edges, apex at (4, -6, 0) m, off the scene reference point at the origin) stands on a
rough ground (medium dry ground, gamma -14 dB), rendered at 35 and 55 deg of incidence and written with
``write_cphd(..., domain="fx")``, placed at -33.9 deg, 151.2 deg.

- sarpy (NGA's reader, independent of sarkit) reads the file; the image formed from what it reads by
  the FX backprojection of the CPHD standard's signal model (``SGN = -1``: a point at ``dTOA`` reads
  ``exp(-j 2 pi fx dTOA)``, so the matched sum is ``sum_v sum_n X_v[n] exp(+j 2 pi fx_n dTOA_v(x))``)
  peaks within 0.5 m of the trihedral's phase centre, its apex, with the impulse response widths of
  the aperture and the band. sarpy forms no images itself.
- FastSAR (PyPI ``fastsar``, the ``fastsar`` extra; factorised backprojection, which reads vendors' FX
  CPHD and refuses TOA) forms the file on its own grid, and ``products.geolocate`` puts the brightest
  pixel within 0.5 m of the apex, on the WGS84 ellipsoid, with the azimuth width of its Taylor window.

The truth is the apex's position in the scene, mapped to ECEF by PROJ (core/georef.py, (GEO1)), and
the -3 dB impulse response widths (IRW) of a uniformly weighted aperture and band, ``0.886 lambda /
(2 dtheta)`` in azimuth (``dtheta`` the angle the track spans at the apex, from the file's PVPs) and
``0.886 c / (2 B sin(theta))`` in ground range (0.886 the -3 dB width of ``sinc``, the compressed pulse
of a rect spectrum: Cumming and Wong, *Digital Processing of SAR Data*, 2005, eq. 3.31), widened by
the Taylor window's factor (nbar 4, -35 dB; ``focus.windows.impulse_response_width``) for FastSAR's
image.
"""
from __future__ import annotations

import importlib.util
import warnings
from pathlib import Path

import numpy as np
import pytest

sarpy_ph = pytest.importorskip("sarpy.io.phase_history")

import sarmitsuba  # noqa: E402
from sarmitsuba.core import georef  # noqa: E402
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C  # noqa: E402
from sarmitsuba.focus import windows  # noqa: E402
from sarmitsuba.formats.cphd import write_cphd  # noqa: E402
from widths import minus_3db_width  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
APEX = np.array([4.0, -6.0, 0.0])
REF = georef.GeoReference(-33.9, 151.2, 40.0)
ANGLES = (35.0, 55.0)
FC, BANDWIDTH = 9.6e9, 150e6


@pytest.fixture(scope="module")
def fx_files(tmp_path_factory):
    """incidence [deg] -> raw.cphd (FX) of the trihedral on rough ground, 32 pulses."""
    import trimesh
    root = tmp_path_factory.mktemp("fx")
    ground = trimesh.Trimesh([[-15, -15, 0], [15, -15, 0], [15, 15, 0], [-15, 15, 0]], [[0, 1, 2], [0, 2, 3]])
    reflector = trimesh.load(ROOT / "scenes" / "meshes" / "trihedral.obj").apply_translation(APEX)
    files = {}
    for incidence in ANGLES:
        scene = sarmitsuba.Scene(
            meshes=[(ground, {"material": "medium_dry_ground", "gamma_db": -14}, "ground"),
                    (reflector, "pec", "reflector")],
            sensor={"frequency": 9.6e9, "bandwidth": 150e6, "incidence_angle": incidence, "scene_center": (0, 0, 0),
                    "altitude": 1000, "velocity": 100, "prf": 250, "n_pulses": 32, "azimuth_beamwidth": 1.2,
                    "geo_origin": f"{REF.latitude_deg}, {REF.longitude_deg}, {REF.height_m}"},
            integrator={"max_depth": 3})
        files[incidence] = write_cphd(sarmitsuba.simulate(scene).raw, root / f"fx_{incidence:g}.cphd", domain="fx")
    return files


def apex_ecef() -> np.ndarray:
    return georef.enu_to_ecef(APEX[None], REF)[0]


def fx_backprojection(reader, points: np.ndarray) -> np.ndarray:
    """complex [n_points]: the FX backprojection (SGN = -1) at ECEF ``points`` [n, 3] of the vectors sarpy's
    ``reader`` gives, fx = SC0 + n SCSS, dTOA from its TxPos, RcvPos and SRPPos."""
    signal = reader[:, :, 0]
    pv = {name: np.asarray(reader.read_pvp_variable(name, 0), dtype=np.float64)
          for name in ("TxPos", "RcvPos", "SRPPos", "SC0", "SCSS")}
    out = np.zeros(len(points), dtype=np.complex128)
    for v in range(signal.shape[0]):
        srp = np.linalg.norm(pv["TxPos"][v] - pv["SRPPos"][v]) + np.linalg.norm(pv["RcvPos"][v] - pv["SRPPos"][v])
        dtoa = (np.linalg.norm(points - pv["TxPos"][v], axis=1) + np.linalg.norm(points - pv["RcvPos"][v], axis=1)
                - srp) / C
        # sum_n X[n] exp(j 2 pi dTOA (SC0 + n SCSS)) = exp(j 2 pi dTOA SC0) sum_n X[n] z^n, z = exp(j 2 pi dTOA SCSS)
        z = np.exp(2j * np.pi * dtoa * pv["SCSS"][v])
        out += np.exp(2j * np.pi * dtoa * pv["SC0"][v]) * np.polyval(signal[v][::-1].astype(np.complex128), z)
    return out


def irw(axis: np.ndarray, amplitude: np.ndarray) -> float:
    """The -3 dB width [m] of the peak of ``amplitude`` sampled along ``axis`` [m] (tests/widths.py)."""
    return minus_3db_width(axis, amplitude)[0]


def azimuth_irw_uniform(reader) -> float:
    """0.886 lambda / (2 dtheta) [m]: dtheta the angle between the first and last transmitter positions
    seen from the apex (sarpy's PVPs)."""
    tx = np.asarray(reader.read_pvp_variable("TxPos", 0), dtype=np.float64)
    first, last = (tx[k] - apex_ecef() for k in (0, -1))
    span = np.arccos(first @ last / (np.linalg.norm(first) * np.linalg.norm(last)))
    return 0.886 * C / FC / (2 * span)


def peak_near(reader, centre: np.ndarray, half: float, step: float) -> np.ndarray:
    """ENU [3] of the largest |FX backprojection| on the ground grid ``centre +- half`` with spacing ``step`` [m]."""
    axis = np.arange(-half, half + step / 2, step)
    x, y = np.meshgrid(centre[0] + axis, centre[1] + axis, indexing="ij")
    enu = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    image = np.abs(fx_backprojection(reader, georef.enu_to_ecef(enu, REF)))
    return enu[np.argmax(image)]


@pytest.mark.filterwarnings("ignore:Call to deprecated class CPHDReader:DeprecationWarning")
@pytest.mark.parametrize("incidence", ANGLES)
def test_backprojection_of_what_sarpy_reads_puts_the_trihedral_at_its_apex(fx_files, incidence):
    """Searched over +-12 m about the SRP (0.5 m steps), then +-0.6 m about that peak (5 cm): within 0.5 m of the
    apex; cuts through the apex along track and across it have the uniform IRWs within 5 %. Bug caught:
    the FX samples' fast-time origin ramp exp(-j 2 pi f (t0 - tau_srp)) dropped (the target moves by
    metres), or the carrier compensated with exp(-j 2 pi fc tau_srp) (the aperture's quadratic phase
    doubled: the azimuth response smears)."""
    reader = sarpy_ph.open(str(fx_files[incidence]))
    coarse = peak_near(reader, np.zeros(3), 12.0, 0.5)
    fine = peak_near(reader, coarse, 0.6, 0.05)
    assert np.linalg.norm(fine - APEX) < 0.5, (coarse, fine)
    line = np.arange(-4.0, 4.0 + 1e-9, 0.02)
    cuts = {}
    for name, axis in (("azimuth", 0), ("range", 1)):
        enu = np.tile(APEX, (line.size, 1))
        enu[:, axis] += line
        cuts[name] = irw(line, np.abs(fx_backprojection(reader, georef.enu_to_ecef(enu, REF))))
    assert cuts["azimuth"] == pytest.approx(azimuth_irw_uniform(reader), rel=0.05)
    assert cuts["range"] == pytest.approx(0.886 * C / (2 * BANDWIDTH) / np.sin(np.radians(incidence)), rel=0.05)


@pytest.mark.filterwarnings("ignore:Call to deprecated class CPHDReader:DeprecationWarning")
@pytest.mark.parametrize("incidence", ANGLES)
def test_fastsar_forms_the_fx_cphd_and_geolocates_the_trihedral(fx_files, incidence):
    """FastSAR's form_cphd (CPU) on a 0.1 m grid over 20 m about the image area's reference point, its
    brightest pixel through products.geolocate: within 0.5 m of the apex (ECEF), 30 dB above the median
    pixel (focused, over the clutter), its azimuth IRW that of the Taylor-weighted aperture within 5 %.
    Bug caught: the samples compensated with exp(-j 2 pi fc tau_srp) (the wrong sign: the azimuth
    response smears), or written without the SRP's delay ramp (the apex moves by metres)."""
    if importlib.util.find_spec("fastsar") is None:
        pytest.skip("FastSAR is not installed: `make setup` installs it (pip install -e '.[fastsar]')")
    import fastsar
    import sarkit.wgs84
    from fastsar import products
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="predicted error", category=UserWarning)   # its FFBP's own estimate
        out = fastsar.form_cphd(str(fx_files[incidence]), backend="cpu", spacing=0.1, extent=(20.0, 20.0))
    image = np.abs(out["image"])
    i, j = np.unravel_index(np.argmax(image), image.shape)
    lat, lon, height = (float(np.ravel(v)[0]) for v in products.geolocate(out, i, j))
    found = sarkit.wgs84.geodetic_to_cartesian(np.array([lat, lon, height]))
    assert np.linalg.norm(found - apex_ecef()) < 0.5, georef.ecef_to_enu(found[None], REF)
    assert 20 * np.log10(image.max() / np.median(image)) > 30.0
    along = np.arange(image.shape[0]) * out["spx"]                # pixel i along e1, the track's direction
    taylor = windows.impulse_response_width("taylor") / windows.impulse_response_width("rect")
    reader = sarpy_ph.open(str(fx_files[incidence]))
    assert irw(along, image[:, j]) == pytest.approx(taylor * azimuth_irw_uniform(reader), rel=0.05)
