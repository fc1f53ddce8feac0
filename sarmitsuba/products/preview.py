"""Optical preview of an acquisition: is the sensor looking where I think? (before any tracing).

:func:`render_preview` renders the scene with Mitsuba's own path tracer (``path``
integrator, in the active ``*_mono`` variant, hence grey) from two perspective cameras
and draws the acquisition on top with matplotlib, projecting 3-D points to pixels through
the cameras' own projection (``Sensor.sample_direction``):

* left, **overview**: the flight track (every pulse position), the antenna at mid-aperture,
  its nadir, the beam cone (antenna to the four corners of the beam footprint at
  mid-aperture), the footprint swept along the track, and the imaged area (the focusing
  grid of :func:`sarmitsuba.pipeline.image_grid`);
* right, **scene**: the scene seen from the radar's side (the mid-aperture line of sight,
  turned 30 degrees about the vertical), with the same ground overlays.

Lighting: a constant (sky) environment plus a directional "sun" that shines along the
mid-aperture line of sight, so the **optical shadows are the radar shadows** at
mid-aperture and the lit facades are those the radar sees. A dark context ground plane just
below the scene shows where the track lies. The radar materials render as diffuse BSDFs of
their ``color`` (plugins/radar_material.py); the preview builds its own Mitsuba scene from
the loaded shapes and leaves ``loaded.scene`` unchanged.

Cost: about 1-5 s for the default 960 x 720 pixels at 16 samples per pixel, for the
built-in ``urban`` scene and for Sionna's ``munich`` (2,367 shapes), on 2 cores.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .plotting import agg_figure, save_png
from ..core.geometry import acquisition_geometry

__all__ = ["render_preview", "PreviewGeometry", "preview_geometry", "MIN_RESOLUTION"]

#: The smallest preview (width, height) [pixels] that holds its two panels and header.
MIN_RESOLUTION = (200, 150)

#: Pixel height of the text header above the two panels, at 100 dpi.
_HEADER_PX = 56
_SKY = np.array([0.80, 0.87, 0.95])
#: Light: constant sky radiance and sun irradiance (mono units).
_SKY_RADIANCE, _SUN_IRRADIANCE = 0.45, 1.6
#: Radiance of a white diffuse surface facing the sun, shown as white: (E + pi L) / pi.
_WHITE = (_SUN_IRRADIANCE + math.pi * _SKY_RADIANCE) / math.pi
#: Mitsuba's perspective sensor cannot see points nearer than this fraction of its distance.
_NEAR = 1e-3


@dataclass(frozen=True)
class PreviewGeometry:
    """World-frame geometry drawn on a preview (float64, metres, z up).

    Attributes
    ----------
    track : float64 [n_pulses, 3]
        Antenna positions of all pulses.
    antenna : float64 [3]
        Mid-aperture antenna position.
    nadir : float64 [3]
        Point of the image plane below the mid-aperture antenna.
    scene_center : float64 [3]
        Where the beam centre points at mid-aperture.
    beam_footprint : float64 [4, 3]
        Corners of the beam footprint at mid-aperture on the plane ``z0``: azimuth width
        ``2 R(r) tan(beta / 2)`` at slant range ``R(r)`` (``beta = azimuth_beamwidth``),
        ground-range extent that of the scene's bounding box (the swath). Order: near-back,
        near-front, far-front, far-back (front = along the track).
    swept_footprint : float64 [4, 3]
        The footprint swept from the first to the last pulse (same corner order); in
        spotlight mode the beam stays on the scene centre, so this is the illuminated patch.
    imaged_area : float64 [4, 3]
        Corners of the focusing grid (pixel centres at the grid's extremes).
    bbox_corners : float64 [8, 3]
        The scene's bounding box.
    mode : str
        ``"stripmap"`` or ``"spotlight"`` (``RadarParameters.mode``).
    """

    track: np.ndarray
    antenna: np.ndarray
    nadir: np.ndarray
    scene_center: np.ndarray
    beam_footprint: np.ndarray
    swept_footprint: np.ndarray
    imaged_area: np.ndarray
    bbox_corners: np.ndarray
    mode: str = "stripmap"


def preview_geometry(loaded: Any) -> PreviewGeometry:
    """The acquisition geometry of a loaded scene, as drawn by :func:`render_preview`.

    Parameters
    ----------
    loaded : LoadedScene
        From :func:`sarmitsuba.scene.loader.load_scene` (radar parameters resolved).

    Returns
    -------
    PreviewGeometry
    """
    from ..focus.scene_grid import image_grid
    from ..scene.planning import box_corners

    params = loaded.params
    geometry = acquisition_geometry(params)
    u, look = geometry.track_direction, geometry.look_direction
    center = geometry.scene_center
    z0 = float(center[2])
    antenna = geometry.positions.mean(axis=0)
    corners = box_corners(loaded.bbox_lo, loaded.bbox_hi)
    across = (corners - center) @ look
    r_near, r_far = float(across.min()), float(across.max())
    half_beam = math.tan(math.radians(params.azimuth_beamwidth) / 2.0)

    def ground(along: float, r: float) -> np.ndarray:
        p = center + along * u + r * look
        p[2] = z0
        return p

    def half_width(r: float) -> float:
        return float(np.linalg.norm(ground(0.0, r) - antenna)) * half_beam

    spotlight = getattr(params, "mode", "stripmap") == "spotlight"
    s_mid = 0.0 if spotlight else float((antenna - center) @ u)       # spotlight: steered at the centre
    s_first, s_last = (0.0, 0.0) if spotlight else (
        float((p - center) @ u) for p in (geometry.positions[0], geometry.positions[-1]))
    w_near, w_far = half_width(r_near), half_width(r_far)
    beam = np.array([ground(s_mid - w_near, r_near), ground(s_mid + w_near, r_near),
                     ground(s_mid + w_far, r_far), ground(s_mid - w_far, r_far)])
    swept = np.array([ground(s_first - w_near, r_near), ground(s_last + w_near, r_near),
                      ground(s_last + w_far, r_far), ground(s_first - w_far, r_far)])
    grid = image_grid(loaded, geometry)
    area = np.array([grid.origin + a * grid.azimuth_direction + r * grid.range_direction
                     for a, r in ((grid.azimuth[0], grid.range[0]), (grid.azimuth[-1], grid.range[0]),
                                  (grid.azimuth[-1], grid.range[-1]), (grid.azimuth[0], grid.range[-1]))])
    nadir = antenna.copy()
    nadir[2] = z0
    return PreviewGeometry(track=geometry.positions, antenna=antenna, nadir=nadir, scene_center=center,
                           beam_footprint=beam, swept_footprint=swept, imaged_area=area, bbox_corners=corners,
                           mode="spotlight" if spotlight else "stripmap")


# ============================================================================ cameras
@dataclass(frozen=True)
class _Camera:
    sensor: Any
    origin: np.ndarray
    forward: np.ndarray
    size: tuple[int, int]       # (width, height) in pixels
    near: float                 # depth [m] below which overlays are clipped

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates float64 [n, 2] (x right, y down) and depth [n] (m, > 0 in front)."""
        import drjit as dr
        import mitsuba as mi
        pts = np.atleast_2d(np.asarray(points, np.float64))
        it = dr.zeros(mi.Interaction3f, len(pts))
        p32 = pts.astype(np.float32)
        it.p = mi.Point3f(p32[:, 0], p32[:, 1], p32[:, 2])
        ds, _ = self.sensor.sample_direction(it, mi.Point2f(0.5, 0.5))
        uv = np.stack([np.array(ds.uv.x), np.array(ds.uv.y)], axis=1).astype(np.float64)
        return uv, (pts - self.origin) @ self.forward


def _camera(target: np.ndarray, direction: np.ndarray, points: np.ndarray, size: tuple[int, int],
            fov: float, spp: int) -> _Camera:
    """A perspective camera looking at ``target`` from along ``direction``, framing ``points``."""
    import mitsuba as mi
    direction = direction / np.linalg.norm(direction)
    radius = float(np.linalg.norm(points - target, axis=1).max())
    distance = 1.05 * radius / math.sin(math.radians(fov) / 2.0)
    origin = target + distance * direction
    forward = -direction
    # aim at the centre of the points' angular extent, then tighten the field of view around
    # them (8 % margin), keeping the aspect ratio
    def tangents(forward: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        left = np.cross([0.0, 0.0, 1.0], forward)
        left /= np.linalg.norm(left)
        cam_up = np.cross(forward, left)
        rel = points - origin
        depth = rel @ forward
        return rel @ left / depth, rel @ cam_up / depth, left, cam_up

    for _ in range(3):
        x, y, left, cam_up = tangents(forward)
        forward = forward + 0.5 * (x.max() + x.min()) * left + 0.5 * (y.max() + y.min()) * cam_up
        forward /= np.linalg.norm(forward)
    x, y, _, _ = tangents(forward)
    target = origin + distance * forward
    aspect = size[0] / size[1]
    tan_x = max(np.abs(x).max(), np.abs(y).max() * aspect)
    fov_x = 2.0 * math.degrees(math.atan(1.08 * tan_x))
    sensor = mi.load_dict({
        "type": "perspective", "fov": fov_x, "fov_axis": "x", "near_clip": _NEAR * distance,
        "far_clip": 100.0 * distance,
        "to_world": mi.ScalarTransform4f().look_at(origin=origin.tolist(), target=target.tolist(), up=[0, 0, 1]),
        "film": {"type": "hdrfilm", "width": int(size[0]), "height": int(size[1]),
                 "pixel_format": "luminance_alpha", "rfilter": {"type": "box"}},
        "sampler": {"type": "multijitter", "sample_count": int(spp)}})
    return _Camera(sensor=sensor, origin=origin, forward=forward, size=(int(size[0]), int(size[1])),
                   near=2.0 * _NEAR * distance)


def _rotate_z(v: np.ndarray, degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]])


# ============================================================================ Mitsuba scene
def _preview_scene(loaded: Any, geo: PreviewGeometry) -> Any:
    """A new Mitsuba scene: the loaded shapes, a context ground, sky and a sun at the radar."""
    import mitsuba as mi
    sun = geo.scene_center - geo.antenna
    sun /= np.linalg.norm(sun)
    pts = np.vstack([geo.bbox_corners, geo.track, geo.nadir[None]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    half = np.full(2, 10.0 * float(np.linalg.norm(hi - lo)))      # to the horizon of every camera
    mid = 0.5 * (hi + lo)
    z_ground = float(loaded.bbox_lo[2]) - 1e-3 * max(1.0, float(np.linalg.norm(loaded.bbox_hi - loaded.bbox_lo)))
    scene: dict[str, Any] = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 3},
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": _SKY_RADIANCE}},
        "sun": {"type": "directional", "direction": sun.tolist(),
                "irradiance": {"type": "rgb", "value": _SUN_IRRADIANCE}},
        "context_ground": {
            "type": "rectangle",
            "to_world": mi.ScalarTransform4f().translate([float(mid[0]), float(mid[1]), z_ground])
            @ mi.ScalarTransform4f().scale([float(half[0]), float(half[1]), 1.0]),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.18}}},
    }
    for i, shape in enumerate(loaded.scene.shapes()):
        scene[f"shape_{i:05d}"] = shape
    return mi.load_dict(scene)


def _render(scene: Any, camera: _Camera, spp: int) -> np.ndarray:
    """Tone-mapped RGB float [h, w, 3] in [0, 1]: grey scene over a sky colour."""
    import mitsuba as mi
    out = np.array(mi.render(scene, sensor=camera.sensor, spp=int(spp)), dtype=np.float64)
    lum, alpha = out[..., 0], np.clip(out[..., -1], 0.0, 1.0)
    grey = np.clip(lum / _WHITE, 0.0, 1.0) ** (1 / 2.2)     # fixed exposure, display gamma
    return alpha[..., None] * grey[..., None] + (1.0 - alpha[..., None]) * _SKY


# ============================================================================ overlays
def _clip_polygon(points: np.ndarray, depth: np.ndarray, near: float, closed: bool) -> list[np.ndarray]:
    """Parts of a 3-D polyline (or polygon, ``closed``) with ``depth >= near`` (in front of the camera).

    Polygons are clipped by Sutherland-Hodgman against the one plane; polylines are split
    into the runs in front.
    """
    n = len(points)
    front = depth >= near
    if front.all():
        return [points]

    def cut(i: int, j: int) -> np.ndarray:
        return points[i] + (points[j] - points[i]) * (near - depth[i]) / (depth[j] - depth[i])

    if closed:
        out = []
        for i in range(n):
            j = (i + 1) % n
            if front[i]:
                out.append(points[i])
            if front[i] != front[j]:
                out.append(cut(i, j))
        return [np.array(out)] if len(out) >= 3 else []
    parts, current = [], []
    for i in range(n - 1):
        j = i + 1
        if front[i] and not current:
            current.append(points[i])
        if front[i] != front[j]:
            if front[i]:
                current.append(cut(i, j))
                parts.append(np.array(current))
                current = []
            else:
                current = [cut(i, j)]
        if front[j]:
            current.append(points[j])
    if len(current) >= 2:
        parts.append(np.array(current))
    return parts


def _draw(ax: Any, camera: _Camera, points: np.ndarray, *, closed: bool = False, fill: str | None = None,
          **line: Any) -> None:
    """Draw a 3-D polyline (or polygon) through the camera, clipped to what lies in front."""
    from matplotlib.patches import Polygon
    points = np.asarray(points, np.float64)
    _, depth = camera.project(points)
    for part in _clip_polygon(points, depth, camera.near, closed):
        if len(part) < 2:
            continue
        uv, _ = camera.project(part)
        if closed and len(part) >= 3:
            ax.add_patch(Polygon(uv, closed=True, facecolor=fill or "none", **line))
        else:
            ax.plot(uv[:, 0], uv[:, 1], **line)


def _overlay(ax: Any, camera: _Camera, geo: PreviewGeometry, *, full: bool) -> None:
    """Draw the acquisition on a panel; ``full`` adds the track, antenna and cone."""
    w, h = camera.size
    swept = "footprint swept along the track" if geo.mode == "stripmap" else "illuminated patch (spotlight)"
    _draw(ax, camera, geo.swept_footprint, closed=True, fill=(1.0, 0.85, 0.1, 0.12), edgecolor="goldenrod",
          linestyle="--", linewidth=1.2, label=swept)
    _draw(ax, camera, geo.imaged_area, closed=True, edgecolor="limegreen", linewidth=1.6, label="imaged area")
    _draw(ax, camera, geo.beam_footprint, closed=True, fill=(1.0, 0.45, 0.0, 0.35), edgecolor="darkorange",
          linewidth=1.2, label="beam footprint at mid-aperture")
    for corner in geo.beam_footprint:
        _draw(ax, camera, np.array([geo.antenna, corner]), color="darkorange", linewidth=0.9)
    _draw(ax, camera, np.array([geo.antenna, geo.scene_center]), color="red", linewidth=0.9, linestyle=":",
          label="line of sight to the scene centre")
    _draw(ax, camera, geo.track, color="royalblue", linewidth=2.0, label="flight track (all pulses)")
    uv, depth = camera.project(np.vstack([geo.track[[0, -1]], geo.antenna[None], geo.nadir[None]]))
    if not full:
        _direction_arrows(ax, camera, geo)
    if full and geo.mode == "spotlight":
        for k, end in enumerate(geo.track[[0, -1]]):
            _draw(ax, camera, np.array([end, geo.scene_center]), color="darkorange", linewidth=0.8,
                  linestyle="--", label=None if k else "beam axis at the first / last pulse")
    if full:
        _draw(ax, camera, np.array([geo.antenna, geo.nadir]), color="0.3", linewidth=0.8, linestyle=":")
        if np.all(depth[:2] > 0):
            ax.annotate("", xy=uv[1], xytext=uv[0] + 0.8 * (uv[1] - uv[0]),
                        arrowprops={"arrowstyle": "-|>", "color": "royalblue", "lw": 2.0})
        if depth[2] > 0:
            ax.plot(*uv[2], marker="v", markersize=10, color="red", markeredgecolor="k", linestyle="none",
                    label="antenna at mid-aperture")
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)


def _direction_arrows(ax: Any, camera: _Camera, geo: PreviewGeometry) -> None:
    """Arrows on the ground at the imaged area's near-back corner: flight and look directions."""
    area = geo.imaged_area
    along, across = area[1] - area[0], area[3] - area[0]
    size = 0.25 * min(np.linalg.norm(along), np.linalg.norm(across))
    base = area[0] + 0.06 * along + 0.06 * across
    for vec, text in ((along, "flight"), (across, "look")):
        tip = base + size * vec / np.linalg.norm(vec)
        uv, depth = camera.project(np.array([base, tip]))
        if np.all(depth > camera.near):
            ax.annotate("", xy=uv[1], xytext=uv[0], arrowprops={"arrowstyle": "-|>", "color": "navy", "lw": 1.8})
            ax.text(*uv[1], f" {text}", color="navy", fontsize=8, fontweight="bold", va="center")


# ============================================================================ public
def render_preview(loaded: Any, path: str | os.PathLike, *, spp: int = 16,
                   resolution: tuple[int, int] = (960, 720), dpi: int = 100) -> Path:
    """Render an optical preview of the scene and the acquisition geometry to a PNG.

    Parameters
    ----------
    loaded : LoadedScene
        From :func:`sarmitsuba.scene.loader.load_scene`; nothing is traced.
    path : str or os.PathLike
        Target file (``.png``), written atomically (temporary name, then rename).
    spp : int, default 16
        Samples per pixel of the path tracer (multi-jittered, so 16 is nearly noise-free).
    resolution : (int, int), default (960, 720)
        Width and height of the PNG in pixels. The two rendered panels share the width,
        below a 56-pixel text header (at 100 dpi).
    dpi : int, default 100
        Dots per inch of the PNG (the header and fonts scale with it).

    Returns
    -------
    Path
        The path written.

    Raises
    ------
    ValueError
        ``spp`` < 1 or a resolution too small for two panels (< 200 x 150 pixels).
    OSError
        When the file cannot be written.

    Notes
    -----
    The header lists what decides where the radar looks: mode, carrier, bandwidth,
    incidence angle, altitude, heading and look side, slant range, pulses and track length,
    azimuth beamwidth, footprint and swath. Every overlay point is projected with the
    panel's Mitsuba sensor (``sample_direction``), so overlays and render agree to the
    pixel; lines are clipped where they pass behind a camera.
    """
    if int(spp) != spp or spp < 1:
        raise ValueError(f"spp must be a whole number >= 1, got {spp!r}")
    width, height = (int(v) for v in resolution)
    if width < MIN_RESOLUTION[0] or height < MIN_RESOLUTION[1]:
        raise ValueError(f"resolution must be at least {MIN_RESOLUTION[0]} x {MIN_RESOLUTION[1]} pixels, "
                         f"got {resolution!r}")
    header = int(round(_HEADER_PX * dpi / 100))
    panel = (width // 2, height - header)
    geo = preview_geometry(loaded)
    scene = _preview_scene(loaded, geo)

    # overview: from above the far side of the scene, looking back up the beam, off to the side
    u = geo.track[-1] - geo.track[0] if len(geo.track) > 1 else np.array([1.0, 0.0, 0.0])
    u = u / np.linalg.norm(u)
    away = geo.scene_center - geo.nadir
    away = away / max(np.linalg.norm(away), 1e-9)
    overview_pts = np.vstack([geo.bbox_corners, geo.track[[0, -1]], geo.antenna[None], geo.nadir[None],
                              geo.beam_footprint, geo.imaged_area])
    target = 0.5 * (geo.antenna + geo.scene_center)
    overview = _camera(target, -0.8 * u + 0.3 * away + 0.6 * np.array([0.0, 0.0, 1.0]), overview_pts,
                       panel, 40.0, spp)
    # scene: from the radar's side, turned 30 degrees about the vertical
    lo, hi = loaded.bbox_lo, loaded.bbox_hi
    scene_target = np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), lo[2] + 0.2 * (hi[2] - lo[2])])
    los = geo.antenna - geo.scene_center
    scene_cam = _camera(scene_target, _rotate_z(los, 30.0), np.vstack([geo.bbox_corners, geo.imaged_area]),
                        panel, 35.0, spp)

    fig = agg_figure((width / dpi, height / dpi), dpi, layout=None)
    fig.text(0.01, 1.0 - 0.5 * header / height, _header_text(loaded, geo), fontsize=8,
             va="center", ha="left", family="monospace")
    for k, (camera, title, full) in enumerate(((overview, "overview: track, antenna, beam, imaged area", True),
                                                (scene_cam, "scene from the radar side (sun at the radar: "
                                                 "optical shadows = radar shadows)", False))):
        ax = fig.add_axes((k * panel[0] / width, 0.0, panel[0] / width, panel[1] / height))
        ax.imshow(_render(scene, camera, spp), extent=(0, panel[0], panel[1], 0), interpolation="nearest",
                  aspect="auto")
        _overlay(ax, camera, geo, full=full)
        ax.set_axis_off()
        ax.text(6, 6, title, fontsize=8, va="top", ha="left", color="k",
                bbox={"facecolor": "white", "alpha": 0.75, "edgecolor": "none", "pad": 2})
        if full:
            ax.legend(loc="lower left", fontsize=7, framealpha=0.8)
    return save_png(fig, path, dpi, "preview")


def _header_text(loaded: Any, geo: PreviewGeometry) -> str:
    p = loaded.params
    track_len = float(np.linalg.norm(geo.track[-1] - geo.track[0]))
    footprint = float(np.linalg.norm(geo.beam_footprint[1] - geo.beam_footprint[0]))
    b = geo.beam_footprint
    swath = float(np.linalg.norm(0.5 * (b[2] + b[3]) - 0.5 * (b[0] + b[1])))
    slant = float(np.linalg.norm(geo.scene_center - geo.antenna))
    c = ", ".join(f"{v:.1f}" for v in geo.scene_center)
    return (f"{loaded.source} ({geo.mode}): fc {p.frequency / 1e9:.2f} GHz, B {p.bandwidth / 1e6:.0f} MHz, incidence "
            f"{p.incidence_angle:g} deg, altitude {p.altitude:g} m, heading {p.heading:g} deg, looking {p.look_side}\n"
            f"slant range {slant:.0f} m to the scene centre ({c}) m; {p.n_pulses} pulses over {track_len:.0f} m "
            f"of track\nazimuth beam {p.azimuth_beamwidth:.2f} deg: footprint {footprint:.1f} m long at the near "
            f"swath edge; swath (scene extent across track) {swath:.0f} m")
