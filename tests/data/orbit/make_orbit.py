"""Writes ``synthetic_s1_poeorb.EOF``: a Sentinel-1-like precise orbit file (ESA Earth Explorer
XML, the layout of ``S1?_OPER_AUX_POEORB_*``) of a physically plausible pass over Munich, for
tests/test_orbit.py. Run from the repository root: ``python tests/data/orbit/make_orbit.py``.

The orbit: Sentinel-1's (693 km above the equator, inclination 98.18 deg, circular), descending,
propagated with two-body gravity plus the J2 oblateness term (WGS84 GM, EGM96 J2) by scipy's
DOP853 in an inertial frame that coincides with ECEF at the middle OSV, then turned into ECEF by
the Earth's rotation: ``r_ecef = Rz(-w t) r_i``, ``v_ecef = Rz(-w t) (v_i - w x r_i)``. 31 OSVs,
10 s apart (Sentinel-1's spacing), UTC times; TAI = UTC + 37 s; UT1 is written equal to UTC
(sarmitsuba does not read it). It imports nothing of sarmitsuba.

It also prints the scene point that the pass sees at closest approach, right-looking at about
35 deg incidence (zero Doppler at the middle OSV), which the tests use as ``geo_origin``.
"""
from __future__ import annotations

import datetime
import math
from pathlib import Path

import numpy as np
from pyproj import Transformer
from scipy.integrate import solve_ivp

GM = 3.986004418e14            # WGS84, m^3/s^2
J2 = 1.08262668e-3             # EGM96 normalised C20 * -sqrt(5)
RE = 6378137.0                 # WGS84 equatorial radius, m
OMEGA = 7.292115e-5            # WGS84 Earth rotation, rad/s
MID = datetime.datetime(2026, 6, 15, 5, 20, 0, tzinfo=datetime.timezone.utc)
STEP, HALF = 10.0, 15
LAT0, LON0 = 48.30, 17.95      # sub-satellite point at the middle OSV (deg)


def gravity(_t: float, y: np.ndarray) -> np.ndarray:
    r, v = y[:3], y[3:]
    d = np.linalg.norm(r)
    z2 = (r[2] / d) ** 2
    k = 1.5 * J2 * GM * RE ** 2 / d ** 5
    a = -GM * r / d ** 3 + k * r * np.array([5 * z2 - 1, 5 * z2 - 1, 5 * z2 - 3])
    return np.concatenate([v, a])


def main() -> None:
    to_ecef = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=False)
    r0 = np.array(to_ecef.transform(LAT0, LON0, 693e3))
    up = r0 / np.linalg.norm(r0)
    east = np.cross([0.0, 0.0, 1.0], up)
    east /= np.linalg.norm(east)
    north = np.cross(up, east)
    inc = math.radians(98.18)
    lat = math.asin(up[2])
    azimuth = math.pi - math.asin(math.cos(inc) / math.cos(lat))   # descending, from north
    speed = math.sqrt(GM / np.linalg.norm(r0))
    v0 = speed * (math.sin(azimuth) * east + math.cos(azimuth) * north)   # inertial (= ECEF axes at t = 0)
    t = STEP * np.arange(-HALF, HALF + 1)
    y0 = np.concatenate([r0, v0])
    fwd = solve_ivp(gravity, (0, t[-1]), y0, t_eval=t[HALF:], method="DOP853", rtol=1e-13, atol=1e-6)
    back = solve_ivp(gravity, (0, t[0]), y0, t_eval=t[HALF::-1], method="DOP853", rtol=1e-13, atol=1e-6)
    states = np.concatenate([back.y[:, ::-1][:, :-1], fwd.y], axis=1).T
    theta = -OMEGA * t
    c, s = np.cos(theta), np.sin(theta)

    def rz(x: np.ndarray) -> np.ndarray:
        return np.stack([c * x[:, 0] - s * x[:, 1], s * x[:, 0] + c * x[:, 1], x[:, 2]], axis=1)
    pos = rz(states[:, :3])
    vel = rz(states[:, 3:] - np.cross([0.0, 0.0, OMEGA], states[:, :3]))
    lines = ['<?xml version="1.0" encoding="UTF-8"?>',
             '<Earth_Explorer_File>',
             '  <Earth_Explorer_Header>',
             '    <Fixed_Header>',
             '      <File_Name>synthetic_s1_poeorb</File_Name>',
             '      <File_Description>Precise Orbit Ephemerides (POE) Orbit File (synthetic, two-body + J2)'
             '</File_Description>',
             '      <Notes>Written by tests/data/orbit/make_orbit.py for sarmitsuba tests</Notes>',
             '      <Mission>Sentinel-1A</Mission>',
             '      <File_Class>TEST</File_Class>',
             '      <File_Type>AUX_POEORB</File_Type>',
             '      <Validity_Period>',
             f'        <Validity_Start>UTC={_utc(MID + datetime.timedelta(seconds=t[0]))}</Validity_Start>',
             f'        <Validity_Stop>UTC={_utc(MID + datetime.timedelta(seconds=t[-1]))}</Validity_Stop>',
             '      </Validity_Period>',
             '      <File_Version>0001</File_Version>',
             '      <Source><System>make_orbit.py</System><Creator>sarmitsuba</Creator>'
             '<Creator_Version>1</Creator_Version><Creation_Date>UTC=2026-06-16T00:00:00</Creation_Date></Source>',
             '    </Fixed_Header>',
             '    <Variable_Header>',
             '      <Ref_Frame>EARTH_FIXED</Ref_Frame>',
             '      <Time_Reference>UTC</Time_Reference>',
             '    </Variable_Header>',
             '  </Earth_Explorer_Header>',
             '  <Data_Block type="xml">',
             f'    <List_of_OSVs count="{t.size}">']
    for k in range(t.size):
        when = MID + datetime.timedelta(seconds=float(t[k]))
        lines += ['      <OSV>',
                  f'        <TAI>TAI={_utc(when + datetime.timedelta(seconds=37))}</TAI>',
                  f'        <UTC>UTC={_utc(when)}</UTC>',
                  f'        <UT1>UT1={_utc(when)}</UT1>',
                  '        <Absolute_Orbit>+64321</Absolute_Orbit>']
        lines += [f'        <{n} unit="m">{pos[k, j]:.6f}</{n}>' for j, n in enumerate("XYZ")]
        lines += [f'        <V{n} unit="m/s">{vel[k, j]:.6f}</V{n}>' for j, n in enumerate("XYZ")]
        lines += ['        <Quality>NOMINAL</Quality>', '      </OSV>']
    lines += ['    </List_of_OSVs>', '  </Data_Block>', '</Earth_Explorer_File>', '']
    out = Path(__file__).with_name("synthetic_s1_poeorb.EOF")
    out.write_text("\n".join(lines))
    # the scene: right of the track, 35 deg incidence, zero Doppler at the middle OSV
    p, v = pos[HALF], vel[HALF]
    right = np.cross(v, p)
    right /= np.linalg.norm(right)
    to_llh = Transformer.from_crs("EPSG:4978", "EPSG:4979", always_xy=False)
    best = None
    for ground in np.linspace(300e3, 700e3, 40001):     # along the zero-Doppler great circle, right side
        r = np.linalg.norm(p)
        angle = ground / 6.371e6
        q = (math.cos(angle) * p / r + math.sin(angle) * right)
        la, lo, _ = to_llh.transform(*(q * 6.366e6))
        x = np.array(to_ecef.transform(la, lo, 0.0))
        u = (p - x) / np.linalg.norm(p - x)
        n = np.array(to_ecef.transform(la, lo, 1.0)) - x
        incidence = math.degrees(math.acos(u @ n / np.linalg.norm(n)))
        if best is None or abs(incidence - 35.0) < abs(best[0] - 35.0):
            best = (incidence, la, lo)
    print(f"wrote {out}; scene at 35 deg incidence: geo_origin = {best[1]:.6f}, {best[2]:.6f}, 0 "
          f"(incidence {best[0]:.4f} deg)")


def _utc(when: datetime.datetime) -> str:
    return when.strftime("%Y-%m-%dT%H:%M:%S.%f")


if __name__ == "__main__":
    main()
