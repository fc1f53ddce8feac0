"""Frequency-domain (FX) CPHD of analytic point-target data: the closed form, the round trip,
bistatic files, other tools' window layouts, and the refusals.

The data come from :mod:`sarmitsuba.analysis.synthetic`: range-compressed echoes
``a sinc(B (t - L/c)) exp(-j 2 pi fc L/c)``. Their spectrum along fast time is known in closed form:
the DFT of the samples of ``sinc(B t)`` is ``fs / B`` over the band, so a point whose two-way
delay exceeds the SRP's by ``dTOA`` reads, in a CPHD with ``SGN = -1`` compensated to the SRP,

    X(fx) = a (fs / B) exp(-j 2 pi fx dTOA)           (|fx - fc| < B / 2)

(NGA.STND.0068-1, CPHD 1.1.0: the FX-domain signal model; phase-flat for a point at the SRP). The
expected values are formed here from the file's own PVPs (ECEF positions, SC0, SCSS) and the
targets' positions, with no call into the code under test.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

sarkit_cphd = pytest.importorskip("sarkit.cphd")

from sarmitsuba.analysis.synthetic import PointTarget, simulate_point_targets, straight_track  # noqa: E402
from sarmitsuba.core import georef  # noqa: E402
from sarmitsuba.core.constants import SPEED_OF_LIGHT as C  # noqa: E402
from sarmitsuba.formats.cphd import CphdError, check_cphd, read_cphd, write_cphd  # noqa: E402

REF = georef.GeoReference(-33.9, 151.2, 40.0)
FC, B, FS, PRF, H = 9.6e9, 150e6, 180e6, 300.0, 3000.0


def point_data(incidence_deg: float, targets, n_pulses: int = 24, rx_offset=None, direction=(1.0, 0.0, 0.0)):
    """Range-compressed echoes of ``targets`` [(position, amplitude)] from a level track along ``direction``
    (+x) at height H, its middle H tan(theta) north of the SRP (the origin); a receiver ``rx_offset`` [m]
    away from the transmitter makes them bistatic. The fast-time window holds every echo with 96 samples
    to spare on either side."""
    track = straight_track(n_pulses, PRF, 100.0, center=(0.0, H * np.tan(np.radians(incidence_deg)), H),
                           direction=direction)
    rx = track.position if rx_offset is None else track.position + np.asarray(rx_offset, float)
    points = [PointTarget(np.asarray(p, float), a) for p, a in targets]
    lengths = [np.linalg.norm(track.position - p.position, axis=1) + np.linalg.norm(rx - p.position, axis=1)
               for p in points]
    t0 = min(x.min() for x in lengths) / C - 96 / FS
    n = int((max(x.max() for x in lengths) / C + 96 / FS - t0) * FS) + 1
    return simulate_point_targets(points, track.position, FC, B, FS, t0, n, prf=PRF, velocity=track.velocity,
                                  pulse_length=5e-6, pulse_time=track.pulse_time, rx_position=rx,
                                  metadata={"radar": {"scene_center": [0.0, 0.0, 0.0]}})


def read_parts(path):
    """(signal, pvp, xml tree) of channel 1, straight from sarkit."""
    with open(path, "rb") as f, sarkit_cphd.Reader(f) as reader:
        signal, pvp = reader.read_channel("1")
        return signal, pvp, reader.metadata.xmltree


def delta_toa(pvp, point_enu):
    """float64 [n_vectors] s: the point's two-way delay minus the SRP's, from the file's ECEF PVPs."""
    x = georef.enu_to_ecef(np.asarray(point_enu, float)[None], REF)[0]
    leg = np.linalg.norm(pvp["TxPos"] - x, axis=1) + np.linalg.norm(pvp["RcvPos"] - x, axis=1)
    srp = np.linalg.norm(pvp["TxPos"] - pvp["SRPPos"], axis=1) + np.linalg.norm(pvp["RcvPos"] - pvp["SRPPos"], axis=1)
    return (leg - srp) / C


@pytest.mark.parametrize("incidence", [30.0, 60.0])
@pytest.mark.parametrize("where", [(0.0, 0.0, 0.0), (6.5, -9.0, 1.5)])
def test_fx_samples_are_the_closed_form_spectrum(tmp_path, incidence, where):
    """A point of amplitude a reads X = a (fs / B) exp(-j 2 pi fx dTOA) over the band (phase-flat at the SRP),
    with fx = SC0 + n SCSS and dTOA from the file's PVPs. Bug caught: the carrier compensation
    exp(+j 2 pi fc tau_srp) left out, or the fast-time origin's ramp exp(-j 2 pi f (t0 - tau_srp)) with the
    wrong sign (the phase then runs across the band); a spectrum not fft-shifted (the bins out of order);
    SC0 written as the band's lower edge instead of the first bin (fx mislabelled by 15 MHz)."""
    a = 0.7 * np.exp(0.9j)
    raw = point_data(incidence, [(where, a)])
    path = write_cphd(raw, tmp_path / "fx.cphd", REF, domain="fx")
    signal, pvp, tree = read_parts(path)
    assert tree.findtext("{*}Global/{*}DomainType") == "FX" and tree.findtext("{*}Global/{*}SGN") == "-1"
    fx = pvp["SC0"][:, None] + np.arange(signal.shape[1])[None, :] * pvp["SCSS"][:, None]
    expected = a * FS / B * np.exp(-2j * np.pi * fx * delta_toa(pvp, where)[:, None])
    band = np.abs(fx - FC) < 0.4 * B          # away from the band edges' Gibbs ripple
    error = np.abs(signal - expected)[band].max() / (abs(a) * FS / B)
    assert error < 0.01, error
    assert np.abs(signal[np.abs(fx - FC) > 0.55 * B]).max() < 0.05 * abs(a) * FS / B     # nothing outside the band


@pytest.mark.parametrize("incidence", [30.0, 60.0])
def test_fx_file_reads_back_the_fast_time_samples(tmp_path, incidence):
    """write_cphd(domain="fx") then read_cphd gives the RawData back: samples within float32 rounding, the
    fast-time axis, carrier, sampling rate and band exactly. Bug caught: the inverse transform taking the
    first samples of the wrong end, a lost zero padding (the window folded), the carrier phase put back
    with the wrong sign."""
    raw = point_data(incidence, [((0.0, 0.0, 0.0), 1.0), ((-7.0, 11.0, 0.0), 0.4j), ((3.0, -20.0, 2.0), -0.8)])
    back = read_cphd(write_cphd(raw, tmp_path / "fx.cphd", REF, domain="fx"))
    np.testing.assert_allclose(back.data, raw.data, rtol=0, atol=2e-6 * np.abs(raw.data).max())
    np.testing.assert_allclose(back.fast_time, raw.fast_time, rtol=0, atol=1e-15)
    assert (back.fc, back.fs, back.bandwidth, back.n_samples) == (raw.fc, raw.fs, raw.bandwidth, raw.n_samples)
    np.testing.assert_allclose(back.tx_position, raw.tx_position, atol=1e-3)


def test_fx_sampling_and_band_are_what_the_standard_asks(tmp_path):
    """FX_OSR = 1 / (SCSS (TOA2 - TOA1)) at least 1.25 (the checks want 1.2), FX1 and FX2 the transmitted band's
    edges inside the sampled bins, FxC and FxBW from them, SCSS = fs / M. Bug caught: no zero padding
    (FX_OSR = N / (N - 1), which sarkit fails), FX1/FX2 set to the sampled span instead of the band."""
    raw = point_data(45.0, [((0.0, 0.0, 0.0), 1.0)], direction=(1.0, -0.3, 0.0))    # TOA1, TOA2 vary
    path = write_cphd(raw, tmp_path / "fx.cphd", REF, domain="fx")
    signal, pvp, tree = read_parts(path)
    assert check_cphd(path) == []
    osr = 1.0 / (pvp["SCSS"] * (pvp["TOA2"] - pvp["TOA1"]))
    assert osr.min() >= 1.25
    np.testing.assert_allclose(pvp["FX1"], FC - B / 2, rtol=1e-15)
    np.testing.assert_allclose(pvp["FX2"], FC + B / 2, rtol=1e-15)
    last = pvp["SC0"] + (signal.shape[1] - 1) * pvp["SCSS"]
    assert np.all(pvp["SC0"] <= pvp["FX1"]) and np.all(last >= pvp["FX2"])
    np.testing.assert_allclose(pvp["SCSS"] * signal.shape[1], FS, rtol=1e-12)     # all M bins of the sampled band
    assert float(tree.findtext("{*}Channel/{*}Parameters/{*}FxC")) == FC
    assert float(tree.findtext("{*}Channel/{*}Parameters/{*}FxBW")) == B
    # the valid delays relative to the SRP: the first and last fast-time samples
    tau = np.linalg.norm(raw.tx_position, axis=1) * 2 / C
    np.testing.assert_allclose(pvp["TOA1"], raw.fast_time[0] - tau, rtol=0, atol=1e-15)
    np.testing.assert_allclose(pvp["TOA2"], raw.fast_time[-1] - tau, rtol=0, atol=1e-15)


def test_bistatic_fx_is_a_bistatic_collection_with_the_closed_form(tmp_path):
    """A receiver 400 m east and 200 m higher: CollectType BISTATIC, sarkit's check passes, the samples are
    the closed form with dTOA over both legs, and the file reads back. Bug caught: the SRP delay of one leg
    doubled (monostatic) in the FX compensation."""
    target = (5.0, -4.0, 0.0)
    raw = point_data(40.0, [(target, 1.0)], rx_offset=(400.0, 0.0, 200.0))
    path = write_cphd(raw, tmp_path / "bi.cphd", REF, domain="fx")
    assert check_cphd(path) == []
    signal, pvp, tree = read_parts(path)
    assert tree.findtext("{*}CollectionID/{*}CollectType") == "BISTATIC"
    fx = pvp["SC0"][:, None] + np.arange(signal.shape[1])[None, :] * pvp["SCSS"][:, None]
    expected = FS / B * np.exp(-2j * np.pi * fx * delta_toa(pvp, target)[:, None])
    band = np.abs(fx - FC) < 0.4 * B
    assert np.abs(signal - expected)[band].max() < 0.01 * FS / B
    back = read_cphd(path)
    np.testing.assert_allclose(back.data, raw.data, rtol=0, atol=2e-6 * np.abs(raw.data).max())
    np.testing.assert_allclose(back.rx_position, raw.rx_position, atol=1e-3)


def test_a_window_fixed_to_the_srp_reads_onto_one_fast_time_axis(tmp_path):
    """Vendors' spotlight files keep one TOA window relative to the SRP (TOAFixed), so their vectors' windows
    start at different absolute delays, off any common sample grid. Such a file (ours, its TOA1/TOA2 set to
    the window every vector holds) reads onto one axis: each vector's samples match the analytic echo
    there (-30 dB: the sinc's truncation), zero outside its window. Bug caught: a vector placed at a
    whole-sample offset without its fractional phase ramp, or at the wrong end of the axis."""
    raw = point_data(50.0, [((2.0, -3.0, 0.0), 1.0)], n_pulses=64, direction=(1.0, -0.3, 0.0))   # closing in
    path = write_cphd(raw, tmp_path / "fx.cphd", REF, domain="fx")
    with open(path, "rb") as f, sarkit_cphd.Reader(f) as reader:
        metadata = reader.metadata
        signal, pvp = reader.read_channel("1")
    pvp["TOA1"], pvp["TOA2"] = pvp["TOA1"].max() + 20 / FS, pvp["TOA2"].min() - 20 / FS
    fixed = tmp_path / "fixed.cphd"
    with open(fixed, "wb") as f, sarkit_cphd.Writer(f, metadata) as writer:
        writer.write_signal("1", signal)
        writer.write_pvp("1", pvp)
    back = read_cphd(fixed)
    assert back.fs == FS and back.fc == FC
    truth = simulate_point_targets([PointTarget(np.array([2.0, -3.0, 0.0]), 1.0)], raw.tx_position, FC, B, FS,
                                   float(back.fast_time[0]), back.n_samples, prf=PRF, velocity=raw.velocity,
                                   pulse_length=5e-6, pulse_time=raw.pulse_time).data
    dtoa = back.fast_time[None, :] - 2 * np.linalg.norm(raw.tx_position, axis=1)[:, None] / C
    # a tenth of a sample from the window's edges either way: the samples surely in, surely out
    inside = (dtoa >= pvp["TOA1"][:, None] + 0.1 / FS) & (dtoa <= pvp["TOA2"][:, None] - 0.1 / FS)
    outside = (dtoa < pvp["TOA1"][:, None] - 0.1 / FS) | (dtoa > pvp["TOA2"][:, None] + 0.1 / FS)
    assert np.ptp((dtoa[:, 0] - pvp["TOA1"]) * FS % 1.0) > 0.5         # the vectors do not share a sample grid
    assert np.all(back.data[outside] == 0) and inside.sum() > 0.9 * (~outside).sum()
    error = np.linalg.norm(back.data[inside] - truth[inside]) / np.linalg.norm(truth[inside])
    assert 20 * np.log10(error) < -30.0


def test_fx_of_chirped_data_is_refused_naming_the_file(tmp_path):
    """Chirped echoes (sensor output=raw) are no deramped phase history: one CphdError naming the file and the
    fix, nothing written. Bug caught: the check dropped (an FX file of chirps, which no FX reader focuses)."""
    raw = point_data(45.0, [((0.0, 0.0, 0.0), 1.0)])
    chirped = dataclasses.replace(raw, range_compressed=False)
    with pytest.raises(CphdError, match=r"raw\.cphd.*chirped.*TOA domain"):
        write_cphd(chirped, tmp_path / "raw.cphd", REF, domain="fx")
    with pytest.raises(CphdError, match=r"domain = 'xf'.*toa and fx"):
        write_cphd(raw, tmp_path / "raw.cphd", REF, domain="xf")
    assert list(tmp_path.iterdir()) == []
