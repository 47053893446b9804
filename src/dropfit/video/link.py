"""The ball among everything that moves: round blobs of many frames linked into a ballistic flight.

The tracker (:mod:`dropfit.video.track`) follows one object from frame to frame and, when it has
lost it, takes the roundest blob of the frame. On a clip that starts with hands in view and a small
ball, that blob can be a knuckle or a sleeve, and the tracker follows the hand. What singles the ball
out is its motion: in flight it keeps its size and its centre follows a parabola in time (constant
acceleration, the same in every frame), which no hand does for long. This module finds that flight:

1. In every frame, the lone round blobs (:func:`dropfit.video.detect.frame_blobs`), not a fixture.
2. From each pair of blobs in consecutive frames of about the same size, a chain is grown frame by
   frame: the next centre is predicted from the last three (constant acceleration; from the last two
   at first) and the blob of about the same size nearest the prediction, within
   ``LINK_TOLERANCE_RADII`` radii, joins; a frame without one may be skipped (``MAX_GAP_FRAMES``).
3. A chain is a flight when it spans ``MIN_FLIGHT_FRAMES`` frames or more, moves by at least
   ``MIN_TRAVEL_DIAMETERS`` diameters, accelerates downwards in the image more than sideways, and
   a parabola in time fits its centres within ``MAX_PARABOLA_RMS_RADII`` radii.

The longest flight wins. The tracker then starts on it as it would on a user's ``--ball-at-px``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .detect import frame_blobs, off_fixtures

#: A candidate joins a chain when it is within this many radii of the predicted centre (and 2 px).
LINK_TOLERANCE_RADII = 1.0
MIN_LINK_TOLERANCE_PX = 2.0
#: Blobs of one chain differ in radius by at most this factor (find_blobs' radii are coarse).
MAX_RADIUS_RATIO = 1.5
#: Frames without a candidate a chain may skip before it ends.
MAX_GAP_FRAMES = 2
#: What makes a chain a flight: frames spanned, travel in diameters, fit of a parabola in time.
MIN_FLIGHT_FRAMES = 6
MIN_TRAVEL_DIAMETERS = 3.0
MAX_PARABOLA_RMS_RADII = 0.5
#: At most this many lone blobs of a frame are linked (the largest first).
MAX_CANDIDATES = 20


class Flight(NamedTuple):
    """A ballistic chain of blobs: the frames, centres (px) and radius (px, the median blob's)."""

    frames: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    radius_px: float

    def start(self):
        """(frame index, x px, y px) of the flight's first blob: where the tracker starts."""
        return int(self.frames[0]), float(self.x_px[0]), float(self.y_px[0])


def frame_candidates(frame, background, contrast):
    """Lone round blobs of one frame in ``contrast``, not at a fixture: array (n, 3) of x, y and radius, px."""
    # (a frame decoded lazily, :class:`dropfit.video.decode.LazyFrame`, is converted whole)
    blobs = [blob for blob in off_fixtures(frame_blobs(np.asarray(frame), background, contrast), contrast.fixtures)
             if blob[3]]
    return np.array([blob[:3] for blob in blobs[:MAX_CANDIDATES]], float).reshape(-1, 3)


def extrapolated(history, index):
    """The centre (x, y) at frame ``index`` continued from the last two or three (frame, x, y) of
    ``history``: constant acceleration through three (Lagrange), constant velocity through two, px."""
    if len(history) == 1:
        return history[0][1:]
    if len(history) == 2:
        (t0, x0, y0), (t1, x1, y1) = history
        f = (index - t1) / (t1 - t0)
        return x1 + f * (x1 - x0), y1 + f * (y1 - y0)
    (t0, x0, y0), (t1, x1, y1), (t2, x2, y2) = history[-3:]
    l0 = (index - t1) * (index - t2) / ((t0 - t1) * (t0 - t2))
    l1 = (index - t0) * (index - t2) / ((t1 - t0) * (t1 - t2))
    l2 = (index - t0) * (index - t1) / ((t2 - t0) * (t2 - t1))
    return l0 * x0 + l1 * x1 + l2 * x2, l0 * y0 + l1 * y1 + l2 * y2


def _grow(candidates, start, first, second):
    """The chain from blob ``first`` of frame ``start`` and blob ``second`` of the next: (frame, row) pairs."""
    chain = [(start, first), (start + 1, second)]
    radius = candidates[start][first, 2]
    frame, gap = start + 2, 0
    while frame < len(candidates) and gap <= MAX_GAP_FRAMES:
        predicted = extrapolated([(f, *candidates[f][row, :2]) for f, row in chain[-3:]], frame)
        here = candidates[frame]
        size_ok = (here[:, 2] <= MAX_RADIUS_RATIO * radius) & (here[:, 2] >= radius / MAX_RADIUS_RATIO)
        distance = np.hypot(here[:, 0] - predicted[0], here[:, 1] - predicted[1])
        distance[~size_ok] = np.inf
        tolerance = max(LINK_TOLERANCE_RADII * radius, MIN_LINK_TOLERANCE_PX) * (1 + gap)
        if here.size and distance.min() <= tolerance:
            chain.append((frame, int(np.argmin(distance))))
            gap = 0
        else:
            gap += 1
        frame += 1
    return chain


def _as_flight(candidates, chain):
    """The chain as a :class:`Flight` when it is one (see the module documentation), else None."""
    frames = np.array([f for f, _ in chain])
    if frames[-1] - frames[0] + 1 < MIN_FLIGHT_FRAMES:
        return None
    blobs = np.array([candidates[f][row] for f, row in chain])
    x, y, radius = blobs[:, 0], blobs[:, 1], float(np.median(blobs[:, 2]))
    if math.hypot(x[-1] - x[0], y[-1] - y[0]) < MIN_TRAVEL_DIAMETERS * 2.0 * radius:
        return None
    fits = [np.polyfit(frames, values, 2) for values in (x, y)]
    residual = np.concatenate([values - np.polyval(fit, frames) for values, fit in zip((x, y), fits)])
    if np.sqrt(np.mean(residual ** 2)) > MAX_PARABOLA_RMS_RADII * radius:
        return None
    # a falling or tossed ball accelerates downwards in the image (rotation already applied)
    if not fits[1][0] > abs(fits[0][0]):
        return None
    return Flight(frames, x, y, radius)


def longest_flight(candidates):
    """The flight spanning the most frames among chains of ``candidates`` (per frame, arrays (n, 3) of
    x, y, radius px, as :func:`frame_candidates` gives), or None when no chain is one."""
    best, used = None, set()
    for start in range(len(candidates) - 1):
        for first in range(len(candidates[start])):
            if (start, first) in used:
                continue
            for second in range(len(candidates[start + 1])):
                ratio = candidates[start + 1][second, 2] / candidates[start][first, 2]
                step = math.hypot(*(candidates[start + 1][second, :2] - candidates[start][first, :2]))
                if not 1.0 / MAX_RADIUS_RATIO <= ratio <= MAX_RADIUS_RATIO or step < 0.5:
                    continue
                chain = _grow(candidates, start, first, second)
                flight = _as_flight(candidates, chain)
                if flight is None:
                    continue
                used.update(chain)
                span = flight.frames[-1] - flight.frames[0]
                if best is None or span > best.frames[-1] - best.frames[0]:
                    best = flight
    return best


def find_flight(frames, background, contrast):
    """The longest ballistic flight of round blobs through ``frames`` (BGR or grey uint8 images, in
    order) in ``contrast``, or None.

    Parameters
    ----------
    frames : iterable of numpy.ndarray
        The clip's frames.
    background : dropfit.video.background.Background
        The static scene.
    contrast : dropfit.video.contrast.Contrast
        The channel searched.

    Returns
    -------
    Flight or None
    """
    return longest_flight([frame_candidates(frame, background, contrast) for frame in frames])


__all__ = ["Flight", "find_flight", "frame_candidates", "longest_flight"]
