"""Which optional effects a scene switches on, and why (docs/design.md section 7).

A simulation pays only for what the scene asks for: each effect below is compiled into the
tracer, or applied by the later stages, only when a sensor, integrator or material
parameter calls for it. :func:`list_effects` names every effect of the docs/design.md section 7
table with the parameter that switches it on, or the reason it is off and what it is
replaced by; ``python -m sarmitsuba info`` prints that list, and rendered data carry the
active ones in their metadata (``metadata["effects"]``, one string each).

The decision is made once, here: :func:`active_effects` turns a loaded scene into an
:class:`EffectSet` that the pipeline hands to the tracer (:func:`sarmitsuba.tracing.driver.trace.trace`,
:class:`sarmitsuba.tracing.driver.kernel.Kernel`), the radar equation
(:func:`sarmitsuba.scene.radar_equation.radar_equation`) and the cost model (:mod:`sarmitsuba.analysis.cost`).
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Iterable

from ..core.constants import SPEED_OF_LIGHT
from .rough_presets import range_warning
from .roughness import RoughSurfaceWarning

if TYPE_CHECKING:                      # only for annotations: no import cycle with scene/loader.py
    from ..core.radar import RadarParameters
    from .motion import ShapeMotion
    from .trace_inputs import MaterialTable, TraceSettings

__all__ = ["Effect", "EffectSet", "list_effects", "active_effects", "warn_rough_surfaces", "rough_materials"]


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


@dataclass(frozen=True)
class EffectSet:
    """Which optional effects a simulation runs: decided once, here, from the loaded scene, and
    handed to the tracer (:class:`sarmitsuba.tracing.driver.kernel.Kernel`), the radar equation
    (:func:`sarmitsuba.scene.radar_equation.radar_equation`) and ``sarmitsuba info``, so that none of them
    re-derives it from the parameters.

    Attributes
    ----------
    max_depth : int
        Bounce orders traced (``> 1`` compiles the reflection loop).
    rough_materials : tuple of str
        Sorted names of the materials used by some shape that have a clutter model (non-empty
        compiles the clutter term).
    antenna : bool
        An explicit antenna (``antenna_length`` or ``antenna_height`` > 0).
    pattern : bool
        An antenna pattern is applied by the tracer: the tapered default beam or the antenna's
        dimensions (``pattern_length > 0`` or ``antenna_height > 0``, docs/physics.md (A)).
    noise : bool
        Thermal noise (``noise_figure_db`` or ``noise_temperature`` given).
    chirped : bool
        Chirped raw echoes (sensor ``output = raw``).
    radiometry : bool
        Absolute radiometry (``transmit_power`` given).
    spotlight : bool
        Beam steered at the scene centre (sensor ``mode = spotlight``).
    squint : bool
        Sensor ``squint`` != 0.
    split_bounces : bool
        One raw data set and image per bounce order as well.
    channels : tuple of str
        The polarimetric channels simulated (sensor ``polarization``; ``("VV",)`` by default).
    jones : bool
        Ray tubes carry a Jones matrix (docs/physics.md (P1)-(P8)): ``sbr`` ``polarimetry =
        jones`` (the default), or any cross-polarised channel. Off only for one co-polarised
        channel with ``polarimetry = scalar``: scalar coefficients (R), (P6), no Jones algebra.
    continuous_motion : bool
        Each echo is received where the antenna has moved to (no stop-and-hop, (J3)): the
        default; off with sensor ``stop_and_hop = true``.
    curved_track : bool
        The antenna's axes turn with the pulses (``trajectory`` circular or state vectors, (J1),
        (J2)): per-pulse axes compiled into the beam and pattern.
    motion_error : bool
        The true track deviates from the nominal one (sensor ``motion_error``, (J4)).
    diffraction : bool
        Equivalent edge currents on the mesh's wedges and free edges (``sbr`` ``diffraction``,
        the default, with ``lit_regions = patches``; docs/physics.md (E1)-(E6)).
    moving_shapes : ShapeMotion or None
        The shapes that move during the acquisition (a ``velocity``, :mod:`sarmitsuba.scene.motion`):
        each sub-aperture traces them where they are, and their lanes move per pulse
        (docs/physics.md (V1)-(V3)). None: the scene holds still and pays nothing.
    bistatic : bool
        A receiver on its own platform (sensor ``receiver_*``, docs/physics.md (B1)-(B4)): the
        return legs, their visibility, the receiver's pattern and the range sum ``R_t + R_r``.
    order_energy : bool
        Each bounce order deposited apart, for the energy it holds (``summary.json``'s
        ``energy_by_order``, :attr:`deposit_groups`); on by default, off for the derivatives,
        which take the raw data of all orders at once.
    scatterers : bool
        Every term also summed coherently at its phase centre, for the scatterer catalogue
        (``sbr`` ``scatterers``, ``render --scatterers``, docs/physics.md (SC1)-(SC4)).
    listed : tuple of Effect
        Every effect of docs/design.md section 7, on or off, with the reason (:func:`list_effects`).

    Iterating over an EffectSet yields the :class:`Effect` s that are on (:attr:`active`).
    """

    max_depth: int
    rough_materials: tuple[str, ...]
    antenna: bool
    pattern: bool
    noise: bool
    chirped: bool
    radiometry: bool
    spotlight: bool
    squint: bool
    split_bounces: bool
    listed: tuple[Effect, ...]
    channels: tuple[str, ...] = ("VV",)
    jones: bool = True
    continuous_motion: bool = False
    curved_track: bool = False
    motion_error: bool = False
    diffraction: bool = False
    order_energy: bool = True
    bistatic: bool = False
    moving_shapes: "ShapeMotion | None" = None
    scatterers: bool = False

    @property
    def cross_polarised(self) -> bool:
        """Some channel is cross-polarised (``HV``, ``VH``, ``quad``): the optional effect."""
        return any(c[0] != c[1] for c in self.channels)

    @property
    def polarimetric(self) -> bool:
        """A Jones matrix per tube (:attr:`jones`)."""
        return self.jones

    @property
    def bounces(self) -> bool:
        """Bounce orders > 1."""
        return self.max_depth > 1

    @property
    def clutter(self) -> bool:
        """Distributed clutter and speckle (some shape's material is rough)."""
        return bool(self.rough_materials)

    @property
    def groups(self) -> int:
        """Spectra the tracer keeps per pulse: one per bounce order with ``split_bounces``, else 1."""
        return self.max_depth if self.split_bounces else 1

    @property
    def deposit_groups(self) -> int:
        """Spectra the tracer forms per pulse and channel: one per bounce order with ``split_bounces``
        or :attr:`order_energy` (each order's energy is measured, docs/physics.md (D6), then the
        orders summed unless kept), else 1."""
        return self.max_depth if self.split_bounces or self.order_energy else 1

    @property
    def active(self) -> tuple[Effect, ...]:
        """The listed effects that are on."""
        return tuple(e for e in self.listed if e.active)

    def __iter__(self):
        return iter(self.active)

    @classmethod
    def of(cls, params: "RadarParameters", settings: "TraceSettings | None" = None,
           rough_materials: Iterable[str] = (), moving_shapes: "ShapeMotion | None" = None) -> "EffectSet":
        """The effects of radar parameters, trace settings and the names of the rough materials
        some shape uses. Without ``settings``, the sensor's effects only (one bounce order, no
        per-order products): what :func:`sarmitsuba.scene.radar_equation.radar_equation` needs."""
        rough = tuple(sorted(set(rough_materials)))
        split = bool(settings.split_bounces) if settings is not None else False
        decided = cls(max_depth=settings.depth if settings is not None else 1, rough_materials=rough,
                      antenna=params.antenna_length > 0 or params.antenna_height > 0,
                      pattern=params.pattern_length > 0 or params.antenna_height > 0,
                      noise=params.noise_figure_db is not None or params.noise_temperature is not None,
                      chirped=params.output == "raw", radiometry=params.transmit_power is not None,
                      spotlight=params.mode == "spotlight", squint=params.squint != 0, split_bounces=split,
                      listed=(), channels=params.channels,
                      jones=getattr(settings, "polarimetry", "jones") == "jones" or params.polarimetric,
                      continuous_motion=not params.stop_and_hop, curved_track=not params.straight_track,
                      motion_error=params.motion_error is not None,
                      diffraction=bool(getattr(settings, "diffraction", False))
                      and getattr(settings, "lit_regions", "patches") == "patches", moving_shapes=moving_shapes,
                      bistatic=params.bistatic, scatterers=bool(getattr(settings, "scatterers", False)))
        return dataclasses.replace(decided, listed=_listed(decided, params, getattr(settings, "seed", None)))


def active_effects(loaded) -> EffectSet:
    """The :class:`EffectSet` of a loaded scene (overrides applied, parameters resolved): compute it
    once and hand it on. Rough materials are those of the BSDFs the scene's shapes use; each whose
    surface lies outside the I2EM's validated range at the carrier is warned about here, once
    (:func:`warn_rough_surfaces`)."""
    rough = [name for s in loaded.scene.shapes() for name in _rough_names(s.bsdf())]
    decided = EffectSet.of(loaded.params, loaded.settings, rough, getattr(loaded, "motion", None))
    warn_rough_surfaces(loaded, decided.cross_polarised)
    return decided


def _rough_names(bsdf) -> list[str]:
    """The rough rows of a BSDF as :func:`rough_materials` names them: its own (a clutter model),
    and ``"NAME (ROLE)"`` for each role whose surface a preset's rule gives it (RS8)."""
    own = [bsdf.name] if getattr(bsdf, "clutter", (0, 0))[0] > 0 else []
    return own + [f"{bsdf.name} ({role})" for role, surface in getattr(bsdf, "role_surfaces", {}).items()
                  if surface is not None]


def warn_rough_surfaces(loaded, cross: bool = False) -> None:
    """One :class:`~sarmitsuba.scene.roughness.RoughSurfaceWarning` per rough material (BSDF) the
    scene's shapes use whose surface lies outside the I2EM's validated range at the carrier
    (docs/physics.md (RS5)): the line of :func:`~sarmitsuba.scene.rough_presets.range_warning`, with
    sigma nought at the scene's incidence. ``cross``: HV is traced (its own range counts)."""
    params, seen = loaded.params, set()
    for shape in loaded.scene.shapes():
        bsdf = shape.bsdf()
        key = getattr(bsdf, "id_key", id(bsdf))
        if key in seen:
            continue
        seen.add(key)
        # the material's own surface, and those a preset's rules give its shapes of some roles (RS8)
        named = [(bsdf.name, getattr(bsdf, "surface", None))]
        named += [(f"{bsdf.name} ({role})", surface) for role, surface in getattr(bsdf, "role_surfaces", {}).items()]
        for (name, surface), role in zip(named, [None, *getattr(bsdf, "role_surfaces", {})]):
            if surface is None:          # smooth: no range to check (nor a permittivity to ask for)
                continue
            eta = (bsdf.material_at(params.frequency) if role is None
                   else bsdf.role_material_at(role, params.frequency)).relative_permittivity
            line = range_warning(name, surface, eta, params.frequency, params.incidence_angle, cross)
            if line is not None:
                warnings.warn(line, RoughSurfaceWarning, stacklevel=3)


def rough_materials(table: "MaterialTable") -> tuple[str, ...]:
    """Sorted names of the rough materials (clutter model) of a material table (its rows are the
    BSDFs the scene's shapes use, :func:`sarmitsuba.scene.loader.material_table`)."""
    if table.clutter is None:
        return ()
    return tuple(sorted({name for name, (kind, _) in zip(table.names, table.clutter) if kind > 0}))


def list_effects(loaded) -> tuple[Effect, ...]:
    """Every optional effect of docs/design.md section 7 for a loaded scene, on or off, with the reason.

    Parameters
    ----------
    loaded : LoadedScene
        A scene after :func:`sarmitsuba.scene.loader.load_scene` (overrides applied, parameters resolved).

    Returns
    -------
    tuple of Effect
        In the order of the docs/design.md section 7 table: bounce orders > 1, distributed clutter and
        speckle, antenna pattern, thermal noise, chirped raw echoes, absolute radiometry,
        spotlight, squint, per-bounce-order products, polarimetry, edge diffraction, then the trajectory's: curved track,
        the stop-and-hop approximation (on request only), motion errors; and moving shapes (:attr:`EffectSet.listed`).
    """
    return active_effects(loaded).listed


def _listed(e: EffectSet, p: "RadarParameters", seed: int | None) -> tuple[Effect, ...]:
    """The docs/design.md section 7 table for the decided effects ``e``: each on or off with its reason."""
    return (_bounces(e.max_depth), _clutter(e.rough_materials, seed), _antenna(e, p), _noise(e.noise, p),
            _chirped(e.chirped, p), _radiometry(e.radiometry, p), _spotlight(e.spotlight, p), _squint(e.squint, p),
            _split(e.split_bounces), _catalogue(e.scatterers), _polarimetry(e), _diffraction(e.diffraction), _curved(e.curved_track, p),
            _continuous(e.continuous_motion, p), _motion_error(e.motion_error, p), _moving(e.moving_shapes),
            _bistatic(e.bistatic, p))


def _bistatic(on: bool, p: "RadarParameters") -> Effect:
    if on:
        given = ", ".join(f"receiver_{k} = {v}" for k, v in p.receiver)
        return Effect("bistatic receiver", True, f"{given}: every echo returns to the receiver's platform, whose "
                      "visibility, pattern and range sum R_t + R_r the tracer follows (docs/physics.md (B1)-(B4))")
    return Effect("bistatic receiver", False, "no receiver_* parameter: the transmitter receives (monostatic)")


def _moving(motion) -> Effect:
    if motion is not None:
        turns = motion.angular_velocity or ((0.0, 0.0, 0.0),) * len(motion.ids)
        shapes = ", ".join(f"{i} at {tuple(round(c, 3) for c in v)} m/s" + (
            f" turning at {tuple(round(c, 3) for c in w)} deg/s" if any(w) else "")
            for i, v, w in zip(motion.ids, motion.velocity, turns))
        return Effect("moving shapes", True, f"{shapes}: traced where each pulse sees them (docs/physics.md (V1)-(V3))")
    return Effect("moving shapes", False, "no shape has a velocity: the scene holds still")


def _diffraction(on: bool) -> Effect:
    if on:
        return Effect("edge diffraction", True, "sbr diffraction = true: equivalent edge currents (fringe waves) on "
                      "every lit wedge and free edge, and double diffraction across faces (docs/physics.md (E1)-(E6))")
    return Effect("edge diffraction", False, "sbr diffraction = false, or lit_regions = tiles: physical optics alone, "
                  "edges as PO ends them (diffraction = true with lit_regions = patches switches it on)")


def _bounces(depth: int) -> Effect:
    if depth > 1:
        return Effect("bounce orders > 1", True, f"integrator max_depth = {depth}: orders 1..{depth} traced")
    return Effect("bounce orders > 1", False,
                  "integrator max_depth = 1: single bounce only, no reflection loop (max_depth > 1 switches it on)")


def _clutter(rough: tuple[str, ...], seed: int | None) -> Effect:
    if rough:
        return Effect("distributed clutter and speckle", True, f"rough materials: {', '.join(rough)}; seed {seed}")
    return Effect("distributed clutter and speckle", False,
                  "no material has rms_height, gamma_db or scattering_coefficient: facets return PO only "
                  "(--material-set roughness=city or gamma_db=DB switches it on)")


def _antenna(e: EffectSet, p: "RadarParameters") -> Effect:
    if e.antenna:
        return Effect("antenna pattern", True,
                      f"antenna_length {p.antenna_length} m, antenna_height {p.antenna_height} m")
    if not e.pattern:
        return Effect("antenna pattern", False,
                      f"beam = uniform (on request): a hard-edged {p.azimuth_beamwidth:.3g} deg beam, no pattern; "
                      "extended targets streak in azimuth beyond their ends")
    return Effect("antenna pattern", False,
                  f"no antenna_length / antenna_height: the default tapered beam, the two-way sinc^2 of the "
                  f"{p.pattern_length:.3g} m aperture whose 3 dB width is azimuth_beamwidth {p.azimuth_beamwidth:.3g} deg, "
                  f"traced to its first nulls ({p.traced_beamwidth:.3g} deg)")


def _noise(on: bool, p: "RadarParameters") -> Effect:
    if on:
        return Effect("thermal noise", True,
                      f"noise_figure_db {p.noise_figure_db}, noise_temperature {p.noise_temperature}")
    return Effect("thermal noise", False, "no noise_figure_db / noise_temperature: noiseless")


def _chirped(on: bool, p: "RadarParameters") -> Effect:
    if on:
        return Effect("chirped raw echoes", True, f"sensor output = raw, T_p {p.pulse_length} s")
    return Effect("chirped raw echoes", False, "sensor output = compressed: range-compressed data")


def _radiometry(on: bool, p: "RadarParameters") -> Effect:
    if on:
        return Effect("absolute radiometry", True, f"transmit_power {p.transmit_power} W")
    return Effect("absolute radiometry", False,
                  "no transmit_power: normalised, unit gains, amplitudes in sqrt(m^2)")


def _spotlight(on: bool, p: "RadarParameters") -> Effect:
    if on:
        return Effect("spotlight", True, f"beam steered at the scene centre, integration angle "
                                         f"{math.degrees(p.integration_angle):.2f} deg")
    return Effect("spotlight", False, "sensor mode = stripmap: beam fixed relative to the track")


def _squint(on: bool, p: "RadarParameters") -> Effect:
    if on:
        return Effect("squint", True, f"sensor squint = {p.squint:g} deg: beam {'ahead' if p.squint > 0 else 'behind'}"
                                      " of broadside, Doppler centroid off zero")
    return Effect("squint", False, "sensor squint = 0: broadside beam, zero Doppler centroid")


def _split(on: bool) -> Effect:
    if on:
        return Effect("per-bounce-order products", True, "split_bounces")
    return Effect("per-bounce-order products", False, "split_bounces off: one raw data set and image for all orders")


def _catalogue(on: bool) -> Effect:
    if on:
        return Effect("scatterer catalogue", True, "scatterers: every term also summed at its phase centre "
                      "(scatterers.csv, docs/physics.md (SC1)-(SC4))")
    return Effect("scatterer catalogue", False, "scatterers off: images only")


def _polarimetry(e: EffectSet) -> Effect:
    if e.cross_polarised:
        return Effect("cross-polarised channels", True, f"polarization = "
                      f"{'quad' if len(e.channels) > 1 else e.channels[0]}: {', '.join(e.channels)} from one trace")
    model = ("a Jones matrix per ray tube" if e.jones else
             "sbr polarimetry = scalar: scalar reflection coefficients, no Jones algebra")
    return Effect("cross-polarised channels", False, f"polarization = {e.channels[0]}: one co-polarised channel, "
                  f"{model} (HV, VH or quad switch it on)")


def _curved(on: bool, p: "RadarParameters") -> Effect:
    if on:
        kind = "circular" if p.trajectory == "circular" else f"state vectors {p.trajectory}"
        return Effect("curved track", True, f"trajectory = {kind}: the antenna's axes, beam and pattern turn with "
                                            "each pulse")
    return Effect("curved track", False, "trajectory = straight: a uniform, level line along heading "
                                         "(trajectory = circular or a CSV of state vectors switch it on)")


def _continuous(continuous: bool, p: "RadarParameters") -> Effect:
    """The stop-and-hop approximation: an accuracy knob (on request), not the default physics."""
    shift = p.velocity * p.slant_range / SPEED_OF_LIGHT * 1e3
    if not continuous:
        return Effect("stop-and-hop approximation", True, f"stop_and_hop = true: the antenna stands still during each "
                      f"echo, an azimuth shift of v R / c = {shift:.3g} mm against the real echo (docs/physics.md (J3))")
    return Effect("stop-and-hop approximation", False, f"every echo is received where the antenna has moved to during it "
                  f"(v tau = {2 * shift:.3g} mm at the scene centre; stop_and_hop = true switches the approximation on)")


def _motion_error(on: bool, p: "RadarParameters") -> Effect:
    if on:
        return Effect("motion errors", True, f"motion_error = {p.motion_error}: the true track deviates across the "
                                             "nominal one; the raw data keep both (focus --track nominal)")
    return Effect("motion errors", False, "no motion_error: the antenna flies the nominal track")
