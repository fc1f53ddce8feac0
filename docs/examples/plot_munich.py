"""
Munich, from Sionna RT
======================

Sionna RT ships a model of central Munich (1,188 buildings, 39,000 triangles), and sarmitsuba
loads any of its scenes as ``sionna:NAME``. The whole city takes 2,326 pulses at the default
sensor's settings; this example images a strip of it with 270 pulses at a coarser resolution
(50 MHz bandwidth and a 0.5 deg beam: 4.2 m in ground range, 1.6 m in azimuth) and two bounce
orders, twice: as shipped, and with every surface rough as its material and its role make it,
with a radar's thermal noise.

Sionna's materials are smooth, and a smooth city images only its edges and specular corners.
``material_overrides={"roughness": "city"}`` gives each ITU material class a measured or assumed
surface texture (an rms height and a correlation length), and each surface then scatters as the
improved integral equation model says it should for its own roughness and permittivity. Where a
class does not say what a surface is, its role does: Sionna labels every roof ``itu_metal``, and
the preset gives the roofs tiles' and gravel's texture instead. The streets image dark, the roofs
mid-grey, the facades' layover between, and the shadows fall to the noise floor of the radar
budget (1 W, 24 dBi, noise figure 4 dB), as in an X-band image. ``info`` prints each class's
sigma nought at the scene's incidence, and the noise-equivalent sigma nought.
Needs Sionna RT (``pip install 'sarmitsuba[sionna]'``).
"""
import warnings

import matplotlib.pyplot as plt

import sarmitsuba
from sarmitsuba.scene.meshcheck import MeshDefectWarning
from sarmitsuba.products.plotting import RELATIVE_DB, colorbar, decibels, intensity, reference_intensity, show_db_image

warnings.filterwarnings("ignore", category=MeshDefectWarning)   # Sionna's Munich has a few open meshes
strip = dict(sensor_overrides={"n_pulses": 270, "bandwidth": 50e6, "azimuth_beamwidth": 0.5, "prf": 90},
             integrator_overrides={"max_depth": 2},
             image_size=(160, 400), image_spacing=1.5)    # (azimuth, range) pixels about the scene centre
shipped = sarmitsuba.simulate("sionna:munich", **strip)
budget = {"transmit_power": 1.0, "antenna_gain_db": 24.0, "noise_figure_db": 4.0, "losses_db": 3.0}
rough = sarmitsuba.simulate("sionna:munich", material_overrides={"roughness": "city"},
                            **{**strip, "sensor_overrides": {**strip["sensor_overrides"], **budget}})
print(rough.summary())

# %%
# The strip the 270 pulses cover: 300 m of the track, 600 m of ground range, both images on one
# scale (the rough render's brightest pixel at 0 dB).

reference = reference_intensity(intensity(rough.image.data))
fig, axes = plt.subplots(2, 1, figsize=(9, 8), layout="constrained")
for ax, sim, title in ((axes[0], shipped, "as shipped: smooth surfaces"),
                       (axes[1], rough, "roughness = city, with thermal noise")):
    db = decibels(intensity(sim.image.data), reference, dynamic_range_db=40)
    shown = show_db_image(ax, sim.image, db, (1, 1), dynamic_range_db=40)
    colorbar(fig, ax, shown, RELATIVE_DB)
    ax.set_title(f"sionna:munich, {title}, VV")
plt.show()

# %%
# The whole city from the command line (2,326 pulses at the full resolution), and each class's
# surface and sigma nought:
#
# .. code-block:: bash
#
#    .venv/bin/python -m sarmitsuba info sionna:munich --material-set roughness=city
#    .venv/bin/python -m sarmitsuba render sionna:munich --material-set roughness=city --set prf=250 \
#        --set transmit_power=1 --set antenna_gain_db=24 --set noise_figure_db=4 --set losses_db=3 --out out/munich
#
# And with a window in every bay of every storey of its plain walls (143,000 windows; 2.1 million
# triangles, 54 times the city's: its render needs more than 24 GiB of memory):
#
# .. code-block:: bash
#
#    .venv/bin/python -m sarmitsuba scene add-windows sionna:munich --out out/munich-windows
