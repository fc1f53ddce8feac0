"""
Bistatic: a transmitter in orbit, a receiver on a drone
=======================================================

A satellite 693 km up illuminates ``urban`` in spotlight mode; a drone 300 m above the ground,
east of the scene and drifting south at 3 m/s, receives. Every echo travels the bistatic range sum
``R_t + R_r``: the transmit legs from the satellite, the return leg to the drone, each with its
own visibility (docs/physics.md (B1)-(B4)). The same transmitter received by itself is the
monostatic image beside it.

What differs:

- **Shadows.** A wall hides the ground behind it from either platform: the bistatic image holds
  the satellite's shadows *and* the drone's, which fall the other way.
- **Resolution.** Range is resolved along the bisector of the two lines of sight, ``c / (2 B
  cos(beta / 2))``; on the ground along the bisector's horizontal part, coarser here than the
  monostatic ``c / (2 B sin(theta))``, and the cells skew.
- **Where things land.** A point is imaged on the ellipse of its range sum, so the double bounce
  at a wall's foot and the layover of a roof move: roofs lean toward both platforms.
- **Sampling.** The receiver's own motion spreads the Doppler too, by about ``v_r Delta u /
  lambda`` across the scene (``Delta u`` the spread of its look directions): a drone 600 m away
  at 15 m/s spreads the echoes over about 310 Hz (the satellite's own part: 74 Hz), and at the
  satellite's 250 Hz PRF the city's aliased copies appear 280 m away; ``info`` and ``render``
  warn, naming ``receiver_velocity``. At 3 m/s the band is about 100 Hz.
"""
import matplotlib.pyplot as plt
import numpy as np

import sarmitsuba
from sarmitsuba.analysis import bistatic
from sarmitsuba.products.plotting import RELATIVE_DB, colorbar, decibels, multilook, reference_intensity, show_db_image

# 160 pulses, a third of the aperture a 1 m azimuth resolution needs (the render warns so): about 3 m
orbit = {"trajectory": "orbit", "altitude": 693e3, "mode": "spotlight", "n_pulses": 160}
drone = {"receiver_trajectory": "straight", "receiver_altitude": 300.0, "receiver_incidence_angle": 60.0,
         "receiver_heading": -60.0, "receiver_velocity": 3.0}
mono = sarmitsuba.simulate("urban", sensor_overrides=orbit, focuser="bp")
bi = sarmitsuba.simulate("urban", sensor_overrides={**orbit, **drone}, focuser="bp")
print(mono.summary())
print(bi.summary())

# %%
# The geometry at mid-aperture: the bistatic angle at the scene centre and the resolutions of
# (B4). ``raw.rx_position`` holds where the drone receives each echo.

raw = bi.raw
mid = raw.n_pulses // 2
tx, rx, centre = raw.tx_position[mid], raw.rx_position[mid], np.zeros(3)
beta = bistatic.bistatic_angle(tx, rx, centre)
print(f"bistatic angle {np.degrees(beta):.1f} deg; ground-range resolution "
      f"{bistatic.bistatic_ground_range_resolution(raw.bandwidth, tx, rx, centre):.2f} m along "
      f"{np.round(bistatic.ground_range_direction(tx, rx, centre), 3)} "
      f"(monostatic {bistatic.bistatic_ground_range_resolution(raw.bandwidth, tx, tx, centre):.2f} m)")

# %%
# The two images on one ground grid and one grey scale. The satellite passes on a descending
# orbit, looking west from the east; the drone looks from the east-south-east at 60 deg
# incidence. Its shadows are longer than the satellite's and point another way: the dark
# patches that only the bistatic image has are the drone's. The long wall's double bounce, the
# bright line of the monostatic image, returns toward the satellite alone: the drone, 36 deg
# away, sees the wall's shadow instead.

looks = (2, 2)
powers = [multilook(sim.image.data, looks) for sim in (mono, bi)]
reference = reference_intensity(*powers)
fig, axes = plt.subplots(1, 2, figsize=(14, 6), layout="constrained")
for ax, sim, power, title in zip(axes, (mono, bi), powers, ("monostatic (the satellite receives)",
                                                              "bistatic (the drone receives)")):
    shown = show_db_image(ax, sim.image, decibels(power, reference, 40), looks, dynamic_range_db=40)
    ax.set_title(title)
colorbar(fig, axes[1], shown, RELATIVE_DB)
plt.show()

# %%
# From the command line the same render is
#
# .. code-block:: bash
#
#    .venv/bin/python -m sarmitsuba render urban --set trajectory=orbit --set altitude=693e3 --set mode=spotlight \
#        --set n_pulses=160 --set receiver_altitude=300 --set receiver_incidence_angle=60 --set receiver_heading=-60 \
#        --set receiver_velocity=3 --cphd --out out/bistatic
#
# and ``out/bistatic/raw.cphd`` is a CPHD whose ``CollectType`` is BISTATIC, with the drone's
# positions in ``RcvPos`` (sarpy and sarkit read it as such).
