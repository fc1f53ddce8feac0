"""``sar`` sensor: a side-looking SAR platform on a straight, circular or measured track.

.. pluginparameters::

 * - frequency
   - float, Hz
   - Carrier frequency (default 9.6e9, X-band).
 * - bandwidth
   - float, Hz
   - Chirp bandwidth B; slant-range resolution c/(2B) (default 100e6).
 * - pulse_length
   - float, s
   - Chirp duration T_p (default 10e-6).
 * - prf
   - float, Hz
   - Pulse repetition frequency (default 150).
 * - sampling_rate
   - float, Hz
   - Fast-time complex sampling rate, >= bandwidth (default 0 = 1.2 x bandwidth).
 * - velocity
   - float, m/s
   - Platform speed (default 100).
 * - altitude
   - float, m
   - Platform height above the scene centre (default 1000).
 * - incidence_angle
   - float, deg
   - Incidence angle at the scene centre, in (0, 90) (default 45).
 * - scene_center
   - point or string "x, y, z", m
   - Where the beam centre looks at mid-aperture (default: centre of the scene's
     bounding box at its lowest z).
 * - track_offset
   - string "dx, dy, dz", m
   - Shift of the whole track (default 0, 0, 0): a second pass for repeat-pass
     interferometry. The beam keeps its pointing and the image grid its place, so two
     passes focus on one grid (``.venv/bin/python -m sarmitsuba interferogram``; docs/physics.md (I1)).
 * - geo_origin
   - string "latitude, longitude, height", deg, deg, m
   - WGS84 position of the scene's origin; x, y, z are east, north, up there
     (docs/physics.md (GEO1)). Places the CPHD, SICD and GeoTIFF products on Earth. Default:
     the scene's known origin (``sionna:munich``), else 0 N 0 E 0 m, a placeholder.
 * - look_side
   - string
   - ``right`` (default) or ``left`` of the track.
 * - collection_start
   - string, ISO 8601 UTC time
   - Time of the first pulse, with an offset: ``2026-11-24T10:00:00Z`` (default: the moment
     of the render). Written into CPHD, SICD and GeoTIFF; set it for reproducible files.
 * - heading
   - float, deg
   - Track direction counter-clockwise from +x (default 0: flying along +x, looking -y).
 * - n_pulses
   - integer
   - Number of pulses; 0 (default) = enough to sweep the beam over the whole scene.
 * - aperture_length
   - float, m
   - Alternative to ``n_pulses``: track length; n_pulses = aperture_length * prf / velocity.
 * - azimuth_beamwidth
   - float, deg
   - Azimuth 3 dB beamwidth beta of the default tapered beam (the two-way sinc^2 pattern of
     the aperture of that width, traced to its first nulls), or the full width of a
     ``uniform`` beam. Default 0 = automatic: 1.0, or the 3 dB width of ``antenna_length``.
 * - beam
   - string
   - ``tapered`` (default; no hard beam edge) or ``uniform`` (hard-edged, uniformly
     illuminated beam of width ``azimuth_beamwidth``; on request only).
 * - mode
   - string
   - ``stripmap`` (default) or ``spotlight`` (beam steered at the scene centre; automatic
     n_pulses gives an azimuth resolution equal to the slant-range resolution).
 * - squint
   - float, deg
   - Beam squint from broadside, positive forward, in (-60, 60); default 0. The aperture
     centre trails the scene centre by R0 tan(squint); Doppler centroid 2 v sin(squint) / lambda.
 * - output
   - string
   - ``compressed`` (default) or ``raw``: chirped echoes instead of range-compressed data.
 * - transmit_power, antenna_gain_db, losses_db
   - float, W, dBi, dB
   - Switch absolute radiometry on (radar equation; raw data in sqrt(W), calibrated image).
 * - noise_temperature, noise_figure_db
   - float, K, dB
   - Switch thermal noise k T B F per sample on (needs transmit_power).
 * - antenna_length, antenna_height
   - float, m
   - Switch the two-way antenna pattern on (sinc^2 of a uniform aperture) in azimuth and
     elevation; default 0 = no pattern.
 * - trajectory
   - string
   - ``straight`` (default: uniform and level along ``heading``), ``circular`` (a level circle
     about the scene centre at ``altitude`` and ``incidence_angle``, the beam on the centre), or
     the path of a CSV of state vectors ``time_s,x_m,y_m,z_m[,vx_mps,vy_mps,vz_mps]`` in the
     scene frame (relative to the scene file's folder), interpolated smoothly; pulses at the PRF
     over its span, the platform parameters from its mid-aperture state (docs/physics.md (J1), (J2)).
     ``# frame = ecef`` makes the rows WGS84 ECEF, a ``utc`` column or ``# epoch = ISO 8601``
     line (or ``# time_scale = gps``) makes the times absolute (J5); a Sentinel-1 orbit file (EOF
     XML) is read too (J6). ``orbit``: a circular orbit ``altitude`` above the WGS84 ellipsoid that
     sees the scene at ``geo_origin`` at ``incidence_angle`` (J7).
 * - orbit_inclination
   - float, deg
   - ``trajectory = orbit``: the orbit's inclination, (0, 180), default 98.18 (Sentinel-1).
 * - orbit_direction
   - string
   - ``trajectory = orbit``: ``descending`` (default) or ``ascending``.
 * - orbit_pass_time
   - string, UTC
   - An ECEF orbit file with an absolute clock that passes the scene several times: the time
     (ISO 8601 with an offset) near the closest approach of the pass to image (docs/physics.md
     (J6)); not given: the rule of :func:`sarmitsuba.core.orbit.choose_pass`.
 * - arc_deg
   - float, deg
   - Arc of a circular trajectory, (0, 360], default 360 (the full circle).
 * - motion_error
   - string
   - ``"AMPLITUDE_M, PERIOD_M"`` (a sinusoid) or ``"random, RMS_M, CORRELATION_M[, SEED]"``: a
     horizontal deviation of the true track across the nominal one (docs/physics.md (J4)); the raw
     data keep both tracks (``focus --track nominal``).
 * - stop_and_hop
   - boolean
   - ``false`` (default): each echo is received where the antenna has moved to during it
     (docs/physics.md (J3)); ``true``: the stop-and-hop approximation, for comparison.
 * - ati_baseline
   - float, m
   - Along-track interferometry: 0 (default) for one channel; ``d`` > 0 adds a second channel
     whose phase centre trails the first by ``d`` along the flight direction (the two-way,
     monostatic-equivalent separation), rendered in the same call and written as
     ``raw_aft.npz`` / ``image_aft.npz`` with ``ati.npz``, ``dpca.npz`` and ``ati.png``
     (docs/physics.md (V6), (V7)). [0, 1000]; not with ``polarization = quad``.
 * - polarization
   - string
   - ``VV`` (default) or ``HH``: one co-polarised channel; ``HV`` or ``VH`` (receive,
     transmit): one cross-polarised channel; ``quad``: HH, HV, VH and VV from one trace, written as ``raw_XX.npz`` /
     ``image_XX.npz`` with ``pauli.png``. Every ray tube carries a Jones matrix (sbr
     ``polarimetry``), docs/physics.md, Polarimetry (P1)-(P8).
 * - receiver_trajectory, receiver_velocity, receiver_altitude, receiver_incidence_angle,
     receiver_heading, receiver_look_side, receiver_track_offset, receiver_arc_deg,
     receiver_orbit_inclination, receiver_orbit_direction, receiver_squint,
     receiver_antenna_length, receiver_antenna_height, receiver_antenna_gain_db
   - as the parameter without the prefix
   - Bistatic SAR: any of these puts the receiver on a platform of its own, flying its own
     track over the same pulse times, looking at the same scene centre; a receiver parameter
     not given takes the transmitter's value, and its antenna is isotropic unless
     ``receiver_antenna_length`` or ``receiver_antenna_height`` gives it a pattern. Traced and
     focused on the bistatic range sum (docs/physics.md (B1)-(B4));
     refused, naming the parameter, where the bistatic angle at the scene centre exceeds
     150 deg. Not with ``ati_baseline``.

Every parameter with a unit must lie in its valid range (:data:`sarmitsuba.core.valid_ranges.VALID_RANGES`,
docs/design.md section 4: frequency [1e6, 1e12] Hz, bandwidth [1e5, 1e11] Hz, velocity
[0.01, 1.2e4] m/s, altitude [1, 4e7] m, ...); a value outside raises ParameterError naming the
unit and, when it looks like another unit (9.6 for 9.6 GHz), the value meant.

The sensor holds parameters only: the tracer (:mod:`sarmitsuba.tracing.driver.trace`) shoots the rays.
Its ``sample_ray`` gives the optical view from the mid-aperture antenna toward the
scene centre, so ``mi.render`` can draw what the radar sees.
"""
from __future__ import annotations

import difflib
import math

import drjit as dr
import mitsuba as mi

from sarmitsuba.core.radar import ParameterError, RadarParameters
from sarmitsuba.core.receiver import RECEIVER_FIELDS, RECEIVER_PREFIX

#: Parameters that the sensor accepts besides the fields of RadarParameters.
EXTRA_PARAMETERS = ("aperture_length",)


class SarSensor(mi.Sensor):
    """Mitsuba sensor holding a :class:`sarmitsuba.core.radar.RadarParameters` (see module docstring)."""

    def __init__(self, props: mi.Properties) -> None:
        super().__init__(props)
        values = {}
        valid = set(RadarParameters.names()) | set(EXTRA_PARAMETERS) | {RECEIVER_PREFIX + f for f in RECEIVER_FIELDS}
        for key in props.keys():
            if key not in valid:
                close = difflib.get_close_matches(key, valid, n=1)
                hint = f" (did you mean {close[0]!r}?)" if close else ""
                raise ParameterError(
                    f"sar sensor: unknown parameter {key!r}{hint}; valid parameters: {', '.join(sorted(valid))}")
            value = props[key]
            values[key] = value if isinstance(value, (int, float, str)) else list(value)
        #: Parameters exactly as written in the scene (before defaults), for overrides.
        self.given = dict(values)
        self.parameters = RadarParameters.from_mapping(values)

    def _view(self):
        p = self.parameters
        center = mi.ScalarPoint3f(p.scene_center or (0.0, 0.0, 0.0))
        h, inc = math.radians(p.heading), math.radians(p.incidence_angle)
        sign = 1.0 if p.look_side == "right" else -1.0
        look = mi.ScalarVector3f(sign * math.sin(h), -sign * math.cos(h), 0.0)
        track = mi.ScalarVector3f(math.cos(h), math.sin(h), 0.0)
        origin = center - track * p.squint_offset - look * p.ground_range + mi.ScalarVector3f(0, 0, p.altitude)
        return origin, dr.normalize(center - origin), math.tan(0.5 * math.radians(20.0)) * (1.0 / math.cos(inc))

    def sample_ray(self, time, wavelength_sample, position_sample, aperture_sample, active=True):
        origin, forward, half = self._view()
        frame = mi.Frame3f(mi.Vector3f(forward))
        u = (position_sample.x * 2.0 - 1.0) * half
        v = (position_sample.y * 2.0 - 1.0) * half
        d = dr.normalize(frame.to_world(mi.Vector3f(u, v, 1.0)))
        return mi.Ray3f(mi.Point3f(origin), d, time, []), mi.Spectrum(1.0)

    def sample_ray_differential(self, time, wavelength_sample, position_sample, aperture_sample, active=True):
        ray, weight = self.sample_ray(time, wavelength_sample, position_sample, aperture_sample, active)
        return mi.RayDifferential3f(ray), weight

    def bbox(self):
        return mi.ScalarBoundingBox3f()

    def traverse(self, callback):
        pass

    def to_string(self):
        return f"SarSensor[{self.parameters}]"


mi.register_sensor("sar", lambda props: SarSensor(props))
