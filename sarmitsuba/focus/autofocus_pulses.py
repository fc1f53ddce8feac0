"""Phase gradient autofocus through the raw data (docs/physics.md (PGA6)).

Backprojection weights every pulse by the azimuth window and the antenna pattern seen from each
pixel, ``w((x - s_p) / R0)``: a weight that follows the pixel. A motion error's phase
``phi(s_p)`` enters the image under that weight, so the image's deramped spectrum (eq. (PGA2))
holds the error as a product only where the weight is flat, and removing the estimate from the
spectrum of a Taylor-weighted image leaves paired echoes wherever the defocused response
spreads over a good part of the beam (measured: a 2 cm, 30 m sway on the built-in trihedral,
-26.8 dB azimuth PSLR even with the true error removed from the spectrum, -58.1 dB on the true
track). :func:`pga_focus` therefore

1. judges whether PGA may run, (PGA3) and (PGA4), on the image asked for;
2. focuses the data by backprojection with a rectangular azimuth window on the grid widened by
   half the azimuth ambiguities' spacing (:func:`ambiguity_spacing`), where the spectrum holds
   the error as a product (the same correction then gives -38.1 dB against -38.8 dB on the
   true track), and refuses a sway whose response folds onto its ambiguities;
3. runs :func:`~sarmitsuba.focus.autofocus.pga` on that image, which says at which along-track
   antenna position each spectral sample stands (``aperture_position``);
4. removes the estimate from each pulse, ``d_p exp(-j phi(s_p))`` (:func:`pulse_correction`),
   repeats 2-4 until a round changes little, and focuses with the focuser and windows asked for.
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
from .autofocus import APERTURE_CELLS, AutofocusReport, AutofocusWarning, pga

__all__ = ["pulse_correction", "ambiguity_spacing", "pga_focus", "corrected", "response_spread", "ROUNDS",
           "ROUND_TOLERANCE", "TWO_WAY"]


#: Rounds of estimate-and-correct through the pulses at most, and the rms [rad] of a round's
#: correction (over the pulses the estimate supports) below which they stop.
ROUNDS = 6
ROUND_TOLERANCE = 0.01
#: The two-way 3 dB Doppler band over the one-way one (``RadarParameters.doppler_bandwidth``) of
#: a uniformly illuminated antenna: sinc^4 against sinc^2 (docs/physics.md (PGA6)).
TWO_WAY = 0.72


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
    """Autofocus a focusing through its raw data (docs/physics.md (PGA6)).

    Parameters
    ----------
    raw : RawData
        Data on the track to focus on (the nominal one).
    algorithm : str
        The focuser of the image returned (``bp``, ``ffbp``, ``omegak``, ``rda``); the estimate is
        made on ``bp`` for ``bp``, else on ``ffbp``.
    window_range, window_azimuth : str or (str, dict)
        The windows of the image returned (:func:`~sarmitsuba.focus.dispatch.focus`).
    reference, progress
        As :func:`~sarmitsuba.focus.autofocus.pga`.

    Returns
    -------
    SarImage
        The data, each pulse corrected by the summed :func:`pulse_correction` of up to
        :data:`ROUNDS` rounds (each PGA on a rectangular-window backprojection widened by half the
        :func:`ambiguity_spacing` at either end), focused with the windows asked for;
        ``metadata["autofocus"]`` is the first round's record with ``"applied_to": "pulses"``,
        ``"rounds"`` and ``"pulse_phase_rad"`` (float [n_pulses], rad). Where PGA declines, the
        nominal image unchanged (``"applied": False``, ``"refusal"`` why).

    Warns
    -----
    AutofocusWarning
        As :func:`~sarmitsuba.focus.autofocus.pga`; where no range line is point-like, with the
        brightest line's spread; a sway beyond PGA (its defocused response folds onto the azimuth
        ambiguities, docs/physics.md (PGA6)); a first round that does not sharpen the image.
    """
    from .dispatch import autofocus_image, focus, render_focusing
    estimator = algorithm if algorithm in ("bp", "ffbp") else "ffbp"
    grid, _, doppler, _, _ = render_focusing(raw)
    spacing = None if grid is None else ambiguity_spacing(raw, grid)

    def estimate(total: np.ndarray) -> tuple[SarImage, AutofocusReport, list]:
        data = corrected(raw, total)
        image = autofocus_image(data, estimator, window_range=window_range, azimuth_margin=(spacing or 0.0) / 2.0,
                                progress=progress)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", AutofocusWarning)
            report = pga(image, reference=reference, progress=progress, aperture_cells=APERTURE_CELLS)[1]
        return image, report, caught
    nominal = focus(raw, algorithm, window_range=window_range, window_azimuth=window_azimuth, progress=progress)
    with warnings.catch_warnings(record=True) as caught:     # (PGA3), (PGA4) judged on the image asked for
        warnings.simplefilter("always", AutofocusWarning)
        unchanged, gate = pga(nominal, reference=reference, max_iterations=1)
    if not gate.applied:                        # the real cause first: a sway beyond PGA is not point-like
        reason = _not_point_like(estimate(np.zeros(raw.n_pulses))[0], raw, doppler) \
            if gate.refusal.endswith("range line(s)") else ""       # clutter alone has no spread to speak of
        for w in caught:
            warnings.warn_explicit(f"{w.message}{reason}", w.category, w.filename, w.lineno)
        metadata = copy.deepcopy(unchanged.metadata)
        metadata["autofocus"].update(refusal=gate.refusal + reason, rounds=0, applied_to="nothing")
        return dataclasses.replace(unchanged, metadata=metadata)
    total, rounds = np.zeros(raw.n_pulses), 0
    image, first, caught = estimate(total)
    report, limit = first, (_beyond(image, raw, doppler) if first.applied else "")
    while report.applied and report.aperture_position is not None and not limit and rounds < ROUNDS:
        step = pulse_correction(report, raw, image.metadata["focus"]["track"])
        inside = _inside(report, raw, image.metadata["focus"]["track"])
        total, rounds = total + step, rounds + 1
        if not np.sqrt(np.mean((step - step[inside].mean())[inside] ** 2)) >= ROUND_TOLERANCE:
            break
        sharpness = _sharpness(image) if rounds == 1 else None
        image, report, _ = estimate(total)
        if sharpness is not None and not _sharpness(image) >= sharpness:
            limit = "its first round made the image less sharp (no point-like target it could learn from)"
    for w in caught if not rounds and not limit else ():
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    if limit:
        warnings.warn(f"PGA not applied: {limit}; the image is focused on the nominal track unchanged",
                      AutofocusWarning, stacklevel=3)
        total, rounds = total * 0.0, 0
    out = focus(corrected(raw, total), algorithm, window_range=window_range, window_azimuth=window_azimuth,
                progress=progress) if rounds else nominal
    metadata = copy.deepcopy(out.metadata)
    metadata["autofocus"] = {**first.as_metadata(), "applied": bool(rounds), "applied_to": "pulses" if rounds else "nothing",
                             "refusal": limit or first.refusal, "rounds": rounds,
                             "pulse_phase_rad": [round(float(v), 5) for v in total]}
    return dataclasses.replace(out, metadata=metadata)


def corrected(raw: RawData, phase: np.ndarray) -> RawData:
    """``raw`` with every pulse multiplied by ``exp(-j phase_p)`` (float64 [n_pulses], rad)."""
    return dataclasses.replace(raw, data=(raw.data * np.exp(-1j * phase)[:, None]).astype(raw.data.dtype))


def _inside(report: AutofocusReport, raw: RawData, track: dict[str, Any]) -> np.ndarray:
    """bool [n_pulses]: the pulses within the estimate's support."""
    along = (np.asarray(raw.tx_position, float) - np.asarray(track["position"], float)) @ np.asarray(track["direction"], float)
    s = report.aperture_position[report.support]
    inside = (along >= s.min()) & (along <= s.max()) if s.size else np.zeros(along.size, bool)
    return inside if inside.any() else np.ones(along.size, bool)


def _sharpness(image: SarImage) -> float:
    """``sum I^2 / (sum I)^2`` of the intensity ``I``: larger for a better focused image."""
    intensity = np.abs(image.data).astype(np.float64) ** 2
    return float(np.sum(intensity ** 2) / np.sum(intensity) ** 2)


def response_spread(image: SarImage, spacing: float) -> float:
    """The full azimuth extent ``X_d = 2 sqrt(2) sigma`` [m] of the defocused response on the brightest
    range line of ``image``: ``sigma`` the energy-weighted rms distance from its centroid, over the
    samples within ``spacing / 2`` [m] of it (the azimuth ambiguities lie beyond). For a sinusoidal
    error ``X_d = lambda R0 max|phi'| / (2 pi)``, the whole sweep of its instantaneous position
    (docs/physics.md (PGA6)); measured within 3 % of it on the built-in trihedral's sways."""
    intensity = np.abs(image.data).astype(np.float64) ** 2
    line = intensity[:, int(np.argmax(intensity.max(axis=0)))]
    step = float(np.median(np.abs(np.diff(image.azimuth))))
    n = line.size
    offset = (np.arange(n) - int(np.argmax(line)) + n // 2) % n - n // 2
    centre = 0.0
    for _ in range(3):                              # the centroid of the samples about it
        near = np.abs(offset - centre) * step <= spacing / 2.0
        centre = float(np.sum(line[near] * offset[near]) / line[near].sum())
    sigma = np.sqrt(np.sum(line[near] * (offset[near] - centre) ** 2) / line[near].sum()) * step
    return float(2.0 * np.sqrt(2.0) * sigma)


def _not_point_like(first: SarImage, raw: RawData, doppler: float | None) -> str:
    """What to add to PGA's point-like refusal (PGA4), ``" (...)"``: the spread of the brightest
    line's response on the first estimation image and, where it reaches the limit of
    :func:`_beyond`, that a defocused point that wide is beyond PGA (it may be a wall or a rim)."""
    beyond = _beyond(first, raw, doppler)
    if beyond:
        return f" (the brightest line's response: if it is a defocused point, {beyond})"
    spacing = ambiguity_spacing(raw, first, _brightest(first))
    return (f" (the brightest line's response spreads over {response_spread(first, spacing):.1f} m of azimuth: a point "
            f"defocused that far is no longer point-like, and PGA cannot tell it from a wall or a rim)")


def _brightest(image: SarImage) -> int:
    """The range column of ``image``'s brightest pixel."""
    return int(np.argmax(np.max(np.abs(image.data), axis=0)))


def _beyond(first: SarImage, raw: RawData, doppler: float | None) -> str:
    """Why the sway is beyond PGA (docs/physics.md (PGA6)), or ``""``: the first estimate's defocused
    response (:func:`response_spread`) ``X_d >= Delta x_amb (1 - TWO_WAY B_D / PRF)``, the
    ambiguities' spacing ``Delta x_amb`` at the brightest line's range: the phase error's Doppler
    excursion ``2 v X_d / (lambda R0)`` and the beam's two-way band exceed the PRF, and the
    defocused image folds onto its ambiguities."""
    if not doppler:
        return ""
    spacing = ambiguity_spacing(raw, first, _brightest(first))
    spread = response_spread(first, spacing)
    limit = spacing * (1.0 - TWO_WAY * doppler / raw.prf)
    if spread < limit:
        return ""
    return (f"the sway is beyond PGA: its defocused response spreads over {spread:.1f} m, where the PRF leaves "
            f"{limit:.1f} m (the azimuth ambiguities' spacing lambda R0 PRF / (2 v) = {spacing:.1f} m less the "
            f"beam's two-way Doppler band, {TWO_WAY * doppler:.0f} of {raw.prf:.0f} Hz): its Doppler excursion folds; "
            f"raise prf, or fly slower")
