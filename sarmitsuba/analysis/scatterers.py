"""What made each bright point: the scatterer catalogue of a render (docs/physics.md (SC1)-(SC4)).

The trace (``scatterers = true``) sums every term lane coherently at its image point and merges
the lanes of one chain of parts by quantisation cube
(:class:`~sarmitsuba.tracing.integration.catalogue.CatalogueRows`). :func:`build_catalogue` turns
those rows into the catalogue of a focused image:

1. each row's image point is mapped to the image (its layover position,
   :func:`~sarmitsuba.core.image.layover_positions`) and rows of one chain of parts whose points
   fall in one resolution cell (the image's energy widths (K2)) are merged: one *scatterer*;
2. its coherent sum is divided by the point-target gain the image divides by
   (:func:`~sarmitsuba.focus.beam.point_gain`, rect window): its complex amplitude, whose
   ``|.|^2`` is its RCS [m^2] and whose angle its phase (SC2);
3. the strongest scatterers are kept until they hold ``share`` of the image's integrated RCS,
   or all within ``-floor_db`` dB of the strongest;
4. distributed clutter is summarised per rough surface: the image pixels its triangles cover and
   their speckle's mean intensity (the median over ln 2) over ``rho_E,az rho_E,rg``, sigma
   nought (K).

:func:`explain` lists the scatterers within one resolution cell of an image position and their
shares of its power.
"""
from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ..core import georef
from ..core.constants import SPEED_OF_LIGHT
from ..core.image import SarImage, image_track, layover_positions
from ..core.radar import ParameterError
from ..focus.beam import beam_weighting, point_gain
from ..focus.dispatch import azimuth_pattern
from ..products.scatterer_files import Catalogue, columns_of
from ..tracing.integration.catalogue import CatalogueRows, group_sums, response_offset
from ..tracing.mesh.facets import scene_meshes
from .impulse_model import ImpulseModel, energy_widths

__all__ = ["build_catalogue", "explain", "resynthesised", "check_selection", "DEFAULT_SHARE", "FLOOR_DB_RANGE"]

#: The share of the image's integrated RCS the listed scatterers hold together, by default.
DEFAULT_SHARE = 0.9
#: ``--scatterers-db``: the floor, in dB below the strongest scatterer's RCS, lies in (-200, 0].
FLOOR_DB_RANGE = (-200.0, 0.0)


def check_selection(share: Any, floor_db: Any) -> tuple[float, float | None]:
    """``(share, floor_db)`` checked: ``share`` in (0, 1]; ``floor_db`` None or a number in
    ``(-200, 0]`` dB (relative to the strongest scatterer). Raises ParameterError naming the option."""
    try:
        share = float(share)
    except (TypeError, ValueError):
        share = math.nan
    if not 0.0 < share <= 1.0:
        raise ParameterError(f"--scatterers-share = {share}: give a share of the image's energy in (0, 1] "
                             f"(default {DEFAULT_SHARE})")
    if floor_db is None:
        return share, None
    try:
        floor = float(floor_db)
    except (TypeError, ValueError):
        floor = math.nan
    lo, hi = FLOOR_DB_RANGE
    if not lo < floor <= hi:
        raise ParameterError(f"--scatterers-db = {floor_db}: give a floor in dB relative to the strongest scatterer, "
                             f"in ({lo:g}, {hi:g}] (e.g. -30 lists every scatterer within 30 dB of the strongest; "
                             "below -200 dB only rounding noise is left)")
    return share, floor


def _merged(rows: CatalogueRows, cell: np.ndarray, reciprocal: bool):
    """``rows`` merged by chain of parts and resolution cell ``cell`` int64 [k, 2]: (first row of
    each merge, group index of every row, number of merges). ``reciprocal`` (monostatic): a chain
    and its reverse are one path, travelled both ways, of one length and phase (SC4)."""
    parts = rows.parts
    if reciprocal and len(parts):
        flipped = parts.copy()
        for i, k in enumerate(rows.order):
            flipped[i, :k] = parts[i, :k][::-1]
        lower = np.array([tuple(f) < tuple(q) for f, q in zip(flipped, parts)], bool)
        parts = np.where(lower[:, None], flipped, parts)
    key = np.concatenate([parts, cell], axis=1)
    order = np.lexsort(key.T[::-1])
    _, first, group = np.unique(key[order], axis=0, return_index=True, return_inverse=True)
    inverse = np.empty_like(order)
    inverse[order] = np.arange(len(order))
    return order[first], group.reshape(-1)[inverse], len(first)


def build_catalogue(sim: Any, share: float = DEFAULT_SHARE, floor_db: float | None = None) -> Catalogue:
    """The scatterer catalogue of a simulation traced with ``scatterers = true``.

    Parameters
    ----------
    sim : sarmitsuba.pipeline.Simulation
        Its ``trace.catalogue`` (every channel's sums), image (HH for ``quad``), raw data and scene.
    share : float in (0, 1]
        Keep the strongest scatterers until they hold this share of the image's integrated RCS.
    floor_db : float in (-200, 0], optional
        Instead, keep every scatterer whose RCS (all channels' powers summed) is within ``-floor_db``
        dB of the strongest one's.

    Returns
    -------
    Catalogue

    Raises
    ------
    ParameterError
        When the simulation was traced without the catalogue, or on a bad ``share`` / ``floor_db``.
    """
    share, floor_db = check_selection(share, floor_db)
    rows = sim.trace.catalogue
    if rows is None:
        raise ParameterError("the simulation was traced without the scatterer catalogue: render with --scatterers "
                             "(simulate(..., scatterers=True), or sbr scatterers = true)")
    loaded, image, raw = sim.loaded, sim.image, sim.raw
    p = loaded.params
    offset = np.asarray(loaded.offset, float)
    track = np.asarray(raw.metadata.get("track_direction", image.azimuth_direction), float)
    with np.errstate(invalid="ignore", divide="ignore"):
        centre = rows.centre / rows.weight[:, None] + offset
        point = centre + (rows.shift / rows.weight)[:, None] * track
    az, rg = layover_positions(image, point) if len(rows) else (np.zeros(0), np.zeros(0))
    rho_az, rho_rg = energy_widths(image)
    seen = np.isfinite(az)
    rows = _select_rows(rows, seen)
    az, rg, centre, point = az[seen], rg[seen], centre[seen], point[seen]
    cell = np.stack([np.round(az / rho_az), np.round(rg / rho_rg)], axis=1).astype(np.int64)
    first, group, n = _merged(rows, cell, reciprocal=not p.bistatic)
    weight = group_sums(rows.weight, group, n)
    amplitude = group_sums(rows.amplitude, group, n)
    mean = lambda v: group_sums(rows.weight[:, None] * v, group, n) / weight[:, None]  # noqa: E731
    centre, point = mean(centre), mean(point)
    image_az, image_rg = mean(np.stack([az, rg], axis=1)).T
    beam = beam_weighting(raw, p.traced_beamwidth if p.mode == "stripmap" else None, p.squint,
                          azimuth_pattern(p), "rect")
    gain = point_gain(raw, beam, point)
    with np.errstate(invalid="ignore", divide="ignore"):
        field = np.where(gain[:, None] > 0, amplitude / gain[:, None], 0.0)
    power = np.sum(np.abs(field) ** 2, axis=1)
    # each scatterer's part of its resolution cell's coherent power (SC4): they add up to |sum|^2
    _, in_cell = np.unique(cell[first], axis=0, return_inverse=True)
    in_cell = in_cell.reshape(-1)
    cell_field = group_sums(field, in_cell, int(in_cell.max(initial=-1)) + 1)[in_cell]
    contribution = np.sum((field * np.conj(cell_field)).real, axis=1)
    images = [c.image for c in sim.channels.values()] if sim.channels else [image]
    image_rcs = sum(float(np.sum(np.abs(im.data.astype(np.complex128)) ** 2)) for im in images) \
        * _pixel_area(image) / (rho_az * rho_rg)
    keep = _chosen(power, contribution, image_rcs, share, floor_db)
    scale, slope = azimuth_response(image, group_sums(rows.side, group, n), amplitude[:, 0], response_offset(p))
    table = dict(azimuth=image_az, range=image_rg, centre=centre, field=field, power=power, scale=scale, slope=slope,
                 contribution=contribution, cell_power=np.sum(np.abs(cell_field) ** 2, axis=1),
                 order=rows.order[first], shapes=rows.shapes[first], parts=rows.parts[first],
                 face=group_sums(rows.face, group, n) / weight, radial=group_sums(rows.radial, group, n) / weight,
                 shift=group_sums(rows.shift, group, n) / weight, lanes=group_sums(rows.lanes.astype(float), group, n))
    table = {k: v[keep] for k, v in table.items()}
    names = [s.id() or f"#shape{i}" for i, s in enumerate(loaded.scene.shapes())]
    geo = georef.of(p) if p.geo_origin is not None else None
    listed = float(np.sum(table["contribution"]))
    selection = f"rcs within {-floor_db:g} dB of the strongest" if floor_db is not None else f"share {share:g}"
    return Catalogue(columns=columns_of(table, image, names, p.channels, geo, image_rcs),
                     clutter=clutter_summary(sim, rho_az, rho_rg), channels=tuple(p.channels), image_rcs=image_rcs,
                     listed_share=listed / image_rcs if image_rcs > 0 else 0.0, selection=selection,
                     resolution=(float(rho_az), float(rho_rg)))


def azimuth_response(image: SarImage, side: np.ndarray, centre: np.ndarray, offset: float) -> tuple:
    """Each scatterer's azimuth response from its sums ``side`` [k, 2] at ``+-offset`` [m] along
    track and ``centre`` [k] at its image point (SC4): ``(scale, slope)`` float64 [k] such that its
    response at ``x`` metres is ``h(scale x) exp(j slope x)``, ``h`` the image's (a point seen over
    the whole aperture: scale 1; a flash seen over part of it: below 1, broader; ``slope`` [rad/m]
    its Doppler centroid's phase ramp). The sums carry no window: ``scale`` is found on the image's
    response without its azimuth window, and taken to stretch the windowed one alike."""
    import dataclasses
    meta = dict(image.metadata)
    meta["focus"] = {**meta.get("focus", {}), "window_azimuth": {"name": "rect"}}
    model = ImpulseModel(dataclasses.replace(image, metadata=meta), (0.0, 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = side / centre[:, None]
    ok = np.all(np.isfinite(ratio), axis=1) & (np.abs(centre) > 0)
    ratio = np.where(ok[:, None], ratio, 1.0)
    slope = np.where(ok, np.angle(ratio[:, 0] / ratio[:, 1]) / (2.0 * offset), 0.0)
    level = np.sqrt(np.abs(ratio[:, 0] * ratio[:, 1]))
    x = np.linspace(0.0, 4.0 * offset, 257)
    h = np.abs(model.response(x, np.zeros_like(x)))
    stop = int(np.argmax(np.diff(h) > 0)) + 1 if np.any(np.diff(h) > 0) else len(h)   # the main lobe
    reach = np.interp(-level, -h[:stop], x[:stop])            # |h(reach)| = level, decreasing h
    scale = np.where(ok, reach / offset, 1.0)
    return scale, slope


def _select_rows(rows: CatalogueRows, keep: np.ndarray) -> CatalogueRows:
    return CatalogueRows(**{name: getattr(rows, name)[keep] for name in CatalogueRows.__dataclass_fields__})


def _pixel_area(image: SarImage) -> float:
    """m^2 of one pixel (the axes' mean steps)."""
    d_az = abs(float(np.mean(np.diff(image.azimuth)))) if image.azimuth.size > 1 else 1.0
    d_rg = abs(float(np.mean(np.diff(image.range)))) if image.range.size > 1 else 1.0
    return d_az * d_rg


def _chosen(power: np.ndarray, contribution: np.ndarray, image_rcs: float, share: float,
            floor_db: float | None) -> np.ndarray:
    """Rows to list, by contribution to the image's power, largest first: all whose own RCS is
    within ``-floor_db`` dB of the strongest's, or the fewest whose contributions reach ``share`` of
    ``image_rcs`` (all, where together they hold less)."""
    order = np.argsort(-contribution, kind="stable")
    if floor_db is not None:
        return order[power[order] >= 10.0 ** (floor_db / 10.0) * power.max(initial=0.0)]
    reached = np.cumsum(contribution[order]) >= share * image_rcs
    count = int(np.argmax(reached)) + 1 if reached.any() else len(order)
    return order[:count]


def clutter_summary(sim: Any, rho_az: float, rho_rg: float) -> tuple[dict, ...]:
    """Per rough surface (a shape whose material has a clutter model): its id, material, the image
    pixels its triangles cover (their layover positions) and its sigma nought there, ``<|I|^2> /
    (rho_az rho_rg)`` in dB (docs/physics.md (K)), the mean ``<|I|^2>`` taken as the median over
    ln 2 (fully developed speckle's intensity is exponential), so that the bright points among
    those pixels do not pull it up. Empty without clutter."""
    from skimage.draw import polygon
    from ..scene.loader import material_table
    loaded, image = sim.loaded, sim.image
    p = loaded.params
    table = material_table(loaded.scene, p.frequency, p.polarization)
    if table.clutter is None:
        return ()
    shapes = list(loaded.scene.shapes())
    rough = table.clutter[table.row_of_shape[:len(shapes)], 0] > 0
    intensity = np.abs(image.data.astype(np.complex128)) ** 2
    out = []
    for index, (vertices, faces) in enumerate(scene_meshes(loaded.scene)):
        if not rough[index] or len(faces) == 0:
            continue
        az, rg = layover_positions(image, vertices + np.asarray(loaded.offset, float))
        rows = np.interp(az, image.azimuth, np.arange(image.azimuth.size), left=-1, right=image.azimuth.size)
        cols = np.interp(rg, image.range, np.arange(image.range.size), left=-1, right=image.range.size)
        mask = np.zeros(image.data.shape, bool)
        for tri in faces:
            if np.all(np.isfinite(rows[tri])):
                rr, cc = polygon(rows[tri], cols[tri], shape=mask.shape)
                mask[rr, cc] = True
        pixels = int(mask.sum())
        # the median over ln 2: the mean of fully developed speckle (exponential intensity), which
        # the bright points inside the surface's pixels do not pull up
        sigma0 = float(np.median(intensity[mask]) / math.log(2.0) / (rho_az * rho_rg)) if pixels else 0.0
        bsdf = shapes[index].bsdf()
        out.append(dict(surface=shapes[index].id() or f"#shape{index}",
                        material=bsdf.id() if bsdf is not None else "", pixels=pixels,
                        sigma0_db=10.0 * math.log10(sigma0) if sigma0 > 0 else -math.inf))
    return tuple(out)


def resynthesised(image: SarImage, columns: dict, azimuth: float, range_: float, channel: str | None = None,
                  resolution: Sequence[float] | None = None, reach: float = 3.0) -> tuple[np.ndarray, complex, np.ndarray]:
    """Each catalogue scatterer's part of the image value at ``(azimuth, range_)`` [m] (eq. (SC4)):
    ``a_i h_az(d_az / rho_az) h_rg(d_rg / rho_rg) exp(j 2 k (R_0(X) - R_0(Q_i)))``, the scatterer
    ``i`` of amplitude ``a_i`` imaged at ``Q_i`` seen through the image's unit-peak response
    (:meth:`~sarmitsuba.analysis.impulse_model.ImpulseModel.response`: windows and pattern), in
    azimuth stretched and ramped as the scatterer's own (columns ``azimuth_scale``,
    ``azimuth_slope_rad_per_m``, :func:`azimuth_response`), and carrier phase (``R_0`` the closest-approach range from the track).
    Returns ``(rows within reach energy widths [m], their parts complex [m], the image value)``.
    The point is taken at the nearest pixel, whose value is the image's; ``channel`` (default: the image's own polarisation,
    ``metadata["polarization"]``) picks the catalogue's amplitudes."""
    i = int(np.argmin(np.abs(image.azimuth - azimuth)))
    j = int(np.argmin(np.abs(image.range - range_)))
    azimuth, range_ = float(image.azimuth[i]), float(image.range[j])          # the pixel's own position
    rho_az, rho_rg = resolution if resolution is not None else energy_widths(image, (azimuth, range_))
    own = image.metadata.get("polarization") if isinstance(image.metadata, dict) else None
    name = channel or (own if f"rcs_dbsm_{own}" in columns else
                       next((k[len("rcs_dbsm_"):] for k in columns if k.startswith("rcs_dbsm_")), "VV"))
    d_az = np.asarray(columns["azimuth_m"], float) - azimuth
    d_rg = np.asarray(columns["range_m"], float) - range_
    rows = np.flatnonzero((np.abs(d_az) <= reach * rho_az) & (np.abs(d_rg) <= reach * rho_rg))
    a = 10.0 ** (np.asarray(columns[f"rcs_dbsm_{name}"], float)[rows] / 20.0) \
        * np.exp(1j * np.radians(np.asarray(columns[f"phase_deg_{name}"], float)[rows]))
    scale = np.asarray(columns.get("azimuth_scale", np.ones(len(d_az))), float)[rows]
    slope = np.asarray(columns.get("azimuth_slope_rad_per_m", np.zeros(len(d_az))), float)[rows]
    h = ImpulseModel(image, (azimuth, range_)).response(-d_az[rows] * scale, -d_rg[rows]) * np.exp(-1j * slope * d_az[rows])
    radar = image.metadata.get("radar", {}) if isinstance(image.metadata, dict) else {}
    lam = SPEED_OF_LIGHT / float(radar["frequency"]) if radar.get("frequency") else 0.0
    carrier = np.ones(len(rows), complex)
    track = image_track(image)
    if lam > 0 and track is not None:
        def r0(az, rg):
            x = image.origin + np.outer(az, image.azimuth_direction) + np.outer(rg, image.range_direction)
            rel = x - track[0]
            return np.linalg.norm(rel - np.outer(rel @ track[1], track[1]), axis=1)
        k = 2.0 * np.pi / lam
        carrier = np.exp(2j * k * (r0(np.array([azimuth]), np.array([range_])) - r0(azimuth + d_az[rows],
                                                                                      range_ + d_rg[rows])))
    return rows, a * h * carrier, complex(image.data[i, j])


def explain(image: SarImage, columns: dict, azimuth: float, range_: float,
            resolution: Sequence[float] | None = None) -> dict:
    """The catalogue's scatterers that make the image at ``(azimuth, range_)`` [m], and their
    shares of its power (eq. (SC4)).

    Parameters
    ----------
    image : SarImage
    columns : dict
        The catalogue's columns (:attr:`Catalogue.columns`, or read back by
        :func:`~sarmitsuba.products.scatterer_files.read_csv`).
    azimuth, range_ : float, m
        Image coordinates of the point (the image's axes).
    resolution : (rho_az, rho_rg), m, optional
        The energy widths; default the image's there (K2).

    Returns
    -------
    dict
        ``point``, ``pixel`` (row, column of the nearest pixel), ``cell`` [m, m], ``pixel_rcs_m2``
        (``|I|^2`` there), ``explained`` (the listed scatterers' share of it: ``Re(sum_i p_i conj(I))
        / |I|^2`` with ``p_i`` each one's part of the image value, :func:`resynthesised`), and
        ``rows``: the scatterers within one resolution cell, each with its ``share``
        ``Re(p_i conj(I)) / |I|^2``, largest first; ``residual``, ``|I - sum_i p_i|^2 / |I|^2``;
        ``ghosts``: scatterers whose azimuth ambiguities fall there (:func:`_ghosts`), with their
        RCS over the pixel's power in dB (a ghost is weaker than its scatterer by the ambiguity
        ratio, (AMB1)).

    Raises
    ------
    ParameterError
        When the point lies outside the image (names the axes' extents).
    """
    lo_a, hi_a = float(image.azimuth.min()), float(image.azimuth.max())
    lo_r, hi_r = float(image.range.min()), float(image.range.max())
    if not (math.isfinite(azimuth) and math.isfinite(range_) and lo_a <= azimuth <= hi_a and lo_r <= range_ <= hi_r):
        raise ParameterError(f"--explain {azimuth:g},{range_:g}: the point lies outside the image, which spans "
                             f"azimuth [{lo_a:.2f}, {hi_a:.2f}] m and range [{lo_r:.2f}, {hi_r:.2f}] m; give "
                             "AZ,RG in the image's coordinates (the axes of its figure)")
    rho_az, rho_rg = resolution if resolution is not None else energy_widths(image, (azimuth, range_))
    rows, parts, value = resynthesised(image, columns, azimuth, range_, resolution=(rho_az, rho_rg))
    power = abs(value) ** 2
    share = (parts * np.conj(value)).real / power if power > 0 else np.zeros(len(rows))
    residual = abs(value - np.sum(parts)) ** 2 / power if power > 0 else 0.0
    near = (np.abs(np.asarray(columns["azimuth_m"], float)[rows] - azimuth) <= rho_az) & \
           (np.abs(np.asarray(columns["range_m"], float)[rows] - range_) <= rho_rg)
    listed = [dict({name: _plain(values[i]) for name, values in columns.items()}, share=float(sh))
              for i, sh in zip(rows[near], share[near])]
    listed.sort(key=lambda r: -r["share"])
    return dict(point=[azimuth, range_], pixel=[int(np.argmin(np.abs(image.azimuth - azimuth))),
                                                int(np.argmin(np.abs(image.range - range_)))],
                cell=[float(rho_az), float(rho_rg)], pixel_rcs_m2=power, explained=float(np.sum(share)),
                residual=float(residual), rows=listed, ghosts=_ghosts(image, columns, azimuth, range_, rho_az, rho_rg, power))


def _ghosts(image: SarImage, columns: dict, azimuth: float, range_: float, rho_az: float, rho_rg: float,
            power: float) -> list:
    """The scatterers whose azimuth ambiguities (orders +-1, +-2) fall within one resolution cell
    of the point: ``m PRF lambda R_0 / (2 V)`` along track from them (docs/physics.md (AMB1)),
    each with its ``order_m`` and its own RCS over the pixel's power in dB."""
    radar = image.metadata.get("radar", {}) if isinstance(image.metadata, dict) else {}
    track = image_track(image)
    if not radar.get("prf") or not radar.get("velocity") or not radar.get("frequency") or track is None:
        return []
    x = image.origin + azimuth * image.azimuth_direction + range_ * image.range_direction
    rel = x - track[0]
    r0 = float(np.linalg.norm(rel - (rel @ track[1]) * track[1]))
    step = float(radar["prf"]) * SPEED_OF_LIGHT / float(radar["frequency"]) * r0 / (2.0 * float(radar["velocity"]))
    az, rg = np.asarray(columns["azimuth_m"], float), np.asarray(columns["range_m"], float)
    out = []
    for m in (-2, -1, 1, 2):
        near = np.flatnonzero((np.abs(az + m * step - azimuth) <= rho_az) & (np.abs(rg - range_) <= rho_rg))
        for i in near:
            level = float(columns["rcs_dbsm"][i]) - 10.0 * math.log10(power) if power > 0 else math.inf
            out.append(dict(rank=int(columns["rank"][i]), order_m=m, shapes=str(columns["shapes"][i]),
                            bounce_order=int(columns["order"][i]), offset_m=m * step, level_db=level))
    return sorted(out, key=lambda g: -g["level_db"])


def _plain(value: Any) -> Any:
    """A JSON-ready scalar of a column entry."""
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (np.floating,)):
        return float(value)
    return value
