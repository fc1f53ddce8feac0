"""
A city from building footprints
===============================

Cities are published as building footprints with heights (OpenStreetMap, cadastral data) in
GeoJSON. :func:`sarmitsuba.scene.city.build_city` extrudes them into meshes in a local
east-north-up frame about their centre, with roofs and materials from the tags, and
:meth:`sarmitsuba.Scene.from_city` makes the scene; ``Scene.from_footprints(path, out=folder)``
does both and writes the scene folder that the command line renders.

``footprints.geojson`` holds five buildings: a block with its ``height``, a courtyard block
(a polygon with a hole) with ``building:levels``, a glass tower turned 30 deg, a gabled house
and a hipped hall in stone. The default sensor flies east and looks south.
"""
import importlib.resources

import matplotlib.pyplot as plt
import numpy as np

import sarmitsuba
from sarmitsuba.core.georef import geodetic_to_enu
from sarmitsuba.products.plotting import RELATIVE_DB, colorbar, decibels, intensity, reference_intensity, show_db_image
from sarmitsuba.scene.city import build_city

geojson = importlib.resources.files("sarmitsuba_scenes") / "footprints.geojson"
city = build_city(geojson)
print(city.summary())
sim = sarmitsuba.simulate(sarmitsuba.Scene.from_city(city))
print(sim.summary())

power = intensity(sim.image.data)
db = decibels(power, reference_intensity(power), dynamic_range_db=50)
fig, ax = plt.subplots(figsize=(8, 6), layout="constrained")
colorbar(fig, ax, show_db_image(ax, sim.image, db, (1, 1), dynamic_range_db=50), RELATIVE_DB)
ax.set_title("five buildings from footprints, VV")
plt.show()

# %%
# On the map: the image turned into east and north (azimuth is east, ground range south here)
# with the footprints' outlines, carried from longitude and latitude into the local frame, and
# their heights as read (to the roof's top from ``height``, to the eaves from ``building:levels``).
# Each wall facing the sensor (north walls) images its double bounce at its foot.

image = sim.image
assert np.allclose(image.azimuth_direction, (1, 0, 0)) and np.allclose(image.range_direction, (0, -1, 0))
half = 0.5 * (image.azimuth[1] - image.azimuth[0])
extent = (image.origin[0] + image.azimuth[0] - half, image.origin[0] + image.azimuth[-1] + half,
          image.origin[1] - image.range[-1] - half, image.origin[1] - image.range[0] + half)
fig, ax = plt.subplots(figsize=(8, 7), layout="constrained")
shown = ax.imshow(db.T, cmap="gray", vmin=-50, vmax=0, origin="upper", extent=extent)
for footprint, _ in city.buildings:
    polygons = getattr(footprint.polygon, "geoms", [footprint.polygon])
    for ring in [r for p in polygons for r in (p.exterior, *p.interiors)]:
        lon, lat = np.asarray(ring.coords).T
        east, north, _ = geodetic_to_enu(np.column_stack([lat, lon, np.zeros_like(lat)]), city.geo_origin).T
        ax.plot(east, north, color="tab:orange", lw=1.2)
    lon, lat = footprint.polygon.representative_point().coords[0]
    east, north, _ = geodetic_to_enu(np.array([lat, lon, 0.0]), city.geo_origin)
    ax.annotate(f"{footprint.height:.0f} m", (east, north - 6), color="tab:orange", ha="center", va="top")
ax.set_xlabel("east of the footprints' centre [m]")
ax.set_ylabel("north of the footprints' centre [m]")
ax.set_title(f"footprints over the image, origin {city.geo_origin.describe()}")
fig.colorbar(shown, ax=ax, label=RELATIVE_DB, shrink=0.8)
plt.show()

# %%
# The same from the command line:
#
# .. code-block:: bash
#
#    .venv/bin/python -m sarmitsuba scene from-footprints scenes/footprints.geojson --out out/footprints-scene
#    .venv/bin/python -m sarmitsuba render out/footprints-scene --geotiff --out out/footprints
