"""The scatterer catalogue's files and figure: ``scatterers.csv``, ``scatterers.geojson``,
``fig_scatterers.png`` (docs/physics.md (SC1)-(SC4); built by
:func:`sarmitsuba.analysis.scatterers.build_catalogue`).

One row per resolved scatterer, the largest share of the image's power first. Columns (units in
the names):

=================================================  =================================================
``rank``                                           1 for the largest share
``azimuth_m``, ``range_m``                         image coordinates where it focuses (its layover
                                                   position, and a moving shape's along-track shift)
``row``, ``column``                                the nearest pixel
``x_m``, ``y_m``, ``z_m``                          its 3-D phase centre in the scene's world frame
                                                   (SC1), at mid-aperture
``latitude_deg``, ``longitude_deg``, ``height_m``  the same on WGS84, with the sensor's
                                                   ``geo_origin`` only
``order``                                          bounce order
``interactions``                                   the kind of each interaction, ``>``-separated:
                                                   ``face`` (a specular reflection, or a face's area
                                                   term near its specular direction) or ``edge``
                                                   (the lit region's edge and corner terms and edge
                                                   currents)
``shapes``                                         the shapes in order, ``>``-separated, by their
                                                   ids in the scene
``rcs_dbsm``                                       its own RCS, every channel's power summed (SC2)
``rcs_dbsm_XY``, ``phase_deg_XY``                  per channel ``XY``: RCS and phase of the complex
                                                   amplitude
``cell_rcs_dbsm``                                  the coherent sum of every scatterer in its
                                                   resolution cell (SC4)
``share``                                          its part of the image's integrated RCS:
                                                   ``Re(a conj(A_cell))`` over it, where ``A_cell``
                                                   is that coherent sum (SC4)
``azimuth_scale``, ``azimuth_slope_rad_per_m``     its azimuth response is the image's
                                                   ``h(scale x) exp(j slope x)``: scale 1 for a
                                                   point seen over the whole aperture, below 1 for a
                                                   flash seen over part of it (broader); slope its
                                                   Doppler centroid (SC4)
``radial_velocity_mps``                            half the path's rate of length (a moving shape's;
                                                   0 when still)
``azimuth_shift_m``                                the image shift that velocity causes,
                                                   ``-R v_r / V`` (SC3)
``lanes``                                          term lanes merged into it
=================================================  =================================================
"""
from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..core import georef
from ..core.image import SarImage
from ..core.radar import ParameterError

__all__ = ["Catalogue", "columns_of", "write_csv", "write_geojson", "read_csv", "scatterers_figure",
           "write_catalogue_files", "CATALOGUE_FILES", "CatalogueFileError"]

#: The catalogue's files by role (``render`` names them in ``OUTPUT_FILES``).
CATALOGUE_FILES = ("scatterers_csv", "scatterers_geojson", "scatterers_png")


class CatalogueFileError(ParameterError):
    """A scatterers.csv that cannot be read (names the file and what is wrong)."""


@dataclass(frozen=True)
class Catalogue:
    """A render's scatterer catalogue.

    Attributes
    ----------
    columns : dict of str -> numpy array [n]
        The columns of ``scatterers.csv`` (module docstring), in file order, largest share first.
    clutter : tuple of dict
        Per rough surface: ``surface`` (shape id), ``material``, ``pixels`` it covers in the
        image, ``sigma0_db`` (its mean sigma nought there, dB).
    channels : tuple of str
    image_rcs : float, m^2
        The image's integrated RCS, ``sum |I|^2 dA / (rho_az rho_rg)`` (K).
    listed_share : float
        The listed scatterers' RCS over it.
    selection : str
        How the rows were chosen (``share 0.9`` or ``rcs within X dB of the strongest``).
    resolution : (float, float), m
        The resolution cell the rows were merged in: the energy widths ``(rho_az, rho_rg)``.
    """

    columns: dict
    clutter: tuple
    channels: tuple
    image_rcs: float
    listed_share: float
    selection: str
    resolution: tuple

    def __len__(self) -> int:
        return len(self.columns["rank"])

    def line(self) -> str:
        """One line: how many scatterers, the share they hold, the orders."""
        orders = np.asarray(self.columns["order"], int)
        by_order = ", ".join(f"{int((orders == k).sum())} of order {k}" for k in np.unique(orders))
        return (f"{len(self)} scatterers ({by_order or 'none'}) hold {100 * self.listed_share:.1f} % of the image's "
                f"RCS ({self.selection}); clutter on {len(self.clutter)} surface(s)")


def columns_of(table: dict, image: SarImage, names: Sequence[str], channels: Sequence[str],
               geo: "georef.GeoReference | None", image_rcs: float) -> dict:
    """The catalogue's columns (module docstring) of the merged rows ``table`` (NumPy arrays by
    name: ``azimuth``, ``range``, ``centre`` [n, 3], ``field`` [n, channels], ``power``, ``order``,
    ``shapes`` [n, D], ``face`` (area terms' share of the weight), ``radial``, ``shift``, ``lanes``)."""
    n = len(table["power"])
    cols: dict[str, Any] = {"rank": np.arange(1, n + 1)}
    cols["azimuth_m"], cols["range_m"] = table["azimuth"], table["range"]
    cols["row"] = np.rint(np.interp(table["azimuth"], image.azimuth, np.arange(image.azimuth.size))).astype(int)
    cols["column"] = np.rint(np.interp(table["range"], image.range, np.arange(image.range.size))).astype(int)
    centre = np.asarray(table["centre"], float).reshape(-1, 3)
    cols["x_m"], cols["y_m"], cols["z_m"] = centre.T
    if geo is not None:
        llh = georef.enu_to_geodetic(centre, geo) if n else np.zeros((0, 3))
        cols["latitude_deg"], cols["longitude_deg"], cols["height_m"] = llh.T
    cols["order"] = np.asarray(table["order"], int)
    cols["interactions"] = np.array([">".join(["face"] * (k - 1) + ["face" if f >= 0.5 else "edge"])
                                     for k, f in zip(cols["order"], table["face"])], dtype=object)
    cols["shapes"] = np.array([">".join(names[s] for s in row[:k]) for row, k in zip(table["shapes"], cols["order"])],
                              dtype=object)
    cols["rcs_dbsm"] = _db(table["power"])
    for c, name in enumerate(channels):
        cols[f"rcs_dbsm_{name}"] = _db(np.abs(table["field"][:, c]) ** 2)
        cols[f"phase_deg_{name}"] = np.degrees(np.angle(table["field"][:, c]))
    cols["cell_rcs_dbsm"] = _db(table["cell_power"])
    cols["share"] = table["contribution"] / image_rcs if image_rcs > 0 else np.zeros(n)
    cols["azimuth_scale"] = table["scale"]
    cols["azimuth_slope_rad_per_m"] = table["slope"]
    cols["radial_velocity_mps"] = table["radial"]
    cols["azimuth_shift_m"] = table["shift"]
    cols["lanes"] = np.asarray(table["lanes"], int)
    return cols


def _db(power: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(np.asarray(power, float))


def write_csv(path: Path, catalogue: Catalogue) -> Path:
    """Write ``catalogue`` as CSV (a header, then one row per scatterer); returns ``path``."""
    cols = catalogue.columns
    with open(path, "w", newline="") as f:
        out = csv.writer(f)
        out.writerow(list(cols))
        for i in range(len(catalogue)):
            out.writerow([_text(cols[name][i]) for name in cols])
    return Path(path)


def _text(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        return repr(float(value)) if math.isfinite(value) else str(float(value))
    return str(value)


def read_csv(path: Path) -> dict:
    """The columns of a ``scatterers.csv`` (numbers as float64 or int64 arrays, text as str
    arrays). Raises CatalogueFileError naming the file when it is missing or not a catalogue."""
    path = Path(path)
    try:
        with open(path, newline="") as f:
            lines = list(csv.reader(f))
    except OSError as exc:
        raise CatalogueFileError(f"{path}: cannot read the scatterer catalogue ({exc.strerror}); render with "
                                 "--scatterers to write scatterers.csv beside the image, or give --scatterers PATH") \
            from None
    needed = ("azimuth_m", "range_m", "rcs_dbsm", "order", "shapes")
    if not lines or any(name not in lines[0] for name in needed):
        raise CatalogueFileError(f"{path}: not a scatterer catalogue (needs the columns {', '.join(needed)}); "
                                 "render with --scatterers to write one")
    header, body = lines[0], lines[1:]
    out = {}
    for c, name in enumerate(header):
        values = [row[c] for row in body]
        if name in ("interactions", "shapes"):
            out[name] = np.array(values, dtype=object)
        elif name in ("rank", "row", "column", "order", "lanes"):
            out[name] = np.array(values, dtype=np.int64)
        else:
            out[name] = np.array(values, dtype=np.float64)
    return out


def write_geojson(path: Path, catalogue: Catalogue) -> Path:
    """Write the scatterers as a GeoJSON FeatureCollection of points: longitude, latitude and
    height with a ``geo_origin`` (RFC 7946), otherwise the scene's local x, y, z [m] with a
    ``crs_note`` saying so; every column is a property. Returns ``path``."""
    cols = catalogue.columns
    geo = "latitude_deg" in cols
    features = []
    for i in range(len(catalogue)):
        xyz = ([cols["longitude_deg"][i], cols["latitude_deg"][i], cols["height_m"][i]] if geo
               else [cols["x_m"][i], cols["y_m"][i], cols["z_m"][i]])
        props = {name: _json(values[i]) for name, values in cols.items()}
        features.append({"type": "Feature", "geometry": {"type": "Point", "coordinates": [float(v) for v in xyz]},
                         "properties": props})
    body = {"type": "FeatureCollection", "features": features,
            "clutter": [dict(c) for c in catalogue.clutter], "selection": catalogue.selection,
            "listed_share": catalogue.listed_share, "image_rcs_m2": catalogue.image_rcs}
    if not geo:
        body["crs_note"] = ("no geo_origin: coordinates are the scene's local x (east), y (north), z (up) in metres, "
                            "not WGS84; give the sensor a geo_origin to geocode them")
    with open(path, "w") as f:
        json.dump(body, f, allow_nan=False, default=str)
    return Path(path)


def _json(value: Any) -> Any:
    if isinstance(value, (np.integer, int)):
        return int(value)
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(value) else None
    return str(value)


def scatterers_figure(path: Path, image: SarImage, catalogue: Catalogue, triangles: Sequence[np.ndarray] = (),
                      labelled: int = 8, title: str = "") -> Path:
    """``fig_scatterers.png``: left, the image in dB with the catalogue's scatterers marked,
    coloured by bounce order, the ``labelled`` strongest named by their shapes; right, a map:
    the phase centres over the scene's footprint (``triangles``: float64 [n, 3, 3] per shape, m,
    drawn from above), coloured by height. Returns ``path``."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection
    cols = catalogue.columns
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.6), constrained_layout=True)
    power = np.abs(image.data.astype(np.complex128)) ** 2
    db = 10.0 * np.log10(power / max(float(power.max()), 1e-300) + 1e-12)
    extent = [image.range[0], image.range[-1], image.azimuth[-1], image.azimuth[0]]
    left.imshow(db, cmap="gray", vmin=-50, vmax=0, extent=extent, aspect="equal")
    orders = np.asarray(cols["order"], int)
    cmap = plt.get_cmap("viridis", max(int(orders.max(initial=1)), 1))
    for k in np.unique(orders):
        here = orders == k
        left.scatter(cols["range_m"][here], cols["azimuth_m"][here], s=28, facecolors="none",
                     edgecolors=[cmap(k - 1)], linewidths=1.2, label=f"order {k}")
    for i in range(min(labelled, len(catalogue))):
        left.annotate(f"{i + 1}: {_short(cols['shapes'][i])}", (cols["range_m"][i], cols["azimuth_m"][i]),
                      xytext=(8, 8 - 9 * (i % 4)), textcoords="offset points", color="yellow", fontsize=7)
    left.set_xlabel("range [m]")
    left.set_ylabel("azimuth [m]")
    left.set_title(f"{len(catalogue)} scatterers, {100 * catalogue.listed_share:.0f} % of the image's RCS "
                   "(circles: bounce order)", fontsize=10)
    if title:
        fig.suptitle(title, fontsize=10)
    if len(orders):
        left.legend(loc="lower right", fontsize=7)
    polys = [t[:, :2] for tris in triangles for t in tris]
    if polys:
        right.add_collection(PolyCollection(polys, facecolors="0.85", edgecolors="0.6", linewidths=0.2))
    points = right.scatter(cols["x_m"], cols["y_m"], c=cols["z_m"], cmap="plasma", s=18 + 4 * orders)
    fig.colorbar(points, ax=right, label="phase centre height z [m]")
    right.set_aspect("equal")
    right.autoscale()
    right.set_xlabel("x (east) [m]")
    right.set_ylabel("y (north) [m]")
    right.set_title("phase centres over the scene (from above)")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def _short(shapes: str, most: int = 28) -> str:
    return shapes if len(shapes) <= most else shapes[:most - 1] + "…"


def write_catalogue_files(out, names: dict, image: SarImage, catalogue: Catalogue, loaded, scene: str) -> dict:
    """Write the catalogue's files into the render's output directory ``out``
    (:class:`~sarmitsuba.core.outputs.OutputDirectory`) under ``names`` (by role,
    :data:`CATALOGUE_FILES`): the CSV, the GeoJSON and the figure over ``loaded``'s meshes (world
    frame). Returns ``{role: path}``."""
    from ..tracing.mesh.facets import scene_meshes
    offset = np.asarray(loaded.offset, float)
    triangles = [v[f] + offset for v, f in scene_meshes(loaded.scene) if len(f)]
    title = f"{scene}: {catalogue.selection}, clutter on {len(catalogue.clutter)} surface(s)"
    writers = {"scatterers_csv": lambda path: write_csv(path, catalogue),
               "scatterers_geojson": lambda path: write_geojson(path, catalogue),
               "scatterers_png": lambda path: scatterers_figure(path, image, catalogue, triangles, title=title)}
    return {role: out.write(names[role], writers[role]) for role in CATALOGUE_FILES}
