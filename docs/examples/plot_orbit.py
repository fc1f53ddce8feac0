"""
A spaceborne acquisition from an orbit
======================================

``trajectory = "orbit"`` flies a circular Keplerian orbit ``altitude`` above the WGS84 ellipsoid
(inclination 98.18 deg by default, Sentinel-1's sun-synchronous orbit) that sees the scene at
``geo_origin`` at ``incidence_angle`` at closest approach. The orbit is carried into the scene's
east-north-up frame exactly (no flat-earth step), the antenna is zero-Doppler steered, and every
echo is received where the satellite has moved to while the pulse travelled.

Here the ``trihedral`` scene is placed at 48.1 N, 11.6 E and imaged from 693 km at 35 deg
incidence; the PRF is 4 kHz and the beam 0.3 deg wide in azimuth. The trihedral opens toward
the north, so the orbit is one of 53 deg inclination, whose ascending pass flies east, a little north,
north-north-west of the scene and looks south-south-east into the reflector.
A state-vector file or a Sentinel-1 orbit file (``trajectory=FILE.EOF``) works the same way.
"""
import matplotlib.pyplot as plt
import numpy as np

import sarmitsuba
from sarmitsuba.products.plotting import colorbar, decibels, intensity, show_db_image

orbit = {"trajectory": "orbit", "altitude": 693e3, "incidence_angle": 35, "orbit_inclination": 53,
         "orbit_direction": "ascending",
         "geo_origin": "48.1, 11.6, 500", "prf": 4000, "azimuth_beamwidth": 0.3}
sim = sarmitsuba.simulate("trihedral", sensor_overrides=orbit)
report = sarmitsuba.analyze(sim.image, (0.0, 0.0, 0.0), raw=sim.raw)
print(sim.summary())

# %%
# The synthetic aperture in the scene's frame (east, north, up about the trihedral, in km): seen
# from above, and in the vertical plane through the scene and the mid-aperture position. Over the
# aperture's 11 km the orbit is all but straight.

track = sim.raw.tx_position / 1e3
middle = track[len(track) // 2]
fig, (ax_map, ax_side, ax_image) = plt.subplots(1, 3, figsize=(15, 5), layout="constrained",
                                                gridspec_kw={"width_ratios": [1, 1, 1.3]})
ax_map.plot(track[:, 0], track[:, 1], lw=3, label=f"aperture: {len(track)} pulses")
ax_map.plot([0, middle[0]], [0, middle[1]], "k--", lw=0.8, label="line of sight at mid-aperture")
ax_map.plot(0, 0, "o", color="tab:red", label="trihedral")
ax_map.set(xlabel="east [km]", ylabel="north [km]", title="seen from above")
ax_map.legend(fontsize="small")
across = np.hypot(track[:, 0], track[:, 1])               # horizontal distance from the scene
ax_side.plot(across, track[:, 2], lw=3)
ax_side.plot([0, np.hypot(*middle[:2])], [0, middle[2]], "k--", lw=0.8)
ax_side.plot(0, 0, "o", color="tab:red")
ax_side.set(xlabel="horizontal distance from the scene [km]", ylabel="up [km]",
            title=f"the vertical plane: slant range {np.linalg.norm(middle):.0f} km", aspect="equal")
for ax in (ax_map, ax_side):
    ax.grid(True, alpha=0.3)

power = intensity(sim.image.data)
shown = show_db_image(ax_image, sim.image, decibels(power, power.max(), 50), (1, 1), dynamic_range_db=50)
colorbar(fig, ax_image, shown, "dB (peak = 0)")
ax_image.set_title(f"the trihedral: IRW {report.irw_azimuth:.2f} m (azimuth), {report.irw_range:.2f} m (range)")
plt.show()

# %%
# The same acquisition planned, not traced, from the command line (``info`` prints the pass's
# slant range, look angle, incidence against the ellipsoid normal and squint):
#
# .. code-block:: bash
#
#    .venv/bin/python -m sarmitsuba info trihedral --set trajectory=orbit --set altitude=693e3 \
#        --set incidence_angle=35 --set "geo_origin=48.1, 11.6, 500" --set prf=4000 \
#        --set azimuth_beamwidth=0.3 --set orbit_inclination=53 --set orbit_direction=ascending
