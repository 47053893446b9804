"""Ball tracking in video: the sub-pixel centre and radius of the ball in every frame.

The camera is static, so the scene without the ball is one image, the background
(:mod:`dropfit.video.background`). In the first frame, and whenever the ball was lost, the whole
(downscaled) frame is searched for the foreground blob with the largest inscribed circle, preferring
lone, roughly circular blobs (:func:`dropfit.video.detect.find_ball`). Afterwards the position is
predicted from the last three positions (constant acceleration) and only a window of about four
radii around the prediction is measured (:func:`dropfit.video.detect.measure_ball`, which gives the
quality flags ``ok``, ``blurred``, ``partial``, ``shaded`` and ``occluded``). While the ball is measured merged
with something (``occluded``), a lone disc found by a search replaces it; when the merged blob was moving about
far from that disc (pieces of a hand), its positions are dropped from the prediction. The tracker adds two flags:

``lost``
    No ball was found (it left the image, or it is hidden): ``x_px``, ``y_px`` and ``radius_px``
    are NaN.
``duplicate``
    The frame is identical to the previous frame, as when a recorder repeats frames to fill a
    nominal rate: its time stamp does not belong to its content, so it is dropped from the
    trajectory (NaN position). Identical means a mean absolute difference of sparse rows (of the
    luma plane as coded, for a 4:2:0 video) within ``DUPLICATE_TOLERANCE_GREY`` (the sensor noise
    repeats) and no pixel of the whole frame changing by more than the foreground threshold
    (nothing moved), while the ball was moving
    (more than ``STILL_BALL_STEP_PX`` a frame between its last two found centres): a ball at rest
    in a noise-free video gives identical frames that are true ones.

``ok`` and ``blurred`` rows are meant for fitting trajectories, and so are ``partial`` and ``shaded``
rows whose ``centre_se_px`` and ``fit_rms_px`` are small (:func:`usable_rows`).

Ball in the background. A ball that is in view for the whole clip and moves less than a few
diameters (a close-up of a contact) covers some pixels in more than half of the background
samples, so their median is the ball, not the scene. The tracker then runs twice: the balls
found in the background samples by the first pass are cut out of them (discs of
``BALL_MASK_RADII`` tracked radii plus ``BALL_MASK_MARGIN_PX``), the median of what is left is
the background of the next pass (:func:`background_without_ball`), until the sampled balls
settle (a first pass misled by the ball in the background can misplace some of them).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import NamedTuple

import numpy as np
import pandas as pd

from ..errors import InputError, shown_path
from ..files import check_input_file
from ..numerics import fast_median, robust_sigma
from .background import (BACKGROUND_SAMPLES, Background, background_without_ball, estimate_background, grey_uint8,
                         to_grey)
from .contrast import (CHANNELS, CHROMA, GREY, Contrast, available_contrasts, contrast_of, frame_gain, hand_pixels,
                       scene_colour, skin_mask)
from .decode import (MIN_FRAMES, LazyFrame, Progress, VideoFile, check_frame_count, check_video_file, frame_times,
                     reduced_px, reduction_note, spread_indices)
from .detect import find_ball, measure_ball, searched_frame
from .link import extrapolated, find_flight
from .opencv import cv2
# the flags and the centre's correlation, kept importable from here (overlay, tests)
from .quality import (CLEAN_QUALITIES, MAX_PARTIAL_FIT_RMS_PX, QUALITY_BLURRED, QUALITY_DUPLICATE,  # noqa: F401
                      QUALITY_LOST, QUALITY_OCCLUDED, QUALITY_OFF_TRACK, QUALITY_OK, QUALITY_PARTIAL, QUALITY_SHADED,
                      TRACKED_CENTRE_CORRELATION, mark_off_track, usable_rows)

COLUMNS = ["frame", "time_s", "x_px", "y_px", "radius_px", "quality", "centre_se_px", "fit_rms_px", "blur_px"]

#: Mean absolute grey-level difference to the previous frame at or below which a frame is a duplicate.
DUPLICATE_TOLERANCE_GREY = 0.5
#: Rows between the sparse rows of the duplicate test.
DUPLICATE_STRIDE_PX = 16
#: A frame whose ball moved less than this fraction of its speed (px a frame) before and after it, the two in the same
#: direction and at least ``REPEAT_MIN_SPEED_PX`` a frame, repeats the previous frame's capture (see
#: :func:`refitted_repeats`). Phonesim's white ping-pong MOV (30 Hz in 60 fps, libx264 crf 18): the repeats its frame
#: test missed moved 0-0.16 px where the ball moved 1-70 px between captures; new captures 1-71 px.
REPEAT_MOVE_FRACTION = 0.2
REPEAT_MIN_SPEED_PX = 1.0
#: A frame identical to the previous one is not a duplicate when the ball moved less than this a frame
#: between its last two found centres, px (a ball at rest in a noise-free video, or just released).
STILL_BALL_STEP_PX = 0.1
#: Qualities of a ball found alone, not merged with anything but its own shadow: a search's ball of one of
#: these replaces a merged one.
FOUND_ALONE = (QUALITY_OK, QUALITY_SHADED)
#: Found centres older than this many frames are not used to predict the next one.
HISTORY_FRAMES = 6
#: The scatter of the ball's radius (passed to :func:`dropfit.video.detect.measure_ball`) is read from
#: this many of its recent ``ok`` radii or more.
MIN_RADII_FOR_SPREAD = 4
#: A ball merged with its shadow (``shaded``) has its radius fitted to its lit side in its first frames
#: with a good fit (RMS residual at most MAX_PARTIAL_FIT_RMS_PX); from this many barely moving ones on, their
#: median is held (a held radius fixes the centre of a half-circle far better). Held apart from the ``ok``
#: balls' radius: the lit side's edge is not where the coverage of a whole ball crosses one half. Seven: a
#: 30 Hz clip has about three such frames at an apex, and the first three, beside the hand that let the ball
#: go, held 14.2 px for phonesim's 15 px white ball (seeds 5 and 6 of 8): its lit sides then fitted poorly,
#: and the track, judged poor, was redone from a flight of the hand's pieces.
SHADED_RADII = 7
#: The last this many lit-side fits give the expected radius before any ``ok`` ball (their median).
SHADED_FITS_KEPT = 3
#: A ball that moved less than this many of its radii a frame in each of its last two steps is barely blurred;
#: its size is learnt from such frames. A blurred ball's lit side is not a circle's and fits a radius several per cent
#: short (a 15 px ball streaked over half its radius: 14.0 px); its coverage in a colour channel at half
#: resolution reads larger (phonesim's red ball: 12.3 px at its apex, 14-14.6 px falling at 30 frames/s),
#: and a reference learnt from those flags the ball at its apex occluded.
STILL_RADII = 0.5
#: An ``ok`` ball smaller than this fraction of the radius fitted to shaded balls' lit sides is a part of the
#: ball: flagged ``occluded``.
SHADED_SIZE_FRACTION = 0.75
#: A ball with a hand's pixels (:func:`dropfit.video.contrast.hand_pixels`) within this of its edge is
#: held or touched: flagged occluded, px.
HAND_TOUCH_PX = 2.0
#: A ball measured alone, in flight, in this many frames in a row, each flagged occluded for its size alone with
#: radii within UNDERSIZED_AGREEMENT of their median, is the ball at its true size: the radius learnt before was
#: too large (:meth:`BallTracker._relearnt_size`). The green ball's real clip: 46.7 px learnt from the frame the
#: hand let it go, then 41-44.5 px in every flight frame, all flagged occluded (a ball 5 % short is hidden).
UNDERSIZED_FRAMES = 4
UNDERSIZED_AGREEMENT = 0.04
#: Extra margin of the search window, px.
WINDOW_MARGIN_PX = 6
#: While the ball stays occluded where it is followed (held in a hand), a lone disc is looked for
#: within LOCAL_SEARCH_RADII radii (at least LOCAL_SEARCH_MIN_PX) of it, where a ball leaving the hand
#: is, and over the whole frame in the first frame of the run and every OCCLUDED_FULL_SEARCH_STRIDE-th
#: after it: a ball held for a second cost a whole-frame search in each of its frames, most of a phone
#: clip's tracking time.
#: While it is held still (or rests against its shadow) only the whole-frame searches are made: a ball
#: that leaves the hand moves, or is measured alone where it is followed.
LOCAL_SEARCH_RADII = 8.0
LOCAL_SEARCH_MIN_PX = 80
OCCLUDED_FULL_SEARCH_STRIDE = 4
#: A prediction more than this many radii a frame from the last found centre is not a ball's (a fall of 3 m
#: filmed at 24 frames/s moves a table-tennis ball 16 of its radii a frame): the frame is searched instead.
MAX_STEP_RADII = 20.0
#: A lone ball found by a search more than this many radii from the merged blob followed until then, when that
#: blob was not still (a hand moving about), ends the tracker's history (which predicts the next centre).
JUMP_RADII = 4.0
#: At most this many further tracking passes, each with the ball cut out of the background samples
#: where the previous pass found it; they stop once the sampled balls move less than
#: BACKGROUND_SETTLED_PX between passes.
MAX_BACKGROUND_REFINEMENTS = 3
BACKGROUND_SETTLED_PX = 0.5
#: In ranking the contrast channels, a lone disc whose radius is within this fraction of the median
#: of those found in the samples counts.
RANK_RADIUS_TOLERANCE = 0.25
#: A colour channel is ranked first only when it shows a lone disc in more samples than grey levels
#: do by at least this many: grey has full resolution, and what the colour channels do not show (a dark
#: hand over a bright ball) cannot flag the ball as occluded.
RANK_GREY_MARGIN = 3
#: Grey levels lose their margin (and get it against them) when their ball's median radius in the
#: samples exceeds the chroma channel's by this factor: a shadow or a hand merged with the ball in grey.
RANK_INFLATED_RADIUS = 1.1
#: Another contrast channel is tried while fewer than this fraction of the frames in which the ball
#: was found are usable (most of them flagged occluded: a shadow merging with the ball, say).
ENOUGH_USABLE_FRACTION = 0.5
#: A blob found within FIXTURE_TOLERANCE_PX of one place in at least FIXTURE_FRACTION of the
#: background's samples is a fixture of the scene, not the ball (a ball at rest that long is in the
#: background itself).
FIXTURE_TOLERANCE_PX = 2.0
FIXTURE_FRACTION = 0.7
#: A channel whose lone discs in the samples have a median radius below this fraction of another channel's (one
#: that shows them in MIN_SIZED_SAMPLES samples or more) shows specks, not the ball: it scores nothing, and its
#: searches get no expected size. The green ball's real clip (1920 × 1080 px): grey levels merge the ball with its
#: shadow in every sample and show lone codec specks of 2-6 px in most of them; chroma shows the ball alone, 44-47 px
#: across, in four. Grey ranked first, its first search took a speck, learnt its size and never looked for the ball.
#: and below SPECK_MAX_RADIUS_PX. A channel's sample radius is what its searches look for only above it: the white
#: ping-pong clip's samples show 4-6 px specks in every channel, and a search for them missed the 27 px ball (68 ok
#: frames fell to 8).
SPECK_RADIUS_FRACTION = 0.25
MIN_SIZED_SAMPLES = 3
SPECK_MAX_RADIUS_PX = 8.0


class TrackerHints(NamedTuple):
    """What the user says of the ball in the image, when the defaults are not enough.

    Attributes
    ----------
    roi_px : (int, int, int, int) or None
        Region of interest x0, y0, x1, y1, px (columns x0 ≤ x < x1, rows y0 ≤ y < y1): the ball is
        looked for only there.
    ball_at_px : (int, float, float) or None
        The ball's centre x, y (px) in one frame (index from 0): measured there first.
    ball_colour_bgr : (float, float, float) or None
        The ball's colour, BGR levels 0–255: the contrast channel in which it stands out most from
        the scene is used first (:func:`scene_and_contrasts`).
    """

    roi_px: tuple | None = None
    ball_at_px: tuple | None = None
    ball_colour_bgr: tuple | None = None


class BallTracker:
    """Frame-by-frame tracker; feed frames in order to :meth:`update`.

    Parameters
    ----------
    background : Background
        The static scene.
    expected_radius_px : float, optional
        Expected ball radius, px; learnt from the first ``ok`` frames when not given.
    contrast : dropfit.video.contrast.Contrast, optional
        The channel in which the ball is measured; grey levels by default.
    hints : TrackerHints, optional
        What the user says of the ball: a region of interest (the ball is looked for and measured
        only there; its borders count as the image's) and its centre in one frame (measured there
        first in that frame).
    """

    def __init__(self, background, expected_radius_px=None, contrast=None, hints=None):
        self.background = background
        self.contrast = contrast or contrast_of(GREY, (), background)
        self.hints = hints or TrackerHints()
        self._gain = 1.0
        self._ball_colours = []  # BGR at the centre of recently measured balls, the frame's gain divided out
        self._ball_bgr = None
        height, width = background.grey.shape
        self.left, self.top, self.right, self.bottom = 0, 0, width, height  # the region searched, px
        if self.hints.roi_px is not None:
            x0, y0, x1, y1 = self.hints.roi_px
            self.left, self.top = min(x0, width - 1), min(y0, height - 1)
            self.right, self.bottom = max(min(x1, width), self.left + 1), max(min(y1, height), self.top + 1)
        self._search_background = background.cropped(self.left, self.top, self.right, self.bottom)
        self.expected_radius_px = expected_radius_px
        self._radii = []  # radii of the last ``ok`` balls, px
        self._still_radii = []  # ... of those that moved less than STILL_RADII radii a frame, px
        self._radius_ref = None
        self._radius_spread = 0.0
        self._shaded_fits = []  # radii fitted to the lit sides of the last shaded balls, px
        self._shaded_radii = []  # ... of those that moved little (not blurred), px
        self._history = []  # (frame index, x, y) of the last found balls
        self._previous = None
        self._index = -1
        self._occluded_run = 0  # frames in a row measured occluded where the ball was followed
        self._undersized = []  # radii of the last lone balls in a row flagged occluded for their size alone, px
        self._hand_touch = False  # whether the last measurement was flagged occluded for a hand touching it

    @property
    def ball_bgr(self):
        """The ball's colour, BGR levels: the median at the centre of the balls recently measured whose
        centre is not skin-coloured, or that were measured alone (None before)."""
        return self._ball_bgr

    @property
    def radius_ref_px(self):
        """The expected radius, px: the median of recent ``ok`` radii of barely blurred balls (before there is
        one, the smallest recent ``ok`` radius); before any ``ok`` ball, the given one, else the median of the
        radii fitted to shaded balls' lit sides (a light ball over a light wall may never be ``ok``)."""
        if self._radii:
            return self._radius_ref
        if self.expected_radius_px is None and self._shaded_fits:
            return float(np.median(self._shaded_fits))
        return self.expected_radius_px

    @property
    def _shaded_radius_px(self):
        """The radius a shaded ball's lit side is fitted with, px: the upper quartile of the first
        ``SHADED_RADII`` fitted ones once there are as many, else None (fitted). A lit side cut by blur or by
        the hand beside it fits short, never long."""
        if len(self._shaded_radii) < SHADED_RADII:
            return None
        return float(np.percentile(self._shaded_radii, 75))

    @property
    def _search_radius_px(self):
        """The radius a whole-frame search looks for, px: the expected one, else the radius of the lone discs of
        the clip's samples in this channel (``Contrast.ball_radius_px``), until a ball was measured ``ok``. A
        search without one takes the largest lone blob, a speck of the codec beside a ball merged with the hand
        that holds it, and then looks only for blobs of the speck's size."""
        reference = self.radius_ref_px
        return reference if reference is not None else self.contrast.ball_radius_px

    def _recent_history(self):
        """(frame index, x, y) of the last found balls, of the last ``HISTORY_FRAMES`` frames."""
        return [h for h in self._history if self._index - h[0] <= HISTORY_FRAMES]

    def _predict(self):
        """Predicted centre (x, y), distance from the last found centre, and travel per frame (dx, dy), px."""
        history = self._recent_history()
        if not history:
            return None, 0.0, None
        predicted = extrapolated(history, self._index)
        last = history[-1]
        step = math.hypot(predicted[0] - last[1], predicted[1] - last[2])
        gap = self._index - last[0]
        if self.radius_ref_px and step > MAX_STEP_RADII * self.radius_ref_px * gap:
            # no ball moves that far: the history mixes other objects with it; the frame is searched
            return None, 0.0, None
        return predicted, step, ((predicted[0] - last[1]) / gap, (predicted[1] - last[2]) / gap)

    def _measure_around(self, frame, centre, half_size, motion_px=None):
        x_c, y_c = centre
        x0 = max(int(math.floor(x_c - half_size)), self.left)
        y0 = max(int(math.floor(y_c - half_size)), self.top)
        x1 = min(int(math.ceil(x_c + half_size)) + 1, self.right)
        y1 = min(int(math.ceil(y_c + half_size)) + 1, self.bottom)
        if x1 - x0 < 3 or y1 - y0 < 3:
            return None
        scene = scene_colour(self.background)
        colour = scene.window(x0, y0, x1, y1) if scene is not None else None
        window = frame[y0:y1, x0:x1]
        # a hand is larger than the ball (before its radius is known: the one the window was sized for)
        hand_area = math.pi * (self.radius_ref_px or max((half_size - WINDOW_MARGIN_PX) / 2.0, 0.0)) ** 2
        hand = hand_pixels(window, colour, self.ball_bgr, hand_area)
        image, background = self.contrast.images(window, self.background.grey[y0:y1, x0:x1], colour, self._gain,
                                                 self.ball_bgr, hand)
        edges = (x0 == self.left, y0 == self.top, x1 == self.right, y1 == self.bottom)
        result = measure_ball(image, background, self.contrast.threshold, (x_c - x0, y_c - y0), self.radius_ref_px,
                              edges, motion_px, self._radius_spread, self._shaded_radius_px)
        if result is None:
            return None
        if result.quality != QUALITY_OCCLUDED and hand is not None and hand.any():
            # a hand touching the ball hides part of it, whether or not it shows in this channel
            rows, columns = np.nonzero(hand)
            reach = result.radius_px + HAND_TOUCH_PX
            if np.any((columns - result.x_px) ** 2 + (rows - result.y_px) ** 2 <= reach * reach):
                result = replace(result, quality=QUALITY_OCCLUDED)
                self._hand_touch = True
        if window.ndim == 3:
            self._learn_colour(window, result)
        return replace(result, x_px=result.x_px + x0, y_px=result.y_px + y0)

    def _learn_colour(self, window, result):
        """Take the ball's colour from a BGR window where it was measured (``result``, window px): the median
        of the pixels within half a radius of its centre, the frame's gain divided out, unless skin-coloured
        where the ball was not measured alone (``ok`` or ``blurred``: a lone disc is no hand)."""
        reach = abs(0.5 * result.radius_px)
        height, width = window.shape[:2]
        left, top, right, bottom = 0, 0, width, height
        if math.isfinite(result.x_px) and math.isfinite(result.y_px) and math.isfinite(reach):
            # the pixels are looked for in the box about the disc, not in the whole window
            left, top = max(math.floor(result.x_px - reach), 0), max(math.floor(result.y_px - reach), 0)
            right = max(min(math.ceil(result.x_px + reach) + 1, width), left)
            bottom = max(min(math.ceil(result.y_px + reach) + 1, height), top)
        rows, columns = np.arange(top, bottom)[:, None], np.arange(left, right)
        core = (columns - result.x_px) ** 2 + (rows - result.y_px) ** 2 <= reach ** 2
        if not core.any():
            return
        centre = fast_median(window[top:bottom, left:right][core])
        # a ball's centre, not a hand's: held or blurred balls teach the colour too; a skin-coloured centre is a
        # ball's only where it is a lone disc (a crimson ball's colour lies in the skin ranges; without it learnt,
        # its blends with the wall are taken for a hand)
        alone = result.quality in (QUALITY_OK, QUALITY_BLURRED)
        if alone or not skin_mask(np.clip(np.rint(centre), 0, 255).astype(np.uint8).reshape(1, 1, 3))[0, 0]:
            self._ball_colours = (self._ball_colours + [centre / self._gain])[-15:]
            self._ball_bgr = tuple(fast_median(np.array(self._ball_colours)))

    def _search(self, frame, near=None):
        """The ball measured where a search of the whole frame (or, ``near`` = (x, y, reach) px, of the
        square ``reach`` about x, y) finds it, or None."""
        left, top, right, bottom, background = self.left, self.top, self.right, self.bottom, self._search_background
        if near is not None:
            x, y, reach = near
            left, top = max(int(x - reach), self.left), max(int(y - reach), self.top)
            right, bottom = min(int(x + reach) + 1, self.right), min(int(y + reach) + 1, self.bottom)
            if right <= left or bottom <= top:  # the square lies wholly outside the searched area
                return None
            background = self.background.cropped(left, top, right, bottom)
        region = frame[top:bottom, left:right]
        fixtures = [(x - left, y - top, r) for x, y, r in self.contrast.fixtures]
        found = find_ball(region, background, self.contrast, self._search_radius_px, self._gain, fixtures,
                          self.hints.ball_colour_bgr)
        if found is None:
            return None
        x, y, r = found[0] + left, found[1] + top, found[2]
        result = self._measure_around(frame, (x, y), 2.0 * max(r, self.radius_ref_px or r) + WINDOW_MARGIN_PX)
        if result is not None and result.truncated:
            result = self._measure_around(frame, (result.x_px, result.y_px), 4.0 * r + 2 * WINDOW_MARGIN_PX)
        return result

    def _recent_steps_px(self):
        """How far the ball moved a frame in each step between its last found centres (at most two steps), px."""
        history = self._recent_history()[-3:]
        return [math.hypot(x1 - x0, y1 - y0) / (t1 - t0) for (t0, x0, y0), (t1, x1, y1) in zip(history, history[1:])]

    def _recent_step_px(self):
        """How far the ball moved a frame between its last two found centres, px (0 before two)."""
        steps = self._recent_steps_px()
        return steps[-1] if steps else 0.0

    def _barely_moving(self, radius_px):
        """Whether the ball moved less than ``STILL_RADII`` radii a frame in each of its last two steps (both
        where there are two: in the frames about a bounce the ball is low twice, one step short, moving fast)."""
        steps = self._recent_steps_px()
        return bool(steps) and max(steps) <= STILL_RADII * radius_px

    def _held_still(self, merged):
        """Whether the ``merged`` blob measured in this frame is where it was (within ``STILL_RADII`` radii of the
        last found centre) and was barely moving before (:meth:`_barely_moving`): a ball held in a hand, or at
        rest against its shadow."""
        radius = self.radius_ref_px or merged.radius_px
        if not self._history or not self._barely_moving(radius):
            return False
        _, x, y = self._history[-1]
        return math.hypot(merged.x_px - x, merged.y_px - y) <= STILL_RADII * radius

    def _another_object(self, merged, lone):
        """Whether the ``merged`` blob that was followed is another object than the ``lone`` ball a search found:
        more than ``JUMP_RADII`` radii from it, and it was not still. A ball held still in a hand is where it
        will be released; a lone disc far from it is something else (a ghost of the ball in the background,
        where it rests at the clip's end). A blob that jumped about (parts of a hand) predicts nothing."""
        radius = self.radius_ref_px or lone.radius_px
        far = math.hypot(merged.x_px - lone.x_px, merged.y_px - lone.y_px) > JUMP_RADII * radius
        return far and not self._barely_moving(radius)

    def _is_duplicate(self, frame, predicted):
        """Whether the whole frame repeats the previous one while the ball was moving."""
        previous = self._previous
        if previous is None or previous.shape != frame.shape:
            return False
        # a ball at rest in a noise-free video repeats itself, and a ball starting to fall moves too little
        # to change a pixel beyond the threshold: their frames are true, not repeated. Judged by the move
        # seen last, not the one predicted: three centres read 0.02 px apart extrapolate to a step of
        # 0.1-0.2 px (the benchmark clip's release frame was taken for a repeat)
        if predicted is not None and self._recent_step_px() <= STILL_BALL_STEP_PX:
            return False
        sample, previous_sample = _duplicate_samples(frame, previous)
        if cv2.norm(sample, previous_sample, cv2.NORM_L1) > DUPLICATE_TOLERANCE_GREY * sample.size:
            return False
        # the sparse rows miss a small ball: nothing in the whole frame may have moved. Where the ball was
        # last seen decides at once in most frames (a codec that copies a static scene unchanged leaves the
        # sparse rows identical)
        threshold = self.background.threshold_grey
        if self._history:
            _, x, y = self._history[-1]
            reach = (self.radius_ref_px or 10.0) + WINDOW_MARGIN_PX
            window = np.s_[max(int(y - reach), 0):int(y + reach) + 1, max(int(x - reach), 0):int(x + reach) + 1]
            if frame[window].size and cv2.norm(frame[window], previous[window], cv2.NORM_INF) > threshold:
                return False
        # whole frames, kept: a repeated frame is compared whole again as the next frame's previous one
        frame, previous = (image.whole() if isinstance(image, LazyFrame) else image for image in (frame, previous))
        return cv2.norm(frame, previous, cv2.NORM_INF) <= threshold

    def _relearnt_size(self, result):
        """``result``, flagged ``ok`` when it is the ``UNDERSIZED_FRAMES``-th lone ball in a row, in flight, flagged
        occluded for its size alone with radii within ``UNDERSIZED_AGREEMENT`` of their median: the expected radius
        was learnt too large (from a ball leaving the hand, with a finger's edge), and no smaller ball could be
        ``ok`` to correct it. The radii learnt are then those balls'."""
        reference = self.radius_ref_px
        lone_and_small = (result.quality == QUALITY_OCCLUDED and not self._hand_touch and not result.truncated
                          and math.isnan(result.centre_se_px) and reference is not None
                          and result.radius_px < reference)
        if not lone_and_small:
            self._undersized = []
            return result
        self._undersized = (self._undersized + [result.radius_px])[-UNDERSIZED_FRAMES:]
        radii = np.array(self._undersized)
        median = float(np.median(radii))
        moving = self._history and math.hypot(result.x_px - self._history[-1][1],
                                              result.y_px - self._history[-1][2]) >= STILL_RADII * median
        if (len(radii) < UNDERSIZED_FRAMES or not moving
                or np.max(np.abs(radii / median - 1.0)) > UNDERSIZED_AGREEMENT):
            return result
        self._radii, self._still_radii, self._undersized = list(radii), [], []
        self._radius_ref = float(np.min(radii))
        self._radius_spread = robust_sigma(radii, centre=self._radius_ref)
        return replace(result, quality=QUALITY_OK)

    def update(self, frame):
        """Measure the ball in the next frame.

        Parameters
        ----------
        frame : numpy.ndarray
            Grey or BGR frame, uint8, the background's size.

        Returns
        -------
        (float, float, float, str, float, float)
            Centre x, y and radius, px (NaN when lost or duplicate), the quality flag, and the
            circle fit's centre standard error and RMS residual, px (NaN unless a fit was used).
        """
        frame = frame if isinstance(frame, LazyFrame) else np.asarray(frame)
        if frame.shape[:2] != self.background.grey.shape:
            raise ValueError(f"frame of shape {frame.shape} does not match the background {self.background.grey.shape}")
        self._index += 1
        predicted, step, motion = self._predict()
        radius = self.radius_ref_px or 10.0
        half_size = 1.5 * radius + 2.0 * step + WINDOW_MARGIN_PX
        duplicate = self._is_duplicate(frame, predicted)
        if isinstance(self._previous, LazyFrame):
            self._previous.release()  # what was converted of it, kept for this frame's comparison
        self._previous = frame
        if duplicate:
            return math.nan, math.nan, math.nan, QUALITY_DUPLICATE, math.nan, math.nan, math.nan
        if self.contrast.in_colour:
            self._gain = frame_gain(frame, scene_colour(self.background))

        result = None
        self._hand_touch = False
        start = self.hints.ball_at_px
        if start is not None and start[0] == self._index:
            result = self._measure_around(frame, start[1:], 2.0 * radius + WINDOW_MARGIN_PX)
            if result is not None:
                self._history = []
                predicted = None
        if predicted is not None:
            result = self._measure_around(frame, predicted, half_size, motion)
            if result is not None and result.truncated:
                result = self._measure_around(frame, (result.x_px, result.y_px), 2.0 * half_size, motion)
        occluded = result is not None and not result.truncated and result.quality == QUALITY_OCCLUDED
        self._occluded_run = self._occluded_run + 1 if occluded else 0
        whole_search = not occluded or (self._occluded_run - 1) % OCCLUDED_FULL_SEARCH_STRIDE == 0
        if result is None or result.truncated or (occluded and (whole_search or not self._held_still(result))):
            # lost, or merged with something (a hand that held the ball and moves away): a lone disc
            # elsewhere in the frame is the ball
            near = None
            if not whole_search:
                reach = max(LOCAL_SEARCH_RADII * (self.radius_ref_px or result.radius_px), LOCAL_SEARCH_MIN_PX)
                near = (result.x_px, result.y_px, reach)
            searched = self._search(frame, near)
            if result is None or result.truncated or (searched is not None and searched.quality in FOUND_ALONE):
                if occluded and searched is not None and self._another_object(result, searched):
                    # the blob followed was not the ball (a hand that let it go): its positions do not predict
                    # the ball's
                    self._history = []
                result = searched
        if result is None:
            return math.nan, math.nan, math.nan, QUALITY_LOST, math.nan, math.nan, math.nan
        if (result.quality == QUALITY_OK and self._shaded_fits
                and result.radius_px < SHADED_SIZE_FRACTION * float(np.median(self._shaded_fits))):
            # smaller than the circle of its own lit side: part of the ball (a light ball over a light wall
            # and a dark floor shows only where it crosses the floor's edge)
            result = replace(result, quality=QUALITY_OCCLUDED)
        if (result.quality == QUALITY_SHADED and self._shaded_radius_px is None
                and result.fit_rms_px <= MAX_PARTIAL_FIT_RMS_PX):
            self._shaded_fits = (self._shaded_fits + [result.radius_px])[-SHADED_FITS_KEPT:]
            # judged by the last step alone: asking for two still steps held another radius for phonesim's white
            # ball (seed 3, half size), and with it the tracker followed a round shadow at the floor for 6 frames
            if len(self._recent_history()) >= 1 and self._recent_step_px() <= STILL_RADII * result.radius_px:
                self._shaded_radii.append(result.radius_px)
        result = self._relearnt_size(result)
        self._history = (self._history + [(self._index, result.x_px, result.y_px)])[-3:]
        if result.quality == QUALITY_OK:
            self._radii = (self._radii + [result.radius_px])[-15:]
            if self._barely_moving(result.radius_px):
                self._still_radii = (self._still_radii + [result.radius_px])[-15:]
            radii = self._still_radii or self._radii
            # blur only enlarges a ball: before a barely moving one was measured (a track started on a fast
            # flight), the least blurred so far is nearest its size
            self._radius_ref = float(fast_median(np.array(radii)) if self._still_radii else min(radii))
            enough = len(radii) >= MIN_RADII_FOR_SPREAD
            self._radius_spread = robust_sigma(radii, centre=self._radius_ref) if enough else 0.0
        return (result.x_px, result.y_px, result.radius_px, result.quality, result.centre_se_px, result.fit_rms_px,
                result.blur_px)


def _duplicate_samples(frame, previous):
    """The sparse rows (every ``DUPLICATE_STRIDE_PX``-th) of two frames that the duplicate test compares first: of
    their luma planes as coded where both are :class:`LazyFrame` objects (no conversion: a repeated frame repeats its
    planes), else of their pixels."""
    rows = slice(None, None, DUPLICATE_STRIDE_PX)
    if isinstance(frame, LazyFrame) and isinstance(previous, LazyFrame):
        return np.ascontiguousarray(frame.luma[rows]), np.ascontiguousarray(previous.luma[rows])
    return frame[rows], previous[rows]


def _found_or_raise(table, source):
    if not table["quality"].isin([QUALITY_OK, QUALITY_PARTIAL, QUALITY_SHADED, QUALITY_OCCLUDED]).any():
        raise InputError(f"{shown_path(source)}: the ball was never found (no round foreground blob in {len(table)} "
                         f"frames): it must stand out from the background and move; if it does, give its centre "
                         f"in one frame (--ball-at-px FRAME,X,Y) or its colour (--ball-colour)")
    return table


def _run(frames, background, expected_radius_px, contrast=None, hints=None):
    """The tracker's rows for ``frames`` (an iterable of images) against ``background``, in ``contrast``."""
    tracker = BallTracker(background, expected_radius_px, contrast, hints)
    return [tracker.update(frame) for frame in frames]


def _sample_blobs(searched, gains, contrast):
    """Round blobs of each sample (:func:`dropfit.video.detect.searched_frame`) in ``contrast``, with the
    sample's gain in a colour channel (as :func:`dropfit.video.detect.frame_blobs`)."""
    return [frame.blobs(contrast, gain if contrast.in_colour else 1.0) for frame, gain in zip(searched, gains)]


def _fixtures(blobs):
    """Blobs found at one place (within ``FIXTURE_TOLERANCE_PX``) in at least ``FIXTURE_FRACTION`` of the samples."""
    flat = [blob for found in blobs for blob in found]
    fixtures = []
    for x, y, radius, *_ in flat:
        if any(math.hypot(x - fx, y - fy) <= FIXTURE_TOLERANCE_PX for fx, fy, _ in fixtures):
            continue
        seen = sum(any(math.hypot(x - bx, y - by) <= FIXTURE_TOLERANCE_PX for bx, by, *_ in found) for found in blobs)
        if seen >= FIXTURE_FRACTION * len(blobs):
            fixtures.append((x, y, radius))
    return tuple(fixtures)


def _rank(samples, background, expected_radius_px):
    """The contrast channels, best first (see :func:`scene_and_contrasts`), each with its fixtures."""
    scored = {}
    # what every channel reads of a sample, read once: its gain, and the frame reduced with its hand pixels
    scene = scene_colour(background)
    gains = [frame_gain(sample, scene) if scene is not None else 1.0 for sample in samples]
    searched = [searched_frame(sample, background, expected_radius_px) for sample in samples]
    for order, name in enumerate(available_contrasts(background)):
        contrast = contrast_of(name, samples, background, gains)
        blobs = _sample_blobs(searched, gains, contrast)
        fixtures = _fixtures(blobs)
        blobs = [[blob for blob in found if not any(math.hypot(blob[0] - x, blob[1] - y) <= FIXTURE_TOLERANCE_PX
                                                    for x, y, _ in fixtures)] for found in blobs]
        best = [max(found, key=lambda blob: (blob[3], blob[2])) for found in blobs if found]
        score, radius = 0, math.nan
        if best:
            radii = np.array([blob[2] for blob in best])
            lone_and_consistent = (np.abs(radii / np.median(radii) - 1.0) <= RANK_RADIUS_TOLERANCE) & np.array(
                [blob[3] for blob in best])
            score = int(lone_and_consistent.sum())
            radius = float(np.median(radii[lone_and_consistent])) if score else math.nan
        scored[name] = [score, order, radius, replace(contrast, fixtures=fixtures,
                                                      ball_radius_px=radius if radius > SPECK_MAX_RADIUS_PX else None)]
    # a channel whose lone discs are specks beside another's ball-sized ones shows codec noise, not the ball
    largest = max((item[2] for item in scored.values() if item[0] >= MIN_SIZED_SAMPLES), default=math.nan)
    specks = [name for name, item in scored.items()
              if item[0] and item[2] < min(SPECK_RADIUS_FRACTION * largest, SPECK_MAX_RADIUS_PX)]
    if GREY in scored:
        grey = scored[GREY]
        chroma = scored.get(CHROMA)
        # a shadow or a hand merged with the ball makes it larger in grey than in colour
        inflated = chroma is not None and chroma[0] >= len(samples) / 2 and grey[2] > RANK_INFLATED_RADIUS * chroma[2]
        grey[0] += -RANK_GREY_MARGIN if inflated else RANK_GREY_MARGIN
    for name in specks:
        scored[name][0], scored[name][3] = 0, replace(scored[name][3], ball_radius_px=None)
    return [item[3] for item in sorted(scored.values(), key=lambda item: (-item[0], item[1]))]


def scene_and_contrasts(samples, expected_radius_px=None, ball_colour_bgr=None):
    """The background of a clip and its contrast channels, the one in which the ball shows best first.

    The background is the samples' median (:func:`dropfit.video.background.estimate_background`).
    In each sample the whole frame is searched for round blobs
    (:func:`dropfit.video.detect.find_blobs`); a channel scores the samples whose best blob (a lone
    disc first, then the largest) is a lone disc with a radius within ``RANK_RADIUS_TOLERANCE`` of
    the median of those found; grey levels get ``RANK_GREY_MARGIN`` more, or as many less when their
    ball is larger than in chroma by ``RANK_INFLATED_RADIUS`` (the shadow merged). Ties keep the order of
    :data:`dropfit.video.contrast.CHANNELS`. Blobs found at one place in most samples are fixtures
    of the scene in that channel (a speck the codec renders differently from the median), not the
    ball: each contrast carries them (``Contrast.fixtures``) and they are not counted. With the
    ball's colour given, the channels go in the order of that colour's contrast to the scene's
    median colour, in units of each channel's threshold.

    Parameters
    ----------
    samples : sequence of numpy.ndarray
        Frames spread over the clip.
    expected_radius_px : float, optional
        Expected ball radius, px.
    ball_colour_bgr : (float, float, float), optional
        The ball's colour, BGR levels 0–255.

    Returns
    -------
    (Background, list of Contrast)
    """
    background = estimate_background(samples)
    contrasts = _rank(samples, background, expected_radius_px)
    if ball_colour_bgr is not None and background.colour is not None:
        scene = np.median(background.colour.reshape(-1, 3), axis=0).reshape(1, 1, 3).astype(np.uint8)
        ball = np.clip(np.rint(np.asarray(ball_colour_bgr, float)), 0, 255).reshape(1, 1, 3).astype(np.uint8)
        scene_grey = to_grey(scene)

        def standing_out(contrast):
            return abs(float(contrast.image(ball, scene_grey, scene)[0, 0])) / contrast.threshold

        contrasts.sort(key=standing_out, reverse=True)
    return background, contrasts


def _usable_and_found(rows):
    """How many rows are usable, and in how many the ball was to be found: the frames from the first where
    it was found (not lost, not a repeated frame) to the last, repeated frames left out (a ball lost in its
    flights counts against a channel; one that left the view does not)."""
    table = _table(rows, np.zeros(len(rows)))
    quality = table["quality"]
    found = np.flatnonzero(~quality.isin([QUALITY_LOST, QUALITY_DUPLICATE]))
    if not found.size:
        return int(usable_rows(table).sum()), 0
    span = quality.iloc[found[0]:found[-1] + 1]
    return int(usable_rows(table).sum()), int((span != QUALITY_DUPLICATE).sum())


def _track_in_best_contrast(track, contrasts, first_rows, samples, indices, background, rescue=None):
    """Rows of the contrast channel with the most usable frames, and that channel.

    ``track(background, contrast)`` tracks all frames; ``first_rows`` are those of ``contrasts[0]``
    against ``background``. Each channel's rows are tracked again with the ball cut out of the
    background where it is in it (:func:`_track_without_ball_in_background`). A channel whose rows are
    poor (fewer than ``ENOUGH_USABLE_FRACTION`` of the frames where the ball was found are usable) is
    tracked afresh from the ball's flight, ``rescue(rows, contrast)`` (:class:`_FlightRescue`; None
    where it finds nothing better). When the first channel is still poor, every other channel is
    tried, and the one with the most usable frames is kept (ties in the order of
    :data:`dropfit.video.contrast.CHANNELS`: grey levels first).
    """
    tracked = []
    for contrast in contrasts:
        rows = first_rows if not tracked else track(background, contrast)
        rows = _track_without_ball_in_background(lambda clean: track(clean, contrast), samples, indices, background,
                                                 rows)
        usable, found = _usable_and_found(rows)
        if usable < ENOUGH_USABLE_FRACTION * found and rescue is not None:
            # a channel that followed a hand is judged by how it follows the ball from its flight: the
            # first-ranked one may measure the ball alone where grey levels merge it with its shadow
            rows = rescue(rows, contrast) or rows
            usable, found = _usable_and_found(rows)
        tracked.append((usable, -CHANNELS.index(contrast.name), rows, contrast))
        if len(tracked) == 1 and usable >= ENOUGH_USABLE_FRACTION * found:
            break
    _, _, rows, contrast = max(tracked, key=lambda item: item[:2])
    return rows, contrast


def _sample_balls(rows, indices):
    """(x, y, radius) of the rows at ``indices``, px, shape (n, 3), NaN where the ball was not found.

    A sample before the first row where the ball was found takes that row's ball, and one after the last
    row takes the last: a ball held still before its release, or at rest after its last bounce, for half
    of the clip is in the median and cannot be found against it there, while its ghost is found in its
    flights (a clip of 440 frames, 45 % of them at rest, lost its drop and first impact to the ghost).
    """
    balls = np.array([rows[i][:3] for i in range(len(rows))], float).reshape(-1, 3)
    found = np.flatnonzero(np.isfinite(balls).all(axis=1))
    picked = balls[list(indices)]
    if found.size:
        picked[np.asarray(indices) < found[0]] = balls[found[0]]
        picked[np.asarray(indices) > found[-1]] = balls[found[-1]]
    return picked


def _track_without_ball_in_background(track, samples, indices, background, rows):
    """Rows of further passes of ``track(background)`` with the ball cut out of the background.

    Stops when the ball is not in the background, when the balls in the samples moved less than
    ``BACKGROUND_SETTLED_PX``, or after ``MAX_BACKGROUND_REFINEMENTS`` passes, or at once without samples.
    """
    if not len(indices):
        return rows
    balls = _sample_balls(rows, indices)
    for _ in range(MAX_BACKGROUND_REFINEMENTS):
        cleaner = background_without_ball(samples, balls, background)
        if cleaner is None:
            break
        rows = track(cleaner)
        moved_balls = _sample_balls(rows, indices)
        change = np.abs(moved_balls - balls)
        change[np.isnan(moved_balls) & np.isnan(balls)] = 0.0
        balls = moved_balls
        if np.nan_to_num(change, nan=np.inf).max() < BACKGROUND_SETTLED_PX:
            break
    return rows


def _rows_before(rows_back, count):
    """Rows of frames 0 … ``count`` - 1 from a pass run backwards from frame ``count`` (``rows_back[k]``
    is frame ``count - k``), in forward order.

    Backwards, the earlier frame of a repeated pair is the one flagged ``duplicate``; forwards the later
    one is (its time stamp does not belong to its content): each run of repeats takes the measurement
    of the frame after it at its first frame, and its other frames are the repeats.
    """
    rows = list(reversed(rows_back))[:count + 1]  # frames 0 … count
    index = 0
    while index < count:
        if rows[index][3] != QUALITY_DUPLICATE:
            index += 1
            continue
        end = index
        while end < count and rows[end + 1][3] == QUALITY_DUPLICATE:
            end += 1
        measured, repeat = rows[end + 1], rows[index]
        rows[index] = measured
        for later in range(index + 1, end + 2):
            rows[later] = repeat
        index = end + 2
    return rows[:count]


#: A flight is judged by the ball's area (its median radius squared, px²) times the frames it spans: the ball is the
#: largest coherent moving blob. The green ball's real clip (1920 × 1080 px): codec specks along the floor and at a
#: hand's fringe chain into a 13-frame "flight" of 5.7 px blobs in grey levels, the ball into one of 11 frames at
#: 44 px in chroma; taking the first channel's flight followed the specks.
def flight_size(flight):
    """A flight's size: its radius squared (px²) times the frames it spans."""
    return flight.radius_px ** 2 * (int(flight.frames[-1]) - int(flight.frames[0]) + 1)


class _FlightRescue:
    """Rows tracked again from the ball's flight, for a channel whose rows followed something else.

    A poor track on a clip that starts with hands in view has often followed a hand or a speck. The
    largest ballistic flight of round blobs (:func:`dropfit.video.link.find_flight` in each contrast
    channel, the largest by :func:`flight_size`; searched once per clip) is the ball: it is tracked
    afresh forwards from the flight's first frame, as from a user's ``--ball-at-px``, and backwards
    from there to the clip's start.

    Parameters
    ----------
    frames : sequence of numpy.ndarray
        Every frame of the clip, in memory.
    background : Background
        The scene.
    contrasts : list of Contrast
        The channels, in their ranking's order.
    expected_radius_px : float or None
        Expected ball radius, px.
    hints : TrackerHints
        What the user says of the ball; with its position given there is nothing to rescue.
    """

    def __init__(self, frames, background, contrasts, expected_radius_px, hints):
        self.frames, self.background, self.contrasts = frames, background, contrasts
        self.expected_radius_px, self.hints = expected_radius_px, hints
        self._searched, self._start = False, None

    def _flight(self):
        """The largest flight of all channels (:func:`flight_size`), or None."""
        if not self._searched:
            self._searched = True
            flights = [flight for flight in (find_flight(self.frames, self.background, contrast)
                                             for contrast in self.contrasts) if flight is not None]
            self._start = max(flights, key=flight_size) if flights else None
        return self._start

    def __call__(self, rows, contrast):
        """Rows of ``contrast`` tracked from the flight when more of them are usable than of ``rows``; else None."""
        flight = self._flight()
        if self.hints.ball_at_px is not None or flight is None:
            return None
        start, x, y = flight.start()
        from_flight = self.hints._replace(ball_at_px=(0, x, y))
        ahead = _run(self.frames[start:], self.background, self.expected_radius_px, contrast, from_flight)
        behind = _run(self.frames[start::-1], self.background, self.expected_radius_px, contrast, from_flight)
        rescued = _rows_before(behind, start) + ahead
        return rescued if _usable_and_found(rescued)[0] > _usable_and_found(rows)[0] else None


def refitted_repeats(x_px, y_px, quality):
    """Frames that measure the previous frame's capture again, which the frame test did not flag.

    A codec re-encodes a repeated capture with changes anywhere in the frame (a 30 Hz capture in a 60 fps MOV), and
    the frame test (:meth:`BallTracker._is_duplicate`) takes it for a new one; its time stamp is then not its
    instant. Its ball has hardly moved (less than ``REPEAT_MOVE_FRACTION`` of the speed) while the ball moves at
    least ``REPEAT_MIN_SPEED_PX`` a frame on both sides in the same direction (a ball in flight cannot stop, and one
    that bounces, is caught or held turns or stops), or its centre repeats the previous frame's to the bit after
    the ball moved (more than ``STILL_BALL_STEP_PX`` a frame).

    Parameters
    ----------
    x_px, y_px : numpy.ndarray
        Centres (px), NaN where not found.
    quality : sequence of str
        Each frame's flag; only frames with the ball measured alone (not occluded) count.

    Returns
    -------
    numpy.ndarray
        Boolean mask of the repeated frames.
    """
    measured = np.flatnonzero(np.isin(np.asarray(quality), [QUALITY_OK, QUALITY_BLURRED, QUALITY_PARTIAL,
                                                           QUALITY_SHADED]))
    repeats = np.zeros(len(quality), dtype=bool)
    for before, previous, current, after in zip(measured, measured[1:], measured[2:], measured[3:]):
        if current - previous != 1:
            continue
        points = np.array([(x_px[k], y_px[k]) for k in (before, previous, current, after)])
        speed_before = (points[1] - points[0]) / (previous - before)
        speed_after = (points[3] - points[2]) / (after - current)
        speed = min(np.hypot(*speed_before), np.hypot(*speed_after))
        # a centre fitted again to the bit is the same pixels, at the apex or a bounce too
        exact = (points[2] == points[1]).all() and np.hypot(*speed_before) > STILL_BALL_STEP_PX
        repeats[current] = exact or (speed >= REPEAT_MIN_SPEED_PX and float(speed_before @ speed_after) > 0
                                     and np.hypot(*(points[2] - points[1])) <= REPEAT_MOVE_FRACTION * speed)
    return repeats


def _table(rows, times_s):
    x, y, r, quality, centre_se, fit_rms, blur = zip(*rows) if rows else ((),) * 7
    x, y, r, centre_se, fit_rms, blur = (np.asarray(column, float) for column in (x, y, r, centre_se, fit_rms, blur))
    quality = np.asarray(quality, object)
    repeats = refitted_repeats(x, y, quality)
    quality[repeats] = QUALITY_DUPLICATE
    for column in (x, y, r, centre_se, fit_rms, blur):
        column[repeats] = np.nan
    table = pd.DataFrame({"frame": np.arange(len(rows)), "time_s": np.asarray(times_s, float), "x_px": x, "y_px": y,
                          "radius_px": r, "quality": list(quality), "centre_se_px": centre_se, "fit_rms_px": fit_rms,
                          "blur_px": blur}, columns=COLUMNS)
    # positions the ballistic track does not support (a jump to something beside the ball) are left out
    return mark_off_track(table)


def track_frames(frames, times_s, expected_radius_px=None, *, background=None, source="frames", hints=None):
    """Track the ball through frames already in memory.

    Parameters
    ----------
    frames : sequence or iterable of numpy.ndarray
        Grey (height, width) or BGR (height, width, 3) uint8 frames in order. A sequence (list,
        array) is indexed to sample the background; any other iterable is first read into a list.
    times_s : array_like
        Time of each frame, s.
    expected_radius_px : float, optional
        Expected ball radius, px.
    background : Background, optional
        The static scene; by default the median of ``BACKGROUND_SAMPLES`` frames spread over the
        clip, with the ball cut out when it is in it (see the module documentation).
    source : str
        Name of the recording in error messages.
    hints : TrackerHints, optional
        What the user says of the ball (region of interest, position in one frame, colour).

    Returns
    -------
    pandas.DataFrame
        One row per frame: ``frame``, ``time_s`` (s), ``x_px``, ``y_px``, ``radius_px`` (px),
        ``quality``, ``centre_se_px``, ``fit_rms_px`` and ``blur_px`` (px; see the module documentation);
        ``attrs`` holds ``source``, ``noise_grey``, ``contrast`` (the channel tracked in) and ``in_colour``
        (whether that channel is a colour one).

    Raises
    ------
    InputError
        When there are no frames or the ball is never found.
    """
    if not isinstance(frames, (Sequence, np.ndarray)):
        frames = list(frames)
    hints = hints or TrackerHints()
    times_s = np.asarray(times_s, float)
    if len(frames) == 0:
        raise InputError(f"{source}: no frames")
    if times_s.shape != (len(frames),):
        raise ValueError(f"{len(frames)} frames but {times_s.size} times")
    if background is None:
        indices = spread_indices(len(frames), BACKGROUND_SAMPLES)
        samples = [frames[i] for i in indices]
        background, contrasts = scene_and_contrasts(samples, expected_radius_px, hints.ball_colour_bgr)
        rows, contrast = _track_in_best_contrast(
            lambda clean, contrast: _run(frames, clean, expected_radius_px, contrast, hints), contrasts,
            _run(frames, background, expected_radius_px, contrasts[0], hints), samples, indices, background,
            _FlightRescue(frames, background, contrasts, expected_radius_px, hints))
    else:
        contrast = contrast_of(GREY, (), background)
        rows = _run(frames, background, expected_radius_px, contrast, hints)
    table = _table(rows, times_s)
    table.attrs.update(source=str(source), noise_grey=background.noise_grey, contrast=contrast.name,
                       in_colour=contrast.in_colour)
    return _found_or_raise(table, source)


#: Decoded frames of one clip kept whole for tracking again (ball in the background) up to this
#: many bytes; beyond, only crops around the ball are kept (:class:`_KeptFrames`). (At 256 MiB the real
#: tennis clip's 110 frames were kept as crops and tracked worse: 14 frames ok instead of both impacts.)
FRAME_MEMORY_BUDGET_BYTES = 400 * 2**20
#: The share of that budget the crops may take: the whole frames they replace do not give all their memory back,
#: and a pass that decodes the clip again needs its own. `dropfit run` of 3000 frames of 640 × 480 with a ball of
#: radius 60 px peaked at 2.40 GB with crops unbounded, 1044 MB with crops up to the whole budget, 882 MB now.
CROP_BUDGET_SHARE = 0.5
#: Half side of a kept crop, in ball radii plus CROP_MARGIN_PX: the tracker's search window about
#: a predicted centre (1.5 radii plus two steps plus its margin) with room for a step of a radius.
CROP_RADII = 4.0
CROP_MARGIN_PX = 2 * WINDOW_MARGIN_PX


def _decoded_frames(path):
    """Every frame of the video at ``path`` again, in order (a second decoding pass)."""
    with VideoFile(path) as video:
        for _, _, image in video.frames(lazy=True):
            yield image


class _KeptFrames:
    """The frames of the one decoding pass, kept to track the ball again with another background.

    Frames are kept whole while they fit in ``budget_bytes``; past it, every frame is cut down to a
    square crop about the ball's last tracked centre (``CROP_RADII`` radii plus ``CROP_MARGIN_PX``
    each way), and frames before the ball was first found to nothing. A frame tracked again is the
    new background's scene (in colour where it has one) with its crop pasted in: a ball that stays near where the first pass saw
    it (what puts it in the background) is measured from the same pixels; elsewhere there is no
    foreground. Crops past :data:`CROP_BUDGET_SHARE` of the budget (a long clip of a large ball: frames ×
    crop pixels) are let go, and the clip is decoded again for each pass: memory stays bounded whatever
    the clip's length.
    """

    def __init__(self, budget_bytes=None):
        self.budget_bytes = FRAME_MEMORY_BUDGET_BYTES if budget_bytes is None else budget_bytes
        self._frames = []  # whole frames, then (x0, y0, crop) or None; None once the crops too are over budget
        self._whole = True
        self._bytes = 0
        self._centre = None  # last tracked (x, y, radius), px

    @property
    def whole(self):
        """Whether the frames are kept whole (else as crops about the ball, or not at all)."""
        return self._whole

    @property
    def kept(self):
        """Whether the frames are kept, whole or as crops (else the clip must be decoded again)."""
        return self._frames is not None

    def keep(self, frame, row):
        """Keep ``frame`` (BGR or grey uint8) that the first pass measured as ``row`` (x, y, radius, ...)."""
        if math.isfinite(row[0]):
            self._centre = row[:3]
        if self._frames is None:
            return
        if self._whole:
            self._frames.append((frame, self._centre))
            self._bytes += frame.nbytes
            if self._bytes > self.budget_bytes:
                self._whole, self._bytes = False, 0
                for index, (image, centre) in enumerate(self._frames):  # in place: each whole frame let go as cut
                    self._frames[index] = self._cropped(image, centre)
        else:
            self._frames.append(self._cropped(frame, self._centre))
        if not self._whole and self._bytes > CROP_BUDGET_SHARE * self.budget_bytes:
            self._frames = None

    def _cropped(self, image, centre):
        """(the crop of ``image`` about ``centre``, ``centre``), its bytes counted."""
        crop = self._crop(image, centre)
        self._bytes += 0 if crop is None else crop[2].nbytes
        return crop, centre

    @staticmethod
    def _crop(image, centre):
        if centre is None:
            return None
        x, y, radius = centre
        reach = CROP_RADII * (radius if math.isfinite(radius) else 10.0) + CROP_MARGIN_PX
        x0, y0 = max(int(x - reach), 0), max(int(y - reach), 0)
        return x0, y0, image[y0:int(y + reach) + 1, x0:int(x + reach) + 1].copy()

    def frames(self, background):
        """The kept frames for tracking against ``background``: whole, or its scene with the crop pasted in."""
        scene = background.image()
        for kept, _ in self._frames:
            if self._whole:
                yield kept
                continue
            frame = scene.copy()
            if kept is not None:
                x0, y0, crop = kept
                if crop.ndim != frame.ndim:
                    crop = grey_uint8(crop)
                frame[y0:y0 + crop.shape[0], x0:x0 + crop.shape[1]] = crop
            yield frame


def _reduced_hints(hints, expected_radius_px, factor):
    """``hints`` and ``expected_radius_px`` (px of the coded frames) in px of frames reduced ``factor`` times."""
    if factor == 1:
        return hints, expected_radius_px
    roi = None if hints.roi_px is None else tuple(value / factor for value in hints.roi_px)  # pixel edges
    ball_at = None if hints.ball_at_px is None else (hints.ball_at_px[0],
                                                     *(reduced_px(value, factor) for value in hints.ball_at_px[1:]))
    return (hints._replace(roi_px=roi, ball_at_px=ball_at),
            None if expected_radius_px is None else expected_radius_px / factor)


def _check_hints(hints, frames, shape, name):
    """InputError for a hint that cannot apply to a clip of ``frames`` frames of ``shape`` (rows, columns) px: a
    frame of ``--ball-at-px`` beyond the clip or a point outside the frame, a ``--roi-px`` outside it."""
    height, width = shape
    if hints.ball_at_px is not None:
        frame, x, y = hints.ball_at_px
        if not 0 <= frame < frames:
            raise InputError(f"{name}: --ball-at-px names frame {frame:g}, but the clip's frames are 0-{frames - 1}; "
                             f"give FRAME,X,Y of a frame in it (see the contact sheet, dropfit overlay)")
        if not (0 <= x < width and 0 <= y < height):
            raise InputError(f"{name}: --ball-at-px puts the ball at {x:g},{y:g} px, outside the {width}x{height} px "
                             f"frame; give X,Y in px from the frame's top left corner")
    if hints.roi_px is not None:
        x0, y0, x1, y1 = hints.roi_px
        if x0 >= width or y0 >= height or x1 <= 0 or y1 <= 0:
            raise InputError(f"{name}: --roi-px {x0:g},{y0:g},{x1:g},{y1:g} lies outside the {width}x{height} px "
                             f"frame; give X0,Y0,X1,Y1 in px from the frame's top left corner")


def track_video(path, capture_fps=None, expected_radius_px=None, *, background_samples=BACKGROUND_SAMPLES,
                progress_stream=None, frame_memory_bytes=None, hints=None):
    """Track the ball through a video file.

    The file is opened once and decoded once (:class:`dropfit.video.decode.VideoFile`): the
    background is the median of ``background_samples`` frames reached by seeking to key frames,
    then every frame is decoded in order, in a second thread, as the phone shows it (rotation
    applied), and tracked. When the ball is in the background, the further tracking passes run on
    frames kept in memory (:class:`_KeptFrames`), not on the file.

    Times are the frames' presentation time stamps, so variable frame timing and dropped frames
    keep their true instants; frames a recorder repeated are flagged ``duplicate``. Without time
    stamps, times come from the frame index and the container's frame rate.

    Parameters
    ----------
    path : str or pathlib.Path
        The video file.
    capture_fps : float, optional
        The rate at which the camera captured the frames, frames/s, for slow-motion files whose
        container rate is a playback rate (a 240 fps capture stored as 30 fps): container times
        are scaled by ``container_fps / capture_fps``. Estimating it from the ball's gravitational
        acceleration is done elsewhere.
    expected_radius_px : float, optional
        Expected ball radius, px.
    background_samples : int
        Frames in the background median.
    progress_stream : file, optional
        Where a long clip's progress goes (:class:`dropfit.video.decode.Progress`); standard error
        by default.
    frame_memory_bytes : int, optional
        Memory for whole frames kept for tracking again, bytes; ``FRAME_MEMORY_BUDGET_BYTES`` by default.
    hints : TrackerHints, optional
        What the user says of the ball (region of interest, position in one frame, colour).

    Returns
    -------
    pandas.DataFrame
        As :func:`track_frames`; ``attrs`` holds ``source``, ``container_fps`` (frames/s),
        ``capture_fps``, ``time_source``, ``frame_count_header``, ``rotation_deg`` (counter-clockwise,
        applied), ``codec``, ``noise_grey``, ``contrast`` and ``in_colour``.

    Raises
    ------
    InputError
        For a missing, unreadable or corrupt file, a file without frames, or a ball never found.
    """
    return track_video_and_background(path, capture_fps, expected_radius_px, background_samples=background_samples,
                                      progress_stream=progress_stream, frame_memory_bytes=frame_memory_bytes,
                                      hints=hints)[0]


class TrackedVideo(NamedTuple):
    """A tracked video: its table (:func:`track_video`) and the background it was tracked against."""

    table: pd.DataFrame
    background: Background


def track_video_and_background(path, capture_fps=None, expected_radius_px=None, *,
                               background_samples=BACKGROUND_SAMPLES, progress_stream=None, frame_memory_bytes=None,
                               hints=None):
    """:func:`track_video`'s table and the background it tracked against, as a :class:`TrackedVideo`,
    for what else is read from the scene (a ruler, a target, the floor) without opening the file again."""
    hints = hints or TrackerHints()
    path = check_input_file(path, "video")
    name = shown_path(path)
    if capture_fps is not None and not capture_fps > 0:
        raise InputError(f"{name}: capture_fps must be positive, got {capture_fps}")
    check_video_file(path)
    with VideoFile(path) as video:
        info = video.info
        # the user's px are of the coded frames; the tracker's of the frames as decoded
        tracked_hints, expected_radius_px = _reduced_hints(hints, expected_radius_px, info.reduced_by)
        samples = video.samples(background_samples)
        if not samples:
            raise InputError(f"{name}: the frames could not be decoded consistently (corrupt video)")
        sample_images = [image for _, image in samples]
        # the frames are decoded while the scene is read from the samples
        with video.frames(Progress(path.name, info.frame_count, progress_stream), lazy=True) as frames:
            background, contrasts = scene_and_contrasts(sample_images, expected_radius_px, hints.ball_colour_bgr)
            tracker = BallTracker(background, expected_radius_px, contrasts[0], tracked_hints)
            kept = _KeptFrames(frame_memory_bytes)
            stamps, rows = [], []
            for _, time_s, image in frames:
                stamps.append(time_s)
                rows.append(tracker.update(image))
                kept.keep(image, rows[-1])
    check_frame_count(len(rows), info.frame_count, path)
    _check_hints(hints, len(rows), tuple(info.reduced_by * size for size in background.grey.shape), name)
    hints = tracked_hints
    if len(rows) < MIN_FRAMES:
        raise InputError(f"{name}: the video has only {len(rows)} frame{'s' if len(rows) > 1 else ''}; a drop "
                         f"test needs at least {MIN_FRAMES}, and tens in each flight")
    position = {stamp: index for index, stamp in enumerate(stamps)}
    found = [(position[stamp], image) for stamp, image in samples if stamp in position]
    indices, images = zip(*found) if found else ((), ())
    # (a clip too long to keep in memory is not tracked again from a flight)
    rescue = _FlightRescue(list(kept.frames(background)), background, contrasts, expected_radius_px, hints) \
        if kept.whole else None

    usable, found = _usable_and_found(rows)
    crops_hold_the_ball = usable >= ENOUGH_USABLE_FRACTION * found

    def track(clean, contrast):
        # crops about the first channel's ball serve that channel only, and only where that pass followed the ball
        # (crops about what a poor pass followed lose the ball in every later pass); else the file is read again
        reuse = kept.whole or (kept.kept and contrast is contrasts[0] and crops_hold_the_ball)
        frames = kept.frames(clean) if reuse else _decoded_frames(path)
        return _run(frames, clean, expected_radius_px, contrast, hints)

    rows, contrast = _track_in_best_contrast(track, contrasts, rows, list(images), list(indices), background, rescue)
    container_fps = float(info.container_fps) if info.container_fps else math.nan
    times, how = frame_times(stamps, container_fps, capture_fps, path)
    table = _table(rows, times)
    table.attrs.update(source=str(path), container_fps=container_fps, capture_fps=capture_fps,
                       time_source=how, frame_count_header=info.frame_count, rotation_deg=info.rotation_deg,
                       codec=info.codec, noise_grey=background.noise_grey, contrast=contrast.name,
                       in_colour=contrast.in_colour, reduced_by=info.reduced_by,
                       frames_note=reduction_note(info.reduced_by))
    return TrackedVideo(_found_or_raise(table, path), background)
