"""Benchmark: is the image a function of the scene alone? (issues 26 and 53)

Every mesh of a scene is moved by whole image pixels (the track kept where it was: an automatic
scene centre and pulse count are pinned to the unmoved render's), rendered, and the image moved
back by those pixels; the image NRMSE ``10 log10(sum |a - b|^2 / sum |b|^2)`` [dB] against the unmoved
render says how much of the image the tracer's own choices hold. Two moves per scene, as the
issue asks: three pixels in ground range (magnitudes compared: the carrier phase of a target
depends on its range), three pixels along the track (complex images compared, the points that
the whole beam sweeps in both renders).

Both moves also change the physics a little, so they bound the tracer's share from above: the
ground move turns every face by about ``move cos(incidence) / R`` (a near-specular roof of
Munich changes by dB: its closed-form PO changes by +4.0 dB, its image by +2.8 dB), and the
along-track move shifts the scene against the pulses by a fraction of their spacing, which
changes the azimuth ambiguities where the PRF undersamples the traced beam (Munich: 150 Hz
against a 252 Hz Doppler band to the pattern's first nulls; at 600 Hz the first bounce's
along-track move drops from -9.3 to -37.7 dB). Two more rows per scene move with the physics
held exactly: the ground move against the unmoved scene seen from a track moved the other way
(what the tracer anchors to the world, or to rounding), and every mesh moved by one pulse
spacing along the track, the raw data compared one pulse later (what it anchors to the track:
the sub-apertures fall differently on the scene; a lattice of ray tubes fails this one).

All rows are measured for the mesh-anchored patches (the default, ``lit_regions = patches``,
docs/physics.md (M1)-(M8)) and the tube preview (``tiles``, the design before issue 53), with
each render's trace seconds, measured back to back in one run.

Scenes: a smooth block of nine buildings turned 30 to 86 deg from the track (built here), the
same block rough, the built-in ``urban``, and Sionna's Munich as shipped (512 central pulses, and
the full default acquisition; needs the ``sionna`` extra). One more row per scene compares the
default sub-aperture with one pulse per trace (complex), the reference it approximates (Munich:
at 512 pulses; per-pulse patches on the full acquisition take about an hour).

Writes ``invariance.csv`` and ``invariance.png`` (NRMSE against trace seconds) into the output
folder (``_table.output_dir``).

Usage: ``python benchmarks/invariance.py [--quick] [--tiny]`` (quick: the blocks and urban;
tiny: the block with 64 pulses, the patches only, a smoke test).
"""
from __future__ import annotations

import gc
import importlib.util
import math
import re
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import trimesh
from _lattice import nrmse_db
from _plot import report_per_scene
from _table import bench_main, machine

import sarmitsuba
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.loader import resolve_source

NAME = "invariance"
#: Pixels every mesh is moved by, in ground range and along the track.
MOVE_PIXELS = 3
#: The issue's acceptance level for every comparison [dB].
TARGET_DB = -30.0
#: Metres added to each point's half footprint where a move along the track keeps only the
#: points the whole beam sweeps (a roof's echo lies up to its height's layover from its pixel).
SWEEP_MARGIN = 5.0
#: The two designs compared: the mesh-anchored patches (after issue 53) and the tube preview.
MODES = ("patches", "tiles")
#: Boxcar [pixels] of the coherence estimate of a ground move.
COHERENCE_WINDOW = 7
#: The bounce orders traced: 3, the default render's depth before ``max_depth = auto``, so that
#: the figures stay comparable (``bounce_depth`` measures ``auto``; :func:`block` gives 3 itself).
MAX_DEPTH = 3


def block(n_pulses: int | None = None, rough: bool = False, shift=(0.0, 0.0, 0.0)) -> sarmitsuba.Scene:
    """Nine smooth concrete boxes, 14 m x 10 m x 8..25 m, on a 160 m smooth ground, each turned
    30 + 7 k deg from the track, X band, 1 km up, every mesh moved by ``shift`` [m];
    ``rough``: the ground and the walls rough (constant gamma, -15 dB and -10 dB)."""
    rng = np.random.default_rng(1)
    ground = trimesh.Trimesh([[-80, -80, 0], [80, -80, 0], [80, 80, 0], [-80, 80, 0]], [[0, 1, 2], [0, 2, 3]])
    ground.apply_translation(shift)
    wall = {"material": "concrete", **({"gamma_db": -10.0} if rough else {})}
    meshes = [(ground, {"material": "medium_dry_ground", **({"gamma_db": -15.0} if rough else {})}, "ground")]
    for k, (ix, iy) in enumerate((ix, iy) for ix in (-1, 0, 1) for iy in (-1, 0, 1)):
        height = float(rng.uniform(8, 25))
        jx, jy = rng.uniform(-3, 3, size=2)
        box = trimesh.creation.box((14, 10, height))
        box.apply_translation((0, 0, height / 2))
        box.apply_transform(trimesh.transformations.rotation_matrix(math.radians(30 + 7 * k), (0, 0, 1)))
        box.apply_translation((ix * 30 + jx + shift[0], iy * 30 + jy + shift[1], shift[2]))
        meshes.append((box, wall, f"building{k}"))
    sensor = {"frequency": 9.6e9, "bandwidth": 150e6, "sampling_rate": 180e6, "prf": 250, "velocity": 100,
              "altitude": 1000, "incidence_angle": 45, "scene_center": (0.0, 0.0, 0.0), "azimuth_beamwidth": 1.2}
    if n_pulses:
        sensor["n_pulses"] = n_pulses
    return sarmitsuba.Scene(meshes=meshes, sensor=sensor, integrator={"max_depth": 3},
                            name="rough block" if rough else "block")


def shifted_xml(source: str, shift, folder: Path) -> str:
    """A copy of the XML scene ``source`` (a path or built-in name) in ``folder`` with every
    top-level shape translated by ``shift`` [m] (appended to its ``to_world``) and every file it
    names made absolute; returns its path."""
    path = resolve_source(source)
    root = ET.parse(path).getroot()
    for element in root.iter("string"):
        if element.get("name") == "filename":
            element.set("value", str((path.parent / element.get("value")).resolve()))
    for shape in root.findall("shape"):
        transform = shape.find("transform[@name='to_world']")
        if transform is None:
            transform = ET.SubElement(shape, "transform", name="to_world")
        ET.SubElement(transform, "translate", x=repr(float(shift[0])), y=repr(float(shift[1])), z=repr(float(shift[2])))
    out = folder / f"{re.sub(r'[^A-Za-z0-9]+', '_', source)}_{len(list(folder.iterdir()))}.xml"
    out.write_text(ET.tostring(root, encoding="unicode"))
    return str(out)


def _render(source, sensor: dict, integrator: dict):
    """One render at ``max_depth`` :data:`MAX_DEPTH` unless ``integrator`` gives one: its trace
    seconds, image, pixel spacings and axes (the simulation dropped)."""
    sim = simulate(source, sensor_overrides=sensor, integrator_overrides={"max_depth": MAX_DEPTH, **integrator})
    image = sim.image
    params = sim.loaded.params
    out = {"trace_s": round(sim.timings["trace"], 2), "image": image.data.copy(), "raw": sim.raw.data.copy(),
           "pulse_step": float(params.velocity / params.prf),
           "axes": (np.asarray(image.azimuth, float).copy(), np.asarray(image.range, float).copy()),
           "spacing": (float(np.diff(image.azimuth[:2])[0]), float(np.diff(image.range[:2])[0])),
           "pulses": sim.raw.n_pulses, "pulses_per_trace": sim.trace.pulses_per_trace,
           "track": _track(sim), "look": _ground_look(sim), "full_aperture": _full_aperture(sim),
           "pinned": {"scene_center": tuple((np.asarray(sim.loaded.params.scene_center) + sim.loaded.offset).tolist()),
                      "n_pulses": int(sim.raw.n_pulses)}}
    del sim
    gc.collect()
    return out


def _full_aperture(sim) -> dict:
    """What says which image points the whole traced beam sweeps over: the antenna's along-track
    span [m] (from the scene centre, world frame, as the image's azimuth), a point of the track,
    the image grid's origin and axes (world frame) and the traced beam's half angle [rad]. A
    point at distance ``D`` from the track is swept whole when the beam's footprint there, ``2 D
    tan(half)``, fits inside the span."""
    # the image's azimuth 0 is the scene centre in the world frame, as the antenna positions are
    # (the tracing frame is the world less ``loaded.offset``)
    centre = np.asarray(sim.loaded.params.scene_center) + sim.loaded.offset
    along = (sim.raw.tx_position - centre) @ _track(sim)
    image = sim.image
    return {"span": (float(along.min()), float(along.max())), "track_point": np.asarray(sim.raw.tx_position).mean(axis=0),
            "origin": np.asarray(image.origin, float), "axes": (np.asarray(image.azimuth_direction, float),
                                                                np.asarray(image.range_direction, float)),
            "half": float(sim.loaded.params.traced_half_angle), "track": _track(sim)}


def _track(sim) -> np.ndarray:
    from sarmitsuba.core.geometry import acquisition_geometry
    return np.asarray(acquisition_geometry(sim.loaded.params).track_direction)


def _ground_look(sim) -> np.ndarray:
    """Unit horizontal vector of increasing ground range (away from the track)."""
    from sarmitsuba.core.geometry import acquisition_geometry
    g = acquisition_geometry(sim.loaded.params)
    away = np.asarray(g.scene_center) - g.positions[len(g.positions) // 2]
    away[2] = 0.0
    return away / np.linalg.norm(away)


def _aligned(base: dict, moved: dict, axis: int, pixels: int) -> tuple[np.ndarray, np.ndarray]:
    """The two images on the pixels both hold, the moved one moved back by ``pixels`` along
    ``axis`` (0 azimuth, 1 range): pixel ``i`` of ``base`` against the moved image's pixel at
    the same coordinate plus the move. The grids' origins may differ (they follow the scene's
    box) but lie on one lattice of the pixel spacing. Along the track only the points the whole
    beam sweeps in both renders are kept (:func:`_swept`; all of them where there are none: a
    short track); elsewhere a moved point sees a different part of the beam."""
    lo, hi = [], []
    for a in range(2):
        b_axis, m_axis = base["axes"][a], moved["axes"][a]
        step = float(b_axis[1] - b_axis[0])
        offset = (b_axis[0] + (pixels * step if a == axis else 0.0) - m_axis[0]) / step
        shift = int(round(offset))
        if abs(offset - shift) > 1e-3:
            raise ValueError(f"image grids are not on one lattice along axis {a}: {offset}")
        start = max(0, -shift)
        stop = min(len(b_axis), len(m_axis) - shift)
        lo.append((start, start + shift))
        hi.append(stop - start)
    b = base["image"][lo[0][0]:lo[0][0] + hi[0], lo[1][0]:lo[1][0] + hi[1]]
    m = moved["image"][lo[0][1]:lo[0][1] + hi[0], lo[1][1]:lo[1][1] + hi[1]]
    if axis == 0:             # a move along the track: the points the whole beam sweeps, both times
        swept = _swept(base["full_aperture"], base["axes"][0][lo[0][0]:lo[0][0] + hi[0]],
                       base["axes"][1][lo[1][0]:lo[1][0] + hi[1]], pixels * float(base["axes"][0][1] - base["axes"][0][0]))
        if np.any(swept):
            b, m = b[swept], m[swept]
    return b, m


def _swept(full: dict, azimuth: np.ndarray, ground: np.ndarray, move: float) -> np.ndarray:
    """bool [azimuth, ground]: the image points whose beam footprint (``2 D tan(half)`` at their
    distance ``D`` from the track, plus :data:`SWEEP_MARGIN`) lies inside the antenna's span
    before and after a move of ``move`` [m] along the track."""
    az_dir, rg_dir = full["axes"]
    points = full["origin"] + azimuth[:, None, None] * az_dir + ground[None, :, None] * rg_dir
    across = points - full["track_point"]
    across -= np.einsum("ijk,k->ij", across, full["track"])[..., None] * full["track"]
    half = np.linalg.norm(across, axis=2) * math.tan(full["half"]) + SWEEP_MARGIN
    first, last = full["span"]
    return (azimuth[:, None] - half >= first) & (azimuth[:, None] + move + half <= last)


def local_coherence(a: np.ndarray, b: np.ndarray, window: int = COHERENCE_WINDOW) -> float:
    """The power-weighted mean of the two complex images' coherence ``|<a b*>| / sqrt(<|a|^2>
    <|b|^2>)`` over ``window x window`` pixels (boxcar, the interferometric estimator), after the
    interferogram's dominant fringe (the flat-earth phase a ground move adds, the peak of its 2-D
    spectrum) is taken out, as InSAR processors do before estimating coherence."""
    from scipy.ndimage import uniform_filter

    def mean(x):
        return uniform_filter(x, window, mode="nearest")

    cross = a * np.conj(b)
    spectrum = np.abs(np.fft.fft2(cross))
    peak = np.unravel_index(int(np.argmax(spectrum)), spectrum.shape)
    fringe = [np.fft.fftfreq(n)[k] for n, k in zip(cross.shape, peak)]
    rows, cols = np.ogrid[:cross.shape[0], :cross.shape[1]]
    cross = cross * np.exp(-2j * np.pi * (fringe[0] * rows + fringe[1] * cols))
    num = np.hypot(mean(cross.real), mean(cross.imag))
    pa, pb = mean(np.abs(a) ** 2), mean(np.abs(b) ** 2)
    gamma = num / np.maximum(np.sqrt(pa * pb), np.finfo(float).tiny)
    weight = pa + pb
    return float(np.sum(gamma * weight) / max(np.sum(weight), np.finfo(float).tiny))


def speckle_magnitude_nrmse_db(gamma: float) -> float:
    """The magnitude NRMSE [dB] of two fully developed speckle images of equal power and complex
    coherence ``gamma``: ``E(|a| - |b|)^2 / E|a|^2 = 2 - (pi / 2) 2F1(-1/2, -1/2; 1; gamma^2)``,
    from ``E|a||b| = (pi / 4) sigma^2 2F1(-1/2, -1/2; 1; |gamma|^2)`` for a circular Gaussian pair
    (Goodman, *Speckle Phenomena in Optics*, 2007, sec. 3.5; Lee et al., IEEE TGRS 32(5), 1994,
    the joint amplitude distribution). 1 gives 0 (-inf dB, or rounding), 0 gives 2 - pi/2 (-3.7 dB)."""
    from scipy.special import hyp2f1

    value = 2.0 - 0.5 * math.pi * hyp2f1(-0.5, -0.5, 1.0, min(gamma, 1.0) ** 2)
    return 10.0 * math.log10(value) if value > 0 else float("-inf")


def sweep(label: str, scene_at, sensor: dict, per_pulse: bool = True, modes=MODES) -> list[dict]:
    """Rows of one scene: for each mode, the unmoved render and the moves; ``scene_at(shift)``
    gives the scene with every mesh moved by ``shift`` [m].

    * The issue's two moves: three pixels in ground range (magnitudes) and along the track
      (complex, the points the whole beam sweeps). Both change the physics a little: the ground
      move turns every facet by about ``move cos(theta) / R`` in incidence (a near-specular roof
      changes by dB), the along-track move shifts the scene against the pulses by a fraction of
      their spacing, which changes the azimuth ambiguities where the PRF undersamples the traced
      beam (Munich's 150 Hz against its 252 Hz).
    * Two moves whose physics is exactly the same, so that only the tracer's own choices differ:
      the ground move against the unmoved scene seen from a track moved the other way (what the
      tracer anchors to the world or to rounding), and every mesh moved by one pulse spacing along
      the track, the raw data compared one pulse later (what it anchors to the track: the
      sub-apertures fall differently on the scene)."""
    rows = []

    def row(mode, setting, render, value, compared):
        rows.append({"scene": label, "mode": mode, "setting": setting, "trace_s": render["trace_s"],
                     "pulses": render["pulses"], "nrmse_db": round(value, 1), "compared": compared,
                     "coherence": "", "speckle_db": ""})

    for mode in modes:
        integrator = {"lit_regions": mode}
        base = _render(scene_at((0.0, 0.0, 0.0)), sensor, integrator)
        # the track stays where it was: an automatic scene centre and pulse count follow the scene
        sensor_fixed = {**sensor, **base["pinned"]}
        d_az, d_rg = base["spacing"]
        rows.append({"scene": label, "mode": mode, "setting": "unmoved", "trace_s": base["trace_s"],
                     "pulses": base["pulses"], "nrmse_db": float("-inf"), "compared": "", "coherence": "",
                     "speckle_db": ""})
        ground = MOVE_PIXELS * d_rg * base["look"]
        moved = _render(scene_at(tuple(ground)), sensor_fixed, integrator)
        before, after = _aligned(base, moved, 1, MOVE_PIXELS)
        row(mode, f"moved {MOVE_PIXELS} px in ground range", moved, nrmse_db(np.abs(after), np.abs(before)), "magnitudes")
        rows[-1]["coherence"] = round(local_coherence(after, before), 4)
        rows[-1]["speckle_db"] = round(speckle_magnitude_nrmse_db(rows[-1]["coherence"]), 1)
        centre = np.asarray(base["pinned"]["scene_center"]) - ground
        counter = _render(scene_at((0.0, 0.0, 0.0)), {**sensor_fixed, "scene_center": tuple(centre.tolist())}, integrator)
        a, b = _aligned(counter, moved, 1, 0)
        row(mode, f"moved {MOVE_PIXELS} px in ground range, against the track moved back", counter, nrmse_db(b, a),
            "complex")
        moved = _render(scene_at(tuple(MOVE_PIXELS * d_az * base["track"])), sensor_fixed, integrator)
        before, after = _aligned(base, moved, 0, MOVE_PIXELS)
        row(mode, f"moved {MOVE_PIXELS} px along track", moved, nrmse_db(after, before), "complex")
        moved = _render(scene_at(tuple(base["pulse_step"] * base["track"])), sensor_fixed, integrator)
        row(mode, "moved 1 pulse along track (raw data a pulse later)", moved, nrmse_db(moved["raw"][1:], base["raw"][:-1]),
            "complex raw")
        if per_pulse and mode == "patches":
            reference = _render(scene_at((0.0, 0.0, 0.0)), sensor_fixed, {**integrator, "pulses_per_trace": 1})
            row(mode, f"sub-aperture ({base['pulses_per_trace']} pulses) vs one pulse per trace", reference,
                nrmse_db(base["image"], reference["image"]), "complex")
    for r in rows:
        r["meets"] = bool(r["nrmse_db"] <= TARGET_DB) if r["setting"] != "unmoved" else ""
    return rows


#: Bounds [dB] of the move along the track where the scene's physics changes with it: a move by a
#: fraction of the pulse spacing shifts a beam-filling scene against the pulses, and the azimuth
#: ambiguities change with it. Munich (150 Hz against the 252 Hz Doppler band of its traced
#: beam) measured -12.3 and -11.9 dB, the same as per-pulse tracing (-21.1 dB both ways on its
#: first bounce), and -37.7 dB at 600 Hz; the rough block measured -28.1 and -28.2 dB against
#: the smooth one's -30.7 to -31.8 dB, and its one-pulse move, where the physics is unchanged,
#: -36.9 dB (README, "Moving the scene moves the image").
ALONG_TRACK_DB = {"rough block": -25.0, "munich (512 pulses)": -10.0, "munich (full)": -10.0}


def checks(rows: list[dict]) -> list[tuple[str, bool, str]]:
    """Per scene, the patches (the default tracer):

    * the moves whose physics is unchanged (the ground move against the track moved back, one
      pulse along the track) and the sub-aperture against per-pulse tracing: within -30 dB;
    * the ground move, magnitudes: within -30 dB, or no farther apart than two fully developed
      speckle images of the coherence the two renders measure (:func:`speckle_magnitude_nrmse_db`,
      +1 dB): the move is an interferometric baseline, and the coherence it leaves bounds how
      alike the magnitudes can be;
    * the move along the track: within -30 dB, or :data:`ALONG_TRACK_DB` where the PRF's
      ambiguities change with it.
    The tiles' figures are the 'before' column."""
    out = []
    for row in rows:
        if row["mode"] != "patches" or row["setting"] == "unmoved":
            continue
        name = f"{row['scene']}, patches: {row['setting']}"
        value = row["nrmse_db"]
        if row["setting"].endswith("in ground range") and row["coherence"] != "":
            bound = max(TARGET_DB, row["speckle_db"] + 1.0)
            out.append((f"{name} within {TARGET_DB:g} dB or the speckle of its coherence + 1 dB (magnitudes)",
                        bool(value <= bound), f"{value} dB; coherence {row['coherence']}: speckle {row['speckle_db']} dB"))
        elif row["setting"].endswith("along track"):
            bound = ALONG_TRACK_DB.get(row["scene"], TARGET_DB)
            out.append((f"{name} within {bound:g} dB ({row['compared']})", bool(value <= bound), f"{value} dB"))
        else:
            out.append((f"{name} within {TARGET_DB:g} dB ({row['compared']})", bool(row["meets"]), f"{value} dB"))
    return out


def run(quick: bool = False, tiny: bool = False) -> list[dict]:
    """Run the comparisons, print the table, write CSV and PNG; returns the rows."""
    print(machine())
    folder = Path(tempfile.mkdtemp(prefix="invariance_"))
    scenes = {"block": (lambda shift: block(shift=shift), {}),
              "rough block": (lambda shift: block(rough=True, shift=shift), {}),
              "urban": (lambda shift: shifted_xml("urban", shift, folder), {})}
    if tiny:
        scenes = {"block": (lambda shift: block(64, shift=shift), {})}
    elif not quick and importlib.util.find_spec("sionna") is not None:
        scenes["munich (512 pulses)"] = (lambda shift: shifted_xml("sionna:munich", shift, folder), {"n_pulses": 512})
        scenes["munich (full)"] = (lambda shift: shifted_xml("sionna:munich", shift, folder), {})
    rows = []
    for label, (scene_at, sensor) in scenes.items():
        # --tiny, a smoke test: the patches (the default tracer, what the checks read) only
        rows += sweep(label, scene_at, sensor, per_pulse=not tiny and label != "munich (full)",
                      modes=MODES[:1] if tiny else MODES)
    report_per_scene(f"{NAME}{'_tiny' if tiny else ''}", rows, dict.fromkeys(r["scene"] for r in rows), "nrmse_db",
                     ylabel="image NRMSE, moved and moved back [dB]",
                     title="the image of a moved scene: patches against tiles")
    return rows


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "the blocks and urban only", "the block, 64 pulses (smoke test)")
