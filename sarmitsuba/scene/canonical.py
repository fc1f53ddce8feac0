"""Canonical radar targets as scenes (validation, tests, benchmarks): meshes made with trimesh,
oriented toward the default sensor (45 deg incidence from the +y side), with their
closed-form radar cross-sections (Knott, Shaeffer and Tuley, *Radar Cross Section*, table 6.1).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import trimesh

#: Unit vector from the scene centre toward the sensor (45 deg incidence, +y side).
TOWARD_SENSOR = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5)])

SENSOR = """<sensor type="sar">
        <float name="bandwidth" value="150e6"/>
        <float name="azimuth_beamwidth" value="1.0"/>
        <float name="prf" value="250"/>
        <string name="scene_center" value="0, 0, 0"/>
    </sensor>"""


__all__ = ["plate", "dihedral", "trihedral", "scene_xml", "rcs_plate", "rcs_dihedral", "rcs_trihedral",
           "rcs_sphere", "PEC", "SPHERE", "TOWARD_SENSOR"]

#: A metal sphere shape of radius 0.5 m for :func:`scene_xml`'s ``extra_shapes``.
SPHERE = '<shape type="sphere"><float name="radius" value="0.5"/><ref id="mat"/></shape>'


def _rotation_to(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """4x4 rotation taking unit vector a onto unit vector b."""
    return trimesh.geometry.align_vectors(a, b)


def plate(side: float) -> trimesh.Trimesh:
    """Square plate of side ``side`` [m] centred at the origin, facing the sensor, one pair of
    edges along the track (x)."""
    u = np.array([1.0, 0.0, 0.0])
    v = np.cross(TOWARD_SENSOR, u)
    h = side / 2
    vertices = np.array([-h * u - h * v, h * u - h * v, h * u + h * v, -h * u + h * v])
    return trimesh.Trimesh(vertices=vertices, faces=[[0, 1, 2], [0, 2, 3]], process=False)


def dihedral(a: float, b: float) -> trimesh.Trimesh:
    """Dihedral of two a x b plates (fold of length a along x), bisector toward the sensor."""
    v = np.array([[-a / 2, 0, 0], [a / 2, 0, 0], [a / 2, b, 0], [-a / 2, b, 0],     # floor (z = 0)
                  [-a / 2, 0, b], [a / 2, 0, b]])                                    # wall (y = 0)
    f = np.array([[0, 1, 2], [0, 2, 3], [1, 0, 4], [1, 4, 5]])         # consistently wound
    mesh = trimesh.Trimesh(vertices=v, faces=f, process=False)
    # bisector of floor (normal +z) and wall (normal +y) is already (0, 1, 1)/sqrt2 = TOWARD_SENSOR
    return mesh


def trihedral(a: float) -> trimesh.Trimesh:
    """Triangular trihedral with edges a along its three axes, boresight toward the sensor."""
    v = np.array([[0, 0, 0], [a, 0, 0], [0, a, 0], [0, 0, a]], float)
    f = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3]])                   # consistently wound
    mesh = trimesh.Trimesh(vertices=v, faces=f, process=False)
    mesh.apply_transform(_rotation_to(np.ones(3) / math.sqrt(3.0), TOWARD_SENSOR))
    return mesh


def scene_xml(folder: Path, mesh: trimesh.Trimesh | None, material: str, depth: int,
              extra_shapes: str = "", name: str = "target") -> Path:
    """Write ``folder/name.xml`` (and ``name.ply``) with the default sensor and one target."""
    folder.mkdir(parents=True, exist_ok=True)
    shape = ""
    if mesh is not None:
        mesh.export(folder / f"{name}.ply")
        shape = (f'<shape type="ply"><string name="filename" value="{name}.ply"/>'
                 f'<boolean name="face_normals" value="true"/><ref id="mat"/></shape>')
    xml = folder / f"{name}.xml"
    xml.write_text(f"""<scene version="3.0.0">
    {SENSOR}
    <integrator type="sbr"><integer name="max_depth" value="{depth}"/></integrator>
    <bsdf type="radar" id="mat">{material}</bsdf>
    {shape}
    {extra_shapes}
</scene>""")
    return xml


PEC = '<string name="model" value="pec"/>'


def rcs_plate(side: float, wavelength: float) -> float:
    """4 pi A^2 / lambda^2."""
    return 4 * math.pi * side**4 / wavelength**2


def rcs_dihedral(a: float, b: float, wavelength: float) -> float:
    """8 pi a^2 b^2 / lambda^2 (viewed along the bisector, normal to the fold)."""
    return 8 * math.pi * a**2 * b**2 / wavelength**2


def rcs_trihedral(a: float, wavelength: float) -> float:
    """4 pi a^4 / (3 lambda^2) (triangular trihedral, boresight)."""
    return 4 * math.pi * a**4 / (3 * wavelength**2)


def rcs_sphere(r: float) -> float:
    """pi r^2 (optical region, r >> lambda)."""
    return math.pi * r**2
