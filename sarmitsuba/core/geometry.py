"""The acquisition geometry: every pulse's antenna at transmission and at reception, from the
sensor's trajectory (docs/design.md section 4, docs/physics.md (J1)-(J4)).

:func:`acquisition_geometry` turns resolved :class:`~sarmitsuba.core.radar.RadarParameters` into
an :class:`AcquisitionGeometry` (float64, world or local frame, z up): the trajectory of the
``trajectory`` parameter (:mod:`.trajectory`), sampled at the PRF, with motion errors added, and
with every pulse's receive position at the arrival of the scene centre's echo unless the sensor
asks for ``stop_and_hop``.

Conventions (docs/design.md section 4): the straight track flies along +x rotated by ``heading``
(degrees, counter-clockwise from +x). ``look_side="right"`` looks to the right of the track,
i.e. toward -y for heading 0: the sensor sits on the +y side of the scene.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .radar import ParameterError, RadarParameters
from . import georef, orbit
from . import trajectory as tj

__all__ = ["AcquisitionGeometry", "acquisition_geometry", "ground_layover", "track_frame", "trajectory_of",
           "pulse_times", "collection_start", "with_receiver"]


@dataclass(frozen=True)
class AcquisitionGeometry:
    """Per-pulse geometry of an acquisition.

    Attributes
    ----------
    positions : float64 [n_pulses, 3], m
        Antenna phase centre at each pulse's transmission (the true track).
    velocity : float64 [n_pulses, 3], m/s
        Its velocity at transmission.
    pulse_time : float64 [n_pulses], s
        Slow time (transmission): zero at mid-aperture for built-in tracks, the state vectors'
        clock for a trajectory file.
    scene_center : float64 [3], m
    track_direction : float64 [3]
        Unit vector along the track; for a curved track the horizontal direction of the
        least-squares line through the whole aperture (:func:`aperture_axis`).
    look_direction : float64 [3]
        Horizontal unit vector from the track toward the scene (away from the sensor),
        perpendicular to ``track_direction``.
    rx_positions : float64 [n_pulses, 3], m
        The antenna when the scene centre's echo arrives (docs/physics.md (J3)); ``positions``
        under stop-and-hop.
    rx_time : float64 [n_pulses], s, or None
        When it arrives; None: stop-and-hop (the antenna stands still during each echo).
    acceleration : float64 [n_pulses, 3], m/s^2
        At transmission (the tracer's receive positions are ``A + v tau + a tau^2 / 2``).
    beam_axes : float64 [n_pulses, 3] or None
        Curved tracks: each pulse's unit along-track axis of the antenna (the direction of the
        nominal velocity, the axis :func:`sarmitsuba.focus.beam.beam_axes` processes; on an orbit the
        Earth-fixed velocity: zero-Doppler steering, docs/physics.md (J7)), which its beam and
        pattern follow; None for a straight track (``track_direction`` throughout).
    nominal_positions, nominal_rx_positions, nominal_velocity : float64 [n_pulses, 3] or None
        The track without its motion errors (sensor ``motion_error``, (J4)); None without them.
    receiver_positions, receiver_velocity, receiver_acceleration : float64 [n_pulses, 3] or None
        Bistatic (sensor ``receiver_*``, docs/physics.md (B1)): the receiver's platform at each
        pulse's transmission [m, m/s, m/s^2]; ``rx_positions`` is then the receiver when the scene
        centre's echo arrives (at transmission with stop-and-hop) and ``rx_time`` None. None:
        the transmitter receives.
    """

    positions: np.ndarray
    velocity: np.ndarray
    pulse_time: np.ndarray
    scene_center: np.ndarray
    track_direction: np.ndarray
    look_direction: np.ndarray
    rx_positions: np.ndarray | None = None
    rx_time: np.ndarray | None = None
    acceleration: np.ndarray | None = None
    beam_axes: np.ndarray | None = None
    nominal_positions: np.ndarray | None = None
    nominal_rx_positions: np.ndarray | None = None
    nominal_velocity: np.ndarray | None = None
    receiver_positions: np.ndarray | None = None
    receiver_velocity: np.ndarray | None = None
    receiver_acceleration: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.rx_positions is None:
            object.__setattr__(self, "rx_positions", self.positions)
        if self.acceleration is None:
            object.__setattr__(self, "acceleration", np.zeros_like(self.positions))

    @property
    def continuous(self) -> bool:
        """Whether echoes are received where the antenna has moved to (no stop-and-hop, (J3))."""
        return self.rx_time is not None

    @property
    def bistatic(self) -> bool:
        """Whether a receiver on its own platform receives (:attr:`receiver_positions`)."""
        return self.receiver_positions is not None

    @property
    def reference_length(self) -> np.ndarray:
        """float64 [n_pulses], m: each pulse's two-way length to the scene centre, ``2 |A - c|``,
        or bistatic ``|A - c| + |R_rx - c|`` (docs/physics.md (B2))."""
        out = np.linalg.norm(self.positions - self.scene_center, axis=1)
        if not self.bistatic:
            return 2.0 * out
        return out + np.linalg.norm(self.rx_positions - self.scene_center, axis=1)

    @property
    def curved(self) -> bool:
        """Whether the antenna's along-track axis turns with the pulses (:attr:`beam_axes`)."""
        return self.beam_axes is not None

    def trailing(self, baseline: float) -> "AcquisitionGeometry":
        """The geometry of a phase centre ``baseline`` [m] behind this one along each pulse's
        direction of flight (along-track interferometry, docs/physics.md (V6)): every position
        moved by ``-baseline v / |v|``, the pulse times kept."""
        unit = self.velocity / np.maximum(np.linalg.norm(self.velocity, axis=1, keepdims=True), 1e-300)
        back = -float(baseline) * unit
        moved = {name: getattr(self, name) + back for name in
                 ("positions", "rx_positions", "nominal_positions", "nominal_rx_positions")
                 if getattr(self, name) is not None}
        return replace(self, **moved)

    def shifted(self, offset: np.ndarray) -> "AcquisitionGeometry":
        """The geometry with every position and the scene centre moved by ``offset`` [m]."""
        offset = np.asarray(offset, np.float64)
        moved = {name: getattr(self, name) + offset for name in
                 ("positions", "rx_positions", "nominal_positions", "nominal_rx_positions", "scene_center",
                  "receiver_positions")
                 if getattr(self, name) is not None}
        return replace(self, **moved)


def track_frame(params: RadarParameters) -> tuple[np.ndarray, np.ndarray]:
    """Unit track direction and horizontal look direction of the sensor's heading, float64 [3] each."""
    h = math.radians(params.heading)
    track = np.array([math.cos(h), math.sin(h), 0.0])
    right = np.array([math.sin(h), -math.cos(h), 0.0])      # track x z_hat
    return track, (right if params.look_side == "right" else -right)


def aperture_axis(positions: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Horizontal unit direction of the least-squares straight line through an aperture,
    float64 [3]: the antenna ``positions`` [n, 3] (m) fitted as ``P_0 + V (t - mean(t))`` over
    their ``times`` [n] (s), ``V = sum (t - t_m)(P - P_m) / sum (t - t_m)^2``, its z dropped.

    The image frame of a curved track (docs/physics.md (J2)): the fit weighs the whole aperture,
    where the velocity at mid-aperture follows any sway there (5.7 deg against the track's 2.4 deg
    in ``scenes/drone_track.csv``); it is the line the FFT focusers fit to the same positions
    (:mod:`sarmitsuba.focus.stripmap`), and for an arc symmetric about mid-aperture (circular SAR)
    the tangent there. Raises ParameterError when the fit has no horizontal motion."""
    positions, times = np.asarray(positions, np.float64), np.asarray(times, np.float64)
    dt = times - times.mean()
    velocity = dt @ (positions - positions.mean(axis=0)) / (dt @ dt) if dt @ dt > 0 else np.zeros(3)
    horizontal = velocity * np.array([1.0, 1.0, 0.0])
    norm = float(np.linalg.norm(horizontal))
    if not norm > 1e-9 * max(float(np.linalg.norm(velocity)), 1e-300):
        raise ParameterError("trajectory: the antenna's positions over the aperture have no horizontal trend (it ends "
                             "where it began, or moves vertically); a SAR image needs an aperture along a track")
    return horizontal / norm


def trajectory_of(params: RadarParameters) -> tj.Trajectory:
    """The nominal trajectory of the sensor, without motion errors (docs/physics.md (J1), (J2)).

    - ``"straight"``: the mid-aperture antenna at ``scene_center - R0 tan(squint) track -
      ground_range look + altitude z``, flying ``velocity`` along ``heading``;
    - ``"circular"``: the level circle about the vertical through ``scene_center`` of radius
      ``ground_range`` at ``altitude``, passing at ``t = 0`` where the straight track's mid-aperture
      antenna would (broadside), flown at ``velocity`` along ``heading`` there, clockwise seen from
      above when looking right (the scene centre on the right) and counter-clockwise when looking left;
    - ``"orbit"``: the circular orbit of :func:`~.orbit.orbit_of` (J7), then as state vectors;
    - state vectors (:class:`~.trajectory.StateVectors`, or a CSV or orbit file read from the
      working directory): their interpolant; ECEF states are carried into the scene's ENU frame
      at ``geo_origin`` first (:func:`~.orbit.in_scene_frame`, (J6)).

    ``track_offset`` shifts every kind. Raises ParameterError (TrajectoryError) for an unreadable
    trajectory file."""
    if params.scene_center is None:
        raise ParameterError("scene_center must be resolved before computing the geometry")
    track, look = track_frame(params)
    center = np.asarray(params.scene_center, dtype=np.float64)
    offset = np.asarray(params.track_offset, float)
    kind = params.trajectory
    if isinstance(kind, str) and kind == "straight":
        mid = center - params.squint_offset * track - params.ground_range * look + np.array([0.0, 0.0, params.altitude])
        return tj.straight(mid + offset, params.velocity * track)
    if isinstance(kind, str) and kind == "circular":
        axis = center + np.array([0.0, 0.0, params.altitude]) + offset
        start = -look                                        # from the centre to the broadside antenna
        sign = -1.0 if params.look_side == "right" else 1.0
        return tj.circular(axis, params.ground_range, math.atan2(start[1], start[0]),
                           sign * params.velocity / params.ground_range)
    states = (kind if isinstance(kind, tj.StateVectors) else orbit.orbit_of(params) if kind == "orbit"
              else tj.read_state_vectors(kind))
    states = orbit.in_scene_frame(states, georef.of(params))
    if np.any(offset):
        states = states.shifted(-offset)
    return tj.from_state_vectors(states)


def pulse_times(params: RadarParameters, nominal: tj.Trajectory) -> np.ndarray:
    """Transmit times [s] of the ``n_pulses`` pulses, float64 [n_pulses]: at the PRF, centred on
    ``t = 0`` for the built-in tracks and on the middle of the state vectors' span for a trajectory
    file (docs/physics.md (J2)); for an orbit (:attr:`~.trajectory.StateVectors.closest_approach`)
    on its closest approach to ``scene_center``, moved inwards as far as the pulses need to fit
    into the span (J6). With an absolute clock (:attr:`~.trajectory.StateVectors.epoch`) the
    train moves by under 0.5 us so that the first pulse falls on a whole microsecond of UTC (J5).
    Raises ParameterError when they do not fit into that span."""
    n = params.n_pulses
    offsets = (np.arange(n, dtype=np.float64) - (n - 1) / 2.0) / params.prf
    lo, hi = nominal.span
    if not math.isfinite(lo):
        return offsets
    if (n - 1) / params.prf > hi - lo + 1e-9 / params.prf:
        fit = int(math.floor((hi - lo) * params.prf + 1e-9)) + 1
        raise ParameterError(f"n_pulses = {n} at prf = {params.prf:g} Hz last {(n - 1) / params.prf:.6g} s, longer "
                             f"than the trajectory's {hi - lo:.6g} s of state vectors ({lo:.6g} .. {hi:.6g} s): use at "
                             f"most {fit} pulses, or n_pulses = 0 for all of them")
    middle = 0.5 * (lo + hi)
    states = nominal.states
    if states is not None and states.closest_approach:
        half = 0.5 * (n - 1) / params.prf
        nearest = orbit.closest_approach(nominal.evaluate, lo, hi, np.asarray(params.scene_center, np.float64))
        middle = min(max(nearest, lo + half), hi - half)
    times = middle + offsets
    if states is not None and states.epoch is not None:
        # an absolute clock: the first pulse on a whole microsecond of UTC (its epoch is on a whole microsecond),
        # the resolution of CollectionStart / CollectStart, so that TxTime needs no rounding (J5)
        times += round(times[0] * 1e6) * 1e-6 - times[0]
    return times


def collection_start(params: RadarParameters) -> str | None:
    """The UTC time of the first pulse (ISO 8601, microseconds) that the sensor's trajectory fixes:
    ``epoch + t_0`` for state vectors with an absolute clock (docs/physics.md (J5)), else the
    ``collection_start`` parameter (None when not given). Requires resolved ``scene_center`` and
    ``n_pulses`` for state vectors."""
    kind = params.trajectory
    if not (isinstance(kind, tj.StateVectors) and kind.epoch is not None):
        return params.collection_start
    nominal = tj.from_state_vectors(orbit.in_scene_frame(kind, georef.of(params)))
    return kind.utc(float(pulse_times(params, nominal)[0])).isoformat()


def acquisition_geometry(params: RadarParameters) -> AcquisitionGeometry:
    """Antenna positions for every pulse (docs/design.md section 4; docs/physics.md (J1)-(J4)).

    The trajectory (:func:`trajectory_of`) is sampled at :func:`pulse_times`; ``motion_error``
    adds its deviation to the true track (the nominal one is kept); unless ``stop_and_hop``, each
    pulse's receive position is the antenna when the scene centre's echo arrives
    (:func:`~.trajectory.receive_time`). Requires resolved ``scene_center`` and ``n_pulses > 0``.

    Raises
    ------
    ParameterError
        When ``scene_center`` or ``n_pulses`` are unresolved, or the trajectory cannot be read or
        holds too few seconds for ``n_pulses``.
    """
    if params.scene_center is None or params.n_pulses <= 0:
        raise ParameterError("scene_center and n_pulses must be resolved before computing the geometry")
    nominal = trajectory_of(params)
    t = pulse_times(params, nominal)
    center = np.asarray(params.scene_center, dtype=np.float64)
    track, look = track_frame(params)
    error = tj.MotionError.parse(params.motion_error)
    true = nominal if error is None else tj.with_motion_error(
        nominal, error, float(t[0]), float(t[-1]), 1.0 if params.look_side == "right" else -1.0)
    positions, velocity = true.position(t), true.velocity(t)
    rx_time = rx = None
    if not params.stop_and_hop:
        rx_time, rx = tj.receive_time(true, t, center)
    beam_axes = None
    if not nominal.straight:
        v = nominal.velocity(t)
        horizontal = v * np.array([1.0, 1.0, 0.0])
        norm = np.linalg.norm(horizontal, axis=1)
        if np.any(norm <= 1e-9 * np.maximum(np.linalg.norm(v, axis=1), 1e-300)):
            i = int(np.argmax(norm <= 1e-9 * np.maximum(np.linalg.norm(v, axis=1), 1e-300)))
            raise ParameterError(f"trajectory: at pulse {i} (t = {t[i]:.6g} s) the antenna moves vertically or not at "
                                 "all; a SAR needs horizontal motion along its track")
        # the antenna's along-track axis is the nominal velocity itself, as the focusers' beam
        # (focus.beam.beam_axes): on an orbit its ENU velocity dips 0.19 deg, and its horizontal part
        # put the beam 0.14 deg off zero Doppler, beside the processed beam (J7)
        beam_axes = v / np.linalg.norm(v, axis=1, keepdims=True)
        mid = aperture_axis(nominal.position(t), t) if len(t) > 1 else horizontal[0] / norm[0]
        sign = 1.0 if params.look_side == "right" else -1.0
        track, look = mid, sign * np.array([mid[1], -mid[0], 0.0])
    nominal_fields = {}
    if error is not None:
        nominal_fields = dict(nominal_positions=nominal.position(t), nominal_velocity=nominal.velocity(t),
                              nominal_rx_positions=nominal.position(rx_time) if rx_time is not None
                              else nominal.position(t))
    geometry = AcquisitionGeometry(positions, velocity, t, center, track, look, rx_positions=rx, rx_time=rx_time,
                                   acceleration=true.acceleration(t), beam_axes=beam_axes, **nominal_fields)
    return geometry if not params.bistatic else with_receiver(params, geometry)


def with_receiver(params: RadarParameters, geometry: AcquisitionGeometry) -> AcquisitionGeometry:
    """``geometry`` with the receiver of ``params.receiver`` (docs/physics.md (B1)): its platform
    (:func:`~sarmitsuba.core.receiver.receiver_parameters`) flown over the same pulse times, and
    each echo received where the receiver is when the scene centre's echo arrives (the
    transmit leg to the centre, then the receive leg solved as (J3)), or at transmission with
    stop-and-hop. Raises ParameterError (naming ``receiver_*``) for a receiver whose trajectory
    does not cover the pulses, that is below the scene's horizon, or whose bistatic angle at
    the scene centre exceeds :data:`~sarmitsuba.core.receiver.MAX_BISTATIC_ANGLE`."""
    from .receiver import check_bistatic_angle, horizon_check, receiver_parameters
    rp = receiver_parameters(params)
    try:
        path = trajectory_of(rp)
        # a built-in track or orbit is at its own mid-aperture (or closest approach) at the pulses'
        # mid-time; state vectors share the transmitter's clock
        own = isinstance(rp.trajectory, str) and rp.trajectory in ("straight", "circular", "orbit")
        mid = 0.5 * (geometry.pulse_time[0] + geometry.pulse_time[-1])
        t = geometry.pulse_time - mid + (_middle(pulse_times(rp, path)) if own else mid)
        lo, hi = path.span
        if t[0] < lo - 1e-9 or t[-1] > hi + 1e-9:
            raise ParameterError(f"its state vectors span {lo:.6g} .. {hi:.6g} s, the pulses {t[0]:.6g} .. {t[-1]:.6g} s")
    except ParameterError as exc:
        raise ParameterError(f"receiver_trajectory: {exc}") from None
    at_tx = path.position(t)
    rx = at_tx
    if not params.stop_and_hop:
        first = np.linalg.norm(geometry.positions - geometry.scene_center, axis=1)
        rx = tj.receive_time(path, t, geometry.scene_center, first_leg=first)[1]
    horizon_check(rx, geometry.scene_center)
    check_bistatic_angle(geometry.positions, rx, geometry.scene_center)
    nominal = {} if geometry.nominal_positions is None else {"nominal_rx_positions": rx}    # no error of its own
    return replace(geometry, **nominal, rx_positions=rx, rx_time=None, receiver_positions=at_tx,
                   receiver_velocity=path.velocity(t), receiver_acceleration=path.acceleration(t))


def _middle(times: np.ndarray) -> float:
    return 0.5 * (float(times[0]) + float(times[-1]))


def ground_layover(geometry: AcquisitionGeometry, points: np.ndarray) -> np.ndarray:
    """Where a focuser matched to the track images world points on the horizontal plane through
    the scene centre: ``(along, across)`` [m] from the scene centre along the track and look
    directions, float64 [n, 2] (NaN for a point the plane cannot show).

    Every point of the circle about the straight track through ``X`` has ``X``'s range history
    (the same closest approach ``R0 = |X - F|`` at the same foot ``F`` on the track), so ``X``
    appears where that circle meets the plane, on ``X``'s side: at the foot's along-track
    position and ``sqrt(R0^2 - H^2)`` from the track's ground trace, ``H`` the track's height
    above the plane (docs/physics.md (G2); Cumming and Wong 2005, section 4.2). A point with
    ``R0 < H`` lies nowhere on the plane (NaN). For a curved track the line through the
    mid-aperture antenna along :attr:`AcquisitionGeometry.track_direction` stands in for it.
    """
    x = np.atleast_2d(np.asarray(points, dtype=np.float64)) - geometry.scene_center
    mid = len(geometry.positions) // 2 if geometry.curved else 0
    a = geometry.positions[mid] - geometry.scene_center
    t, look = geometry.track_direction, geometry.look_direction
    foot = a + ((x - a) @ t)[:, None] * t
    r0 = np.linalg.norm(x - foot, axis=1)
    height = float(a[2])                                     # the level track above the plane
    trace_across = foot @ look                               # the foot's ground trace, across-track
    side = np.where((x - foot) @ look >= 0.0, 1.0, -1.0)
    with np.errstate(invalid="ignore"):
        ground = np.sqrt(r0 * r0 - height * height)
    return np.stack([foot @ t, trace_across + side * ground], axis=1)
