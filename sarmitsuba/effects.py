"""Which optional effects a scene switches on, and why (docs/design.md section 7).

A simulation pays only for what the scene asks for: each effect below is compiled into the
tracer, or applied by the later stages, only when a sensor, integrator or material
parameter calls for it. :func:`list_effects` names every effect of the docs/design.md section 7
table with the parameter that switches it on, or the reason it is off and what it is
replaced by; ``python -m sarmitsuba info`` prints that list, and rendered data carry the
active ones in their metadata (``metadata["effects"]``, one string each).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:                      # only for annotations: no import cycle with scene.py
    from .scene import LoadedScene

__all__ = ["Effect", "list_effects", "active_effects"]


@dataclass(frozen=True)
class Effect:
    """One optional effect of a simulation.

    Attributes
    ----------
    name : str
        The effect, as in docs/design.md section 7 (e.g. ``"bounce orders > 1"``).
    active : bool
        Whether this scene, with its overrides, simulates it.
    reason : str
        When active, the parameter values that switch it on; when off, why, what is
        simulated instead, and which parameter would switch it on.
    """

    name: str
    active: bool
    reason: str

    def __str__(self) -> str:
        """``"name (reason)"``: the form stored in ``metadata["effects"]``."""
        return f"{self.name} ({self.reason})"


def list_effects(loaded: "LoadedScene") -> tuple[Effect, ...]:
    """Every optional effect of docs/design.md section 7 for a loaded scene, on or off, with the reason.

    Parameters
    ----------
    loaded : LoadedScene
        A scene after :func:`sarmitsuba.scene.load_scene` (overrides applied, parameters resolved).

    Returns
    -------
    tuple of Effect
        In the order of the docs/design.md section 7 table: bounce orders > 1, distributed clutter and
        speckle, antenna pattern, thermal noise, chirped raw echoes, absolute radiometry,
        spotlight, squint, then per-bounce-order products.
    """
    return (_bounces(loaded), _clutter(loaded), _antenna(loaded), _noise(loaded), _chirped(loaded),
            _radiometry(loaded), _spotlight(loaded), _squint(loaded), _split(loaded))


def active_effects(loaded: "LoadedScene") -> tuple[Effect, ...]:
    """The effects of :func:`list_effects` that are on."""
    return tuple(e for e in list_effects(loaded) if e.active)


def _bounces(loaded: "LoadedScene") -> Effect:
    depth = loaded.settings.max_depth
    if depth > 1:
        return Effect("bounce orders > 1", True, f"integrator max_depth = {depth}: orders 1..{depth} traced")
    return Effect("bounce orders > 1", False,
                  "integrator max_depth = 1: single bounce only, no reflection loop (max_depth > 1 switches it on)")


def _clutter(loaded: "LoadedScene") -> Effect:
    rough = sorted({s.bsdf().name for s in loaded.scene.shapes() if getattr(s.bsdf(), "clutter", (0, 0))[0] > 0})
    if rough:
        return Effect("distributed clutter and speckle", True,
                      f"rough materials: {', '.join(rough)}; seed {loaded.settings.seed}")
    return Effect("distributed clutter and speckle", False,
                  "no material has gamma_db or scattering_coefficient: facets return PO only "
                  "(--material-set gamma_db=DB switches it on)")


def _antenna(loaded: "LoadedScene") -> Effect:
    p = loaded.params
    if p.antenna_length > 0 or p.antenna_height > 0:
        return Effect("antenna pattern", True,
                      f"antenna_length {p.antenna_length} m, antenna_height {p.antenna_height} m")
    if p.beam == "uniform":
        return Effect("antenna pattern", False,
                      f"beam = uniform (on request): a hard-edged {p.azimuth_beamwidth:.3g} deg beam, no pattern; "
                      "extended targets streak in azimuth beyond their ends")
    return Effect("antenna pattern", False,
                  f"no antenna_length / antenna_height: the default tapered beam, the two-way sinc^2 of the "
                  f"{p.pattern_length:.3g} m aperture whose 3 dB width is azimuth_beamwidth {p.azimuth_beamwidth:.3g} deg, "
                  f"traced to its first nulls ({p.traced_beamwidth:.3g} deg)")


def _noise(loaded: "LoadedScene") -> Effect:
    p = loaded.params
    if p.noise_figure_db is not None or p.noise_temperature is not None:
        return Effect("thermal noise", True,
                      f"noise_figure_db {p.noise_figure_db}, noise_temperature {p.noise_temperature}")
    return Effect("thermal noise", False, "no noise_figure_db / noise_temperature: noiseless")


def _chirped(loaded: "LoadedScene") -> Effect:
    p = loaded.params
    if p.output == "raw":
        return Effect("chirped raw echoes", True, f"sensor output = raw, T_p {p.pulse_length} s")
    return Effect("chirped raw echoes", False, "sensor output = compressed: range-compressed data")


def _radiometry(loaded: "LoadedScene") -> Effect:
    p = loaded.params
    if p.transmit_power is not None:
        return Effect("absolute radiometry", True, f"transmit_power {p.transmit_power} W")
    return Effect("absolute radiometry", False,
                  "no transmit_power: normalised, unit gains, amplitudes in sqrt(m^2)")


def _spotlight(loaded: "LoadedScene") -> Effect:
    p = loaded.params
    if p.mode == "spotlight":
        return Effect("spotlight", True, f"beam steered at the scene centre, integration angle "
                                         f"{math.degrees(p.integration_angle):.2f} deg")
    return Effect("spotlight", False, "sensor mode = stripmap: beam fixed relative to the track")


def _squint(loaded: "LoadedScene") -> Effect:
    squint = loaded.params.squint
    if squint != 0:
        return Effect("squint", True, f"sensor squint = {squint:g} deg: beam {'ahead' if squint > 0 else 'behind'}"
                                      " of broadside, Doppler centroid off zero")
    return Effect("squint", False, "sensor squint = 0: broadside beam, zero Doppler centroid")


def _split(loaded: "LoadedScene") -> Effect:
    if loaded.settings.split_bounces:
        return Effect("per-bounce-order products", True, "split_bounces")
    return Effect("per-bounce-order products", False, "split_bounces off: one raw data set and image for all orders")
