"""Benchmark: rough surfaces (docs/physics.md (RS1)-(RS7)), every figure measured in one run.

1. **A rough plate against the model.** An 80 m plate of medium dry ground with ``s = 3 mm``,
   ``l = 20 mm`` (exponential; ``k s = 0.6``), quad pol at 25, 45 and 60 deg: the calibrated mean
   intensity over its 60 m interior per unit ground area (K2) against the I2EM's HH, VV and HV
   averaged over the same pixels' incidence. Bound: 0.5 dB.
2. **Munich with the ``city`` preset**, a strip of Sionna's Munich (270 pulses, 50 MHz, a 0.5 deg
   beam, two bounce orders: the gallery's settings):
   - seconds of the render as shipped (smooth), with ``gamma_db = -8`` everywhere and with
     ``roughness=city``, best of two each; the preset's ratio to the smooth render (bound 1.2x)
     and to the constant-gamma one;
   - each rough class alone (the other classes given their permittivity explicitly, so the preset
     leaves them smooth), rendered with two seeds at bounce order 1: the difference of the two
     images holds no PO and twice the class's clutter power. Multilooked 5 x 5, per unit ground
     area, its median over the pixels the class lights (within 10 dB of its brightest 1 %: shadows
     fall 30 dB and more below; and only where the whole 11 x 11 neighbourhood is lit), against
     ``info``'s sigma nought of the class at the scene's incidence and against the model at each
     pixel's own incidence (the strip spans 35 to 52 deg; bound 1 dB for the ground;
     the facades are vertical, so their image sigma nought carries the slope's area factor and
     their local incidence, and is reported, not bounded) and the classes' order against the
     model's.

Writes ``rough_city.csv``. Needs Sionna RT for part 2. ``--quick``: the plate at 45 deg and the
ground class only.
Usage: ``python benchmarks/rough_city.py [--quick]``
"""
from __future__ import annotations

import math
import re
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

import sarmitsuba as sm
from sarmitsuba.analysis.point_target import energy_widths
from sarmitsuba.core.constants import VACUUM_PERMITTIVITY
from sarmitsuba.pipeline import simulate
from sarmitsuba.scene.materials import itu_permittivity
from sarmitsuba.scene.roughness import RoughSurface, sigma0_backscatter
from _table import bench_main, report_rows

NAME = "rough_city"
PLATE = RoughSurface(0.003, 0.02)
STRIP = dict(sensor_overrides={"n_pulses": 270, "bandwidth": 50e6, "azimuth_beamwidth": 0.5, "prf": 90},
             image_size=(160, 400), image_spacing=1.5)
CLASSES = ("concrete", "marble", "brick", "wood", "metal")
LOOKS = 5


def _plate_rows(quick: bool) -> list[dict]:
    import trimesh
    rows = []
    quad = trimesh.Trimesh(np.array([[-40, -40, 0], [40, -40, 0], [40, 40, 0], [-40, 40, 0]], float),
                           [[0, 1, 2], [0, 2, 3]])
    material = {"material": "medium_dry_ground", "rms_height": PLATE.rms_height,
                "correlation_length": PLATE.correlation_length}
    for degrees in (45.0,) if quick else (25.0, 45.0, 60.0):
        scene = sm.Scene([(quad, material, "ground")], name=f"rough_plate_{degrees:g}",
                         sensor={"bandwidth": 150e6, "azimuth_beamwidth": 1.2, "prf": 250,
                                 "scene_center": (0.0, 0.0, 0.0), "incidence_angle": degrees, "polarization": "quad"},
                         integrator={"max_depth": 1, "ray_spacing": 0.2, "seed": 1})
        sim = simulate(scene)
        k = 2 * math.pi * sim.loaded.params.frequency / 299792458.0
        eta = itu_permittivity("medium_dry_ground", sim.loaded.params.frequency)
        for name in ("HH", "VV", "HV"):
            image = sim.channels[name].image
            az, gr = np.meshgrid(image.azimuth, image.range, indexing="ij")
            box = (np.abs(az) < 30.0) & (np.abs(gr) < 30.0)
            positions = image.positions()[box]
            antenna = sim.raw.tx_position.mean(axis=0)
            cos_theta = (antenna[2] - positions[:, 2]) / np.linalg.norm(antenna - positions, axis=1)
            model = float(sigma0_backscatter(PLATE, eta, k, cos_theta)[name].mean())
            measured = float(np.mean(np.abs(image.data[box]) ** 2) / np.prod(energy_widths(image)))
            rows.append(dict(part="plate", case=f"{degrees:g} deg", channel=name,
                             measured_db=round(10 * math.log10(measured), 2), model_db=round(10 * math.log10(model), 2),
                             error_db=round(10 * math.log10(measured / model), 2), seconds=None))
    return rows


def _seconds(source, **kwargs) -> float:
    best = math.inf
    for _ in range(2):
        start = time.perf_counter()
        simulate(source, integrator_overrides={"max_depth": 2}, **STRIP, **kwargs)
        best = min(best, time.perf_counter() - start)
    return best


def _timing_rows() -> list[dict]:
    simulate("sionna:munich", integrator_overrides={"max_depth": 2}, **STRIP)       # warm the kernel cache
    smooth = _seconds("sionna:munich")
    gamma = _seconds("sionna:munich", material_overrides={"gamma_db": -8})
    city = _seconds("sionna:munich", material_overrides={"roughness": "city"})
    return [dict(part="time", case="as shipped (smooth)", channel="VV", seconds=round(smooth, 2)),
            dict(part="time", case="gamma_db = -8", channel="VV", seconds=round(gamma, 2),
                 ratio=round(gamma / smooth, 3)),
            dict(part="time", case="roughness = city", channel="VV", seconds=round(city, 2),
                 ratio=round(city / smooth, 3), ratio_to_gamma=round(city / gamma, 3))]


def _class_only(folder: Path, keep: str) -> Path:
    """A copy of Munich where every class but ``keep`` has its permittivity given explicitly (a
    ``radar`` slab of the same P.2040 values), which the preset leaves alone."""
    from sarmitsuba.scene.loader import resolve_source
    source = Path(resolve_source("sionna:munich"))
    target = folder / keep
    shutil.copytree(source.parent, target, dirs_exist_ok=True)
    text = (target / source.name).read_text()
    frequency = 9.6e9

    def replace(match):
        name = match.group(1)
        if name == keep:
            return match.group(0)
        eta = itu_permittivity(name, frequency)
        sigma = -eta.imag * 2 * math.pi * frequency * VACUUM_PERMITTIVITY
        return (f'<bsdf type="radar" id="{name}"><string name="model" value="slab"/>'
                f'<float name="thickness" value="0.1"/><float name="relative_permittivity" value="{eta.real!r}"/>'
                f'<float name="conductivity" value="{sigma!r}"/></bsdf>')

    pattern = r'<bsdf type="itu-radio-material" id="([a-z_]+)">.*?</bsdf>'
    (target / source.name).write_text(re.sub(pattern, replace, text, flags=re.S))
    return target / source.name


def _class_rows(quick: bool) -> list[dict]:
    from scipy.ndimage import minimum_filter, uniform_filter
    from sarmitsuba.scene.rough_presets import describe_surface, preset_surface
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name in ("concrete",) if quick else CLASSES:
            path = str(_class_only(Path(folder), name))
            images = [simulate(path, integrator_overrides={"max_depth": 1, "seed": seed},
                               material_overrides={"roughness": "city"}, **STRIP) for seed in (1, 2)]
            image, params = images[0].image, images[0].loaded.params
            power = np.abs(image.data - images[1].image.data) ** 2 / (2 * np.prod(energy_widths(image)))
            looked = uniform_filter(power, LOOKS)
            # lit: within 10 dB of the class's brightest 1 % (shadows and the sidelobes there,
            # 30 dB and more below, drop out); kept where the whole 11 x 11 neighbourhood is lit, so
            # that no look window straddles a shadow's edge (which biases the median 1.3 dB low)
            lit = looked > 0.1 * np.percentile(looked, 99) if looked.any() else looked > 0
            lit = minimum_filter(lit.astype(np.uint8), 2 * LOOKS + 1) > 0
            surface = preset_surface("city", name)
            expected = local = None
            if surface is not None:
                eta = itu_permittivity(name, params.frequency)
                text = describe_surface(surface, eta, params.frequency, params.incidence_angle)
                expected = float(re.search(r"VV (-?[\d.]+) dB", text).group(1))
                # a level surface at each pixel: the model at the pixel's own incidence
                positions = image.positions()[lit]
                antenna = images[0].raw.tx_position.mean(axis=0)
                cosine = (antenna[2] - positions[:, 2]) / np.linalg.norm(antenna - positions, axis=1)
                k = 2 * math.pi * params.frequency / 299792458.0
                model = sigma0_backscatter(surface, eta, k, cosine)["VV"]
                local = 10 * math.log10(np.median(looked[lit] / model))
            median = 10 * math.log10(np.median(looked[lit])) if lit.any() else None
            rows.append(dict(part="class", case=name, channel="VV", pixels=int(lit.sum()),
                             measured_db=None if median is None else round(median, 2), model_db=expected,
                             error_db=None if median is None or expected is None else round(median - expected, 2),
                             error_local_db=None if local is None else round(local, 2)))
    return rows


def run(quick: bool = False) -> list[dict]:
    rows = _plate_rows(quick)
    try:
        import importlib.util
        has_sionna = importlib.util.find_spec("sionna") is not None
    except ImportError:
        has_sionna = False
    if has_sionna:
        rows += ([] if quick else _timing_rows()) + _class_rows(quick)
    keys = list(dict.fromkeys(key for row in rows for key in row))        # one table: every row every column
    return report_rows(f"{NAME}.csv", [{key: row.get(key) for key in keys} for row in rows])


def checks(rows: list[dict]):
    for row in rows:
        if row["part"] == "plate":
            yield (f"plate {row['case']} {row['channel']} within 0.5 dB of the I2EM", abs(row["error_db"]) <= 0.5,
                   f"{row['error_db']:+.2f} dB")
        elif row["part"] == "time" and row["case"].startswith("roughness"):
            yield "city preset at most 1.2x the smooth render", row["ratio"] <= 1.2, f"{row['ratio']:.2f}x"
        elif row["part"] == "class" and row["case"] == "concrete" and row["error_db"] is not None:
            yield "ground's median within 1 dB of info's sigma0", abs(row["error_db"]) <= 1.0, f"{row['error_db']:+.2f} dB"


if __name__ == "__main__":
    bench_main(__doc__, run, checks, "the plate at 45 deg and the ground class only")
