"""Phase gradient autofocus through the raw data (docs/physics.md (PGA6), (PGA7), (PGA8)).

Backprojection weights every pulse by the azimuth window and the antenna pattern seen from each
pixel, ``w((x - s_p) / R0)``: a weight that follows the pixel. A motion error's phase
``phi(s_p)`` enters the image under that weight, so the image's deramped spectrum (eq. (PGA2))
holds the error as a product only where the weight is flat, and removing the estimate from the
spectrum of a Taylor-weighted image leaves paired echoes wherever the defocused response
spreads over a good part of the beam (measured: a 2 cm, 30 m sway on the built-in trihedral,
-26.8 dB azimuth PSLR even with the true error removed from the spectrum, -58.1 dB on the true
track). :func:`pga_focus` therefore

1. backprojects the data with a rectangular azimuth window on the grid widened by half the
   azimuth ambiguities' spacing (:func:`ambiguity_spacing`); reads a first estimate from every
   range bin of the clutter where no scatterer outshines it (:func:`~sarmitsuba.focus.pga_clutter.across_range`,
   (PGA8)), kept where it sharpens that image or raises its brightest pixel; and judges on the image then whether PGA may run ((PGA3), (PGA4):
   a dominant scatterer, or one smeared along a range line that stands out of its clutter) and
   which lines it learns from;
2. reads the pulses' echoes of those lines' targets and runs the kernel of (PGA) on them
   (:func:`~sarmitsuba.focus.pga_pulses.estimate_pulses`, eq. (PGA7)): the phase error of every
   pulse, however far the sway smears the image; a round whose window holds less than
   :data:`WINDOW_SCR_DB` more target than clutter is not applied (its estimate fits the clutter's
   phase, (PGA8));
3. removes the estimate from each pulse, ``d_p exp(-j phi(s_p))``, repeats 1-2 (the window
   narrowing round by round) until a round changes little, checks that the scatterer was found,
   and focuses with the focuser and windows asked for; ``metadata["autofocus"]`` says what it
   did, and :func:`outcome_line` says it in one line.

:func:`pulse_correction` reads the estimate of :func:`~sarmitsuba.focus.autofocus.pga` on a
deramped image at every pulse's position, for the image-domain estimate.
"""
from __future__ import annotations

import copy
import dataclasses
import warnings
from typing import Any

import numpy as np

from ..core.image import SarImage
from ..core.raw import RawData
from .grid import ImageGrid
from .autofocus import APERTURE_CELLS, BACKGROUND, DOMINANCE_DB, MIN_LINES, AutofocusReport, AutofocusWarning
from .pga_lines import band_occupancy, dominance_db, doppler_band, smeared_lines
from .pga_clutter import across_range, common_bins
from .pga_pulses import estimate_pulses, pulse_positions, reference_phase

__all__ = ["pulse_correction", "ambiguity_spacing", "pga_focus", "outcome_line", "corrected", "response_spread",
           "ROUNDS", "ROUND_TOLERANCE", "FOUND_DB", "SHARPER", "WINDOW_SCR_DB", "MIN_BINS", "ACROSS_RISE_DB"]


#: Rounds of estimate-and-correct through the pulses at most, and the rms [rad] of a round's
#: correction (over the pulses the estimate supports) below which they stop.
ROUNDS = 6
ROUND_TOLERANCE = 0.01
#: After the rounds, the scatterer PGA found must stand this far over the clutter [dB] (eq. (PGA3)
#: on the last estimation image): a point 20 dB over its clutter's mean reads about 21.6 dB over its
#: median, speckle alone 12 to 14 dB (docs/physics.md (PGA3)).
FOUND_DB = 18.0
#: ... and the rounds must leave the estimation image at least this sharp relative to the one they
#: started from, the nominal track's or the round from the clutter's where it was kept
#: (``sum I^2 / (sum I)^2``; a barely defocused point may lose a little in the first round).
SHARPER = 0.98
#: The first round from the clutter (eq. (PGA8)) needs this many range bins, and is kept where it
#: leaves the estimation image sharper or its brightest pixel this much higher over the median [dB]:
#: sharpness hardly moves where clutter fills the image (a trihedral 20 dB over its clutter with a
#: 5 cm, 60 m sway: 0.95 times the nominal track's with the round, 0.97 with the exact phase, while
#: the trihedral rose from 17.7 to 21.8 dB over the median).
MIN_BINS = 16
ACROSS_RISE_DB = 1.0
#: A round on the target's lines is applied only where its last window holds this much more of the
#: target than of the clutter [dB] (:func:`~sarmitsuba.focus.pga_pulses.window_scr_db`): its phase noise
#: is then about 0.07 rad; below, the estimate fits the clutter's phase inside the window and gathers
#: that clutter into the peak (a trihedral 20 dB over its clutter: about 10 dB, its IRW 27 % narrower
#: than the true track's; docs/physics.md (PGA8)).
WINDOW_SCR_DB = 20.0


def pulse_correction(report: AutofocusReport, raw: RawData, track: dict[str, Any]) -> np.ndarray:
    """float64 [n_pulses], rad: the phase PGA removed, read at every pulse's antenna position.

    Parameters
    ----------
    report : AutofocusReport
        Of a deramped image (``report.aperture_position`` not None) where PGA was applied.
    raw : RawData
        The data the image was focused from (its ``tx_position`` the track it was focused on).
    track : dict
        ``image.metadata["focus"]["track"]``: ``position`` (mid-aperture, m) and ``direction``.

    Returns
    -------
    float64 [n_pulses]
        ``correction`` at ``(tx_p - position) . direction`` (docs/physics.md (PGA6)) through a cubic
        spline over the estimate's support (the spectral samples lie ``lambda R0 / (2 X)`` apart,
        about a metre for an image ``X`` of 20 m; linear interpolation would leave 0.03 rad on a
        30 m sway); pulses beyond the support get its end values, as the image's spectrum does.

    Raises
    ------
    ValueError
        The report has no aperture positions (an image without a deramp) or was not applied.
    """
    from scipy.interpolate import CubicSpline
    if report.aperture_position is None or report.correction is None:
        raise ValueError("pulse_correction needs the report of PGA applied to a deramped (backprojected) image")
    position = np.asarray(track["position"], float)
    direction = np.asarray(track["direction"], float)
    along = (np.asarray(raw.tx_position, float) - position) @ direction
    order = np.argsort(report.aperture_position)
    s, phase, keep = report.aperture_position[order], report.correction[order], report.support[order]
    if keep.sum() >= 4:
        s, phase = s[keep], phase[keep]
    return CubicSpline(s, phase)(np.clip(along, s[0], s[-1]))


def ambiguity_spacing(raw: RawData, grid: ImageGrid, column: int | None = None) -> float:
    """The along-track spacing [m] of a point's azimuth ambiguities, ``lambda R0 PRF / (2 v)``
    (``R0`` the closest-approach range from the mid-aperture track of the grid's range ``column``,
    default its farthest; ``v`` the mean speed): no defocused response PGA can undo spreads wider
    (docs/physics.md (PGA6))."""
    from ..core.constants import SPEED_OF_LIGHT
    velocity = np.mean(raw.velocity, axis=0)
    speed = float(np.linalg.norm(velocity))
    direction = velocity / speed
    columns = grid.origin + grid.range[:, None] * grid.range_direction - raw.tx_position[raw.n_pulses // 2]
    r0 = np.linalg.norm(columns - np.outer(columns @ direction, direction), axis=1)
    return SPEED_OF_LIGHT / raw.fc * float(r0.max() if column is None else r0[column]) * raw.prf / (2.0 * speed)


def pga_focus(raw: RawData, algorithm: str, *, window_range: Any, window_azimuth: Any, reference: Any = None,
              progress: bool = False) -> SarImage:
    """Autofocus a focusing through its raw data (docs/physics.md (PGA6), (PGA7)).

    Parameters
    ----------
    raw : RawData
        Data on the track to focus on (the nominal one).
    algorithm : str
        The focuser of the image returned (``bp``, ``ffbp``, ``omegak``, ``rda``); the estimate is
        made on ``bp`` for ``bp``, else on ``ffbp``.
    window_range, window_azimuth : str or (str, dict)
        The windows of the image returned (:func:`~sarmitsuba.focus.dispatch.focus`).
    reference : 3 floats, m, optional
        A known point-like scatterer: the linear part of the error is removed at it (eq. (PGA5)).
    progress : bool

    Returns
    -------
    SarImage
        The data, each pulse corrected by the sum of up to :data:`ROUNDS` rounds (each PGA on the
        pulses' echoes, eq. (PGA7), of the lines chosen on a rectangular-window backprojection
        widened by half the :func:`ambiguity_spacing` at either end), focused with the windows
        asked for. ``metadata["autofocus"]`` says what PGA did: ``applied`` (bool),
        ``applied_to`` (``"pulses"`` or ``"nothing"``), ``rounds`` (the rounds whose estimate was
        applied; 0 where refused), ``refusal`` (why it was not applied; ``""`` where it was),
        ``iterations`` (summed over the rounds), ``per_round`` (each round's ``iterations``,
        ``window_samples`` [samples of one ambiguity period, ``n_pulses`` of them], ``lines``,
        ``window_scr_db`` (:func:`~sarmitsuba.focus.pga_pulses.window_scr_db`) and ``converged``;
        the round from the clutter, (PGA8), has ``across_range`` true, its range bins as ``lines``,
        no windows and ``converged`` false: one estimate, not iterated), ``converged`` (the last round's), ``dominance_db`` (the estimation
        image's after the round from the clutter, (PGA3)), ``found_db`` (the last one's,
        :data:`FOUND_DB`), ``lines_found_as`` (``"point-like"`` or ``"smeared"``, (PGA4), or
        ``"clutter"`` where only the round from the clutter was applied), ``rms_phase_error_rad``
        (of the removed phase over the pulses the estimate supports, less its mean), ``pulse_phase_rad`` (float
        [n_pulses]) and ``linear_part`` ((PGA5)). Where PGA declines, the nominal image unchanged.

    Warns
    -----
    AutofocusWarning
        Where PGA is not applied, saying why (the metadata's ``refusal``): the estimation image
        holds no dominant scatterer (PGA3) nor a smeared one, or too few point-like lines (PGA4),
        or cannot be deramped; or the target's window holds less than :data:`WINDOW_SCR_DB` more
        target than clutter and the round from the clutter was not kept (PGA8); or
        the rounds made it less sharp, or left no scatterer :data:`FOUND_DB` over its clutter.
    """
    from .dispatch import focus, render_focusing
    rounds = _Rounds(raw, algorithm, window_range, render_focusing(raw), progress)
    nominal = focus(raw, algorithm, window_range=window_range, window_azimuth=window_azimuth, progress=progress)
    refusal = rounds.run()
    total = rounds.total
    shift = None
    if not refusal and reference is not None:                 # eq. (PGA5), on the last estimation image
        linear, shift = reference_phase(rounds.image, reference, rounds.positions)
        total = total + linear
    if refusal:
        warnings.warn(f"PGA not applied: {refusal}; the image is focused on the nominal track unchanged",
                      AutofocusWarning, stacklevel=3)
    out = nominal if refusal else focus(corrected(raw, total), algorithm, window_range=window_range,
                                        window_azimuth=window_azimuth, progress=progress)
    metadata = copy.deepcopy(out.metadata)
    metadata["autofocus"] = _metadata(rounds, refusal, total, shift, reference)
    return dataclasses.replace(out, metadata=metadata)


class _Rounds:
    """The rounds of estimate-and-correct through the pulses (docs/physics.md (PGA6), (PGA7)): each
    round backprojects the corrected pulses on the widened grid, picks there the lines to learn from
    (the first round's, kept after), reads the pulses' echoes at their targets and runs (PGA) on
    them, and adds the estimate to ``total`` [rad, per pulse]; ``records`` holds what each round did."""

    def __init__(self, raw: RawData, algorithm: str, window_range: Any, focusing: Any, progress: bool) -> None:
        self.raw, self.window_range, self.progress = raw, window_range, progress
        self.estimator = algorithm if algorithm in ("bp", "ffbp") else "ffbp"
        self.spacing = None if focusing.grid is None else ambiguity_spacing(raw, focusing.grid)
        self.total = np.zeros(raw.n_pulses)
        self.records: list[dict[str, Any]] = []
        self.image = self._estimation_image()
        self.positions = pulse_positions(raw.tx_position, self.image.metadata["focus"]["track"]) \
            if isinstance(self.image.metadata.get("focus", {}).get("track"), dict) else None
        self.dominance_db: float | None = None
        self.found_db: float | None = None
        self.lines: np.ndarray | None = None
        self.smeared = np.zeros(0, int)
        self.found_by = "point-like"
        self.across_tried = False
        self.pulses: RawData | None = None

    def _estimation_image(self, total: np.ndarray | None = None) -> SarImage:
        from .dispatch import autofocus_image
        return autofocus_image(corrected(self.raw, self.total if total is None else total), self.estimator,
                               window_range=self.window_range, azimuth_margin=(self.spacing or 0.0) / 2.0,
                               progress=self.progress)

    def run(self) -> str:
        """Up to :data:`ROUNDS` rounds; ``""``, or why PGA may not be applied. The first window holds at
        most one ambiguity period (the samples' image domain); each round's last window is the next
        one's widest, so that the window narrows round by round."""
        sharp, window = _sharpness(self.image), None
        level = dominance_db(_intensity(self.image))
        if not level >= DOMINANCE_DB:                           # clutter rivals every scatterer: (PGA8)
            kept = self._across_range(sharp, level)
            if kept is not None:
                sharp, level = kept                             # the rounds are judged against its image
        refusal = self._gate(level)
        if refusal:
            self.total[:] = 0.0
            return refusal
        for _ in range(ROUNDS):
            step, reason, window = self._round(window)
            if reason:
                if self.records:
                    break
                return reason
            self.total = self.total + step
            self.image = self._estimation_image()
            inside = self.records[-1]["inside"]
            if not np.sqrt(np.mean((step - step[inside].mean())[inside] ** 2)) >= ROUND_TOLERANCE:
                break
        if not _sharpness(self.image) >= SHARPER * sharp:
            self.total[:] = 0.0
            return (f"its {len(self.records)} round(s) made the image less sharp (sum I^2 / (sum I)^2 fell by "
                    f"{100 * (1 - _sharpness(self.image) / sharp):.0f} %: nothing point-like it could learn from)")
        return self._found()

    def _across_range(self, sharp: float, level: float) -> tuple[float, float] | None:
        """The first round, from every range bin of the clutter (eq. (PGA8),
        :func:`~sarmitsuba.focus.pga_clutter.across_range`), tried where no pixel of the nominal
        track's estimation image stands :data:`~sarmitsuba.focus.autofocus.DOMINANCE_DB` over the
        median of its signal (``level`` [dB]: a scatterer that stands that high outshines the clutter in the
        range bins, its Doppler ramp is not the beam's centroid, and the rounds on its lines need no
        help), on ground-plane images only (:func:`~sarmitsuba.focus.pga_clutter.common_bins`), and
        kept where it leaves that image sharper than ``sharp`` (``sum I^2 / (sum I)^2`` of the
        nominal track's) or its brightest pixel :data:`ACROSS_RISE_DB` higher over the median.
        Returns the kept image's ``(sharpness, dominance [dB])``, or None where it was not kept."""
        raw = _compressed(self.raw, "rect")          # independent bins: a range window would correlate them
        bins = common_bins(raw, self.image)
        if np.count_nonzero(bins) < MIN_BINS:
            return None
        phase, inside = across_range(np.asarray(raw.data)[:, bins])
        if not inside.any():
            return None
        self.across_tried = True
        image = self._estimation_image(phase)
        after, rise = _sharpness(image), dominance_db(_intensity(image))
        if not (after > sharp or rise >= level + ACROSS_RISE_DB):
            return None
        self.total, self.image = phase, image
        self.records.append({"iterations": 1, "window_samples": [], "lines": int(np.count_nonzero(bins)),
                             "window_scr_db": None, "converged": False, "inside": inside, "across_range": True})
        return after, rise

    def _weak(self, scr_db: float) -> str:
        """Why a round on the target's lines is not applied: the clutter in its window rivals it."""
        clutter = ("the estimate from the clutter across range neither sharpened the image nor lifted its peak "
                   f"{ACROSS_RISE_DB:g} dB" if self.across_tried else
                   "no estimate from the clutter across range could be tried (a scatterer 25 dB over the median, too "
                   "few range bins of a common look angle, or a slant-range image)")
        return (f"the scatterer stands only {scr_db:.1f} dB over the clutter in its window (an estimate from its "
                f"range lines needs >= {WINDOW_SCR_DB:g} dB: below, it fits the clutter's phase and gathers the "
                f"clutter into the peak), and {clutter}")

    def _gate(self, level: float) -> str:
        """Why the first estimation image holds nothing PGA may learn from, or ``""``: no pixel
        :data:`~sarmitsuba.focus.autofocus.DOMINANCE_DB` over the median of its signal (eq. (PGA3))
        and no scatterer smeared along a range line standing out of its clutter
        (:func:`~sarmitsuba.focus.pga_lines.smeared_lines`, eq. (PGA4)). On clutter alone the rounds
        would gather speckle into a point: each pulse's phase at one pixel, removed, adds them all
        in phase there."""
        if self.positions is None:
            return "the estimation image records no straight track, so its pulses' positions are unknown"
        data = np.asarray(self.image.data)
        self.smeared = smeared_lines(_intensity(self.image), None, band_occupancy(data, doppler_band(self.image)))[0]
        self.dominance_db = float(level)
        if level >= DOMINANCE_DB or self.smeared.size >= MIN_LINES:
            return ""
        return (f"no dominant scatterer: the brightest pixel is {level:.1f} dB above the median of the image's signal "
                f"(PGA needs >= {DOMINANCE_DB:g} dB; clutter alone reaches about 14 dB), and no range line holds a "
                f"smeared scatterer standing out of its clutter")

    def _found(self) -> str:
        """``""`` where the last estimation image holds a dominant scatterer (its brightest pixel
        :data:`FOUND_DB` over the median of its signal, eq. (PGA3)); else why not."""
        level = dominance_db(_intensity(self.image))
        self.found_db = float(level)
        if level >= FOUND_DB:
            return ""
        self.total[:] = 0.0
        return (f"no dominant scatterer found: after {len(self.records)} round(s) the brightest pixel stands "
                f"{level:.1f} dB over the median of the image's signal (PGA needs >= {FOUND_DB:g} dB once focused; "
                f"clutter alone reaches about 14 dB)")

    def _round(self, window: int | None) -> tuple[np.ndarray, str, int | None]:
        """One round's estimate [rad per pulse], or why there is none, and the next round's widest window
        [samples of the period]."""
        if self.pulses is None:               # a per-pulse phase commutes with range compression: compress once
            self.pulses = _compressed(self.raw, self.window_range)
        raw = corrected(self.pulses, self.total)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", AutofocusWarning)
            found, reason = estimate_pulses(self.image, raw, self.positions, cells=APERTURE_CELLS, max_window=window,
                                            lines=self.lines, progress=self.progress)
            if found is None and self.lines is None and self.smeared.size >= MIN_LINES:
                self.found_by = "smeared"                     # (PGA4): a scatterer smeared below (PGA3)'s peak
                found, reason = estimate_pulses(self.image, raw, self.positions, cells=APERTURE_CELLS,
                                                max_window=window, lines=self.smeared, progress=self.progress)
        if found is None:
            return np.zeros(self.raw.n_pulses), reason, window
        self.lines = found.line_index
        if not found.window_scr_db >= WINDOW_SCR_DB:            # eq. (PGA8): it would fit the clutter's phase
            return np.zeros(self.raw.n_pulses), self._weak(found.window_scr_db), window
        self.records.append({"iterations": len(found.windows), "window_samples": list(found.windows),
                             "lines": found.lines,
                             "window_scr_db": round(found.window_scr_db, 2) if np.isfinite(found.window_scr_db) else None,
                             "converged": bool(found.converged), "inside": found.support})
        return found.phase, "", found.windows[-1]


def _compressed(raw: RawData, window_range: Any) -> RawData:
    """``raw`` range compressed with ``window_range``, as backprojection takes it."""
    from .range_compression import apply_range_window, range_compress
    from .windows import window_spec
    name, params = window_spec(window_range)
    if not raw.range_compressed:
        return range_compress(raw, name, **params)
    return apply_range_window(raw, name, **params) if name != "rect" else raw


def _metadata(rounds: _Rounds, refusal: str, total: np.ndarray, shift: float | None, reference: Any) -> dict[str, Any]:
    """``metadata["autofocus"]`` of :func:`pga_focus` (its Returns give the keys), in JSON types."""
    applied = not refusal and bool(rounds.records)
    inside = rounds.records[0]["inside"] if rounds.records else np.ones(total.size, bool)
    phase = total if applied else np.zeros(total.size)
    rms = float(np.sqrt(np.mean((phase[inside] - phase[inside].mean()) ** 2))) if inside.any() else 0.0
    dominance = rounds.dominance_db
    return {"method": "pga", "applied": applied, "applied_to": "pulses" if applied else "nothing",
            "rounds": len(rounds.records) if applied else 0, "refusal": "" if applied else refusal,
            "iterations": sum(r["iterations"] for r in rounds.records) if applied else 0,
            "per_round": [{k: v for k, v in r.items() if k != "inside"} for r in rounds.records] if applied else [],
            "converged": bool(applied and rounds.records[-1]["converged"]),
            "dominance_db": None if dominance is None or not np.isfinite(dominance) else round(float(dominance), 2),
            "found_db": None if rounds.found_db is None else round(rounds.found_db, 2),
            "lines_found_as": "clutter" if applied and all(r.get("across_range") for r in rounds.records)
            else rounds.found_by,
            "rms_phase_error_rad": round(rms, 4), "deramp": True,
            "linear_part": {"estimated": shift is not None, "shift_m": None if shift is None else round(float(shift), 4),
                            "reference": None if shift is None else [float(v) for v in reference]},
            "pulse_phase_rad": [round(float(v), 5) for v in phase]}


def outcome_line(record: dict[str, Any]) -> str:
    """One line saying what PGA did, from ``metadata["autofocus"]`` alone (the command line prints it,
    so that it cannot disagree with the record): ``"PGA applied through the pulses: R round(s), I
    iterations, phase removed X rad rms[, shift S m removed at the reference]"``, or ``"PGA not
    applied (REFUSAL; image unchanged)"`` with the recorded refusal."""
    if not record.get("applied"):
        return f"PGA not applied ({record.get('refusal') or 'no reason recorded'}; image unchanged)"
    rms = f"{record.get('rms_phase_error_rad', 0.0):.3g} rad rms"
    if "rounds" not in record:
        return f"PGA applied: {record.get('iterations', 0)} iterations, phase error {rms}"
    linear = record.get("linear_part") or {}
    shift = f", shift {linear['shift_m']:.3g} m removed at the reference" if linear.get("estimated") else ""
    return (f"PGA applied through the pulses: {record['rounds']} round(s), {record.get('iterations', 0)} "
            f"iterations, phase removed {rms}{shift}")


def corrected(raw: RawData, phase: np.ndarray) -> RawData:
    """``raw`` with every pulse multiplied by ``exp(-j phase_p)`` (float64 [n_pulses], rad)."""
    return dataclasses.replace(raw, data=(raw.data * np.exp(-1j * phase)[:, None]).astype(raw.data.dtype))


def _intensity(image: SarImage) -> np.ndarray:
    """float64 ``|data|^2`` of ``image``."""
    return np.abs(np.asarray(image.data)).astype(np.float64) ** 2


def _sharpness(image: SarImage) -> float:
    """``sum I^2 / (sum I)^2`` of the intensity ``I``: larger for a better focused image."""
    intensity = _intensity(image)
    return float(np.sum(intensity ** 2) / np.sum(intensity) ** 2)


def response_spread(image: SarImage, spacing: float, column: int | None = None) -> float:
    """The full azimuth extent ``X_d = 2 sqrt(2) sigma`` [m] of the defocused response on range line
    ``column`` of ``image`` (default the brightest): ``sigma`` the rms distance from its centroid,
    weighted by the intensity above :data:`~sarmitsuba.focus.autofocus.BACKGROUND` times the line's
    median (its clutter), over the samples within
    ``spacing / 2`` [m] of it (the azimuth ambiguities lie beyond). For a sinusoidal
    error ``X_d = lambda R0 max|phi'| / (2 pi)``, the whole sweep of its instantaneous position
    (docs/physics.md (PGA6)); measured within 3 % of it on the built-in trihedral's sways."""
    intensity = np.abs(image.data).astype(np.float64) ** 2
    line = intensity[:, int(np.argmax(intensity.max(axis=0))) if column is None else column]
    line = np.maximum(line - BACKGROUND * np.median(line), 0.0)
    step = float(np.median(np.abs(np.diff(image.azimuth))))
    n = line.size
    offset = (np.arange(n) - int(np.argmax(line)) + n // 2) % n - n // 2
    centre = 0.0
    for _ in range(3):                              # the centroid of the samples about it
        near = np.abs(offset - centre) * step <= spacing / 2.0
        centre = float(np.sum(line[near] * offset[near]) / line[near].sum())
    sigma = np.sqrt(np.sum(line[near] * (offset[near] - centre) ** 2) / line[near].sum()) * step
    return float(2.0 * np.sqrt(2.0) * sigma)


