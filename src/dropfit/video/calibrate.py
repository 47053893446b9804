"""Calibration of a drop-test video: the image scale from a ruler, the choice among several scales,
and the capture rate of a slow-motion file from gravity.

Pure functions on arrays and numbers (no file I/O); :mod:`dropfit.videolog` applies them.

Scales (m/px) and their precedence
----------------------------------
A scale can be *given* (``scale_m_per_px``), read off a *ruler* in the background, taken from
*gravity* (the flights' shared acceleration in px/s², drag included, over g) or from the ball's
known *diameter*. The one used is the first available in the order given > ruler > gravity >
diameter (:data:`SCALE_PRECEDENCE`): an order by accuracy, not by precision. A ruler in the ball's
plane is a direct length standard over the whole drop, and measures the keystone as well (below);
gravity is the most precise (about 0.004 % on the default phone clip) but carries what its model
leaves out (without a ruler to rectify the rows, a camera tilt's keystone adds a speed-dependent
curvature, +0.2 % at 0.5°); the tracked diameter depends on the
edge threshold, blur and compression (about 0.2 %). Every other available scale is reported with
its disagreement relative to the chosen one, s_other / s_chosen − 1.

Ruler
-----
:func:`ruler_scale` finds a ruler's tick marks in the background image: columns whose vertical
grey-level changes are strong form the ruler; in each such column the ticks are the dark runs of
the row profile. The ticks are assumed to follow the usual marking, the finest every
``tick_m`` and longer ones every 5 and 10 ticks. The columns with the most regularly spaced,
resolved ticks give the tick rows (a darkness-weighted centroid, sub-pixel); the zones of columns
with fewer (longer) ticks check the count: every longer tick must fall on the same index modulo its
spacing ratio (5 or 10 when the finest ticks are resolved, 2 when only the 5- and 10-tick marks
are). The tick rows against tick number then give px per tick and its standard error.

Keystone
--------
A camera tilted about its horizontal axis images the ball's plane through a homography, so the
scale changes along the image's height: a straight line through the ruler's ticks averages it, and
heights read through that one scale are curved (on the default phone clip, 0.5° of tilt: 3 mm low
at mid-height, the first impact's v_in 0.37 % low and e 1.9 standard errors high). Along a column a
homography is a one-dimensional projective map, so the ticks are fitted by one: the *rectified*
row u = r₀ + (r − r₀) / (1 + κ (r − r₀)) (:func:`rectify_rows`) of every tick is a straight line in
its number, with the keystone κ (1/px) fitted with it and r₀ the ticks' mean row, where the scale
is given. The tracked rows are rectified with the same κ before they become heights. The map does
not depend on the column for a tilt about the horizontal axis alone; a roll or a sideways tilt as
well makes the ruler's κ only approximately the ball's. κ's standard error is recorded, not
budgeted: on the default clip it moves speeds by about 2 κ_se · |r − r₀| ≈ 0.002 %.

Capture rate
------------
In a slow-motion file the container's time runs ``capture/container`` times slower than real time,
so the acceleration measured in container time is g·(container/capture)² in metres. With a length
scale that does not come from gravity (given, ruler or diameter), :func:`infer_capture_rate` turns
the measured acceleration into the capture rate and snaps it to the nearest common camera rate
(:data:`COMMON_CAPTURE_RATES_FPS`) when within :data:`CAPTURE_RATE_SNAP_TOLERANCE`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..numerics import least_squares_covariance, linear_fit, robust_sigma

#: Scale sources in the order in which they are preferred.
SCALE_PRECEDENCE = ("given", "ruler", "gravity", "diameter")
#: A column belongs to the ruler if its mean |vertical grey-level step| is this many times the image median.
RULER_COLUMN_CONTRAST = 3.0
#: Ticks closer than this (px) are not resolved well enough to locate.
MIN_TICK_SPACING_PX = 4.0
#: Fewest adjacent-or-not columns that must agree on a tick count to make a zone of one tick length.
MIN_ZONE_COLUMNS = 3
#: Fewest ticks a column needs for a scale, and fewest longest ticks to check the count.
MIN_TICKS, MIN_LONG_TICKS = 10, 2
#: Largest robust spread of a column's tick spacings, relative to their median, for regular ticks.
MAX_TICK_SPACING_SPREAD = 0.1
#: Largest darkness between resolved ticks, relative to a tick's (aliased fine ticks leave half-dark rows).
MAX_GAP_DARKNESS = 0.25
#: Relative steps of longer ticks on a ruler marked every 5 and 10 ticks: spacing ratio → ticks per step.
_TICKS_PER_STEP = {10: 1, 5: 1, 2: 5}
#: Common capture rates of phone and high-speed cameras, frames/s.
COMMON_CAPTURE_RATES_FPS = (24, 25, 30, 48, 50, 60, 90, 100, 120, 125, 200, 240, 250, 300, 400, 480, 500, 960,
                            1000, 1200, 2000, 2400, 3000, 4000, 5000, 6000, 10000, 20000)
#: An inferred capture rate within this relative distance of a common rate is taken to be that rate.
CAPTURE_RATE_SNAP_TOLERANCE = 0.02
#: A container rate within this relative distance of the inferred capture rate is the capture rate:
#: the independent scale's error (about 1 %) moves the inferred rate by half as much.
CAPTURE_RATE_MATCH_TOLERANCE = 0.05


@dataclass(frozen=True)
class RulerCalibration:
    """Result of :func:`ruler_scale`.

    Attributes
    ----------
    scale_m_per_px, scale_se_m_per_px : float
        Image scale in m/px of rectified rows (the scale at ``keystone_row_px``) and its standard error.
    n_ticks : int
        Ticks in the fit.
    ticks_per_step : int
        Finest ticks between two fitted ticks (1 if the finest ticks are resolved, 5 if only the
        5- and 10-tick marks are).
    keystone_per_px, keystone_se_per_px : float
        The keystone κ in 1/px (:func:`rectify_rows`; 0 for a camera square to the ruler) and its
        standard error.
    keystone_row_px : float
        The row r₀ in px about which rows are rectified: the ticks' mean row.
    """

    scale_m_per_px: float
    scale_se_m_per_px: float
    n_ticks: int
    ticks_per_step: int
    keystone_per_px: float
    keystone_se_per_px: float
    keystone_row_px: float


def rectify_rows(rows_px, keystone_per_px, keystone_row_px):
    """Image rows → rows of one scale throughout, in px: u = r₀ + (r − r₀) / (1 + κ (r − r₀)).

    Parameters
    ----------
    rows_px : numpy.ndarray or float
        Image rows r in px (down).
    keystone_per_px : float
        The keystone κ in 1/px (:attr:`RulerCalibration.keystone_per_px`).
    keystone_row_px : float
        The row r₀ in px where rectified and image rows agree in position and scale.

    Returns
    -------
    numpy.ndarray or float
        Rectified rows u in px.
    """
    offset = np.asarray(rows_px, dtype=float) - keystone_row_px
    return keystone_row_px + offset / (1.0 + keystone_per_px * offset)


def keystoned_rows(rectified_px, keystone_per_px, keystone_row_px):
    """Rectified rows → image rows in px: the inverse of :func:`rectify_rows`."""
    offset = np.asarray(rectified_px, dtype=float) - keystone_row_px
    return keystone_row_px + offset / (1.0 - keystone_per_px * offset)


def _keystoned_line_fit(index, rows):
    """Fit tick rows (px) against tick numbers as a straight line in rectified rows, u = a + b·index.

    Returns
    -------
    (float, float, float, float, float)
        px per tick b and its standard error, the keystone κ (1/px) and its standard error, and r₀ (px).
    """
    row0 = float(np.mean(rows))
    start, _ = linear_fit(np.column_stack([np.ones_like(index), index]), rows)

    def residuals(theta):
        return keystoned_rows(theta[0] + theta[1] * index, theta[2], row0) - rows

    fit = least_squares(residuals, [start[0], start[1], 0.0], x_scale="jac")
    covariance = least_squares_covariance(fit.jac, fit.fun)
    return (float(fit.x[1]), float(np.sqrt(covariance[1, 1])), float(fit.x[2]), float(np.sqrt(covariance[2, 2])),
            row0)


def _dark_runs(profile):
    """Sub-pixel rows (darkness-weighted centroids) and lengths (px) of the dark runs of a row profile,
    and the darkness (grey levels below the 90th percentile, the ruler's face) of every row."""
    face = float(np.percentile(profile, 90))
    darkness = np.clip(face - profile, 0.0, None)
    contrast = float(darkness.max())
    if contrast <= 0:
        return np.array([]), np.array([]), darkness
    dark = np.concatenate([[False], darkness > 0.3 * contrast, [False]])
    starts = np.flatnonzero(dark[1:] & ~dark[:-1])
    ends = np.flatnonzero(~dark[1:] & dark[:-1])  # one past the last dark row
    rows = np.arange(profile.size, dtype=float)
    centres = np.array([np.average(rows[max(a - 1, 0): b + 1], weights=darkness[max(a - 1, 0): b + 1])
                        for a, b in zip(starts, ends)])
    return centres, (ends - starts).astype(float), darkness


def _regular_ticks(profile):
    """Tick rows of a column profile if its ticks are resolved and regularly spaced, else None.

    Resolved means clean gaps: between two ticks, more than a tick's half length plus 1.5 px from
    both, the profile is back near the ruler's face. Fine ticks under 2 px apart alias into a
    regular pattern of every other tick with half-dark rows between them, which this rejects.
    """
    centres, lengths, darkness = _dark_runs(profile)
    inside = (centres - 0.5 * lengths > 1.0) & (centres + 0.5 * lengths < profile.size - 2.0)
    centres, lengths = centres[inside], lengths[inside]  # a tick cut by the image border is off-centre
    if centres.size < MIN_LONG_TICKS:
        return None
    spacing = float(np.median(np.diff(centres)))
    # runs much longer than a tick mark are the background or floor beyond the ruler's ends
    ticks = centres[(lengths <= 0.6 * spacing) & (lengths <= 3.0 * np.median(lengths))]
    if ticks.size < MIN_LONG_TICKS:
        return None
    steps = np.diff(ticks)
    spacing = float(np.median(steps))
    spread = robust_sigma(steps, centre=spacing)
    if spacing < MIN_TICK_SPACING_PX or spread > MAX_TICK_SPACING_SPREAD * spacing:
        return None
    clearance = 0.5 * float(np.median(lengths)) + 1.5
    rows = np.arange(profile.size)
    gaps = [darkness[(rows > a + clearance) & (rows < b - clearance)].max(initial=0.0)
            for a, b in zip(ticks[:-1], ticks[1:])]
    if np.median(gaps) > MAX_GAP_DARKNESS * darkness.max():
        return None
    return ticks


def _check_count(base, longer):
    """Spacing ratios (2, 5 or 10) of the longer ticks to the ``base`` ticks, or None if any longer tick
    is off a base tick, off the common phase, or at another ratio."""
    spacing = float(np.median(np.diff(base)))
    index = np.rint((base - base[0]) / spacing)
    ratios = []
    for ticks in longer:
        exact = float(np.median(np.diff(ticks))) / spacing
        ratio = int(round(exact))
        if ratio not in _TICKS_PER_STEP or abs(exact - ratio) > 0.05 * ratio:
            return None
        nearest = np.abs(ticks[:, None] - base[None, :]).argmin(axis=1)
        if np.any(np.abs(ticks - base[nearest]) > 0.25 * spacing) or np.unique(np.mod(index[nearest], ratio)).size != 1:
            return None
        ratios.append(ratio)
    return ratios


def ruler_scale(grey, tick_m):
    """Image scale from the tick marks of a vertical ruler in a background image.

    Parameters
    ----------
    grey : numpy.ndarray
        Background grey levels, shape (height, width) (e.g. :attr:`dropfit.video.track.Background.grey`).
    tick_m : float
        Spacing of the ruler's finest ticks in m.

    Returns
    -------
    (RulerCalibration or None, str)
        The calibration, or None, and a sentence saying what was found.
    """
    grey = np.asarray(grey, dtype=float)
    score = np.mean(np.abs(np.diff(grey, axis=0)), axis=0)
    strong = score > RULER_COLUMN_CONTRAST * float(np.median(score))
    if not strong.any():
        return None, "no ruler: no column with strong vertical grey-level changes"
    peak = int(np.argmax(np.where(strong, score, -np.inf)))
    first, last = peak, peak
    while first > 0 and strong[first - 1]:
        first -= 1
    while last + 1 < strong.size and strong[last + 1]:
        last += 1
    ticks = {column: _regular_ticks(grey[:, column]) for column in range(first, last + 1)}
    ticks = {column: rows for column, rows in ticks.items() if rows is not None}
    if not ticks:
        return None, f"no ruler: columns {first}-{last} px show no regularly spaced, resolved ticks"
    counts = {column: rows.size for column, rows in ticks.items()}
    # a tick length is a zone of several columns with the same count; lone columns (the ruler's
    # edges, where fine ticks alias) do not count
    zones = {}
    for column, count in counts.items():
        zones.setdefault(count, []).append(column)
    zones = {count: [c for c in counts if abs(counts[c] - count) <= 0.05 * count] for count in zones}
    zones = {count: columns for count, columns in zones.items() if len(columns) >= MIN_ZONE_COLUMNS}
    if not zones:
        return None, f"no ruler: no {MIN_ZONE_COLUMNS} columns in {first}-{last} px agree on their ticks"
    zone_ticks = {count: _regular_ticks(np.mean([grey[:, c] for c in columns], axis=0))
                  for count, columns in zones.items()}
    zone_ticks = {count: ticks for count, ticks in sorted(zone_ticks.items(), reverse=True) if ticks is not None}
    # the finest zone whose count every longer tick confirms; a zone that fails (fine ticks aliased
    # to every other one, say) gives way to the next
    for count, base in zone_ticks.items():
        longer = [ticks for other, ticks in zone_ticks.items() if other < count]
        ratios = _check_count(base, longer) if base.size >= MIN_TICKS and longer else None
        if ratios:
            break
    else:
        return None, (f"no ruler: no zone of columns in {first}-{last} px has {MIN_TICKS} or more regular ticks "
                      f"whose count the longer ticks (every 2, 5 or 10 of them) confirm")
    ratio = max(ratios)
    per_step = _TICKS_PER_STEP[ratio]
    index = np.rint((base - base[0]) / float(np.median(np.diff(base))))
    px_per_tick, px_per_tick_se, keystone, keystone_se, keystone_row = _keystoned_line_fit(index * per_step, base)
    px_per_tick = abs(px_per_tick)
    scale = tick_m / px_per_tick
    result = RulerCalibration(scale, scale * px_per_tick_se / px_per_tick, int(base.size), per_step,
                              keystone, keystone_se, keystone_row)
    return result, (f"ruler in columns {first}-{last} px: {base.size} ticks {per_step} apart, count checked "
                    f"against the longer ticks (every {', '.join(str(r) for r in sorted(set(ratios)))}); "
                    f"keystone {keystone:.3g} ± {keystone_se:.2g} 1/px about row {keystone_row:.1f} px")


def choose_scale(scales):
    """The scale to use and every other one's disagreement with it.

    Parameters
    ----------
    scales : dict
        Source name (one of :data:`SCALE_PRECEDENCE`) → (scale in m/px, standard error in m/px).

    Returns
    -------
    (str, dict)
        The chosen source, and source → s / s_chosen − 1 (dimensionless) for every other source.
    """
    chosen = next(name for name in SCALE_PRECEDENCE if name in scales)
    reference = scales[chosen][0]
    return chosen, {name: value / reference - 1.0 for name, (value, _) in scales.items() if name != chosen}


def infer_capture_rate(acceleration_px_s2, scale_m_per_px, file_fps, gravity_m_s2):
    """Capture rate of a clip from its acceleration measured in file time and a non-gravity scale.

    Parameters
    ----------
    acceleration_px_s2 : float
        Shared downward acceleration of the flights in px/s² of the file's time.
    scale_m_per_px : float
        Image scale in m/px from a source other than gravity.
    file_fps : float
        Frame rate of the file's time base in frames/s.
    gravity_m_s2 : float
        Gravity in m/s².

    Returns
    -------
    dict
        ``estimate_fps`` (√(g / (s·A)) × file rate), ``capture_fps`` (the rate to use: the file's
        own if it matches, else the snapped or the raw estimate), ``snapped`` (bool) and ``why``.
    """
    estimate = file_fps * float(np.sqrt(gravity_m_s2 / (scale_m_per_px * acceleration_px_s2)))
    if abs(estimate / file_fps - 1.0) <= CAPTURE_RATE_MATCH_TOLERANCE:
        return {"estimate_fps": estimate, "capture_fps": file_fps, "snapped": False,
                "why": f"the file's rate {file_fps:g} fps is the capture rate (gravity gives {estimate:.4g} fps)"}
    common = np.asarray(COMMON_CAPTURE_RATES_FPS, dtype=float)
    nearest = float(common[np.argmin(np.abs(common / estimate - 1.0))])
    if abs(nearest / estimate - 1.0) <= CAPTURE_RATE_SNAP_TOLERANCE:
        return {"estimate_fps": estimate, "capture_fps": nearest, "snapped": True,
                "why": f"gravity gives {estimate:.4g} fps against the file's {file_fps:g} fps: "
                       f"slow motion captured at {nearest:g} fps (within {100 * CAPTURE_RATE_SNAP_TOLERANCE:g} %)"}
    return {"estimate_fps": estimate, "capture_fps": estimate, "snapped": False,
            "why": f"gravity gives {estimate:.4g} fps against the file's {file_fps:g} fps, not within "
                   f"{100 * CAPTURE_RATE_SNAP_TOLERANCE:g} % of a common rate: the estimate is used"}
