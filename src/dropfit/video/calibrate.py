"""Calibration of a drop-test video: the image scale from a ruler, the choice among several scales,
and the capture rate of a slow-motion file from gravity.

Pure functions on arrays and numbers (no file I/O); :mod:`dropfit.videolog` applies them.

Scales (m/px) and their precedence
----------------------------------
A scale can be *given* (``scale_m_per_px``), from two *points* the user gives a known distance apart,
from a *target* (an ArUco marker or a checkerboard, :mod:`dropfit.video.targets`), read off a *ruler*
in the background, taken from *gravity* (the flights' shared acceleration in px/s², drag included,
over g) or from the ball's known *diameter*. The one used is the first available in the order given
> points > target > ruler > gravity > diameter (:data:`SCALE_PRECEDENCE`): what the user states
first, then an order by accuracy, not by precision (a target also corrects a camera's tilt). A ruler in the ball's
plane is a direct length standard over the whole drop, and an upright one measures the keystone as
well (below); gravity is the most precise (about 0.004 % on the default phone clip) but carries what
its model leaves out (without a ruler or target to rectify the rows, a camera tilt's keystone adds a
speed-dependent curvature, +0.2 % at 0.5°); the tracked diameter depends on the
edge threshold, the ball's shading, blur and compression (1–3 % on phonesim's colour clips:
:data:`dropfit.videolog.DIAMETER_SCALE_RELATIVE_SE`). Every other available scale is reported with
its disagreement relative to the chosen one, s_other / s_chosen − 1. g arbitrates (:func:`choose_scale`):
a target, ruler or diameter that disagrees with gravity's scale beyond their errors is suspect and named
with its likely cause (:data:`SUSPECT_CAUSES`), and the next scale is used.

Ruler
-----
:func:`ruler_scale` finds a ruler's, tape measure's or banded stick's marks in the background image,
upright or lying, in every CIE Lab channel of a colour image (a black tick on a green ruler differs
in a as well as in L), dark marks or light ones. Columns whose changes along them are strong form the
ruler; in each such column the marks are the dark runs below the ruler's local face (the highest
level nearby, so a ruler darker than its wall keeps its face), or, for painted bands, the runs'
edges. The ticks are assumed to follow the usual marking, the finest every ``tick_m`` and longer
ones every 5 and 10 ticks. The columns with the most regularly spaced, resolved ticks give the tick
rows (a darkness-weighted centroid, sub-pixel); the zones of columns with fewer (longer) ticks check
the count: every longer tick must fall on the same index modulo its spacing ratio (5 or 10 when the
finest ticks are resolved, 2 when only the 5- and 10-tick marks are). Marks all of one length that
cross the ruler (a stick's lines, bands) are each taken as one ``tick_m`` with no count check: a
scale off by a whole factor shows as a disagreement with gravity or the diameter. Marks are numbered
from a spacing fitted to all of them (:func:`mark_numbers`; ticks on whole pixel rows step 4 and 5 px
for 4.5, and a median step would let the count drift); a straight line of mark position against
number, with outliers left out, gives px per tick and its standard error from the residuals.

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

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ..numerics import least_squares_covariance, linear_fit, robust_sigma

#: Scale sources in the order in which they are preferred.
SCALE_PRECEDENCE = ("given", "points", "target", "ruler", "gravity", "diameter")
#: A column belongs to the ruler if its mean |step| along it (smoothed over 1 px, so that noise does
#: not hide broad bands) is this many times the image median; the ruler's columns then extend to
#: either side while it is :data:`RULER_COLUMN_EXTENT` times the median, over gaps of up to
#: :data:`RULER_COLUMN_GAP_PX` (a ruler's sparse long ticks and its numbers are weaker than its fine ticks).
RULER_COLUMN_CONTRAST, RULER_COLUMN_EXTENT, RULER_COLUMN_GAP_PX = 3.0, 1.5, 4
#: Shortest window (px) in which a profile's highest level is the ruler's face.
FACE_WINDOW_PX = 31
#: Marks of one length only must be found in this fraction of the ruler's strong columns (they cross
#: it: a stick's lines or bands; a ruler's long ticks alone do not).
MIN_UNIFORM_COVERAGE = 0.4
#: Marks closer than this (px) are not resolved well enough to locate.
MIN_TICK_SPACING_PX = 4.0
#: Fewest adjacent-or-not columns that must agree on a tick count to make a zone of one tick length.
MIN_ZONE_COLUMNS = 3
#: Fewest marks a column needs for a scale, and fewest longest ticks to check the count.
MIN_TICKS, MIN_LONG_TICKS = 10, 2
#: Largest robust spread of the marks about their straight line, relative to their spacing ...
MAX_TICK_RESIDUAL = 0.1
#: ... or in px, whichever is larger: marks drawn on whole pixel rows sit up to 0.5 px off the line.
MAX_TICK_RESIDUAL_PX = 0.5
#: A mark this many robust standard deviations off the line is left out of it.
OUTLIER_IN_SIGMA = 4.0
#: Largest darkness between resolved ticks, relative to a tick's (aliased fine ticks leave half-dark rows).
MAX_GAP_DARKNESS = 0.25
#: Dark runs this long (px) and at least this fraction of their spacing are painted bands, not ticks:
#: their edges are the marks, one band length apart.
MIN_BAND_PX, MIN_BAND_DUTY = 6.0, 0.35
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
#: Slow motion plays a capture back at least this many times slower than it was filmed (60 fps stored as
#: 30): an estimate nearer the file's rate, at no common rate, says that the length scale is off (a ball
#: measured with its shadow or its blur), not the rate.
MIN_SLOW_MOTION_FACTOR = 1.5


@dataclass(frozen=True)
class RulerCalibration:
    """Result of :func:`ruler_scale`.

    Attributes
    ----------
    scale_m_per_px, scale_se_m_per_px : float
        Image scale in m/px of rectified rows (the scale at ``keystone_row_px``) and its standard
        error (from the residuals of the fit of mark position against mark number).
    n_ticks : int
        Marks in the line fit.
    ticks_per_step : int
        Finest ticks between two fitted marks (1 if the finest ticks are resolved, 5 if only the
        5- and 10-tick marks are).
    orientation : str
        ``upright`` (ticks along image rows) or ``lying`` (along columns).
    channel : str
        The image channel the marks were found in: ``grey``, or ``L``, ``a``, ``b`` of CIE Lab, with
        ``inverted`` for light marks on a dark face.
    marks : str
        ``ticks, count checked`` (longer ticks confirm the count), ``marks of one length`` (no longer
        ticks; each mark is one ``tick_m`` on) or ``band edges`` (painted alternating bands).
    keystone_per_px, keystone_se_per_px : float
        The keystone κ in 1/px (:func:`rectify_rows`; 0 for a camera square to the ruler, and for a
        lying ruler, which cannot tell it) and its standard error.
    keystone_row_px : float
        The row r₀ in px about which rows are rectified: the ticks' mean row.
    """

    scale_m_per_px: float
    scale_se_m_per_px: float
    n_ticks: int
    ticks_per_step: int
    orientation: str = "upright"
    channel: str = "grey"
    marks: str = "ticks, count checked"
    n_columns: int = 0
    keystone_per_px: float = 0.0
    keystone_se_per_px: float = 0.0
    keystone_row_px: float = 0.0


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
    """Dark runs of a profile along the ruler: their sub-pixel centres (darkness-weighted centroids),
    lengths (px) and edges (half-darkness crossings, shape (n, 2)), and the darkness of every row.

    The darkness is the level below the ruler's local face, the highest level within a sixth of the
    profile's length (at least :data:`FACE_WINDOW_PX`): a ruler darker than the wall behind it keeps its
    own face level, and a painted band is shorter than the window.
    """
    from scipy.ndimage import maximum_filter1d  # here: only a ruler's image needs it, not every trajectory

    window = max(FACE_WINDOW_PX, profile.size // 6)
    face = maximum_filter1d(profile, window, mode="nearest")
    darkness = np.clip(face - profile, 0.0, None)
    contrast = float(darkness.max())
    if contrast <= 0:
        return np.array([]), np.array([]), np.empty((0, 2)), darkness
    dark = np.concatenate([[False], darkness > 0.3 * contrast, [False]])
    starts = np.flatnonzero(dark[1:] & ~dark[:-1])
    ends = np.flatnonzero(~dark[1:] & dark[:-1])  # one past the last dark row
    rows = np.arange(profile.size, dtype=float)
    centres = np.array([np.average(rows[max(a - 1, 0): b + 1], weights=darkness[max(a - 1, 0): b + 1])
                        for a, b in zip(starts, ends)])
    edges = np.array([[_crossing(darkness, a - 1, a), _crossing(darkness, b, b - 1)] for a, b in zip(starts, ends)])
    return centres, (ends - starts).astype(float), edges.reshape(-1, 2), darkness


def _crossing(darkness, outside, inside):
    """Sub-pixel row between adjacent rows ``outside`` and ``inside`` where the darkness crosses half
    the run's median darkness (linear interpolation)."""
    if outside < 0 or outside >= darkness.size:
        return float(inside)
    low, high = darkness[outside], darkness[inside]
    half = 0.5 * float(np.median(darkness[darkness > 0.3 * darkness.max()]))
    fraction = np.clip((half - low) / (high - low), 0.0, 1.0) if high != low else 0.5
    return float(outside + fraction * (inside - outside))


def _level(profile, row):
    """The profile's level at the nearest row to ``row``, clipped to the profile."""
    return float(profile[int(np.clip(np.rint(row), 0, profile.size - 1))])


def mark_numbers(positions):
    """Mark numbers and the spacing of regularly spaced marks, allowing for missing ones.

    The spacing starts from the median step and is refined from the marks' whole extent over the
    count of steps it holds: with marks on whole pixel rows (steps of 4 and 5 px for 4.4) a median
    step would let the numbers drift. A mark less than half a step after the previous one is dropped.

    Parameters
    ----------
    positions : numpy.ndarray
        Sorted mark positions in px.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, float)
        The marks kept (px), their numbers (0, 1, …, float) and the spacing in px per number.
    """
    positions = np.asarray(positions, dtype=float)
    spacing = float(np.median(np.diff(positions)))
    for _ in range(3):
        steps = np.rint(np.diff(positions) / spacing)
        keep = np.concatenate([[True], steps > 0])
        positions, numbers = positions[keep], np.concatenate([[0.0], np.cumsum(steps[steps > 0])])
        spacing = (positions[-1] - positions[0]) / max(numbers[-1], 1.0)
    return positions, numbers, spacing


def _regular_ticks(profile):
    """Mark rows of a profile along the ruler if its marks are resolved and regularly spaced, else None.

    Marks are the dark runs' centroids, or, for painted bands (runs of :data:`MIN_BAND_PX` or more
    and :data:`MIN_BAND_DUTY` of their spacing), the runs' edges. Resolved means clean gaps:
    between two ticks, more than a tick's half length plus 1.5 px from both, the profile is back
    near the ruler's face. Fine ticks under 2 px apart alias into a regular pattern of every other
    tick with half-dark rows between them, which this rejects.
    """
    centres, lengths, edges, darkness = _dark_runs(profile)
    inside = (centres - 0.5 * lengths > 1.0) & (centres + 0.5 * lengths < profile.size - 2.0)
    centres, lengths, edges = centres[inside], lengths[inside], edges[inside]  # cut by the border: off-centre
    if centres.size < MIN_LONG_TICKS:
        return None
    spacing = float(np.median(np.diff(centres)))
    # runs much longer than a mark are the background or floor beyond the ruler's ends
    keep = (lengths <= 0.6 * spacing) & (lengths <= 3.0 * np.median(lengths))
    ticks, lengths, edges = centres[keep], lengths[keep], edges[keep]
    if ticks.size < MIN_LONG_TICKS:
        return None
    banded = np.median(lengths) >= max(MIN_BAND_PX, MIN_BAND_DUTY * spacing)
    if banded:
        # a band is lighter on both sides in the profile itself; past the ruler's end the local face
        # falls to the wall's level and makes a run there with no real edge
        real = [min(_level(profile, e0 - 2.0), _level(profile, e1 + 2.0)) - _level(profile, centre)
                > 0.3 * darkness.max() for centre, (e0, e1) in zip(ticks, edges)]
        edges = edges[np.asarray(real, dtype=bool)]
        if edges.shape[0] < MIN_LONG_TICKS:
            return None
    marks, numbers, spacing = mark_numbers(np.sort(edges.ravel()) if banded else ticks)
    residuals = marks - np.polyval(np.polyfit(numbers, marks, 1), numbers)
    if spacing < MIN_TICK_SPACING_PX or \
            robust_sigma(residuals, centre=0.0) > max(MAX_TICK_RESIDUAL * spacing, MAX_TICK_RESIDUAL_PX):
        return None
    clearance = 0.5 * float(np.median(lengths)) + 1.5
    rows = np.arange(profile.size)
    gaps = [darkness[(rows > a + clearance) & (rows < b - clearance)].max(initial=0.0)
            for a, b in zip(ticks[:-1], ticks[1:])]
    if np.median(gaps) > MAX_GAP_DARKNESS * darkness.max():
        return None
    return marks, bool(banded)


def _check_count(base, longer):
    """Spacing ratios (2, 5 or 10) of the longer ticks to the ``base`` ticks, or None if any longer tick
    is off a base tick, off the common phase, or at another ratio."""
    base, index, spacing = mark_numbers(base)
    ratios = []
    for ticks in longer:
        exact = mark_numbers(ticks)[2] / spacing
        ratio = int(round(exact))
        if ratio not in _TICKS_PER_STEP or abs(exact - ratio) > 0.05 * ratio:
            return None
        nearest = np.abs(ticks[:, None] - base[None, :]).argmin(axis=1)
        if np.any(np.abs(ticks - base[nearest]) > 0.25 * spacing) or np.unique(np.mod(index[nearest], ratio)).size != 1:
            return None
        ratios.append(ratio)
    return ratios


def _longest_run(columns):
    """The longest run of adjacent columns among sorted ``columns`` (a tick length's zone is one run;
    columns of printed numbers that happen to match its count lie apart)."""
    runs = np.split(np.asarray(columns), np.flatnonzero(np.diff(columns) > 1) + 1)
    return list(max(runs, key=len))


def _contrast_channels(image):
    """Name → 2-D float image of the channels a ruler's marks may show in, each also inverted (light
    marks on a dark face): grey for a grey image; CIE Lab's L, a and b for a BGR one, so that a mark
    that differs from the face in hue only (black on a green ruler differs in a) is seen too."""
    image = np.asarray(image)
    if image.ndim == 2:
        planes = {"grey": image.astype(float)}
    else:
        from .opencv import cv2

        lab = cv2.cvtColor(np.clip(image, 0, 255).astype(np.uint8), cv2.COLOR_BGR2LAB).astype(float)
        planes = {name: lab[:, :, k] for k, name in enumerate("Lab")}
    return {**planes, **{f"{name} inverted": 255.0 - plane for name, plane in planes.items()}}


def ruler_scale(image, tick_m):
    """Image scale from the marks of a ruler, tape measure or banded stick in a background image.

    The ruler may stand upright or lie (along image rows or columns), be of any colour (every CIE
    Lab channel is searched, dark and light marks), have ticks on whole pixel rows, finest ticks too
    close to resolve (the 5- and 10-tick marks are then used), marks of one length only, or painted
    alternating bands (their edges are the marks). Of every channel and orientation that gives a
    scale, one whose count longer ticks confirm is preferred, then the smallest standard error.

    Parameters
    ----------
    image : numpy.ndarray
        Background grey levels, shape (height, width), or BGR colours, shape (height, width, 3).
    tick_m : float
        Spacing in m of the ruler's finest ticks, of its marks when they are all alike, or the
        length of a painted band.

    Returns
    -------
    (RulerCalibration or None, str)
        The calibration, or None, and a sentence saying what was found.
    """
    found, notes = [], []
    for orientation in ("upright", "lying"):
        for channel, plane in _contrast_channels(image).items():
            ruler, note = _ruler_in(plane if orientation == "upright" else plane.T, tick_m)
            if ruler is None:
                notes.append(note)
            else:
                lying = {} if orientation == "upright" else {"keystone_per_px": 0.0, "keystone_se_per_px": 0.0}
                found.append((dataclasses.replace(ruler, orientation=orientation, channel=channel, **lying), note))
    if not found:
        return None, notes[0] + " (nor in any other colour channel or lying)"
    ruler, note = _best(found)
    return ruler, f"{note}; {ruler.orientation}, in the {ruler.channel} channel"


def _ruler_in(grey, tick_m):
    """:func:`ruler_scale` on one channel with the ruler along its rows (its columns cross the ticks)."""
    from scipy.ndimage import gaussian_filter1d  # here: only a ruler's image needs it, not every trajectory

    score = np.mean(np.abs(np.diff(gaussian_filter1d(grey, 1.0, axis=0), axis=0)), axis=0)
    median = float(np.median(score))
    strong = score > RULER_COLUMN_CONTRAST * median
    if not strong.any():
        return None, "no ruler: no column with strong changes along it"
    extent = score > RULER_COLUMN_EXTENT * median
    found, notes, column = [], [], 0
    while strong[column:].any():  # each zone of strong columns, widened to its extent
        first = last = column + int(np.argmax(strong[column:]))
        while first > 0 and extent[max(first - RULER_COLUMN_GAP_PX, 0): first].any():
            first -= 1
        while last + 1 < strong.size and extent[last + 1: last + 1 + RULER_COLUMN_GAP_PX].any():
            last += 1
        ruler, note = _ruler_in_columns(grey, first, last, strong, tick_m)
        (notes if ruler is None else found).append(note if ruler is None else (ruler, note))
        column = last + 1
    if not found:
        return None, notes[int(np.argmax([note.count(" ") for note in notes]))] if len(notes) > 1 else notes[0]
    return _best(found)


def _best(found):
    """The (calibration, note) whose count longer ticks confirm, else whose marks cross the most
    columns; then the smallest relative standard error."""
    return min(found, key=lambda item: (item[0].marks != "ticks, count checked", -item[0].n_columns,
                                        item[0].scale_se_m_per_px / item[0].scale_m_per_px))


def _ruler_in_columns(grey, first, last, strong, tick_m):
    """:func:`ruler_scale` on columns ``first`` to ``last`` of one channel (``strong``: the columns of
    strong changes)."""
    ticks = {column: _regular_ticks(grey[:, column]) for column in range(first, last + 1)}
    ticks = {column: found[0] for column, found in ticks.items() if found is not None}
    if not ticks:
        return None, f"no ruler: columns {first}-{last} px show no regularly spaced, resolved marks"
    counts = {column: rows.size for column, rows in ticks.items()}
    # a tick length is a zone of several columns with the same count; lone columns (the ruler's
    # edges, where fine ticks alias) do not count
    zones = {}
    for column, count in counts.items():
        zones.setdefault(count, []).append(column)
    zones = {count: _longest_run([c for c in counts if abs(counts[c] - count) <= 0.05 * count]) for count in zones}
    zones = {count: columns for count, columns in zones.items() if len(columns) >= MIN_ZONE_COLUMNS}
    if not zones:
        return None, f"no ruler: no {MIN_ZONE_COLUMNS} columns in {first}-{last} px agree on their marks"
    zone_ticks = {count: _regular_ticks(np.mean([grey[:, c] for c in columns], axis=0))
                  for count, columns in zones.items()}
    zone_ticks = {count: found for count, found in sorted(zone_ticks.items(), reverse=True) if found is not None}
    # the finest zone whose count every longer tick confirms; a zone that fails (fine ticks aliased
    # to every other one, say) gives way to the next
    for count, (base, _) in zone_ticks.items():
        longer = [ticks for other, (ticks, _) in zone_ticks.items() if other < count]
        ratios = _check_count(base, longer) if base.size >= MIN_TICKS and longer else None
        if ratios:
            marks, per_step = "ticks, count checked", _TICKS_PER_STEP[max(ratios)]
            columns = len(zones[count])
            break
    else:
        # marks all of one length (one zone, or zones that agree): each is one tick_m on, there are
        # no longer ticks to check the count against
        sizes = {found[0].size for found in zone_ticks.values()}
        crossing = sum(len(columns) for count, columns in zones.items() if count in zone_ticks)
        if not zone_ticks or max(sizes) > 1.05 * min(sizes) or max(sizes) < MIN_TICKS \
                or crossing < MIN_UNIFORM_COVERAGE * np.count_nonzero(strong[first: last + 1]):
            return None, (f"no ruler: no zone of columns in {first}-{last} px has {MIN_TICKS} or more regular "
                          f"marks whose count the longer ticks (every 2, 5 or 10 of them) confirm")
        base, banded = max(zone_ticks.values(), key=lambda found: found[0].size)
        columns = crossing
        marks, per_step = "band edges" if banded else "marks of one length", 1
    base, index, _ = mark_numbers(base)
    design = np.column_stack([np.ones_like(index), index * per_step])
    kept = np.ones(base.size, dtype=bool)
    for _ in range(3):  # a mark next to the ruler's end or a number is off the line: leave it out
        coef, covariance = linear_fit(design[kept], base[kept])
        residuals = base - design @ coef
        limit = max(OUTLIER_IN_SIGMA * robust_sigma(residuals[kept], centre=0.0), MAX_TICK_RESIDUAL_PX)
        if np.array_equal(kept, np.abs(residuals) <= limit):
            break
        kept = np.abs(residuals) <= limit
    px_per_tick, px_per_tick_se, keystone, keystone_se, keystone_row = _keystoned_line_fit(
        index[kept] * per_step, base[kept])
    px_per_tick = abs(px_per_tick)
    scale = tick_m / px_per_tick
    result = RulerCalibration(scale, scale * px_per_tick_se / px_per_tick, int(kept.sum()), per_step, marks=marks,
                              n_columns=columns, keystone_per_px=keystone, keystone_se_per_px=keystone_se,
                              keystone_row_px=keystone_row)
    if marks != "ticks, count checked":
        return result, f"ruler in columns {first}-{last} px: {base.size} {marks}, each taken as {tick_m:g} m"
    return result, (f"ruler in columns {first}-{last} px: {base.size} ticks {per_step} apart, count checked "
                    f"against the longer ticks (every {', '.join(str(r) for r in sorted(set(ratios)))})")


#: How far a scale may differ from the ball's diameter, beyond the pixel by which a tracked radius can
#: be off (the edge threshold, blur): a ruler counted in the wrong marks, a slipped unit or a wrong ball
#: radius shows as a whole factor (2, 2.54, 5, 10), far outside this.
DIAMETER_AGREEMENT = 0.15


def diameter_conflict(scales, radius_px):
    """The scale that the ball's diameter contradicts, if any: the one chosen by precedence among the
    sources that do not come from gravity.

    Parameters
    ----------
    scales : dict
        Source name (one of :data:`SCALE_PRECEDENCE`) → (scale in m/px, standard error in m/px), with
        ``diameter`` among them.
    radius_px : float
        The ball's median tracked radius, px.

    Returns
    -------
    (str, float) or None
        The contradicted source and its scale over the diameter's (dimensionless), or None when they
        agree within :data:`DIAMETER_AGREEMENT` plus one pixel of radius, or there is nothing to compare.
    """
    if "diameter" not in scales or not np.isfinite(radius_px) or radius_px <= 0:
        return None
    chosen = next(name for name in SCALE_PRECEDENCE if name in scales and name != "gravity")
    if chosen == "diameter":
        return None
    ratio = scales[chosen][0] / scales["diameter"][0]
    if abs(np.log(ratio)) <= np.log1p(DIAMETER_AGREEMENT + 1.0 / radius_px):
        return None
    return chosen, ratio


#: Scales that gravity arbitrates: measured in the image, each with a way of being off that its own standard error
#: does not hold (what the user states, a given scale or two points, is used as stated).
ARBITRATED_SCALES = ("target", "ruler", "diameter")
#: A scale agrees with gravity's within this many standard errors of the two together ...
SCALE_AGREEMENT_SIGMAS = 3.0
#: ... or within this relative difference, whichever is larger: what each one's model leaves out (a ruler a little
#: nearer the camera than the ball, a camera's tilt bending the flights) is of this order.
SCALE_AGREEMENT_FLOOR = 0.03
#: What makes each arbitrated scale disagree with gravity, as the report names it.
SUSPECT_CAUSES = {
    "diameter": "the ball's tracked outline is not its size (a halo, motion blur, shading or its shadow), or its "
                "radius is not the one given",
    "ruler": "the ruler is not in the ball's plane (nearer or farther from the camera: perspective), or its ticks "
             "were misread (check --ruler-tick-m)",
    "target": "the marker or board is not in the ball's plane, or its printed size is not the one given",
}


def scales_agree(first, second):
    """True when two (scale in m/px, se in m/px) agree within :data:`SCALE_AGREEMENT_SIGMAS` of their combined
    relative standard error or :data:`SCALE_AGREEMENT_FLOOR`, whichever is larger."""
    (a, a_se), (b, b_se) = first, second
    combined = float(np.hypot(a_se / a, b_se / b))
    return abs(a / b - 1.0) <= max(SCALE_AGREEMENT_SIGMAS * combined, SCALE_AGREEMENT_FLOOR)


def choose_scale(scales):
    """The scale to use, every other one's disagreement with it, and the scales gravity names as suspect.

    The first in :data:`SCALE_PRECEDENCE` is used, except that g arbitrates the scales measured in the
    image (:data:`ARBITRATED_SCALES`): one that disagrees with gravity's (:func:`scales_agree`) is suspect
    and not used; g is known to 0.3 % anywhere, a ball's apparent diameter or a ruler's distance from the
    ball's plane is not. Gravity's scale comes before the diameter's however uncertain it is: it makes the
    flights fall with g by construction, so e, fitted with g held, takes no bias from it (a diameter 16 % off,
    within three of its and an imprecise gravity's standard errors, bends every flight by 16 %), and its
    uncertainty goes into the heights alone.

    Parameters
    ----------
    scales : dict
        Source name (one of :data:`SCALE_PRECEDENCE`) → (scale in m/px, standard error in m/px).

    Returns
    -------
    (str, dict, dict)
        The chosen source; source → s / s_chosen − 1 (dimensionless) for every other source; suspect
        source → its likely cause (:data:`SUSPECT_CAUSES`).
    """
    gravity = scales.get("gravity")
    suspects = {} if gravity is None else {
        name: SUSPECT_CAUSES[name] for name in ARBITRATED_SCALES
        if name in scales and not scales_agree(scales[name], gravity)}
    chosen = next(name for name in SCALE_PRECEDENCE if name in scales and name not in suspects)
    reference = scales[chosen][0]
    return (chosen, {name: value / reference - 1.0 for name, (value, _) in scales.items() if name != chosen},
            suspects)


def slow_motion_reading(acceleration_ratio, file_fps, advice="give --capture-fps {rate:g}"):
    """What an acceleration far below g in a file's time says of its time base, or None.

    Slow motion plays a capture back ``capture/file`` times slower, so the flights fall with
    g·(file/capture)² in the file's time: a ratio a/g of at most 1/:data:`MIN_SLOW_MOTION_FACTOR`² points
    to it, at a capture rate of about file·√(g/a), snapped to a common rate within
    :data:`CAPTURE_RATE_SNAP_TOLERANCE` (or the nearest 10 % otherwise).

    Parameters
    ----------
    acceleration_ratio : float
        The flights' downward acceleration in the file's time over g (dimensionless).
    file_fps : float
        The file's frame or sample rate, frames/s.
    advice : str
        What to do, formatted with the ``rate`` (frames/s).

    Returns
    -------
    str or None
        One clause, e.g. "falls 1110 times slower than g: a slow-motion clip? its capture rate would be about
        1000 fps; give --capture-fps 1000", or None when the ratio does not point to slow motion.
    """
    if not (np.isfinite(acceleration_ratio) and 0 < acceleration_ratio <= MIN_SLOW_MOTION_FACTOR ** -2) \
            or not (np.isfinite(file_fps) and file_fps > 0):
        return None
    estimate = file_fps / float(np.sqrt(acceleration_ratio))
    common = np.asarray(COMMON_CAPTURE_RATES_FPS, dtype=float)
    nearest = float(common[np.argmin(np.abs(common / estimate - 1.0))])
    rate = nearest if abs(nearest / estimate - 1.0) <= CAPTURE_RATE_SNAP_TOLERANCE else float(f"{estimate:.2g}")
    return (f"falls {1.0 / acceleration_ratio:.0f} times slower than g: a slow-motion clip? its capture rate would "
            f"be about {rate:g} fps ({file_fps:.4g} fps in the file); {advice.format(rate=rate)}")


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
        own if it matches, else the snapped estimate; off every common rate, the raw estimate for slow
        motion, ``MIN_SLOW_MOTION_FACTOR`` times the file's rate or more, else the file's own),
        ``snapped`` (bool) and ``why``.
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
    if estimate < MIN_SLOW_MOTION_FACTOR * file_fps:
        return {"estimate_fps": estimate, "capture_fps": file_fps, "snapped": False,
                "why": f"the file's rate {file_fps:g} fps is kept: gravity gives {estimate:.4g} fps, neither a "
                       f"common rate nor slow motion, so the length scale it was measured with is "
                       f"{100 * ((estimate / file_fps) ** 2 - 1):+.0f} % off"}
    return {"estimate_fps": estimate, "capture_fps": estimate, "snapped": False,
            "why": f"gravity gives {estimate:.4g} fps against the file's {file_fps:g} fps, not within "
                   f"{100 * CAPTURE_RATE_SNAP_TOLERANCE:g} % of a common rate: the estimate is used"}
