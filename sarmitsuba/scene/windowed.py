"""Windows for a scene that has none: a copy of a Mitsuba XML scene (a Sionna RT city, a footprint
scene folder, a file of your own) whose plain walls get the recessed windows of a
:class:`~sarmitsuba.scene.facades.FacadeLayout`.

``.venv/bin/python -m sarmitsuba scene add-windows sionna:munich --out DIR`` runs
:func:`write_windowed`: every PLY or OBJ shape without a ``to_world`` transform whose area is
mostly steep (a facade, :mod:`sarmitsuba.scene.roles`) has its plain walls (pairs of triangles
making an upright rectangle, :func:`~sarmitsuba.scene.facades.wall_rectangles`) replaced by walls
with windows; their panes become one more shape per facade (``<id>-windows``) of ITU glass. The
storeys count from each wall's foot. Other shapes and walls are copied as they are, so the folder
renders, with ``info`` and ``preview``, as the original does.
"""
from __future__ import annotations

import shutil
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .city import scene_folder
from .facades import FacadeLayout, add_windows
from .roles import face_normals, steep

__all__ = ["WindowedScene", "write_windowed", "GLASS_ID"]

#: Id of the glass BSDF the panes use.
GLASS_ID = "sarmitsuba-window-glass"
_GLASS_THICKNESS = 0.02            # m, as footprint cities' glass


@dataclass(frozen=True)
class WindowedScene:
    """What :func:`write_windowed` wrote.

    Attributes
    ----------
    path : Path
        ``out/scene.xml``.
    windows : int
    facades : int
        Shapes that received windows.
    triangles_before, triangles_after : int
        Triangles of all mesh shapes read, and written (panes included).
    """

    path: Path
    windows: int
    facades: int
    triangles_before: int
    triangles_after: int

    def summary(self) -> str:
        """One line: ``143,179 windows on 1,163 facades, 38,936 -> 2,102,734 triangles (+2,063,798)``."""
        added = self.triangles_after - self.triangles_before
        return (f"{self.windows:,} windows on {self.facades:,} facades, {self.triangles_before:,} -> "
                f"{self.triangles_after:,} triangles (+{added:,})")


def _steep_share(vertices: np.ndarray, faces: np.ndarray) -> float:
    """The share of a mesh's area that is steep (a facade's, :func:`sarmitsuba.scene.roles.steep`)."""
    normal, area = face_normals(vertices, faces)
    total = float(area.sum())
    return float(area[steep(normal)].sum() / total) if total > 0 else 0.0


def write_windowed(xml_path: str | Path, out: str | Path, layout: FacadeLayout) -> WindowedScene:
    """Write ``out/scene.xml`` and ``out/meshes/`` (module docstring), atomically: a failure leaves
    ``out`` as it was.

    Raises
    ------
    OSError
        ``out`` is a file, cannot be written, or is the source's own folder.
    ValueError
        The XML cannot be read (the message names the file).
    """
    import trimesh
    xml_path = Path(xml_path).resolve()
    out = Path(out)
    if out.resolve() == xml_path.parent:
        raise OSError(f"--out {out}: the source scene's own folder; give another folder")
    try:
        tree = ET.parse(xml_path)
    except ET.ParseError as exc:
        raise ValueError(f"{xml_path}: not readable XML ({exc})") from None
    root = tree.getroot()
    windows = facades = before = after = 0
    with scene_folder(out) as staging:
        added = []
        for index, shape in enumerate(root.findall("shape")):
            name = shape.find("string[@name='filename']")
            if name is None or shape.get("type") not in ("ply", "obj"):
                continue
            source = (xml_path.parent / name.get("value")).resolve()
            ident = shape.get("id") or f"shape{index}"
            target = f"meshes/{index:05d}-{Path(source).name}"
            mesh = trimesh.load(source, process=False, force="mesh")
            vertices, faces = np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)
            before += len(faces)
            result = None
            if shape.find("transform") is None and len(faces) and _steep_share(vertices, faces) > 0.5:
                result = add_windows(vertices, faces, layout, ident)
            if result is None or result[4] == 0:
                shutil.copyfile(source, staging / target)
                after += len(faces)
            else:
                wall_v, wall_f, pane_v, pane_f, count = result
                _write_ply(staging / target, wall_v, wall_f)
                pane_target = f"meshes/{index:05d}-windows.ply"
                _write_ply(staging / pane_target, pane_v, pane_f)
                added.append((ident, pane_target))
                windows += count
                facades += 1
                after += len(wall_f) + len(pane_f)
            name.set("value", target)
        if added:
            glass = ET.Element("bsdf", {"type": "itu-radio-material", "id": GLASS_ID})
            ET.SubElement(glass, "string", {"name": "type", "value": "glass"})
            ET.SubElement(glass, "float", {"name": "thickness", "value": repr(_GLASS_THICKNESS)})
            root.insert(0, glass)
            for ident, target in added:
                pane = ET.SubElement(root, "shape", {"type": "ply", "id": f"{ident}-windows"})
                ET.SubElement(pane, "string", {"name": "filename", "value": target})
                ET.SubElement(pane, "boolean", {"name": "face_normals", "value": "true"})
                ET.SubElement(pane, "ref", {"id": GLASS_ID, "name": "bsdf"})
        tree.write(staging / "scene.xml", encoding="utf-8", xml_declaration=True)
    return WindowedScene(out / "scene.xml", windows, facades, before, after)


def _write_ply(path: Path, vertices: np.ndarray, faces: np.ndarray) -> None:
    import trimesh
    lean = trimesh.Trimesh(np.asarray(vertices, np.float32), np.asarray(faces, np.int64), process=False)
    path.write_bytes(trimesh.exchange.ply.export_ply(lean, encoding="binary"))
