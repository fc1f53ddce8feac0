"""The README's footprints-to-map figure: the footprints of a GeoJSON file and the rendered GeoTIFF,
both on the GeoTIFF's UTM grid, the outlines drawn over the image.

Usage (after the README's walk-through has written out/footprints/image.tif)::

    .venv/bin/python docs/figures/footprints_map.py scenes/footprints.geojson out/footprints/image.tif \\
        docs/img/footprints_map.png

Only the GeoJSON, rasterio and pyproj are used to place things: the figure checks the map placement
independently of the simulator's own frame.
"""
from __future__ import annotations

import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402
import rasterio  # noqa: E402
from pyproj import Transformer  # noqa: E402


def outlines(geojson: str, crs) -> list[tuple[str, list[np.ndarray]]]:
    """(label, rings in the CRS's metres) of each feature."""
    to_map = Transformer.from_crs("EPSG:4326", crs.to_wkt(), always_xy=True)
    shapes = []
    for feature in json.load(open(geojson))["features"]:
        props, geometry = feature["properties"], feature["geometry"]
        polygons = geometry["coordinates"] if geometry["type"] == "MultiPolygon" else [geometry["coordinates"]]
        rings = [np.column_stack(to_map.transform(*np.asarray(ring).T)) for polygon in polygons for ring in polygon]
        height = props.get("height") or f"{props.get('building:levels')} levels"
        shapes.append((f"{props.get('name', feature.get('id', ''))}\n{height}", rings))
    return shapes


def main(geojson: str, tif: str, png: str) -> None:
    with rasterio.open(tif) as image:
        db, bounds, crs = image.read(1), image.bounds, image.crs
    shapes = outlines(geojson, crs)
    extent = (bounds.left, bounds.right, bounds.bottom, bounds.top)
    fig, ax = plt.subplots(figsize=(8.5, 7.5), constrained_layout=True)
    ax.set_title("image.tif (dBsm, UTM) with the GeoJSON footprints drawn over it (pyproj)", fontsize=10)
    ax.set_xlabel(f"easting [m], {crs.to_string()}")
    ax.set_ylabel("northing [m]")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(5))
    peak = np.nanpercentile(db, 99.5)
    shown = ax.imshow(db, extent=extent, cmap="gray", vmin=peak - 50, vmax=peak, interpolation="nearest")
    fig.colorbar(shown, ax=ax, label="dBsm per sample", shrink=0.8)
    for label, rings in shapes:
        for ring in rings:
            ax.plot(ring[:, 0], ring[:, 1], color="tab:red", lw=0.8)
        ax.text(rings[0][:, 0].mean(), rings[0][:, 1].min() - 4, label, ha="center", va="top", fontsize=7,
                color="tab:orange")
    ax.annotate("sensor flies east, looks south: double bounce at the north walls' feet", xy=(0.02, 0.97),
                xycoords="axes fraction", fontsize=8, color="white", va="top")
    fig.savefig(png, dpi=90)
    print(f"footprints map -> {png}")


if __name__ == "__main__":
    main(*sys.argv[1:4])
