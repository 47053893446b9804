"""The scene without the ball: the per-pixel median of frames spread over the clip.

Not the first frames: the ball is usually held at the top, by a hand, before release. A pixel
belongs to the foreground where its grey level differs from the background by more than
``NOISE_THRESHOLD_SIGMAS`` robust noise standard deviations (at least ``MIN_THRESHOLD_GREY``
grey levels). A ball in view for the whole clip can be in the median: :func:`background_without_ball`
cuts it out of the samples where it was tracked.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from ..numerics import robust_sigma
from .opencv import cv2

#: Foreground threshold, in robust noise standard deviations of (frame - background).
NOISE_THRESHOLD_SIGMAS = 5.0

#: Lower bound of the foreground threshold, grey levels (for noise-free or quantised video).
MIN_THRESHOLD_GREY = 6.0

#: A background pixel is a blend of scene and foreground (see :func:`_most_agreed`) when fewer than this
#: fraction of the samples agree with the median there (a hand moving about at one place leaves almost
#: none) ...
BLEND_AGREEMENT = 0.2
#: ... and the samples agreeing on the scene there are at least this fraction of them (the shading of a
#: large ball that moves slowly all clip long differs in every sample: its median stays).
SCENE_AGREEMENT = 0.45
#: Number of frames, spread over the clip, whose per-pixel median is the background.
BACKGROUND_SAMPLES = 11

#: Radius of the disc cut out of a background sample around a tracked ball, in tracked radii (a
#: ball flattened in contact is up to ~10 % wider), plus BALL_MASK_MARGIN_PX (motion blur, edge).
BALL_MASK_RADII = 1.2

BALL_MASK_MARGIN_PX = 3.0

#: Whole-frame work over all the samples goes in strips of rows of about this many bytes of samples, so
#: that what is derived from them stays in the processor's cache (:func:`_strip_rows`).
STRIP_BYTES = 4 * 2**20



@dataclass(frozen=True)
class Background:
    """The static scene.

    Attributes
    ----------
    grey : numpy.ndarray
        Background grey levels, float32, shape (height, width).
    noise_grey : float
        Robust standard deviation of a frame's grey level about the background, grey levels.
    threshold_grey : float
        Foreground threshold on ``|frame - background|``, grey levels.
    colour : numpy.ndarray or None
        The scene in colour, uint8 BGR (height, width, 3), for what is read off it in colour (a
        ruler, a marker); None when the samples were grey.
    """

    grey: np.ndarray
    noise_grey: float
    threshold_grey: float
    colour: np.ndarray | None = None

    def cropped(self, left, top, right, bottom):
        """The background of the region columns ``left ≤ x < right``, rows ``top ≤ y < bottom`` (px)."""
        if (left, top, right, bottom) == (0, 0, self.grey.shape[1], self.grey.shape[0]):
            return self
        colour = None if self.colour is None else self.colour[top:bottom, left:right]
        return Background(self.grey[top:bottom, left:right], self.noise_grey, self.threshold_grey, colour)

    def image(self):
        """The scene as a frame: the colour one where there is one, else the grey levels as uint8."""
        return self.colour if self.colour is not None else np.clip(np.rint(self.grey), 0, 255).astype(np.uint8)

    def derived(self, key, compute):
        """``compute()``, made once per background and kept with it under ``key``: what the tracker derives
        from the scene (its colour's unit vectors, a reduced copy) for every frame of a clip."""
        kept = self.__dict__.setdefault("_derived", {})
        if key not in kept:
            kept[key] = compute()
        return kept[key]

    def shrunk(self, factor):
        """The background reduced ``factor`` times in each direction (pixel areas averaged), made once."""
        def shrink():
            height, width = self.grey.shape[0] // factor, self.grey.shape[1] // factor

            def reduce(image):
                return cv2.resize(image[:height * factor, :width * factor], (width, height),
                                  interpolation=cv2.INTER_AREA)

            colour = None if self.colour is None else reduce(self.colour)
            return Background(reduce(self.grey), self.noise_grey, self.threshold_grey, colour)

        return self if factor == 1 else self.derived(("shrunk", factor), shrink)


def to_grey(image):
    """Grey levels of an image as float32.

    Parameters
    ----------
    image : numpy.ndarray
        Grey (height, width) or BGR (height, width, 3) image, any numeric type.

    Returns
    -------
    numpy.ndarray
        float32 grey levels, shape (height, width).
    """
    image = np.asarray(image)
    if image.ndim == 2:
        return image.astype(np.float32, copy=False)
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image.astype(np.float32), cv2.COLOR_BGR2GRAY)
    if image.ndim == 3 and image.shape[2] == 1:
        return image[:, :, 0].astype(np.float32)
    raise ValueError(f"expected a grey or BGR image, got shape {image.shape}")


@functools.lru_cache
def _median_network(count):
    """The compare-exchanges of a sorting network of ``count`` values (Batcher's merge exchange, Knuth's
    algorithm 5.2.2M) that the middle value depends on: (i, j, whether the minimum goes on to i, whether
    the maximum goes on to j), in order.

    Only the middle one of the sorted values is wanted, so exchanges it does not depend on are left out,
    and so is the half of an exchange whose output is not used again: 52 of the 110 minima and maxima of
    an odd-even transposition sort of 11 images.
    """
    pairs = []
    t = max(math.ceil(math.log2(count)), 1)
    p = 2 ** (t - 1)
    while p > 0:
        q, r, d = 2 ** (t - 1), 0, p
        while True:
            pairs += [(i, i + d) for i in range(count - d) if i & p == r]
            if q == p:
                break
            d, q, r = q - p, q // 2, p
        p //= 2
    needed, network = {count // 2}, []
    for i, j in reversed(pairs):
        if i in needed or j in needed:
            network.append((i, j, i in needed, j in needed))
            needed |= {i, j}
    return tuple(reversed(network))


def _strip_rows(images):
    """Rows of a strip of ``images`` (arrays of one shape) that hold about ``STRIP_BYTES`` together."""
    return max(STRIP_BYTES // max(images[0][:1].nbytes * len(images), 1), 1)


def median_uint8(images):
    """Per-pixel median of an odd number of uint8 images (a sorting network cut down to the middle value).

    Taken in strips of rows (:func:`_strip_rows`), so that the network's intermediate images stay in the
    processor's cache: whole 720p frames went to memory and back for each minimum and maximum (11 colour
    samples: 30 -> 8 ms).
    """
    images = [np.asarray(image) for image in images]
    network = _median_network(len(images))
    median = np.empty_like(images[0])
    step = _strip_rows(images)
    for top in range(0, median.shape[0], step):
        strip = [image[top:top + step] for image in images]
        for i, j, low, high in network:
            strip[i], strip[j] = (cv2.min(strip[i], strip[j]) if low else None,
                                  cv2.max(strip[i], strip[j]) if high else None)
        median[top:top + step] = strip[len(strip) // 2]
    return median


def grey_uint8(image):
    image = np.asarray(image)
    if image.dtype != np.uint8:
        return None
    if image.ndim == 3 and image.shape[2] == 3:
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.ndim == 3 and image.shape[2] == 1:
        return np.ascontiguousarray(image[:, :, 0])
    return np.ascontiguousarray(image) if image.ndim == 2 else None


def estimate_background(samples):
    """Background from frames spread over the clip.

    Parameters
    ----------
    samples : sequence of numpy.ndarray
        At least one grey or BGR frame; an odd number of 5 or more, spread over the whole clip,
        makes the ball and hand disappear from the median.

    Returns
    -------
    Background
        Per-pixel median grey level (and colour, for uint8 BGR samples), robust noise in grey levels
        and the foreground threshold.
    """
    samples = [np.asarray(sample) for sample in samples]
    if len(samples) % 2 == 0 and len(samples) >= 4:
        samples = samples[:-1]  # an odd count has a middle value: the uint8 median of a sorting network
    colour_samples = samples
    in_colour = len(colour_samples) % 2 == 1 and all(
        sample.dtype == np.uint8 and sample.ndim == 3 and sample.shape[2] == 3 for sample in colour_samples)
    colour = median_uint8(colour_samples) if in_colour else None  # cv2.min/max work per channel
    greys = [grey_uint8(sample) for sample in samples]
    if len(greys) % 2 and all(g is not None for g in greys):
        grey = median_uint8(greys).astype(np.float32)
        stack = np.stack([g[::8, ::8] for g in greys]).astype(np.float32)
    else:
        full = np.stack([to_grey(sample) for sample in samples])
        grey = np.median(full, axis=0).astype(np.float32)
        stack = full[:, ::8, ::8]
    k = stack.shape[0]
    if k >= 3:
        # median absolute deviation about the median; of k samples, the median one contributes 0
        noise = robust_sigma(stack - grey[::8, ::8], centre=0.0) * k / (k - 1)
    else:
        noise = 0.0
    threshold = max(NOISE_THRESHOLD_SIGMAS * noise, MIN_THRESHOLD_GREY)
    grey, colour = _most_agreed(samples, grey, colour, threshold)
    return Background(np.ascontiguousarray(grey, dtype=np.float32), noise, threshold, colour)


def _distance(a, b, in_colour):
    """Distance between grey levels, or colours (last axis BGR), NaN where either is NaN."""
    return np.sqrt(((a - b) ** 2).sum(axis=-1)) if in_colour else np.abs(a - b)


def _agreed(values, threshold, in_colour):
    """Per pixel, the median of the samples that agree with the sample most others agree with.

    ``values`` has shape (k, n), or (k, n, 3) ``in_colour``, NaN for samples left out at a pixel;
    two samples agree within ``threshold`` (grey levels, or colour distance). Returns the values,
    shape (n,) or (n, 3), and how many samples agree at each pixel.
    """
    k = values.shape[0]
    agreement = np.stack([np.nan_to_num(_distance(values, values[i][None], in_colour), nan=np.inf) <= threshold
                          for i in range(k)]).sum(axis=1)
    valid = np.isfinite(values[..., 0] if in_colour else values)
    agreement = np.where(valid, agreement, -1)
    most = values[np.argmax(agreement, axis=0), np.arange(values.shape[1])]
    agreeing = np.nan_to_num(_distance(values, most[None], in_colour), nan=np.inf) <= threshold
    # the median of the samples that agree: less noisy than one sample
    return (np.nanmedian(np.where(agreeing[..., None] if in_colour else agreeing, values, np.nan), axis=0),
            agreeing.sum(axis=0))


def _set(grey, colour, where, values):
    """``grey`` and ``colour`` (copies) with ``values`` (colour or grey, per the samples) at ``where``."""
    grey = grey.copy()
    if colour is not None:
        colour = colour.copy()
        colour[where] = np.clip(np.rint(values), 0, 255).astype(np.uint8)
        grey[where] = to_grey(colour[where][None])[0]
    else:
        grey[where] = values
    return grey, colour


def _sample_values(samples, colour, where=None):
    """The samples' colours (or grey levels without a colour background), float32, (k, ...)."""
    # the pixels by their indices, found once: a mask is read whole for every sample (1 ms a 720p frame)
    index = slice(None) if where is None else np.nonzero(where)
    if colour is not None:
        stack = np.stack([np.asarray(sample)[index] for sample in samples])
    else:
        stack = np.stack([to_grey(sample)[index] for sample in samples])
    return stack.astype(np.float32)


def _count_within(samples, grey, colour, threshold):
    """Per pixel, how many samples lie within ``threshold`` of the median: grey levels, or the colour
    distance (:func:`_distance`) when ``colour`` (uint8 BGR, like the samples) is given.

    One sample at a time in OpenCV: the stack of every sample in float (100 MB for 11 HD frames) and
    its NumPy reductions cost a second per clip. In colour, in strips of rows (:func:`_strip_rows`) whose
    float differences stay in the processor's cache (11 720p samples: 26 -> 14 ms).
    """
    count = np.zeros(grey.shape, np.uint8)
    if colour is None:
        for sample in samples:
            count += (np.abs(to_grey(sample) - grey) <= threshold).reshape(grey.shape)
        return count
    step = _strip_rows(samples)
    for top in range(0, count.shape[0], step):
        rows = slice(top, top + step)
        for sample in samples:
            difference = cv2.absdiff(sample[rows], colour[rows]).astype(np.float32)
            squared = cv2.transform(cv2.multiply(difference, difference), np.ones((1, 3), np.float32))
            count[rows] += squared <= threshold * threshold
    return count


def _most_agreed(samples, grey, colour, threshold):
    """The median, except where most samples disagree with it: there the sample most others agree with.

    A hand that holds the ball near the floor for more than half of the clip, or a ball bouncing
    low, makes the median of those pixels a blend of scene and foreground, which no sample shows.
    Where fewer than ``BLEND_AGREEMENT`` of the samples are within ``threshold`` (grey levels, colour
    distance for colour samples) of the median, the background takes the median of the samples that agree
    with the sample most others agree with (:func:`_agreed`), when at least ``SCENE_AGREEMENT`` of
    them do: the scene, seen whenever the moving foreground is elsewhere.
    """
    in_colour = colour is not None
    unsettled = _count_within(samples, grey, colour, threshold) < BLEND_AGREEMENT * len(samples)
    if not unsettled.any():
        return grey, colour
    agreed, count = _agreed(_sample_values(samples, colour, unsettled), threshold, in_colour)
    # a scene seen again and again, not one sample among many that differ (a slowly moving ball's shading)
    seen = count >= SCENE_AGREEMENT * len(samples)
    unsettled[unsettled] = seen
    return _set(grey, colour, unsettled, agreed[seen]) if seen.any() else (grey, colour)


def background_without_ball(samples, balls, background):
    """The background again with the ball cut out of its samples, when the ball is in it; else None.

    Parameters
    ----------
    samples : sequence of numpy.ndarray
        The frames whose per-pixel median is ``background`` (grey or BGR).
    balls : sequence of (float, float, float)
        The ball's centre x, y and radius tracked in each sample with ``background``, px (NaN when
        not found).
    background : Background
        The first background.

    Returns
    -------
    Background or None
        None when no pixel is covered by the ball (a disc of ``BALL_MASK_RADII`` radii plus
        ``BALL_MASK_MARGIN_PX``) in more than half of the samples: the median is then the scene.
        Else, where the ball covered some samples, what most of the uncovered samples agree on
        (:func:`_agreed`), and elsewhere the first background (where every sample is covered too),
        with the first background's noise and threshold.
    """
    balls = np.asarray(balls, float).reshape(-1, 3)
    found = np.isfinite(balls).all(axis=1)
    if not found.any():
        return None
    typical_radius = float(np.median(balls[found, 2]))
    reach = BALL_MASK_RADII * np.fmax(balls[:, 2], typical_radius) + BALL_MASK_MARGIN_PX
    height, width = background.grey.shape
    # each disc drawn in its own box: whole-frame masks of every sample took 170 MB for 11 samples of a 4K clip
    covered = np.zeros((height, width), np.uint16)
    for (x, y, _), is_found, far in zip(balls, found, reach):
        if is_found:
            top, left = max(int(np.floor(y - far)), 0), max(int(np.floor(x - far)), 0)
            bottom, right = min(int(np.ceil(y + far)) + 1, height), min(int(np.ceil(x + far)) + 1, width)
            rows, columns = np.ogrid[top:bottom, left:right]
            covered[top:bottom, left:right] += (columns - x) ** 2 + (rows - y) ** 2 <= far * far
    if covered.max() <= len(balls) // 2:
        return None
    # where it covered every sample, the first background stays
    changed = (covered > 0) & (covered < len(balls))
    values = _sample_values(samples, background.colour, changed)
    rows, columns = np.nonzero(changed)
    discs = np.stack([((columns - x) ** 2 + (rows - y) ** 2 <= far * far) if is_found else np.zeros(rows.size, bool)
                      for (x, y, _), is_found, far in zip(balls, found, reach)])
    values[discs] = np.nan
    grey, colour = _set(background.grey, background.colour, changed,
                        _agreed(values, background.threshold_grey, background.colour is not None)[0])
    return Background(grey, background.noise_grey, background.threshold_grey, colour)

