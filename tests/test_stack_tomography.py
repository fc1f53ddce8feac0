"""A rendered tomographic stack of three trihedrals, focused in elevation (docs/physics.md (TS1)-(TS6)).

Trihedrals ``near`` (apex on the ground at the origin) and ``far`` (apex ``H_FAR`` up, placed on
the same iso-range circle, so it lays over into the same pixel) share one range-azimuth cell;
``alone`` (apex ``H_ALONE`` up, 6 m along track) has a cell to itself. The stack is 14 passes at
an even spacing ``D_B`` chosen so that ten spacings give ``rho_s`` equal to the near-far
elevation distance: sub-stacks of consecutive passes then put that distance at 1.3, 1.0 and 0.5
``rho_s``.

The truths are the test's own: the trihedrals' apexes (their triple-bounce phase centres),
each pass's straight track line from the sensor parameters and the stack's offsets, elevations as
arc lengths on circles about that line, the Dirichlet kernel for the elevation response.
"""
from __future__ import annotations

import json
import math
import shutil
import dataclasses

import numpy as np
import pytest
import trimesh

import sarmitsuba
from sarmitsuba.stacks.tomo_stack import focus_elevation
from sarmitsuba.stacks.tomo_products import read_stack
from sarmitsuba.cli import main
from sarmitsuba.core.image import SarImage
from sarmitsuba.scene import canonical
from sarmitsuba.stack import render_stack

ALTITUDE, GROUND_RANGE = 1000.0, 1000.0                   # the track: y = 1000, z = 1000, flying +x
R = math.hypot(ALTITUDE, GROUND_RANGE)
WAVELENGTH = 299_792_458.0 / 9.6e9
H_FAR, H_ALONE, X_ALONE = 2.0, 3.0, 6.0
N_PASSES = 14


def _on_circle(x: float, height: float) -> np.ndarray:
    """The apex ``height`` up on the iso-range circle of the origin about the nominal track."""
    y = GROUND_RANGE - math.sqrt(R ** 2 - (ALTITUDE - height) ** 2)
    return np.array([x, y, height])


def _elevation(point: np.ndarray, offset: np.ndarray) -> float:
    """Arc length from the ground point of ``point``'s circle about the track line shifted by
    ``offset`` up to ``point``."""
    centre = np.array([point[0], GROUND_RANGE, ALTITUDE]) + offset
    radius = float(np.linalg.norm(point - centre))
    ground = np.array([point[0], centre[1] - math.sqrt(radius ** 2 - centre[2] ** 2), 0.0])
    cos = float((point - centre) @ (ground - centre)) / radius ** 2
    return radius * math.acos(min(1.0, cos))


NEAR, FAR, ALONE = np.zeros(3), _on_circle(0.0, H_FAR), _on_circle(X_ALONE, H_ALONE)
D_S = _elevation(FAR, np.zeros(3))                       # near-far elevation distance
D_B = WAVELENGTH * R / (2.0 * D_S * 10)                  # ten spacings: rho_s = D_S


def _scene() -> sarmitsuba.Scene:
    meshes = []
    for name, apex in (("near", NEAR), ("far", FAR), ("alone", ALONE)):
        mesh = canonical.trihedral(0.4)
        mesh.apply_translation(apex)
        meshes.append((mesh, "pec", name))
    sensor = {"frequency": 9.6e9, "bandwidth": 150e6, "sampling_rate": 180e6, "prf": 250, "velocity": 100,
              "altitude": ALTITUDE, "incidence_angle": 45, "scene_center": "0, 0, 0", "azimuth_beamwidth": 1.2,
              "n_pulses": 64}
    return sarmitsuba.Scene(meshes=meshes, sensor=sensor, integrator={"max_depth": 3})


@pytest.fixture(scope="module")
def stack(tmp_path_factory):
    folder = tmp_path_factory.mktemp("stack")
    summary = render_stack(_scene(), folder, span=D_B * (N_PASSES - 1), count=N_PASSES, progress=False)
    return folder, summary, read_stack([folder])


def _two_way(points: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Twice the distance [m] of points [..., 3] to the nominal track line (along x, at y =
    GROUND_RANGE, z = ALTITUDE) shifted by ``offset``: a straight track's closest-approach two-way length."""
    p = np.asarray(points, np.float64)
    return 2 * np.hypot(p[..., 1] - GROUND_RANGE - offset[1], p[..., 2] - ALTITUDE - offset[2])


def _pixel(image: SarImage, point: np.ndarray) -> tuple[int, int]:
    row, col = image.pixel_of(point)
    return int(round(row)), int(round(col))


def _sub(stack_input, first: int, count: int):
    return stack_input.images[first:first + count], stack_input.raws[first:first + count]


def _found(result, pixel):
    at = (result.scatterers["row"] == pixel[0]) & (result.scatterers["col"] == pixel[1])
    return np.sort(result.scatterers["elevation"][at])


def test_stack_json_gives_rho_s_and_the_ambiguity_of_the_closed_form(stack):
    folder, summary, _ = stack
    body = json.loads((folder / "stack.json").read_text())
    span = D_B * (N_PASSES - 1)
    assert body["elevation_resolution"] == pytest.approx(WAVELENGTH * R / (2 * span), rel=1e-6)
    assert body["elevation_ambiguity"] == pytest.approx(WAVELENGTH * R / (2 * D_B), rel=1e-6)
    assert [p["folder"] for p in body["passes"]] == [f"pass-{n:02d}" for n in range(N_PASSES)]
    assert np.ptp([p["perpendicular_baseline"] for p in body["passes"]]) == pytest.approx(span, rel=1e-6)


def test_the_phase_of_a_point_at_known_height_on_every_pass(stack):
    """angle(y_n y_ref*) = -k [(L_n(P) - L_n(x)) - (L_ref(P) - L_ref(x))], L = twice the distance
    to each pass's track line (docs/physics.md (TS2))."""
    folder, summary, st = stack
    ref = st.reference
    offsets = summary.plan.baselines.track_offsets
    image = st.images[ref]
    q = _pixel(image, ALONE)
    x = image.positions()[q]
    k = 2 * math.pi / WAVELENGTH

    expected = np.array([-k * ((_two_way(ALONE, o) - _two_way(x, o)) - (_two_way(ALONE, offsets[ref])
                                                                        - _two_way(x, offsets[ref]))) for o in offsets])
    observed = np.array([np.angle(im.data[q] * np.conj(image.data[q])) for im in st.images])
    error = np.angle(np.exp(1j * (observed - expected)))
    assert np.ptp(expected) > 2 * math.pi                # the check spans more than a cycle
    assert np.max(np.abs(error)) < 0.05                  # rad


def _widths(profile: np.ndarray, s: np.ndarray) -> tuple[float, float]:
    """(-3 dB width [m], peak sidelobe ratio [dB]) of a profile, measured here."""
    p = profile / profile.max()
    i = int(np.argmax(p))
    lo, hi = i, i
    while lo > 0 and p[lo - 1] < p[lo]:
        lo -= 1
    while hi < p.size - 1 and p[hi + 1] < p[hi]:
        hi += 1
    half = np.flatnonzero(p[lo:hi + 1] >= 0.5) + lo
    a, b = half[0], half[-1]
    left = s[a - 1] + (0.5 - p[a - 1]) / (p[a] - p[a - 1]) * (s[a] - s[a - 1])
    right = s[b] + (0.5 - p[b]) / (p[b + 1] - p[b]) * (s[b + 1] - s[b])
    sidelobe = max(p[:lo].max(initial=0), p[hi + 1:].max(initial=0))
    return right - left, 10 * math.log10(sidelobe)


def test_the_elevation_response_of_one_point_is_the_dirichlet_kernel(stack):
    _, _, st = stack
    centre = _elevation(ALONE, np.zeros(3))
    amb = WAVELENGTH * R / (2 * D_B)
    q = _pixel(st.images[st.reference], ALONE)
    result = focus_elevation(st.images, st.raws, (centre - 0.45 * amb, centre + 0.45 * amb), reference=st.reference,
                             region=(slice(q[0], q[0] + 1), slice(q[1], q[1] + 1)))
    width, pslr = _widths(result.profiles[0].astype(np.float64), result.elevation)
    s = np.linspace(-0.45 * amb, 0.45 * amb, 40001)
    xx = 2 * math.pi * D_B * s / (WAVELENGTH * R)
    with np.errstate(invalid="ignore", divide="ignore"):
        dirichlet = np.where(np.abs(np.sin(xx)) > 1e-12, np.sin(N_PASSES * xx) / (N_PASSES * np.sin(xx)), 1.0) ** 2
    width0, pslr0 = _widths(dirichlet, s)
    assert width == pytest.approx(width0, rel=0.05)
    assert 10 ** (pslr / 20) == pytest.approx(10 ** (pslr0 / 20), rel=0.05)      # sidelobe amplitude
    assert abs(result.elevation[np.argmax(result.profiles[0])] - centre) < 0.05 * WAVELENGTH * R / (2 * D_B * 13)


@pytest.mark.parametrize("method, count, ratio", [("beamforming", 14, 1.3), ("sparse", 14, 1.3),
                                                  ("sparse", 11, 1.0), ("sparse", 6, 0.5)])
def test_two_trihedrals_in_one_cell_are_separated(stack, method, count, ratio):
    """Separation ``ratio`` rho_s: each elevation within 0.1 rho_s of its apex's."""
    _, _, st = stack
    first = (N_PASSES - count) // 2
    images, raws = _sub(st, first, count)
    rho = WAVELENGTH * R / (2 * D_B * (count - 1))
    assert D_S / rho == pytest.approx(ratio, rel=0.01)
    q = _pixel(images[0], NEAR)
    result = focus_elevation(images, raws, (-2.5, 7.0), method=method, region=(slice(q[0], q[0] + 1),
                                                                               slice(q[1], q[1] + 1)))
    found = _found(result, q)
    truth = np.array([_elevation(NEAR, np.zeros(3)), D_S])
    assert found.size == 2, found
    assert np.max(np.abs(found - truth)) < 0.1 * rho, (found, truth, rho)


def test_capon_puts_a_lone_point_at_its_elevation_sharper_than_beamforming(stack):
    _, _, st = stack
    centre = _elevation(ALONE, np.zeros(3))
    q = _pixel(st.images[st.reference], ALONE)
    rho = WAVELENGTH * R / (2 * D_B * (N_PASSES - 1))
    profiles = {}
    for method in ("beamforming", "capon"):
        result = focus_elevation(st.images, st.raws, (-2.5, 10.0), method=method, reference=st.reference,
                                 region=(slice(q[0], q[0] + 1), slice(q[1], q[1] + 1)))
        found = _found(result, q)
        assert found.size == 1 and abs(found[0] - centre) < 0.1 * rho, (method, found, centre)
        profiles[method] = _widths(result.profiles[0].astype(np.float64), result.elevation)[0]
    assert profiles["capon"] < 0.7 * profiles["beamforming"]


def test_an_independent_two_point_fit_agrees_with_the_sparse_inversion(stack):
    """The test's own inversion: exhaustive least squares over pairs of elevations, steering from
    the track lines' distances (not the package's phase model), amplitudes by linear least squares."""
    _, summary, st = stack
    ref = st.reference
    offsets = summary.plan.baselines.track_offsets
    image = st.images[ref]
    q = _pixel(image, NEAR)
    x = image.positions()[q]
    y = np.array([im.data[q] for im in st.images], np.complex128)
    k = 2 * math.pi / WAVELENGTH
    centre = np.array([x[0], GROUND_RANGE, ALTITUDE]) + offsets[ref]
    radius = float(np.linalg.norm(x - centre))
    grid = np.arange(-1.0, 4.5, 0.02)
    angle = math.atan2(x[2] - centre[2], x[1] - centre[1]) - grid / radius          # up the circle: +s
    points = np.stack([np.full(grid.size, x[0]), centre[1] + radius * np.cos(angle),
                       centre[2] + radius * np.sin(angle)], axis=1)

    steer = np.stack([np.exp(-1j * k * ((_two_way(points, o) - _two_way(x, o))
                                        - (_two_way(points, offsets[ref]) - _two_way(x, offsets[ref])))) for o in offsets])
    best = (np.inf, None)
    for i in range(grid.size):
        for j in range(i + 10, grid.size):
            a = steer[:, [i, j]]
            r = y - a @ np.linalg.lstsq(a, y, rcond=None)[0]
            rss = float(np.vdot(r, r).real)
            if rss < best[0]:
                best = (rss, grid[[i, j]])
    result = focus_elevation(st.images, st.raws, (-2.5, 7.0), method="sparse", reference=ref,
                             region=(slice(q[0], q[0] + 1), slice(q[1], q[1] + 1)))
    assert np.max(np.abs(_found(result, q) - best[1])) < 0.03


def test_a_reference_point_removes_phase_errors_of_each_pass(stack):
    """Random per-pass phases (orbit or atmosphere) scramble the profile; calibrating on the lone
    trihedral's apex restores the near-far pair (docs/physics.md (TS6))."""
    _, _, st = stack
    rng = np.random.default_rng(3)
    screens = rng.uniform(-math.pi, math.pi, N_PASSES)
    images = [dataclasses.replace(im, data=im.data * np.complex64(np.exp(1j * p))) for im, p in zip(st.images, screens)]
    q = _pixel(images[0], NEAR)
    region = (slice(q[0], q[0] + 1), slice(q[1], q[1] + 1))
    truth = np.array([0.0, D_S])
    rho = WAVELENGTH * R / (2 * D_B * (N_PASSES - 1))
    raw = focus_elevation(images, st.raws, (-2.5, 7.0), method="sparse", reference=st.reference, region=region)
    fixed = focus_elevation(images, st.raws, (-2.5, 7.0), method="sparse", reference=st.reference, region=region,
                            calibration_point=ALONE)
    found = _found(fixed, q)
    assert found.size == 2 and np.max(np.abs(found - truth)) < 0.1 * rho
    scrambled = _found(raw, q)
    assert scrambled.size != 2 or np.max(np.abs(scrambled - truth)) > 0.3 * rho
    wrapped = np.angle(np.exp(1j * (fixed.calibration - (screens - screens[st.reference]))))
    assert np.max(np.abs(wrapped)) < 0.05


def test_the_cli_writes_the_products_and_any_two_passes_make_an_interferogram(stack, tmp_path, capsys):
    folder, _, st = stack
    q = _pixel(st.images[st.reference], NEAR)
    out = tmp_path / "tomo"
    code = main(["tomography", str(folder), "--out", str(out), "--method", "sparse", "--no-progress",
                 "--rows", f"{q[0] - 1}:{q[0] + 2}", "--cols", f"{q[1] - 1}:{q[1] + 2}", "--min-power-db", "-6"])
    assert code == 0, capsys.readouterr().err
    assert {p.name for p in out.iterdir()} >= {"profiles.npz", "scatterers.npz", "points.csv", "tomography.json",
                                              "tomogram.png", "point_cloud.png"}
    with np.load(out / "scatterers.npz") as f:
        assert np.any(np.abs(f["z"] - H_FAR) < 0.1) and np.any(np.abs(f["z"]) < 0.1)
        near = f["row"] == q[0]
        near &= f["col"] == q[1]
        assert near.sum() == 2
        truth = f["truth_height"][near]                  # the plates the pixel's circle meets (an apex is the
        known = np.isfinite(truth)                       # farthest point of its trihedral: the circle may miss it)
        assert known.any() and np.all(np.abs(f["height"][near][known] - truth[known]) < 0.3)
    assert main(["interferogram", str(folder / "pass-02"), str(folder / "pass-11"), "--out", str(tmp_path / "ifg"),
                 "--no-progress"]) == 0


#: The Python names of the two commands' parameters: a message of the command line names flags.
PYTHON_NAMES = ("min_power_db", "threshold_db", "max_scatterers", "tomogram_row", "calibration_point", "region",
                "out_dir", "count =", "seed =", "span =", "track_offsets", "spacing =")


def _refused(argv, capsys, *words):
    """Run ``argv``: exit 2, one ``error:`` line holding ``words`` and no Python name."""
    capsys.readouterr()
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("error:") == 1 and "Traceback" not in err, err
    assert all(w in err for w in words), (words, err)
    assert not [name for name in PYTHON_NAMES if name in err], err
    return err


def test_bad_stacks_end_with_one_message_and_code_2(stack, tmp_path, capsys):
    folder, _, st = stack
    passes = [folder / f"pass-{n:02d}" for n in range(3)]
    n_az, n_rg = st.images[0].data.shape
    cases = {
        ("one stack folder or three or more render folders", "got 2 render folders"):
            ["tomography", str(passes[0]), str(passes[1]), "--out", str(tmp_path / "a")],
        ("outside the image",): ["tomography", str(folder), "--out", str(tmp_path / "b"), "--reference-point", "0,300,0"],
        ("alias",): ["stack", "trihedral", "--span", "300", "--passes", "3", "--out", str(tmp_path / "c")],
        ("2 of the 2 folders given are stack folders", "one stack folder, or three or more render folders"):
            ["tomography", str(folder), str(folder), "--out", str(tmp_path / "f")],
        ("--rows 0:99999", f"{n_az} azimuth rows", f"{n_az} x {n_rg} pixels"):
            ["tomography", str(folder), "--out", str(tmp_path / "g"), "--rows", "0:99999"],
        ("--cols 10:400", f"{n_rg} range columns"):
            ["tomography", str(folder), "--out", str(tmp_path / "h"), "--cols", "10:400"],
        ("--tomogram-row 500", f"0 to {n_az - 1}"):
            ["tomography", str(folder), "--out", str(tmp_path / "i"), "--tomogram-row", "500"],
    }
    shifted = tmp_path / "shifted"
    shutil.copytree(passes[2], shifted)
    image = SarImage.load(shifted / "image.npz")
    dataclasses.replace(image, origin=image.origin + np.array([0.0, 0.5, 0.0])).save(shifted / "image.npz")
    cases[("grids differ in origin",)] = ["tomography", str(passes[0]), str(passes[1]), str(shifted), "--out",
                                          str(tmp_path / "e")]
    for words, argv in cases.items():
        _refused(argv, capsys, *words)
    assert not [p.name for p in tmp_path.iterdir() if p.name != "shifted"]          # nothing written


@pytest.mark.parametrize("argv, words", [
    (["stack", "trihedral", "--span", "2", "--passes", "2"], ("--passes", "whole number >= 3")),
    (["tomography", "STACK", "--threshold-db", "3"], ("--threshold-db", "< 0")),
    (["tomography", "STACK", "--min-power-db", "nan"], ("--min-power-db", "< 0")),
    (["tomography", "STACK", "--max-scatterers", "0"], ("--max-scatterers", ">= 1")),
])
def test_flags_out_of_range_are_refused_by_argparse_with_the_flag(stack, tmp_path, capsys, argv, words):
    """Flags outside their range stop before anything is read or rendered: argparse's line naming
    the flag and the range, exit 2."""
    argv = [str(stack[0]) if a == "STACK" else a for a in argv]
    with pytest.raises(SystemExit) as stop:
        main([*argv, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and all(w in err for w in words), err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("point", [(3.0, 3.0, 0.0), (-4.0, 0.0, 0.0)])
def test_a_reference_point_on_an_empty_pixel_is_refused_naming_the_brightest_nearby(stack, tmp_path, capsys, point):
    """(3, 3, 0) images 60 dB below the brightest pixel, on nothing; (-4, 0, 0) 4 m along the track
    from the near trihedral, on its azimuth sidelobes (their phase is the trihedral's). Calibrating
    on either would put the clutter's phase into every pass: refused, naming the 20 dB margin and,
    as the brightest pixel nearby, the near trihedral's (the pixel of its apex)."""
    folder, _, st = stack
    image = st.images[st.reference]
    power = np.mean([np.abs(im.data) ** 2 for im in st.images], axis=0)
    q = _pixel(image, np.array(point))
    assert 10 * math.log10(power[q] / power.max()) < -20
    near = _pixel(image, NEAR)
    err = _refused(["tomography", str(folder), "--out", str(tmp_path / "t"),
                    "--reference-point=" + ",".join(str(v) for v in point), "--no-progress"], capsys,
                   "--reference-point", "20 dB", "1/sqrt(2 SCR)", f"brightest pixel within 15 pixels is {near}")
    assert not (tmp_path / "t").exists(), err


def test_a_window_without_echo_is_refused_naming_its_level(stack, tmp_path, capsys):
    """A stack whose rows 0 to 19 are 0 in every pass (as beyond a short track): ``--rows 0:20`` wrote
    empty products with exit 0; now one line naming the window, its brightest pixel's level and
    the --min-power-db (none) that would include pixels; nothing written."""
    folder, _, st = stack
    dark = tmp_path / "dark"
    shutil.copytree(folder, dark)
    for n in range(N_PASSES):
        path = dark / f"pass-{n:02d}" / "image.npz"
        image = SarImage.load(path)
        data = image.data.copy()
        data[:20] = 0
        dataclasses.replace(image, data=data).save(path)
    _refused(["tomography", str(dark), "--out", str(tmp_path / "t"), "--rows", "0:20", "--no-progress"], capsys,
             "no echo", "-inf dBsm", "--min-power-db", "--rows and --cols", "rows 0:20")
    assert not (tmp_path / "t").exists()
    assert main(["tomography", str(dark), "--out", str(tmp_path / "u"), "--rows", "15:25", "--no-progress"]) == 0


def test_truth_heights_are_paired_by_height_not_by_elevation(stack, tmp_path):
    """The lone trihedral's scatterer lies at height 3 m, elevation 3 / sin(45 deg) = 4.24 m. With
    the truth of its pixel 3 m and 4.24 m, its truth_height is 3 m (pairing the elevation with the
    heights picks 4.24 m)."""
    from sarmitsuba.stacks.tomo_products import write_products
    folder, _, st = stack
    q = _pixel(st.images[st.reference], ALONE)
    truth = np.full_like(st.truth, np.nan)
    elevation = _elevation(ALONE, np.zeros(3))
    truth[q] = [H_ALONE, elevation, np.nan, np.nan]
    products = write_products(tmp_path / "t", dataclasses.replace(st, truth=truth),
                              region=(slice(q[0], q[0] + 1), slice(q[1], q[1] + 1)))
    sc = products.result.scatterers
    assert sc["row"].size == 1 and sc["height"][0] == pytest.approx(H_ALONE, abs=0.1)
    assert sc["elevation"][0] == pytest.approx(elevation, abs=0.15)
    assert sc["truth_height"][0] == pytest.approx(H_ALONE, abs=1e-5)


def test_the_disk_estimate_holds_the_files_written(stack):
    """``stack_cost`` against the stack's own files. Each pass's raw.npz, image.npz and image.exr
    hold the complex64 raw data, the complex64 image and three float32 channels (1.5 times the
    image): the estimate of a pass, less its allowance for the quicklook and the summary, falls
    short of the three files by their axes, metadata and headers alone (under 64 KiB; an EXR
    counted at the image's size falls 65 KiB more short); truth.npz is float32 [n_az, n_rg, 4];
    all the files together are at most the estimate."""
    from sarmitsuba.info import scene_info
    from sarmitsuba.stack import QUICKLOOK_BYTES, stack_cost
    folder, _, st = stack
    estimate = stack_cost(scene_info(_scene()).cost, N_PASSES)
    n_az, n_rg = st.images[0].data.shape
    for n in range(N_PASSES):
        sizes = {p.name: p.stat().st_size for p in (folder / f"pass-{n:02d}").iterdir()}
        assert sizes["image.npz"] - n_az * n_rg * 8 < 32 * 1024 and sizes["image.exr"] - n_az * n_rg * 12 < 32 * 1024
        files = sizes["raw.npz"] + sizes["image.npz"] + sizes["image.exr"]
        assert 0 <= files - (estimate.bytes_per_pass - QUICKLOOK_BYTES) < 64 * 1024, (n, sizes)
    assert 0 <= (folder / "truth.npz").stat().st_size - estimate.truth_bytes < 32 * 1024
    assert estimate.truth_bytes == n_az * n_rg * 4 * 4
    everything = sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    assert everything <= estimate.bytes


def test_an_interval_longer_than_the_ambiguity_is_refused_and_baselines_refer_to_the_reference(stack):
    from sarmitsuba.stacks.tomography import TomographyError
    _, summary, st = stack
    amb = WAVELENGTH * R / (2 * D_B)
    q = _pixel(st.images[st.reference], ALONE)
    region = (slice(q[0], q[0] + 1), slice(q[1], q[1] + 1))
    with pytest.raises(TomographyError, match="alias"):
        focus_elevation(st.images, st.raws, (-2.0, 1.05 * amb - 2.0), reference=st.reference, region=region)
    result = focus_elevation(st.images, st.raws, (-2.0, 0.9 * amb - 2.0), reference=st.reference, region=region)
    expected = summary.plan.baselines.perpendicular - summary.plan.baselines.perpendicular[st.reference]
    assert result.perpendicular == pytest.approx(expected, abs=1e-4)
