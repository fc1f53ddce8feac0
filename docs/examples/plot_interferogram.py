"""
Interferometry: two passes, an interferogram and its coherence
==============================================================

``track_offset`` shifts the whole track: a second pass over the same scene. Both passes focus
onto one ground grid, and the clutter scatterers are fixed to the surfaces, so the same roof patch
keeps its speckle from either track. Here the second pass of ``urban`` is shifted by
(0, 0.11, -0.11) m, normal to the line of sight (45 deg incidence, looking toward -y): a
perpendicular baseline of 0.156 m, with a height of ambiguity of about 100 m.

Ground backprojection removes the flat-earth phase exactly, so open ground reads 0; a roof keeps
the phase ``k_z h`` of its height. The facades' layover mixes ground, wall and roof, reads heights
between theirs and loses coherence.
"""
import matplotlib.pyplot as plt
import numpy as np

import sarmitsuba
from sarmitsuba.stacks import interferometry as insar
from sarmitsuba.products.plotting import edges, label_image_axes, reference_intensity

primary = sarmitsuba.simulate("urban")
secondary = sarmitsuba.simulate("urban", sensor_overrides={"track_offset": (0.0, 0.11, -0.11)})
baseline = insar.pair_baseline(primary.image, primary.raw, secondary.raw)
print(f"perpendicular baseline {baseline.perpendicular:.3f} m, critical {baseline.critical:.1f} m, "
      f"height of ambiguity {baseline.height_of_ambiguity:.1f} m")

# %%
# The interferogram and the coherence over 5 x 5 looks, and the height from the unwrapped phase.
# Pixels with no echo (beyond the 240 m ground) are left grey.

looks = (5, 5)
phase = np.angle(insar.multilooked_interferogram(primary.image, secondary.image, looks))
gamma = insar.coherence(primary.image, secondary.image, looks)
height = insar.height(primary.image, secondary.image, primary.raw, secondary.raw, looks)
power = insar.multilooked_interferogram(primary.image, primary.image, looks).real     # <|I1|^2>
no_echo = power < 1e-5 * reference_intensity(power)     # 50 dB down: no echo
phase[no_echo] = gamma[no_echo] = height[no_echo] = np.nan
height[gamma < 0.3] = np.nan                              # too little coherence to read a height

image = primary.image
extent = (*edges(image.range), *edges(image.azimuth))
fig, axes = plt.subplots(1, 3, figsize=(14, 5), layout="constrained")
for ax, values, title, style, label in (
        (axes[0], phase, "interferometric phase", dict(cmap="twilight", vmin=-np.pi, vmax=np.pi), "phase [rad]"),
        (axes[1], gamma, "coherence, 5 x 5 looks", dict(cmap="gray", vmin=0, vmax=1), "coherence"),
        (axes[2], height, "height (coherence >= 0.3)", dict(cmap="viridis", vmin=0, vmax=50), "height [m]")):
    ax.set_facecolor("0.6")
    shown = ax.imshow(values, origin="lower", extent=extent, interpolation="nearest", **style)
    label_image_axes(ax, image)
    ax.set_title(title)
    fig.colorbar(shown, ax=ax, label=label, shrink=0.7, location="bottom")
plt.show()

# %%
# From the command line, two renders and the ``interferogram`` command (which writes
# ``interferogram.npz``, ``coherence.npz``, ``height.npz`` and ``interferogram.png``):
#
# .. code-block:: bash
#
#    .venv/bin/python -m sarmitsuba render urban --out out/urban-primary
#    .venv/bin/python -m sarmitsuba render urban --out out/urban-secondary --set "track_offset=0, 0.11, -0.11"
#    .venv/bin/python -m sarmitsuba interferogram out/urban-primary out/urban-secondary --out out/urban-insar --looks 5,5
