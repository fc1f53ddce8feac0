"""
An inverse problem: a wall's permittivity from its image
========================================================

The simulator is differentiable with respect to material and shape parameters:
:func:`sarmitsuba.gradients` focuses by backprojection as a linear map, carries the gradient of a
loss on the image back through its adjoint and the tracer (reverse mode), and returns the loss,
its gradient and the image (complex, on the ground grid about the scene centre). With scipy's
L-BFGS-B that solves inverse problems.

The scene: a brick box (6 x 4 m, 5 m high, turned 20 deg, relative permittivity 4.5, 0.02 S/m)
on a metal plate, imaged from 20 km altitude with 16 pulses onto a 48 x 48 grid of 0.5 m. Its
image is the target (16 pulses give a coarse azimuth resolution, so the image is in effect a
range profile: the box's walls, roof and double bounce). The descent starts 30 % off, at a
permittivity of 5.85, and minimises the amplitude loss ``sum (|I| - |T|)^2``. The first
evaluations compile the derivative kernels (minutes with an empty Dr.Jit kernel cache, seconds
once they are cached).
"""
import matplotlib.pyplot as plt
import numpy as np
import scipy.optimize
import trimesh

import sarmitsuba
from sarmitsuba.derivatives import AmplitudeLoss, MaterialParameter


def building(eps_r):
    """The brick box on a 30 x 30 m metal plate, seen from 20 km."""
    ground = trimesh.Trimesh([[-15, -15, 0], [15, -15, 0], [15, 15, 0], [-15, 15, 0]], [[0, 1, 2], [0, 2, 3]])
    box = trimesh.creation.box((6, 4, 5)).apply_translation((0, 0, 2.5))
    box.apply_transform(trimesh.transformations.rotation_matrix(np.radians(20), (0, 0, 1)))
    brick = {"model": "half_space", "relative_permittivity": eps_r, "conductivity": 0.02, "id": "brick"}
    sensor = {"frequency": 9.6e9, "bandwidth": 150e6, "sampling_rate": 180e6, "prf": 250, "velocity": 100,
              "altitude": 20e3, "incidence_angle": 45, "azimuth_beamwidth": 1.2, "scene_center": (0, 0, 0)}
    return sarmitsuba.Scene([(ground, "pec", "ground"), (box, brick, "box")], sensor=sensor,
                            integrator={"max_depth": 2})


grid = {"image_size": (48, 48), "image_spacing": 0.5, "sensor_overrides": {"n_pulses": 16}}
permittivity = MaterialParameter("brick", "relative_permittivity")
target = sarmitsuba.gradients(building(4.5), AmplitudeLoss(np.zeros((48, 48))), [], **grid).image
loss = AmplitudeLoss(target)
history = []


def loss_and_gradient(x):
    result = sarmitsuba.gradients(building(float(x[0])), loss, [permittivity], **grid)
    history.append((float(x[0]), result.loss))
    return result.loss, np.array([result.gradient[permittivity]])


found = scipy.optimize.minimize(loss_and_gradient, [5.85], jac=True, method="L-BFGS-B",
                                bounds=[(1.5, 20.0)], options={"maxiter": 30, "ftol": 1e-6})
print(f"found relative permittivity {found.x[0]:.4f} (true 4.5) after {len(history)} evaluations")

# %%
# The target, and the descent: the loss and the permittivity at each evaluation.

estimates, losses = np.array(history).T
fig, axes = plt.subplots(1, 3, figsize=(13, 4), layout="constrained")
ground_range = (np.arange(48) - 24) * 0.5             # the grid: 48 pixels of 0.5 m about the centre
amplitude_db = 20 * np.log10(np.maximum(np.abs(target[24]), 1e-12) / np.abs(target).max())
axes[0].plot(ground_range, amplitude_db, "k-")
axes[0].set_xlabel("ground range from scene centre [m]")
axes[0].set_ylabel("amplitude [dB, peak = 0]")
axes[0].set_title("target image, the cut through its centre")
axes[0].grid(True, alpha=0.3)
axes[1].semilogy(np.arange(1, len(losses) + 1), np.maximum(losses, 1e-30), "o-")
axes[1].set_ylabel("amplitude loss")
axes[1].set_title("loss")
axes[2].plot(np.arange(1, len(estimates) + 1), estimates, "o-", label="estimate")
axes[2].axhline(4.5, color="0.5", ls="--", label="truth")
axes[2].set_ylabel("relative permittivity of the brick")
axes[2].set_title("permittivity")
axes[2].legend()
for ax in axes[1:]:
    ax.set_xlabel("evaluation (loss and gradient)")
    ax.grid(True, alpha=0.3)
plt.show()
