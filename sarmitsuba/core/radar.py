"""Radar and platform parameters.

:class:`RadarParameters` holds what the ``<sensor type="sar">`` plugin reads (docs/design.md
section 4); :func:`sarmitsuba.core.geometry.acquisition_geometry` turns it into per-pulse antenna
positions (float64, world frame, z up) along its trajectory (docs/physics.md (J1)-(J4)).
The valid range of each parameter with a unit: :mod:`sarmitsuba.core.valid_ranges`; the checks a
new set of parameters runs, and the valid values of the named ones: :mod:`sarmitsuba.core.sensor_checks`.

Conventions (docs/design.md section 4): the platform flies along +x rotated by ``heading``
(degrees, counter-clockwise from +x). ``look_side="right"`` looks to the right of the
track, i.e. toward -y for heading 0: the sensor sits on the +y side of the scene.
Angles are degrees at the interface, radians inside.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any, Mapping

import numpy as np

from . import georef
from .constants import SPEED_OF_LIGHT
from .receiver import receiver_values
from .sensor_checks import (CHANNELS, HALF_POWER_SINC, ORBIT_DIRECTIONS, POLARIZATIONS, TRAJECTORIES, check_sensor,
                            utc_time)
from .trajectory import StateVectors
from .valid_ranges import VALID_RANGES, ParameterError, ValidRange, unknown_name

__all__ = ["CHANNELS", "POLARIZATIONS", "RadarParameters", "ParameterError", "HALF_POWER_SINC", "ValidRange",
           "VALID_RANGES", "utc_time", "TRAJECTORIES", "ORBIT_DIRECTIONS"]


@dataclass(frozen=True)
class RadarParameters:
    """Radar and platform parameters of a SAR acquisition (the ``sar`` sensor's manual).

    Attributes
    ----------
    frequency : float, Hz
        Carrier frequency ``fc``.
    bandwidth : float, Hz
        Transmitted chirp bandwidth ``B``; (0, sampling_rate].
    pulse_length : float, s
        Chirp duration ``T_p``; the chirp rate is ``B / T_p``.
    prf : float, Hz
        Pulse repetition frequency.
    sampling_rate : float, Hz
        Fast-time complex sampling rate ``fs``; must be >= ``bandwidth``; 0 (default) =
        ``1.2 * bandwidth``.
    velocity : float, m/s
        Platform speed along the track.
    altitude : float, m
        Platform height above the scene centre.
    incidence_angle : float, deg
        Incidence (= look, flat earth) angle at the scene centre; (0, 90).
    scene_center : tuple of 3 float, m
        Point the beam centre looks at, mid-aperture; ``None`` = centre of the scene's
        bounding box at ground level, resolved by the scene loader.
    track_offset : tuple of 3 float, m
        Shift of the whole track (every antenna position; the beam keeps its pointing and the
        image grid its place): a second pass with a baseline, for interferometry
        (docs/physics.md (I1)). Default ``(0, 0, 0)``.
    geo_origin : tuple (latitude deg, longitude deg, height m) or None
        WGS84 position of the world frame's origin, whose x, y, z axes are taken as east,
        north, up (docs/physics.md (GEO1)); written into CPHD, SICD and GeoTIFF products. ``None``
        = the scene's known origin (``sionna:munich``) or :data:`sarmitsuba.core.georef.DEFAULT`.
        Given as ``"48.138, 11.576, 566"``; latitude in [-90, 90], longitude in [-180, 180].
    look_side : str
        ``"right"`` or ``"left"`` of the track.
    heading : float, deg
        Track direction, counter-clockwise from +x.
    n_pulses : int
        Number of pulses; 0 = enough to illuminate the whole scene (resolved by the loader).
    azimuth_beamwidth : float, deg
        Azimuth beamwidth ``beta``. With ``beam = "tapered"`` (default) it is the one-way 3 dB
        width of the uniform aperture whose two-way pattern weights the echoes
        (:attr:`pattern_length`), and rays are traced, and pulses backprojected, out to that
        pattern's first nulls (:attr:`beam_sines`, about ``2.26 beta`` wide); with
        ``beam = "uniform"`` it is the full width of a hard-edged, uniformly illuminated beam.
        0 (default) = automatic: ``2 asin(0.443 lambda / L_a)`` with ``antenna_length``,
        else 1.0 deg. docs/physics.md (A).
    beam : str
        ``"tapered"`` (default): the two-way pattern ``sinc^2(L sin(phi) / lambda)`` of an
        aperture of length ``L`` = ``antenna_length``, or of the aperture whose 3 dB width is
        ``azimuth_beamwidth``, traced to its first nulls (no hard beam edge). ``"uniform"``:
        a hard-edged beam of full width ``azimuth_beamwidth`` with no pattern, on request
        only (extended targets streak along azimuth beyond their ends); needs
        ``antenna_length = 0``.
    polarization : str
        ``"VV"`` (default) or ``"HH"``: one co-polarised channel; ``"HV"`` or ``"VH"``
        (receive, transmit): one cross-polarised channel; ``"quad"``: all four channels
        (:data:`CHANNELS`) from one trace. The polarisation model (a Jones matrix per ray tube,
        or for one co-polarised channel the scalar coefficients) is the ``sbr`` parameter
        ``polarimetry`` (docs/physics.md (P1)-(P8)).
    antenna_length, antenna_height : float, m
        Antenna aperture along track (L_a) and in elevation (H_a). Each switches on its
        two-way pattern ``sinc^2(L_a sin(phi_az) / lambda)``, ``sinc^2(H_a sin(phi_el) / lambda)``
        (uniform aperture; phi_el measured from the look direction to the scene centre).
        0 (default) = no pattern in that plane.
    transmit_power : float, W, optional
        Peak transmit power; switches absolute radiometry on (radar equation, eq. (R1)).
    antenna_gain_db : float, dBi, optional
        Antenna gain; default ``4 pi L_a H_a / lambda^2`` from the antenna dimensions.
    losses_db : float, dB
        System losses (default 0).
    noise_temperature : float, K, optional
        Receiver noise temperature (default 290 K when ``noise_figure_db`` is given).
    noise_figure_db : float, dB, optional
        Receiver noise figure; with ``noise_temperature`` it switches thermal noise of power
        ``k T B F`` per sample on.
    mode : str
        ``"stripmap"`` (default; beam fixed at broadside, sweeping the scene) or ``"spotlight"``
        (beam steered at ``scene_center`` for every pulse; the patch is ``R beta`` wide and the
        integration angle ``dtheta = n_pulses v / (prf R)`` sets the azimuth resolution
        ``lambda / (2 dtheta)``; automatic ``n_pulses`` gives ``dtheta = lambda / (2 rho_slant)``).
    squint : float, deg
        Beam squint: the angle of the beam centre from the zero-Doppler plane, positive
        forward (looking ahead); (-60, 60), default 0 (broadside). The mid-aperture antenna
        then sits ``R0 tan(squint)`` behind the scene centre (``R0`` the closest-approach
        slant range), the beam spans sines ``[sin(squint - beta / 2), sin(squint + beta / 2)]``
        along track, and the Doppler centroid is ``2 v sin(squint) / lambda`` (Cumming and
        Wong 2005, eq. 4.34). Spotlight: the aperture is centred on the squinted position and
        the beam follows the scene centre.
    output : str
        ``"compressed"`` (default: range-compressed raw data) or ``"raw"`` (chirped echoes
        ``rect(t / T_p) exp(j pi K_r t^2)``, band-limited to the receiver band; the fast-time
        window grows by ``T_p`` so every chirp fits).
    collection_start : str, optional
        UTC time of the first pulse, ISO 8601 with an offset (``"2026-11-24T10:00:00Z"``),
        stored as ``"2026-11-24T10:00:00+00:00"``; written into CPHD, SICD and GeoTIFF. None
        (default): the moment of the render (:func:`sarmitsuba.pipeline.simulate`); set it
        for reproducible files.
    trajectory : str or StateVectors
        The antenna's path (docs/physics.md (J1), (J2)): ``"straight"`` (default: uniform, level,
        along ``heading``); ``"circular"``: a level circle about the scene centre at ``altitude``
        and ``incidence_angle`` (radius ``ground_range``), flown at ``velocity`` over ``arc_deg``,
        the beam following the scene centre (``mode`` becomes ``spotlight``); ``"orbit"``: a
        circular Keplerian orbit on the real Earth (:func:`sarmitsuba.core.orbit.builtin_orbit`,
        docs/physics.md (J7)) ``altitude`` above the WGS84 ellipsoid, of ``orbit_inclination`` and
        ``orbit_direction``, seeing the scene at ``geo_origin`` at ``incidence_angle`` (against the
        ellipsoid normal) on ``look_side`` at closest approach; or the path of a CSV
        file of state vectors (``time_s,x_m,y_m,z_m[,vx_mps,vy_mps,vz_mps]``, scene frame unless
        ``# frame = ecef``, absolute times with ``utc`` or ``# epoch``; or a Sentinel-1 orbit file;
        :func:`sarmitsuba.core.trajectory.read_state_vectors`, docs/physics.md (J5), (J6)), or :class:`StateVectors` from
        Python, interpolated smoothly, pulses at the PRF over their span; the scene loader then
        sets ``altitude``, ``incidence_angle``, ``velocity``, ``heading`` and ``look_side`` from the
        mid-aperture state. An ECEF orbit file passing the scene several times (a day's orbit
        file) images one pass (:func:`sarmitsuba.core.orbit.choose_pass`, docs/physics.md (J6)).
    arc_deg : float, deg
        ``trajectory = "circular"``: the arc flown, centred on the broadside position; (0, 360],
        default 360 (a full circle). Sets ``n_pulses`` when that is automatic.
    motion_error : str, optional
        A horizontal deviation of the true track normal to the nominal one (docs/physics.md (J4)):
        ``"AMPLITUDE_M, PERIOD_M"`` (a sinusoid along the distance flown) or ``"random, RMS_M,
        CORRELATION_M[, SEED]"`` (a Gaussian spectrum). The raw data keep both tracks; focusing
        uses the true one unless asked for the nominal one (``focus --track nominal``).
    stop_and_hop : bool
        False (default): each echo is received where the antenna has moved to by its arrival
        (docs/physics.md (J3)); True: the antenna stands still during each echo (the classical
        approximation, for comparison).
    orbit_inclination : float, deg
        ``trajectory = "orbit"``: the inclination of the circular orbit's plane, (0, 180) deg;
        default 98.18 (Sentinel-1's sun-synchronous orbit).
    orbit_direction : str
        ``trajectory = "orbit"``: ``"descending"`` (default) or ``"ascending"``: the satellite moves
        south or north as it passes the scene.
    ati_baseline : float, m
        Along-track interferometry: 0 (default) for one channel; ``d`` > 0 adds a second
        channel whose phase centre trails the first by ``d`` along the flight direction (the
        two-way, monostatic-equivalent separation: receivers ``2 d`` apart behind one
        transmitter, or ping-pong antennas ``d`` apart), rendered in the same call
        (docs/physics.md (V6)).
    orbit_pass_time : str, optional
        An ECEF orbit file with an absolute clock: the UTC time (ISO 8601 with an offset) near the
        closest approach of the pass to image, when the file passes the scene several times
        (docs/physics.md (J6)); None (default): the rule of :func:`sarmitsuba.core.orbit.choose_pass`.
    receiver : tuple of (name, value) pairs
        A receiver on a platform of its own (bistatic, docs/physics.md (B1)-(B4)), given as the
        sensor parameters ``receiver_NAME`` (``receiver_altitude``, ``receiver_trajectory``, ...;
        :data:`sarmitsuba.core.receiver.RECEIVER_FIELDS`) or from Python as a mapping
        ``{"altitude": 300, ...}``; empty (default): the transmitter receives (monostatic).

    Valid ranges (:data:`VALID_RANGES`; VHF to sub-THz radars, drones to LEO/MEO platforms):
    frequency [1e6, 1e12] Hz; bandwidth [1e5, 1e11] Hz; sampling_rate [1e5, 1e12] Hz; prf
    [1, 1e7] Hz; pulse_length [1e-9, 0.1] s; velocity [0.01, 1.2e4] m/s; altitude [1, 4e7] m;
    antenna_length, antenna_height 0 or [wavelength, 100] m; scene_center each coordinate
    within +-1e8 m; heading [-360, 360] deg; transmit_power [1e-6, 1e9] W; noise_temperature
    [1, 1e5] K; antenna_gain_db [-30, 80] dBi; losses_db [0, 100] dB; noise_figure_db [0, 50] dB.

    Raises
    ------
    ParameterError
        A value outside its valid range, with the unit and, when the value looks like another
        unit (9.6 for 9.6 GHz, 10 for 10 us), the value it probably meant.
    """

    frequency: float = 9.6e9
    bandwidth: float = 100e6
    pulse_length: float = 10e-6
    prf: float = 150.0
    sampling_rate: float = 0.0
    velocity: float = 100.0
    altitude: float = 1000.0
    incidence_angle: float = 45.0
    scene_center: tuple[float, float, float] | None = None
    track_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    geo_origin: tuple[float, float, float] | None = None
    look_side: str = "right"
    heading: float = 0.0
    n_pulses: int = 0
    azimuth_beamwidth: float = 0.0
    polarization: str = "VV"
    antenna_length: float = 0.0
    antenna_height: float = 0.0
    transmit_power: float | None = None
    antenna_gain_db: float | None = None
    losses_db: float = 0.0
    noise_temperature: float | None = None
    noise_figure_db: float | None = None
    output: str = "compressed"
    mode: str = "stripmap"
    squint: float = 0.0
    beam: str = "tapered"
    collection_start: str | None = None
    trajectory: str | StateVectors = "straight"
    arc_deg: float = 360.0
    motion_error: str | None = None
    stop_and_hop: bool = False
    orbit_inclination: float = 98.18
    orbit_direction: str = "descending"
    orbit_pass_time: str | None = None
    ati_baseline: float = 0.0
    receiver: tuple = ()

    def __post_init__(self) -> None:
        """Check every field and fill the derived defaults (:func:`~.sensor_checks.check_sensor`)."""
        check_sensor(self, coerce_parameters)

    @property
    def bistatic(self) -> bool:
        """Whether a receiver on its own platform receives (``receiver_*`` parameters given)."""
        return bool(self.receiver)

    @property
    def straight_track(self) -> bool:
        """Whether the nominal track is the built-in straight line (``trajectory = "straight"``)."""
        return isinstance(self.trajectory, str) and self.trajectory == "straight"

    # -- derived quantities (standard formulas; Cumming & Wong 2005, ch. 4) -----------------
    @property
    def wavelength(self) -> float:
        """Carrier wavelength ``c / fc`` [m]."""
        return SPEED_OF_LIGHT / self.frequency

    @property
    def chirp_rate(self) -> float:
        """LFM chirp rate ``K_r = B / T_p`` [Hz/s]."""
        return self.bandwidth / self.pulse_length

    @property
    def slant_range_resolution(self) -> float:
        """Slant-range resolution ``c / (2 B)`` [m] (IRW is 0.886 of this, unweighted)."""
        return SPEED_OF_LIGHT / (2.0 * self.bandwidth)

    @property
    def ground_range_resolution(self) -> float:
        """Ground-range resolution ``c / (2 B sin(theta_inc))`` [m]."""
        return self.slant_range_resolution / math.sin(math.radians(self.incidence_angle))

    @property
    def pattern_length(self) -> float:
        """Length ``L`` [m] of the uniform aperture whose two-way azimuth pattern
        ``sinc^2(L sin(phi) / lambda)`` weights the echoes: ``antenna_length``, or for the tapered
        default beam ``L = 0.443 lambda / sin(beta / 2)`` (3 dB width ``beta`` =
        ``azimuth_beamwidth``); 0 for ``beam = "uniform"``. docs/physics.md (A)."""
        if self.antenna_length > 0:
            return self.antenna_length
        if self.beam == "uniform":
            return 0.0
        return HALF_POWER_SINC * self.wavelength / math.sin(math.radians(self.azimuth_beamwidth) / 2.0)

    @property
    def channels(self) -> tuple[str, ...]:
        """The polarimetric channels simulated: :data:`CHANNELS` for ``quad``, else the one named."""
        return CHANNELS if self.polarization == "quad" else (self.polarization,)

    @property
    def polarimetric(self) -> bool:
        """Whether a cross-polarised channel is asked for (``HV``, ``VH``, ``quad``), which needs
        the Jones model (docs/physics.md (P3'))."""
        return self.polarization in ("HV", "VH", "quad")

    @property
    def traced_half_angle(self) -> float:
        """Half-width [rad] of the traced (and backprojected) beam about its centre: the
        pattern's first null ``asin(lambda / L)``, or ``beta / 2`` for a uniform beam."""
        if self.pattern_length > 0:
            return math.asin(self.wavelength / self.pattern_length)
        return math.radians(self.azimuth_beamwidth) / 2.0

    @property
    def traced_beamwidth(self) -> float:
        """Full width [deg] of the traced beam, ``2 traced_half_angle``."""
        return math.degrees(2.0 * self.traced_half_angle)

    @property
    def azimuth_resolution(self) -> float:
        """Stripmap azimuth resolution [m]: ``L / 2`` for an aperture of length ``L``
        (:attr:`pattern_length`; Cumming and Wong 2005, eq. 4.37), ``lambda / (2 beta)`` for a
        uniform beam of width ``beta``; spotlight: ``lambda / (2 dtheta)``; a circular arc ``a``:
        ``lambda / (4 sin(theta_inc) sin(min(a, pi) / 2))``, the extent of its ground wavenumbers
        (docs/physics.md (J1))."""
        if self.trajectory == "circular" and self.n_pulses > 0:     # docs/physics.md (J1)
            arc = min(max(self.n_pulses - 1, 1) * self.velocity / (self.prf * self.ground_range), math.pi)
            return self.wavelength / (4.0 * math.sin(math.radians(self.incidence_angle)) * math.sin(arc / 2.0))
        if self.mode == "spotlight" and self.n_pulses > 0:
            return self.wavelength / (2.0 * self.integration_angle)
        if self.pattern_length > 0:
            return self.pattern_length / 2.0
        return self.wavelength / (2.0 * math.radians(self.azimuth_beamwidth))

    @property
    def integration_angle(self) -> float:
        """Spotlight integration angle ``n_pulses v / (prf R)`` [rad] seen from the scene centre."""
        return self.n_pulses * self.velocity / (self.prf * self.slant_range)

    @property
    def slant_range(self) -> float:
        """Slant range from the mid-aperture antenna to the scene centre [m] (flat earth)."""
        return self.altitude / math.cos(math.radians(self.incidence_angle))

    @property
    def ground_range(self) -> float:
        """Horizontal distance from the nadir track to the scene centre [m]."""
        return self.altitude * math.tan(math.radians(self.incidence_angle))

    @property
    def footprint_length(self) -> float:
        """Azimuth extent of the traced beam footprint at the scene centre [m]:
        ``2 R tan(traced_half_angle)``."""
        return 2.0 * self.slant_range * math.tan(self.traced_half_angle)

    @property
    def beam_sines(self) -> tuple[float, float]:
        """Along-track sines ``(sin(squint - h), sin(squint + h))`` bounding the traced
        stripmap beam, ``h`` = :attr:`traced_half_angle`: a direction ``u`` from the antenna
        is in the beam when ``u . track`` lies between them."""
        half = self.traced_half_angle
        squint = math.radians(self.squint)
        return math.sin(squint - half), math.sin(squint + half)

    @property
    def doppler_bandwidth(self) -> float:
        """Azimuth Doppler bandwidth ``2 v (sin(squint + beta/2) - sin(squint - beta/2)) / lambda`` [Hz]
        of the beam's 3 dB width ``beta`` (the full width of a uniform beam); ``4 v sin(beta/2) / lambda``
        at broadside. The PRF must exceed it (Cumming and Wong 2005, eq. 4.36)."""
        half = math.radians(self.azimuth_beamwidth) / 2.0
        squint = math.radians(self.squint)
        return 2.0 * self.velocity * (math.sin(squint + half) - math.sin(squint - half)) / self.wavelength

    @property
    def doppler_centroid(self) -> float:
        """Doppler centroid ``2 v sin(squint) / lambda`` [Hz] (Cumming and Wong 2005, eq. 4.34)."""
        return 2.0 * self.velocity * math.sin(math.radians(self.squint)) / self.wavelength

    @property
    def squint_offset(self) -> float:
        """Along-track distance ``R0 tan(squint)`` [m] by which the mid-aperture antenna trails the scene centre."""
        return self.slant_range * math.tan(math.radians(self.squint))

    def with_overrides(self, overrides: Mapping[str, Any]) -> "RadarParameters":
        """Return a copy with some parameters replaced (names checked, values validated)."""
        return replace(self, **coerce_parameters(overrides))

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """Names of all parameters (plus ``aperture_length``, accepted by :meth:`from_mapping`)."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> "RadarParameters":
        """Build from a name -> value mapping (strings allowed), as read from XML or the CLI.

        ``aperture_length`` [m] may replace ``n_pulses``:
        ``n_pulses = max(1, round(aperture_length * prf / velocity))``.

        Raises
        ------
        ParameterError
            Unknown names (listing the valid ones) or invalid values.
        """
        values = dict(values)
        aperture = values.pop("aperture_length", None)
        params = cls(**coerce_parameters(values))
        if aperture is None:
            return params
        try:
            aperture = float(aperture)
        except (TypeError, ValueError):
            raise ParameterError(f"aperture_length: cannot use value {aperture!r}") from None
        if not (math.isfinite(aperture) and aperture > 0):
            raise ParameterError(f"aperture_length = {aperture} m must be a finite number > 0")
        return replace(params, n_pulses=max(1, round(aperture * params.prf / params.velocity)))


def coerce_parameters(values: Mapping[str, Any]) -> dict[str, Any]:
    """Convert strings / numbers to the field types of :class:`RadarParameters`.

    Raises :class:`ParameterError` for unknown names (listing the valid ones) and for
    values that cannot be converted.
    """
    types = {f.name: f.type for f in fields(RadarParameters)}
    out: dict[str, Any] = {}
    receiver = {}
    for name, value in values.items():
        if name.startswith("receiver"):             # the receiver's platform, (B1)
            receiver.update({name[9:]: value} if name != "receiver" else {})
            continue
        if name not in types:
            raise ParameterError(unknown_name("sar sensor parameter", name, sorted(types)))
        try:
            if name in ("scene_center", "track_offset"):
                parts = value.replace(",", " ").split() if isinstance(value, str) else list(value)
                out[name] = tuple(float(v) for v in parts)
            elif name == "geo_origin":
                ref = georef.parse(value)
                out[name] = None if ref is None else ref.as_tuple()
            elif name == "n_pulses":
                out[name] = int(value)
            elif value is None:
                out[name] = None
            elif name in ("look_side", "polarization", "output", "mode", "beam", "collection_start", "orbit_direction",
                          "orbit_pass_time"):
                out[name] = str(value)
            elif name == "trajectory":
                out[name] = value if isinstance(value, StateVectors) else str(value).strip()
            elif name == "motion_error":
                out[name] = str(value).strip()
            elif name == "stop_and_hop":
                out[name] = _boolean(name, value)
            else:
                out[name] = float(value)
        except georef.GeoReferenceError as exc:
            raise ParameterError(str(exc)) from None
        except (TypeError, ValueError) as exc:
            raise ParameterError(f"sar sensor parameter {name}: cannot use value {value!r} ({exc})") from None
    if receiver or "receiver" in values:
        out["receiver"] = receiver_values({**dict(values.get("receiver") or {}), **receiver}, coerce_parameters)
    return out


def _boolean(name: str, value: Any) -> bool:
    """``value`` as a bool: a bool, 0 / 1, or ``true`` / ``false`` (any case)."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)) and value in (0, 1):
        return bool(value)
    text = str(value).strip().lower()
    if text in ("true", "false"):
        return text == "true"
    raise ValueError("give true or false")
