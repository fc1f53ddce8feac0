"""Absolute time (issue 55, item 1; docs/physics.md (J5)): a trajectory file whose times say they
are UTC (a ``utc`` column, an ``# epoch`` line) or GPS seconds (``# time_scale = gps``) fixes the
collection's start, and every product refers to the same instant.

Acceptance: every CPHD pulse time (``CollectionStart + TxTime``, read with sarkit) is the time of
the CSV row it came from within 1 us, and its ``TxPos`` that row's position within 1 mm; the
SICD's ``CollectStart`` (sarkit) and the GeoTIFF's ``ACQUISITION_START_TIME`` (rasterio) are the
same instant. The truth is the file itself: ECEF rows compared with ECEF PVPs, nothing of
sarmitsuba's reader involved.
"""
from __future__ import annotations

import datetime
import math

import numpy as np
import pytest
from pyproj import Transformer

from sarmitsuba.core import trajectory as tj
from sarmitsuba.core.radar import ParameterError
from sarmitsuba.core.trajectory import TrajectoryError, read_state_vectors

sarkit_cphd = pytest.importorskip("sarkit.cphd")

ORIGIN = (35.6812, 139.7671, 40.0)          # (lat, lon, h): Tokyo station, where east and north both matter
FIRST = datetime.datetime(2025, 3, 1, 12, 0, 7, 123457, tzinfo=datetime.timezone.utc)
PRF, ROWS, PULSES = 100.0, 61, 41            # one row per pulse, the pulses centred: pulse i is row i + 10
SKIP = (ROWS - PULSES) // 2


def _ecef_track() -> tuple[list[datetime.datetime], np.ndarray, np.ndarray]:
    """A straight level airborne track (built-in geometry: 1000 m up, 45 deg, heading 0, the
    sensor on +y) as UTC times, ECEF positions and velocities, converted with PROJ's own
    topocentric pipeline (the truth the test writes, not sarmitsuba's)."""
    lat, lon, h = ORIGIN
    enu = np.stack([np.linspace(-30.0, 30.0, ROWS), np.full(ROWS, 1000.0), np.full(ROWS, 1000.0)], axis=1)
    pipe = Transformer.from_pipeline(f"+proj=pipeline +step +proj=topocentric +ellps=WGS84 +lat_0={lat} "
                                     f"+lon_0={lon} +h_0={h}")
    x, y, z = pipe.transform(enu[:, 0], enu[:, 1], enu[:, 2], direction="INVERSE")
    ecef = np.stack([x, y, z], axis=1)
    lam = math.radians(lon)
    east = np.array([-math.sin(lam), math.cos(lam), 0.0])          # the ENU axes in ECEF (closed form)
    velocity = np.tile(100.0 * east, (ROWS, 1))
    times = [FIRST + datetime.timedelta(microseconds=10_000 * i) for i in range(ROWS)]
    return times, ecef, velocity


def _write_csv(path, times, ecef, velocity, clock="utc"):
    lines = ["# frame = ecef"]
    if clock == "gps":
        lines.append("# time_scale = gps")
    lines.append(("utc" if clock == "utc" else "time_s") + ",x_m,y_m,z_m,vx_mps,vy_mps,vz_mps")
    for t, p, v in zip(times, ecef, velocity):
        stamp = t.isoformat().replace("+00:00", "Z") if clock == "utc" else _gps_seconds(t)
        lines.append(f"{stamp},{p[0]:.6f},{p[1]:.6f},{p[2]:.6f},{v[0]:.6f},{v[1]:.6f},{v[2]:.6f}")
    path.write_text("\n".join(lines) + "\n")
    return path


def _gps_seconds(t: datetime.datetime) -> str:
    """GPS seconds since 1980-01-06T00:00:00Z of a 2025 UTC instant: elapsed UTC seconds + 18 leap
    seconds (GPS - UTC = 18 s since 2017-01-01, IERS Bulletin C), exact decimal text."""
    delta = t - datetime.datetime(1980, 1, 6, tzinfo=datetime.timezone.utc)
    micro = (delta.days * 86400 + delta.seconds + 18) * 1_000_000 + delta.microseconds
    return f"{micro // 1_000_000}.{micro % 1_000_000:06d}"


def _cphd_of(tmp_path, csv, n_pulses=PULSES):
    from sarmitsuba.formats.cphd import write_cphd
    from sarmitsuba.pipeline import simulate
    sim = simulate("trihedral", sensor_overrides={"trajectory": str(csv), "geo_origin": ", ".join(map(str, ORIGIN)),
                                                  "prf": PRF, "n_pulses": n_pulses}, focuser="bp", image_size=(24, 24))
    path = write_cphd(sim.raw, tmp_path / "raw.cphd")
    with open(path, "rb") as f, sarkit_cphd.Reader(f) as reader:
        _, pvp = reader.read_channel("1")
        start = reader.metadata.xmltree.findtext("{*}Global/{*}Timeline/{*}CollectionStart")
    return sim, pvp, start


def _pulse_utc(start: str, tx_time: np.ndarray) -> list[datetime.datetime]:
    base = datetime.datetime.fromisoformat(start.replace("Z", "+00:00"))
    if base.tzinfo is None:
        base = base.replace(tzinfo=datetime.timezone.utc)
    return [base + datetime.timedelta(seconds=float(t)) for t in tx_time]


@pytest.mark.filterwarnings("ignore::UserWarning")
@pytest.mark.parametrize("clock", ["utc", "gps"])
def test_every_cphd_pulse_is_its_csv_row_in_time_and_place(tmp_path, clock):
    """Catches a time offset: the CPHD clock starting at the first pulse with CollectionStart not
    moved with it (1.5 ms in issue 55), the re-basing of the CSV clock dropping its fraction,
    GPS time taken as UTC (18 s), and TxPos not the file's ECEF row (a frame or axis error).
    Row times off the whole microsecond grid of the epoch (...123457) test the microseconds end to
    end; the first pulse is row 10, not the file's first row (where the epoch of the file and that
    of the collection differ by 0.1 s)."""
    times, ecef, velocity = _ecef_track()
    csv = _write_csv(tmp_path / "track.csv", times, ecef, velocity, clock)
    _, pvp, start = _cphd_of(tmp_path, csv)
    got = _pulse_utc(start, pvp["TxTime"])
    rows = slice(SKIP, SKIP + PULSES)
    error_us = [abs((g - t) / datetime.timedelta(microseconds=1)) for g, t in zip(got, times[rows])]
    assert len(got) == PULSES and max(error_us) < 1.0, max(error_us)
    assert np.max(np.linalg.norm(pvp["TxPos"] - ecef[rows], axis=1)) < 1e-3


@pytest.mark.filterwarnings("ignore::UserWarning")
def test_sicd_and_geotiff_start_at_the_cphd_collection_start(tmp_path):
    """Catches a product that keeps its own clock (the render's moment, or the old default) while
    the CPHD follows the file (all rows flown: the first pulse is the first row): SICD CollectStart (sarkit) and the GeoTIFF's ACQUISITION_START_TIME
    (rasterio) must be the first row's UTC time too."""
    import rasterio
    import sarkit.sicd as sksicd
    from sarmitsuba.formats.geotiff import write_geotiff
    from sarmitsuba.formats.sicd import write_sicd
    times, ecef, velocity = _ecef_track()
    sim, _, start = _cphd_of(tmp_path, _write_csv(tmp_path / "track.csv", times, ecef, velocity), ROWS)
    sicd = write_sicd(sim.image, tmp_path / "image.nitf", sim.raw)
    with open(sicd, "rb") as f, sksicd.NitfReader(f) as reader:
        collect = reader.metadata.xmltree.findtext("{*}Timeline/{*}CollectStart")
    tif = write_geotiff(sim.image, tmp_path / "image.tif")
    with rasterio.open(tif) as ds:
        tag = ds.tags()["ACQUISITION_START_TIME"]
    for text in (start, collect, tag):
        when = datetime.datetime.fromisoformat(text.replace("Z", "+00:00"))
        when = when if when.tzinfo else when.replace(tzinfo=datetime.timezone.utc)
        assert abs((when - times[0]) / datetime.timedelta(microseconds=1)) < 1.0, (text, times[0])


def test_an_epoch_line_sets_the_clock_of_relative_seconds(tmp_path):
    """Catches the epoch ignored, or read in the machine's zone: ``# epoch = ...+02:00`` with
    time_s = 2.5 is 08:00:02.5 UTC."""
    path = tmp_path / "t.csv"
    path.write_text("# epoch = 2026-11-24T10:00:00+02:00\ntime_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps\n"
                    "2.5,0,0,1000,100,0,0\n3.5,100,0,1000,100,0,0\n")
    states = read_state_vectors(path)
    assert states.utc(states.time[0]) == datetime.datetime(2026, 11, 24, 8, 0, 2, 500000, tzinfo=datetime.timezone.utc)


def test_gps_seconds_across_a_leap_second_or_past_the_table_are_refused(tmp_path):
    """Catches a silent 1 s error: GPS seconds spanning 2017-01-01 (where UTC repeats a second), or
    later than the leap-second table knows, must be refused with the fix (give UTC)."""
    path = tmp_path / "t.csv"
    leap = 1167264017.0                      # GPS seconds of 2017-01-01T00:00:00 UTC (+18 s after it)
    path.write_text("# time_scale = gps\ntime_s,x_m,y_m,z_m\n" +
                    "".join(f"{leap - 2 + k},{k},0,1000\n" for k in range(4)))
    with pytest.raises(TrajectoryError, match="leap second"):
        read_state_vectors(path)
    path.write_text("# time_scale = gps\ntime_s,x_m,y_m,z_m\n" +
                    "".join(f"{2.0e9 + k},{k},0,1000\n" for k in range(4)))
    with pytest.raises(TrajectoryError, match="utc column"):
        read_state_vectors(path)


@pytest.mark.parametrize("text, words", [
    ("# frame = ecef\n# epoch = 2026-11-24T10:00:00\ntime_s,x_m,y_m,z_m\n", ["line epoch", "no UTC offset"]),
    ("# frame = ecf\ntime_s,x_m,y_m,z_m\n", ["frame", "'ecf'", "scene, ecef"]),
    ("# clock = gps\ntime_s,x_m,y_m,z_m\n", ["line 1", "no known header line", "# time_scale = gps"]),
    ("utc,x_m,y_m,z_m\n2026-11-24T10:00:00Z,0,0,1\nyesterday,1,0,1\n", ["line 3", "column utc", "ISO 8601"]),
])
def test_a_malformed_clock_names_the_file_line_and_fix(tmp_path, text, words):
    """Catches a clock silently taken as relative or local: each mistake is refused naming the file,
    the line or header key, and the form to use."""
    path = tmp_path / "nav.csv"
    path.write_text(text + "".join(f"{k},{k},0,1000\n" for k in range(4)) if "utc," not in text else text)
    with pytest.raises(TrajectoryError) as info:
        read_state_vectors(path)
    assert "nav.csv" in str(info.value) and all(w in str(info.value) for w in words), str(info.value)


def test_collection_start_and_an_absolute_track_may_not_both_set_the_time():
    """Catches a given collection_start silently overriding (or overridden by) the file's clock."""
    from sarmitsuba.core.radar import RadarParameters
    states = tj.StateVectors([0.0, 1.0], [[0, 0, 1000], [100, 0, 1000]], [[100, 0, 0]] * 2, "nav.csv",
                             epoch="2026-11-24T10:00:00Z")
    with pytest.raises(ParameterError, match="remove collection_start"):
        RadarParameters(trajectory=states, collection_start="2026-11-24T10:00:00Z")


def test_gps_seconds_of_2026_are_read_with_a_warning_and_18_leap_seconds(tmp_path):
    """GPS seconds past the leap-second table's last bulletin (end of 2025) but within its year of
    grace: converted with GPS - UTC = 18 s and a LeapSecondWarning. The oracle is the calendar:
    2026-06-01T00:00:00 UTC is the days since 1980-01-06 plus 18 s in GPS seconds. Catches GPS
    files of the current year refused (they were), and a warning-free conversion."""
    utc = datetime.datetime(2026, 6, 1, tzinfo=datetime.timezone.utc)
    gps = (utc - datetime.datetime(1980, 1, 6, tzinfo=datetime.timezone.utc)).total_seconds() + 18.0
    path = tmp_path / "t.csv"
    path.write_text("# time_scale = gps\ntime_s,x_m,y_m,z_m\n" + "".join(f"{gps + k},{k},0,1000\n" for k in range(4)))
    from sarmitsuba.core.state_vectors import LeapSecondWarning
    with pytest.warns(LeapSecondWarning, match="18 s"):
        states = read_state_vectors(path)
    assert states.utc(states.time[0]) == utc


@pytest.mark.parametrize("stamp", ["nan", "inf", "1e999999999", "1e20", "-1e12"])
def test_times_that_name_no_date_are_refused_by_line(tmp_path, stamp):
    """A first time of NaN, infinity or 1e20 s from the epoch (and negative GPS seconds): refused as
    a TrajectoryError naming the line. Catches the tracebacks (ValueError, OverflowError) and the
    hang (int() of a billion-digit Decimal) these gave."""
    for header in ("# epoch = 2026-11-24T10:00:00Z", "# time_scale = gps"):
        path = tmp_path / "t.csv"
        path.write_text(f"{header}\ntime_s,x_m,y_m,z_m\n{stamp},0,0,1000\n" +
                        "".join(f"{1.0e9 + k},{k},0,1000\n" for k in range(1, 4)))
        with pytest.raises(TrajectoryError, match="line 3, column time_s"):
            read_state_vectors(path)


def test_utc_times_across_a_leap_second_are_refused(tmp_path):
    """UTC rows spanning 2016-12-31T23:59:60, and a row at 23:59:60 itself: refused naming the leap
    second. Catches UTC differences taken as elapsed seconds across it (one physical second missing
    between two rows: the interpolant 7.6 km off for an orbit) and '23:59:60' called 'not ISO 8601'."""
    path = tmp_path / "t.csv"
    rows = ["2016-12-31T23:59:58Z", "2016-12-31T23:59:59Z", "2017-01-01T00:00:00Z", "2017-01-01T00:00:01Z"]
    path.write_text("utc,x_m,y_m,z_m\n" + "".join(f"{t},{k},0,1000\n" for k, t in enumerate(rows)))
    with pytest.raises(TrajectoryError, match="span the leap second before 2017-01-01"):
        read_state_vectors(path)
    rows[2] = "2016-12-31T23:59:60Z"
    path.write_text("utc,x_m,y_m,z_m\n" + "".join(f"{t},{k},0,1000\n" for k, t in enumerate(rows)))
    with pytest.raises(TrajectoryError, match="line 4, column utc.*is a leap second"):
        read_state_vectors(path)


def test_utc_times_ending_or_starting_at_a_leap_seconds_midnight(tmp_path):
    """Rows ending exactly at 2017-01-01T00:00:00Z: their last interval holds the leap second
    23:59:60 (two physical seconds for one of UTC), refused; rows starting there: no leap second
    between them, accepted, and their times are UTC's own. Catches the span test made strict
    (``first < day < last``), which accepts the first file and puts its last state 1 s, 7.6 km of
    an orbit, off."""
    path = tmp_path / "t.csv"
    ending = ["2016-12-31T23:59:57Z", "2016-12-31T23:59:58Z", "2016-12-31T23:59:59Z", "2017-01-01T00:00:00Z"]
    path.write_text("utc,x_m,y_m,z_m\n" + "".join(f"{t},{k},0,1000\n" for k, t in enumerate(ending)))
    with pytest.raises(TrajectoryError, match="span the leap second before 2017-01-01"):
        read_state_vectors(path)
    starting = ["2017-01-01T00:00:00Z", "2017-01-01T00:00:01Z", "2017-01-01T00:00:02Z", "2017-01-01T00:00:03Z"]
    path.write_text("utc,x_m,y_m,z_m\n" + "".join(f"{t},{k},0,1000\n" for k, t in enumerate(starting)))
    states = read_state_vectors(path)
    assert np.allclose(np.diff(states.time), 1.0, rtol=0, atol=1e-9)


def test_nanosecond_utc_digits_round_to_the_microsecond(tmp_path):
    """``...07.1234567Z`` is 07.123457 (rounded), ``...07.9999996Z`` is 08.000000. Catches the digits
    beyond the microsecond cut, as ``datetime.fromisoformat`` cuts them (a bias of up to 1 us, 7.6 mm
    at orbital speed)."""
    from sarmitsuba.core.state_vectors import utc_instant
    assert utc_instant("2026-11-24T10:00:07.1234567Z", "t").microsecond == 123457
    assert utc_instant("2026-11-24T10:00:07.9999996Z", "t") == datetime.datetime(2026, 11, 24, 10, 0, 8,
                                                                                   tzinfo=datetime.timezone.utc)


def test_a_spreadsheets_byte_order_mark_is_read(tmp_path):
    """A CSV saved with a UTF-8 byte-order mark (Excel's 'CSV UTF-8'): read as the same states.
    Catches the header refused as the unknown column '\\ufefftime_s'."""
    path = tmp_path / "t.csv"
    text = "time_s,x_m,y_m,z_m\n" + "".join(f"{k},{10 * k},0,1000\n" for k in range(4))
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    assert np.array_equal(read_state_vectors(path).position[:, 0], [0.0, 10.0, 20.0, 30.0])
