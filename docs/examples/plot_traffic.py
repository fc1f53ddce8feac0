"""
Moving cars: displaced images, along-track interferometry and DPCA
==================================================================

The built-in ``traffic`` scene is ``urban`` with three metal cars driving on its open ground.
Each car stands where the scene puts it at the middle of the aperture and moves at its
``velocity``; every pulse meets it where it is when the wave reaches it. A focuser matched to
still points images a car whose range changes at ``v_r`` (positive away from the radar)
``-R v_r / V`` along track from where it is (``R`` its slant range, ``V`` the platform speed),
and smears one that moves along track (docs/physics.md (V4), (V5)):

- ``car_a`` drives toward the sensor at 2 m/s: imaged about 20 m ahead, off its road;
- ``car_b`` drives along track at 15 m/s: smeared in azimuth, not displaced;
- ``car_c`` drives away from the sensor and along track: displaced about 15 m back, and smeared.

``ati_baseline = 0.4`` renders a second channel in the same call, its phase centre 0.4 m behind
the first (one pulse spacing at 100 m/s and 250 Hz): ``sim.aft``. Still scatterers look the same
to both channels; a moving car has the along-track interferometric (ATI) phase
``4 pi v_r d / (lambda V)``, and the difference of the two images (DPCA, displaced phase
centres) keeps the moving cars and cancels the still city (docs/physics.md (V6), (V7)).
"""
import matplotlib.pyplot as plt
import numpy as np

import sarmitsuba
from sarmitsuba.stacks import along_track
from sarmitsuba.products.plotting import (RELATIVE_DB, colorbar, decibels, multilook, reference_intensity,
                                          show_db_image)

sim = sarmitsuba.simulate("traffic", sensor_overrides={"ati_baseline": 0.4})
print(sim.summary())

# %%
# Where each car should be imaged. In stripmap each point is seen by its own stretch of track,
# centred where the antenna passes abreast of it; a car moving along track is passed later (or
# earlier) than a still point at its mid-aperture position, and lies there ``v (t - t_mid)``
# from it. Its range rate ``v_r = v . u`` (``u`` the unit vector from that antenna position to the
# car) shifts it by ``-R v_r / V`` along track (V4). The cars' ids, shape indices and velocities
# are in ``sim.loaded.motion``, their boxes (mid-aperture) in ``sim.loaded.shape_boxes``.

image, raw, p = sim.image, sim.raw, sim.loaded.params
motion = sim.loaded.motion
t = raw.pulse_time
t_mid = 0.5 * (t[0] + t[-1])
along = image.azimuth_direction                      # the flight direction, +x here
speed = float(np.linalg.norm(raw.velocity, axis=1).mean())


def antenna_at(time):
    """The antenna's transmit position at ``time`` (s), interpolated between pulses."""
    return np.array([np.interp(time, t, raw.tx_position[:, k]) for k in range(3)])


def image_metres(point):
    """(azimuth, ground range) [m] on the image's axes where a still ``point`` is imaged."""
    row, column = image.pixel_of(point)
    return (np.interp(row, np.arange(len(image.azimuth)), image.azimuth),
            np.interp(column, np.arange(len(image.range)), image.range))


interferogram = along_track.ati_interferogram(sim.image, sim.aft.image)
power = np.abs(image.data) ** 2
azimuth, ground_range = np.meshgrid(image.azimuth, image.range, indexing="ij")
cars = []
for car, shape, v in zip(motion.ids, motion.shapes, motion.velocities()):
    middle = sim.loaded.shape_boxes[shape].mean(axis=0) + sim.loaded.offset   # the car at mid-aperture
    ahead = (middle - antenna_at(t_mid)) @ along                             # how far ahead of the antenna
    t_abreast = t_mid + ahead / (speed - v @ along)
    car_then = middle + v * (t_abreast - t_mid)
    line_of_sight = car_then - antenna_at(t_abreast)
    slant_range = np.linalg.norm(line_of_sight)
    v_r = v @ line_of_sight / slant_range
    shift = -slant_range * v_r / speed                                        # (V4)
    az, rg = image_metres(car_then)
    predicted = (az + shift, rg)
    near = (np.abs(azimuth - predicted[0]) < 12) & (np.abs(ground_range - predicted[1]) < 6)
    peak = np.unravel_index(np.argmax(np.where(near, power, 0)), power.shape)
    phase = np.angle(interferogram[peak])
    cars.append((car, image_metres(middle), predicted))
    print(f"{car}: v_r {v_r:+.2f} m/s, shift {round(shift, 2) + 0.0:+.1f} m; predicted at azimuth {predicted[0]:+.1f} m, "
          f"imaged at {image.azimuth[peak[0]]:+.1f} m; ATI phase {phase:+.2f} rad "
          f"(V6: {along_track.ati_phase(v_r, p.wavelength, speed, p.ati_baseline):+.2f}), "
          f"v_r from it {along_track.radial_velocity(phase, p.wavelength, speed, p.ati_baseline):+.2f} m/s")

# %%
# The fore channel's image. Circle: where a still car at the mid-aperture position would be
# imaged. Cross: where the car is when the antenna passes abreast of it, moved by (V4). ``car_b``
# is only passed later (the antenna catches up at ``V - v_a``); ``car_a`` and ``car_c`` are
# displaced by their range rates. Both also have a faint copy 55 m away: their azimuth
# ambiguities, ``PRF lambda R / (2 V)`` apart, where the Doppler shift pushes part of their
# spectrum beyond the PRF.

looks = (2, 2)
shown_power = multilook(image.data, looks)
reference = reference_intensity(shown_power)
fig, ax = plt.subplots(figsize=(9, 6.5), layout="constrained")
shown = show_db_image(ax, image, decibels(shown_power, reference, 40), looks, dynamic_range_db=40)
colorbar(fig, ax, shown, RELATIVE_DB)
for car, (az0, rg0), (az1, rg1) in cars:
    ax.plot(rg0, az0, "o", mfc="none", mec="tab:cyan", ms=12)
    ax.annotate("", xy=(rg1, az1), xytext=(rg0, az0), arrowprops=dict(arrowstyle="->", color="tab:cyan"))
    ax.plot(rg1, az1, "x", color="tab:orange", ms=12, mew=2)
    ax.annotate(car, (rg0, az0), xytext=(8, 6), textcoords="offset points", color="tab:cyan")
ax.set_title("traffic, fore channel: circle at mid-aperture, cross where it is imaged (V4)")
plt.show()

# %%
# The ATI phase ``arg(I_fore I_aft*)`` over the pixels within 25 dB of the reference (averaged
# over the looks as complex numbers), and the DPCA image ``|I_fore - I_aft|`` on the fore image's
# scale. The still buildings read 0 rad and vanish from the DPCA image; ``car_a`` reads about
# -2.3 rad (toward the radar), ``car_c`` about +1.7 rad (away), and ``car_b``, which has no range
# rate, about 0. ATI is unambiguous for ``|v_r| < lambda V / (4 d)``, here 1.95 m/s.

n0, n1 = shown_power.shape
product = interferogram[:n0 * looks[0], :n1 * looks[1]].reshape(n0, looks[0], n1, looks[1]).mean(axis=(1, 3))
bright = decibels(shown_power, reference, 200) > -25
dpca = along_track.dpca_image(sim.image, sim.aft.image)
fig, axes = plt.subplots(1, 2, figsize=(14, 5.5), layout="constrained")
show_db_image(axes[0], image, np.full(shown_power.shape, -20.0), looks, dynamic_range_db=40)   # grey backdrop
phase = axes[0].imshow(np.ma.masked_where(~bright, np.angle(product)), cmap="twilight", vmin=-np.pi, vmax=np.pi,
                       origin="lower", extent=axes[0].images[0].get_extent(), interpolation="nearest")
colorbar(fig, axes[0], phase, "ATI phase [rad]")
axes[0].set_title("ATI phase where within 25 dB")
shown = show_db_image(axes[1], image, decibels(multilook(dpca, looks), reference, 40), looks, dynamic_range_db=40)
colorbar(fig, axes[1], shown, RELATIVE_DB + " (fore)")
axes[1].set_title("DPCA |I_fore - I_aft|")
plt.show()

# %%
# From the command line, ``--set ati_baseline=0.4`` writes the aft channel (``raw_aft.npz``,
# ``image_aft.npz``), the interferogram ``ati.npz``, the DPCA image ``dpca.npz`` and the figure
# ``ati.png`` beside the usual files:
#
# .. code-block:: bash
#
#    .venv/bin/python -m sarmitsuba render traffic --set ati_baseline=0.4 --out out/traffic
