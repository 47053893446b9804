"""How the ball stands out from the scene: one contrast value per pixel, in one of three channels.

The tracker measures the ball in one image, the frame's contrast to the background, with the
background at 0 (:mod:`dropfit.video.detect`). Which contrast depends on the scene, so it is
chosen per clip (:func:`choose_contrasts`):

``grey``
    The grey level minus the background's, signed (full resolution in every codec). A ball as bright
    as its surroundings (yellow on green) is invisible in it, and the ball's shadow on the wall
    behind is as dark as a dark ball: a shadow that touches the ball merges with it.
``chroma``
    The length of the frame's colour difference to the background that is *not* along the
    background's own colour (BGR vectors: with ``D = I/g - B``, the part of ``D`` perpendicular to
    ``B``). A shadow or a flickering light scales the background's colour, ``I = s B``, so it
    has no such part and vanishes; a ball of another hue than the wall (green on white, yellow on
    green, a slightly warm white on a grey wall) keeps it. For a pixel covered by the ball to a
    fraction ``a``, ``I = a F + (1 - a) B`` gives ``a |F_perp|``: linear in the coverage, as the
    measurement needs. Codecs store colour at half resolution (4:2:0), so its edges are blurred
    over about two pixels, which a coverage-weighted centroid tolerates.
``brighter``
    How much brighter than the background, along the background's colour (``D`` projected on
    ``B``), negative values cut to 0: a white ball on a light wall, whose shadow is darker, not
    brighter. Measured against the background in the shade of its neighbourhood, so that the
    ball's rim over its own shadow counts in full.

``g`` is the frame's gain against the background (:func:`frame_gain`): lighting that flickers
with the mains or an automatic exposure that drifts scales every pixel alike, and is divided out
before the colour channels are formed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np

from ..numerics import robust_sigma
from .background import NOISE_THRESHOLD_SIGMAS, to_grey
from .opencv import connected_components, cv2

GREY = "grey"
CHROMA = "chroma"
BRIGHTER = "brighter"
#: The channels, in the order preferred when they show the ball equally well (grey has full resolution).
CHANNELS = (GREY, CHROMA, BRIGHTER)

#: Pixels between the sparse samples of a channel's noise.
SAMPLE_STRIDE_PX = 8
#: Pixels between the sparse samples of the frame gain, computed for every frame: a 720p frame gives
#: 3 600, whose median ratio is good to 0.05 % with a sensor noise of 2 % of the level.
GAIN_STRIDE_PX = 16
#: Lower bound of a colour channel's foreground threshold, grey levels: the background's samples are
#: key frames, and a codec renders the frames between them with colour errors of several levels that
#: key frames do not show.
MIN_COLOUR_THRESHOLD = 12.0
#: The ball's chroma against a pixel's background counts as at least this fraction of its median over
#: the window (a background of the ball's own hue would make the scaled contrast noise).
MIN_BALL_CHROMA_FRACTION = 0.25
#: Neighbourhood whose darkest shade is a pixel's background in ``brighter``.
SHADE_NEIGHBOURHOOD = np.ones((3, 3), np.uint8)
#: Background colour vectors shorter than this (grey levels) have no direction to measure along.
MIN_BACKGROUND_LENGTH = 10.0
#: Sums the three channels of a pixel (:func:`channel_dot`).
_CHANNEL_SUM = np.ones((1, 3), np.float32)


def channel_dot(a, b):
    """Pixel by pixel, the dot product of two BGR images (last axis of three): Σ a_c · b_c, float32.

    Done by OpenCV (multiply, then a channel transform): NumPy's sum over a trailing axis of three is
    ten to twenty times slower, and these products are most of what the colour channels cost.

    Parameters
    ----------
    a, b : numpy.ndarray
        Arrays of shape (..., 3); ``b`` broadcast to ``a``'s shape.

    Returns
    -------
    numpy.ndarray
        float32, ``a``'s shape without its last axis.
    """
    a = np.ascontiguousarray(a, dtype=np.float32)
    if a.size == 0:
        return np.zeros(a.shape[:-1], np.float32)
    if np.ndim(b) == 1:  # one colour for every pixel: a channel transform alone
        return cv2.transform(a.reshape(-1, 1, 3), np.asarray(b, np.float32).reshape(1, 3)).reshape(a.shape[:-1])
    b = np.ascontiguousarray(np.broadcast_to(b, a.shape), dtype=np.float32)
    product = cv2.multiply(a.reshape(-1, 1, 3), b.reshape(-1, 1, 3))
    return cv2.transform(product, _CHANNEL_SUM).reshape(a.shape[:-1])


@dataclass(frozen=True)
class Contrast:
    """One contrast channel with its noise and foreground threshold.

    Attributes
    ----------
    name : str
        ``grey``, ``chroma`` or ``brighter`` (see the module documentation).
    noise : float
        Robust standard deviation of the channel where the scene is static, grey levels.
    threshold : float
        Foreground threshold on the channel's absolute value, grey levels.
    fixtures : tuple of (float, float, float)
        Blobs that stay in one place in this channel through the clip, x, y and radius in px: not
        the ball (see :func:`dropfit.video.track.scene_and_contrasts`).
    ball_radius_px : float or None
        The radius of the lone discs this channel shows in most of the clip's samples, px (coarse), None where
        it shows none or only specks (SPECK_MAX_RADIUS_PX): what the tracker's first search looks for (see
        :func:`dropfit.video.track.scene_and_contrasts`).
    """

    name: str
    noise: float
    threshold: float
    fixtures: tuple = ()
    ball_radius_px: float | None = None

    @property
    def in_colour(self):
        """Whether the channel needs the frame and the background in colour."""
        return self.name != GREY

    def image(self, frame, background_grey, background_colour, gain=1.0, hand=None):
        """The frame's contrast to the background, float32, background at 0.

        Parameters
        ----------
        frame : numpy.ndarray
            A window of the frame, grey or BGR uint8.
        background_grey : numpy.ndarray
            The background's grey levels over the same window, float32.
        background_colour : numpy.ndarray or None
            The background's BGR over the same window, uint8 (colour channels only).
        gain : float
            The frame's gain against the background (:func:`frame_gain`), dimensionless.
        hand : numpy.ndarray, optional
            The frame's hand pixels when known (:func:`hand_pixels` without the ball's colour), as in :meth:`images`.

        Returns
        -------
        numpy.ndarray
            float32, the window's shape without channels, grey levels.
        """
        image, background = self.images(frame, background_grey, background_colour, gain, hand=hand)
        return image - background

    def images(self, frame, background_grey, background_colour, gain=1.0, ball_bgr=None, hand=None):
        """The frame and the background in this channel, float32, for :func:`dropfit.video.detect.measure_ball`.

        ``grey`` gives the grey levels of both, so that the ball's coverage of each pixel is
        measured against that pixel's own background on a textured scene; a colour channel gives
        its contrast image and zeros. With the ball's colour ``ball_bgr`` known (BGR levels),
        ``chroma`` is scaled pixel by pixel to the ball's own chroma against that pixel's
        background (:func:`chroma_contrast`), so that a ball passing from a wall to a floor of
        another colour is covered alike on both. A hand (``hand``, by default :func:`hand_pixels`) is
        taken out: its pixels are given the background's value. Parameters as :meth:`image`;
        ``background_colour`` may be given for ``grey`` too (then a hand is taken out of it as well).
        """
        if background_colour is not None and self.in_colour:
            background_colour = SceneColour.of(background_colour)  # derived once for the channel and the hand
        if self.name == GREY:
            image, background = to_grey(frame), np.asarray(background_grey, np.float32)
        elif self.name == BRIGHTER:
            image, background = _brightness_and_shade(frame, background_colour, gain)
        else:
            image = chroma_contrast(frame, background_colour, gain, ball_bgr)
            background = np.zeros_like(image)
        if hand is None:
            hand = hand_pixels(frame, background_colour, ball_bgr)
        if hand is not None and hand.any():
            image = np.where(hand, background, image)
        return image, background


@dataclass(frozen=True)
class SceneColour:
    """A background's colour with what the colour channels derive from it, pixel by pixel.

    Made once per background (:meth:`of`) and cut to a window (:meth:`window`) for each frame, so that
    the tracker does not derive them again from the same scene for every frame. Every function of
    this module that takes a background colour takes one of these or a BGR uint8 array.

    Attributes
    ----------
    bgr : numpy.ndarray
        The colour, uint8 (height, width, 3).
    vector : numpy.ndarray
        The colour as float32 vectors B, grey levels.
    length : numpy.ndarray
        |B|, float32 (height, width).
    unit : numpy.ndarray
        B / max(|B|, ``MIN_BACKGROUND_LENGTH``), float32 (height, width, 3).
    unit_power : numpy.ndarray
        |unit|², float32 (height, width): 1 but where |B| < ``MIN_BACKGROUND_LENGTH``.
    skin : numpy.ndarray
        Which pixels are skin-coloured (:func:`skin_mask`), bool (height, width).
    """

    bgr: np.ndarray
    vector: np.ndarray
    length: np.ndarray
    unit: np.ndarray
    unit_power: np.ndarray
    skin: np.ndarray

    @classmethod
    def of(cls, background_colour):
        """The scene colour of a BGR uint8 array (returned as it is when it is one already)."""
        if isinstance(background_colour, cls):
            return background_colour
        vector = background_colour.astype(np.float32)
        length = np.sqrt(channel_dot(vector, vector))
        unit = vector / np.maximum(length, MIN_BACKGROUND_LENGTH)[..., None]
        return cls(background_colour, vector, length, unit, channel_dot(unit, unit), skin_mask(background_colour))

    def window(self, left, top, right, bottom):
        """The part of columns ``left ≤ x < right``, rows ``top ≤ y < bottom`` (px), as views."""
        return self._indexed((slice(top, bottom), slice(left, right)))

    def at(self, rows, columns):
        """The scene at the pixels (``rows``, ``columns``): arrays of one entry per pixel."""
        return self._indexed((rows, columns))

    def _indexed(self, index):
        return SceneColour(*(getattr(self, field.name)[index] for field in fields(self)))

    @cached_property
    def gain_reference(self):
        """:func:`frame_gain`'s sparse samples of the scene, made once: (which samples are lit, their colour
        vectors B and B · B)."""
        return _gain_reference(self.bgr)


def scene_colour(background):
    """The :class:`SceneColour` of a :class:`dropfit.video.background.Background`, made once and kept with
    it; None for a grey background."""
    if background.colour is None:
        return None
    return background.derived("scene colour", lambda: SceneColour.of(background.colour))


def _brightness_and_shade(frame, background_colour, gain):
    """``brighter``'s image and background: the frame's brightness along the background's colour, and
    the background's brightness times the darkest shade (frame over background, at most 1) within a
    pixel, float32 grey levels.

    A shadow touching the ball darkens the wall under the ball's rim: measured against the lit wall,
    the rim's coverage by the ball would come out too low on the shadow's side. The rim's own
    background is the shadowed wall next to it, so each pixel is measured against the darkest shade
    of its 3 × 3 neighbourhood; away from shadows that shade is 1.
    """
    scene = SceneColour.of(background_colour)
    length = scene.length
    brightness = channel_dot(frame.astype(np.float32) * np.float32(1.0 / gain), scene.unit)
    shade = np.clip(brightness / np.maximum(length, MIN_BACKGROUND_LENGTH), 0.0, 1.0)
    return brightness, cv2.erode(shade, SHADE_NEIGHBOURHOOD) * length


def _across(vectors, scene):
    """The length of BGR ``vectors`` (one per pixel, or one for all) across the scene's unit colours (pixel by
    pixel), float32.

    With ``a = v · u``, the part across is ``v - a u``, of squared length ``|v|² - a² (2 - |u|²)``
    (``|u|`` is 1 but on the darkest pixels): no vector of it need be formed.
    """
    if vectors.ndim == 1:  # one colour against every pixel's
        along, power = channel_dot(scene.unit, vectors), float(vectors @ vectors)
    else:
        along, power = channel_dot(vectors, scene.unit), channel_dot(vectors, vectors)
    return np.sqrt(np.maximum(power - along * along * (2.0 - scene.unit_power), 0.0))


def chroma_contrast(frame, background_colour, gain=1.0, ball_bgr=None):
    """The ``chroma`` contrast of a BGR frame (window) to the background's colour, float32 grey levels.

    With ``ball_bgr``, each pixel's contrast is divided by the ball's own contrast to that pixel's
    background (at least ``MIN_BALL_CHROMA_FRACTION`` of its median over the window) and multiplied
    by that median: a fully covered pixel reads the same wherever the ball is, in grey levels of the
    window's typical contrast.
    """
    scene = SceneColour.of(background_colour)
    image = _across(frame.astype(np.float32) * np.float32(1.0 / gain) - scene.vector, scene)
    if ball_bgr is None:
        return image
    full = _across(np.asarray(ball_bgr, np.float32), scene)
    typical = float(np.median(full))
    if typical <= 0.0:
        return image
    return image * (typical / np.maximum(full, MIN_BALL_CHROMA_FRACTION * typical))


#: Skin in YCrCb (8-bit OpenCV scale): red-difference Cr and blue-difference Cb ranges of human skin
#: under common lighting (Chai and Ngan's rule), dark to light complexions.
SKIN_CR = (135, 175)
SKIN_CB = (80, 130)
#: The skin ranges as YCrCb bounds for :func:`cv2.inRange` (any Y).
_SKIN_LOW = np.array([0, SKIN_CR[0], SKIN_CB[0]], np.uint8)
_SKIN_HIGH = np.array([255, SKIN_CR[1], SKIN_CB[1]], np.uint8)
#: Least chroma contrast (grey levels) of a hand's pixel to the background.
HAND_MIN_CHROMA = 20.0
#: A pixel within this fraction of the ball-to-background colour distance (at least MIN_BLEND_TOLERANCE
#: grey levels) of the segment between them is a blend of the two.
BLEND_TOLERANCE = 0.15
MIN_BLEND_TOLERANCE = 12.0
#: Opening that keeps only skin-coloured areas broader than a ball's blended rim.
HAND_OPENING = np.ones((5, 5), np.uint8)
#: A blob whose area exceeds this multiple of its largest inscribed circle's (plus a perimeter's worth for a coarse
#: grid) is not a lone disc (:func:`is_lone_disc`).
MAX_FILL_RATIO = 1.3
#: A skin-coloured area that is a lone disc is a ball of a skin-like colour (crimson, orange, pink: inside the skin
#: ranges), not a hand, which has fingers, a wrist and an arm, and reaches in from the image's border. A lone disc as
#: the whole-frame search judges one (:func:`is_lone_disc`) by its convex hull (a highlight can cut a notch into the
#: ball's colour) ...
#: ... the area fills at least this fraction of its hull (a thumb and fingers curled about nothing do not) ...
ROUND_SOLIDITY = 0.8
#: ... and at least this fraction of the ring ROUND_RING_PX beyond it is the scene or a blend of the scene with the
#: disc's colour (its blurred rim): a ball alone before the scene, its shadow under part of it. The warm-lit side of
#: a white ball above a wooden table is a compact skin-coloured patch too, amid the ball's white.
ROUND_ALONE_FRACTION = 0.5
ROUND_RING_PX = 3


def skin_mask(frame):
    """Which pixels of a BGR uint8 frame (window) are skin-coloured (``SKIN_CR``, ``SKIN_CB``): a hand, whatever
    the brightness, or a ball of a skin-like colour (crimson, orange, pink; :func:`hand_pixels` tells them apart by
    shape). White, black, yellow, green, blue and pure red balls fall outside the ranges.

    Returns
    -------
    numpy.ndarray
        bool, the frame's shape without channels.
    """
    # one OpenCV pass over the three channels: NumPy's four comparisons of strided channels cost 2.5 times more
    ycrcb = cv2.cvtColor(np.ascontiguousarray(frame), cv2.COLOR_BGR2YCrCb)
    return cv2.inRange(ycrcb, _SKIN_LOW, _SKIN_HIGH).reshape(ycrcb.shape[:-1]) != 0


def _ball_blend(frame, background_colour, ball_bgr):
    """Which pixels are a blend of the ball's colour and the background's (its rim, its blur): the
    frame's colour lies on the segment from the background's to the ball's, within
    ``BLEND_TOLERANCE`` of the segment's length (and ``MIN_BLEND_TOLERANCE`` grey levels).

    With ``o`` the frame's colour less the background's, ``s`` the ball's less the background's and
    ``d = o · s``, the share along the segment is ``d / |s|²`` and the distance off it squared
    ``|o|² - 2 share d + share² |s|²``."""
    scene = SceneColour.of(background_colour)
    ball = np.asarray(ball_bgr, np.float32)
    scene_ball = channel_dot(scene.vector, ball)
    span2 = float(ball @ ball) - 2.0 * scene_ball + scene.length * scene.length
    length2 = np.maximum(span2, 1.0)
    offset = frame.astype(np.float32) - scene.vector
    along = channel_dot(offset, ball) - channel_dot(offset, scene.vector)
    share = along / length2
    off_line2 = channel_dot(offset, offset) - 2.0 * share * along + share * share * span2
    tolerance = np.maximum(BLEND_TOLERANCE * np.sqrt(length2), MIN_BLEND_TOLERANCE)
    return (share >= -0.05) & (share <= 1.05) & (off_line2 <= tolerance * tolerance)


def hand_pixels(frame, background_colour, ball_bgr=None, min_area_px=0.0):
    """Pixels of a BGR frame (window) that are skin-coloured where the background is not, and differ from
    it in hue by more than ``HAND_MIN_CHROMA``: a hand (areas at least 5 px across: ``HAND_OPENING``), but for
    lone discs clear of the window's border (:func:`is_lone_disc`): balls of a skin-like colour. With the ball's
    colour ``ball_bgr`` known, blends of it with the background are not; with ``min_area_px``, only skin-coloured
    areas at least that large, or reaching the window's border, count (a hand is larger than the ball).

    Returns
    -------
    numpy.ndarray or None
        bool, the frame's shape without channels; None for a grey frame or without a colour background.
    """
    frame = np.asarray(frame)
    if background_colour is None or frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        return None
    hand = skin_mask(frame)
    if not hand.any():  # most windows: nothing skin-coloured, nothing more to compute
        return hand
    # skin-coloured where the background is not (a wooden floor is), and not the background in shade (a
    # shadow keeps its hue): judged at the few pixels left only
    scene = SceneColour.of(background_colour)
    hand &= ~scene.skin
    rows, columns = np.nonzero(hand)
    pixels, at = frame[rows, columns], scene.at(rows, columns)
    keep = chroma_contrast(pixels, at) > HAND_MIN_CHROMA
    if ball_bgr is not None:  # a red ball blurred over a white wall is pink: its blend, not a hand
        keep &= ~_ball_blend(pixels, at, ball_bgr)
    hand[rows[~keep], columns[~keep]] = False
    hand = hand.astype(np.uint8)
    # a ball's anti-aliased rim blends its colour with the wall's into skin-like tones, a ring at most
    # two pixels wide; a hand is broader
    hand = cv2.morphologyEx(hand, cv2.MORPH_OPEN, HAND_OPENING)
    if hand.any():
        hand = _without_lone_discs(hand, frame, scene)
    if min_area_px > 0 and hand.any():
        # the shaded side of a red or orange ball is skin-coloured too, but smaller than the ball
        _, labels, stats = connected_components(hand)[:3]
        x0, y0, width, height, area = stats.T
        # what reaches the window's border goes on beyond it: an arm
        at_border = (x0 == 0) | (y0 == 0) | (x0 + width == hand.shape[1]) | (y0 + height == hand.shape[0])
        large = np.flatnonzero((area >= min_area_px) | at_border)
        return np.isin(labels, large[large > 0])
    return hand.astype(bool)


def is_lone_disc(area_px, inscribed_radius_px):
    """Whether a blob of ``area_px`` (px²) whose largest inscribed circle has radius ``inscribed_radius_px`` (px) is a
    lone disc: no more area than :data:`MAX_FILL_RATIO` times the circle's plus a perimeter's worth (a ball alone,
    not merged with its shadow or a hand)."""
    return area_px <= MAX_FILL_RATIO * math.pi * inscribed_radius_px ** 2 + 2 * math.pi * inscribed_radius_px


def _without_lone_discs(hand, frame, scene):
    """A uint8 skin mask of a BGR ``frame`` without its lone discs alone before the :class:`SceneColour` ``scene``
    and clear of the mask's border (:func:`is_lone_disc`): balls of a skin-like colour, not hands."""
    contours, _ = cv2.findContours(hand, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    discs = []
    grow = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * ROUND_RING_PX + 1,) * 2)
    for contour in contours:
        x0, y0, width, height = cv2.boundingRect(contour)
        if x0 == 0 or y0 == 0 or x0 + width == hand.shape[1] or y0 + height == hand.shape[0]:
            continue  # goes on beyond the window: an arm
        hull = np.zeros((height + 2, width + 2), np.uint8)  # a pixel of margin for the distance transform
        cv2.drawContours(hull, [cv2.convexHull(contour)], -1, 1, thickness=-1, offset=(1 - x0, 1 - y0))
        hull_area = np.count_nonzero(hull)
        inscribed = float(cv2.distanceTransform(hull, cv2.DIST_L2, cv2.DIST_MASK_PRECISE).max())
        area = np.count_nonzero(hand[y0:y0 + height, x0:x0 + width] & hull[1:-1, 1:-1])
        if area < ROUND_SOLIDITY * hull_area or not is_lone_disc(hull_area, inscribed):
            continue
        # the disc and the ring about it, in a box ROUND_RING_PX larger (within the frame)
        left, top = max(x0 - ROUND_RING_PX, 0), max(y0 - ROUND_RING_PX, 0)
        right = min(x0 + width + ROUND_RING_PX, hand.shape[1])
        bottom = min(y0 + height + ROUND_RING_PX, hand.shape[0])
        disc = np.zeros((bottom - top, right - left), np.uint8)
        cv2.drawContours(disc, [contour], -1, 1, thickness=-1, offset=(-left, -top))
        rows, columns = np.nonzero(cv2.dilate(disc, grow) & (1 - disc))
        box = frame[top:bottom, left:right]
        colour = np.median(box[disc.astype(bool)], axis=0)
        blend = _ball_blend(box[rows, columns], scene.at(rows + top, columns + left), colour)
        if blend.mean() >= ROUND_ALONE_FRACTION:
            discs.append(contour)
    if not discs:
        return hand
    hand = hand.copy()
    cv2.drawContours(hand, discs, -1, 0, thickness=-1)
    return hand


def chromaticity(bgr):
    """The share of each channel in a colour's sum, (b, g, r) / (b + g + r): its hue and saturation
    without its brightness (a ball in shade keeps it)."""
    bgr = np.asarray(bgr, float)
    return bgr / max(float(bgr.sum()), 1.0)


def frame_gain(frame, background_colour):
    """The frame's brightness relative to the background, from sparse samples, dimensionless.

    The median over pixels of ``(I · B) / (B · B)`` (BGR vectors): 1 for a frame lit like the
    background, 1.05 for a flicker peak 5 % brighter; a ball or a hand covering part of the frame
    does not move a median.

    Parameters
    ----------
    frame : numpy.ndarray
        BGR uint8 frame.
    background_colour : numpy.ndarray or SceneColour
        The background's BGR uint8.

    Returns
    -------
    float
        The gain (1.0 when the background is too dark to tell).
    """
    lit, background, power = (background_colour.gain_reference if isinstance(background_colour, SceneColour)
                              else _gain_reference(background_colour))
    if background.shape[0] < 10:
        return 1.0
    s = GAIN_STRIDE_PX
    sample = frame[::s, ::s].reshape(-1, 3)[lit]
    return float(np.median(channel_dot(sample, background) / power))


def _gain_reference(background_colour):
    s = GAIN_STRIDE_PX
    background = background_colour[::s, ::s].reshape(-1, 3).astype(np.float32)
    power = channel_dot(background, background)
    lit = power > MIN_BACKGROUND_LENGTH ** 2
    return lit, background[lit], power[lit]


def contrast_of(name, samples, background, gains=None):
    """The channel ``name`` with its noise and threshold measured on the background's samples.

    Parameters
    ----------
    name : str
        One of :data:`CHANNELS`.
    samples : sequence of numpy.ndarray
        The frames whose median is the background (BGR uint8 for the colour channels).
    background : dropfit.video.background.Background
        The background.
    gains : sequence of float, optional
        The samples' gains (:func:`frame_gain`) when known.

    Returns
    -------
    Contrast
        ``grey`` keeps the background's own noise and threshold. A colour channel's noise is the
        robust spread of its sparse samples about 0 (``chroma`` is a length, so its values about 0
        count both ways); its threshold is ``NOISE_THRESHOLD_SIGMAS`` of it, at least
        ``MIN_COLOUR_THRESHOLD``.
    """
    if name == GREY:
        return Contrast(GREY, background.noise_grey, background.threshold_grey)
    s = SAMPLE_STRIDE_PX
    colour = background.colour[::s, ::s]
    values = []
    channel = Contrast(name, 0.0, 0.0)
    if gains is None:
        gains = [frame_gain(sample, scene_colour(background)) for sample in samples]
    for sample, gain in zip(samples, gains):
        image = channel.image(sample[::s, ::s], None, colour, gain)
        values.append(image.ravel())
    values = np.concatenate(values)
    if name == CHROMA:
        values = np.concatenate([values, -values])
    noise = robust_sigma(values, centre=0.0) if values.size else 0.0
    return Contrast(name, float(noise), max(NOISE_THRESHOLD_SIGMAS * noise, MIN_COLOUR_THRESHOLD))


def available_contrasts(background):
    """The channels a background allows: all with a colour background, else ``grey``."""
    return CHANNELS if background.colour is not None else (GREY,)


__all__ = ["BRIGHTER", "CHANNELS", "CHROMA", "GREY", "Contrast", "SceneColour", "available_contrasts",
           "channel_dot", "chroma_contrast", "chromaticity", "contrast_of", "frame_gain", "hand_pixels", "scene_colour",
           "skin_mask"]
