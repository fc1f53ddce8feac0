"""
Quad-pol: four channels and the Pauli RGB
=========================================

Every ray tube carries a 2x2 Jones matrix through its bounces, so one trace gives all four
channels of the scattering matrix: ``polarization = "quad"`` returns HH, HV, VH and VV (receive,
transmit) on one image grid, in ``sim.channels``. The Pauli decomposition colours a pixel by
its scattering mechanism: red ``|HH - VV|`` (double bounce), green ``|HV + VH|`` (structures
turned about the line of sight), blue ``|HH + VV|`` (single and triple bounce).

The scene, built in Python: the three canonical targets, in metal, on rough ground: a trihedral
(HH = VV), a dihedral with its fold along the track (HH = -VV) and the same dihedral turned by
45 deg about the line of sight (HV = VH only).
"""
import math

import matplotlib.pyplot as plt
import trimesh

import sarmitsuba
from sarmitsuba.products.figures_pol import pauli_rgb
from sarmitsuba.products.plotting import (RELATIVE_DB, colorbar, decibels, edges, intensity, reference_intensity,
                                          show_db_image)
from sarmitsuba.scene import canonical

look = -canonical.TOWARD_SENSOR                 # line of sight: the sensor is on the +y side at 45 deg
turned = canonical.dihedral(2.0, 2.0)
turned.apply_transform(trimesh.transformations.rotation_matrix(math.radians(45), look))
ground = trimesh.Trimesh([[-30, -30, 0], [30, -30, 0], [30, 30, 0], [-30, 30, 0]], [[0, 1, 2], [0, 2, 3]])
scene = sarmitsuba.Scene(
    meshes=[(ground, {"material": "medium_dry_ground", "gamma_db": -14}, "ground"),
            (canonical.trihedral(1.5).apply_translation((-12, 0, 0.1)), "pec", "trihedral"),
            (canonical.dihedral(2.0, 2.0).apply_translation((0, 0, 0.1)), "pec", "dihedral"),
            (turned.apply_translation((12, 0, 1.0)), "pec", "turned_dihedral")],   # lifted clear of the ground
    sensor={"frequency": 9.6e9, "bandwidth": 150e6, "prf": 300, "incidence_angle": 45,
            "scene_center": (0, 0, 0), "polarization": "quad"},
    integrator={"max_depth": 3})
sim = sarmitsuba.simulate(scene, image_size=(160, 160), image_spacing=0.25)
images = {name: channel.image for name, channel in sim.channels.items()}
print(sim.summary())

# %%
# The four channels on one dB scale (relative to the 99.5th percentile of all four).

powers = {name: intensity(image.data) for name, image in images.items()}
reference = reference_intensity(*powers.values())
fig, axes = plt.subplots(2, 2, figsize=(10, 10), layout="constrained")
for ax, name in zip(axes.flat, ("HH", "HV", "VH", "VV")):
    shown = show_db_image(ax, images[name], decibels(powers[name], reference, 40), (1, 1), dynamic_range_db=40)
    ax.set_title(name)
    colorbar(fig, ax, shown, RELATIVE_DB)
plt.show()

# %%
# The Pauli RGB, 30 dB below one reference common to the three components: the trihedral
# blue, the dihedral red, the turned dihedral green; the rough ground's weak clutter is mostly
# blue, with a cross-polarised part 15 dB below it, and mostly below the scale.

image = images["HH"]
fig, ax = plt.subplots(figsize=(7, 6.5), layout="constrained")
ax.imshow(pauli_rgb(images, dynamic_range_db=30), origin="lower", interpolation="nearest",
          extent=(*edges(image.range), *edges(image.azimuth)))
ax.set_xlabel("ground range from scene centre [m]")
ax.set_ylabel("azimuth from scene centre [m]")
ax.set_title("Pauli RGB: R |HH - VV|, G |HV + VH|, B |HH + VV|")
plt.show()

# %%
# From the command line, ``render SCENE --set polarization=quad --out FOLDER`` writes
# ``raw_XX.npz`` and ``image_XX.npz/.exr/.png`` for each channel and ``pauli.png``.
