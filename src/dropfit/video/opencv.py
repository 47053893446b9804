"""OpenCV for dropfit: imported here, once, with its own logging quietened.

dropfit uses OpenCV for image operations only (videos are decoded with PyAV in
:mod:`dropfit.video.decode`). Every dropfit module imports ``cv2`` from here, so OpenCV's log level
is set before it is first loaded and its warnings stay off the terminal, where dropfit says what
matters itself, in one line. Connected components of a mask with a small foreground are labelled
here too (:func:`connected_components`), where OpenCV's own statistics cost most on such masks.
"""

from __future__ import annotations

import os
from typing import NamedTuple

os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

import cv2  # noqa: E402  (after the environment that configures it)
import numpy as np  # noqa: E402

try:  # in case cv2 was imported before dropfit, when the environment came too late
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
except AttributeError:  # pragma: no cover - an OpenCV build without the logging module
    pass


def foreground_components(mask):
    """The 8-connected components of a uint8 mask, labelled within the box of its foreground.

    OpenCV's statistics visit every pixel of the image, the background's too: a whole frame's few blobs
    cost ten times their labelling. The box starts at an even row and column, so that the labelling's
    2 × 2 blocks, and with them the labels' order, are those of the whole mask.

    Returns
    -------
    (int, int, numpy.ndarray, numpy.ndarray, numpy.ndarray)
        The box's left column and top row in the mask, px, and :func:`cv2.connectedComponentsWithStats`'s
        labels, statistics and centroids in the box (the background's row 0 of the box only).
    """
    x, y, width, height = cv2.boundingRect(mask)
    left, top = x - x % 2, y - y % 2
    if width == 0:
        return left, top, np.zeros((0, 0), np.int32), np.zeros((1, 5), np.int32), np.zeros((1, 2))
    _, labels, stats, centroids = cv2.connectedComponentsWithStats(mask[top:y + height, left:x + width],
                                                                   connectivity=8)
    return left, top, labels, stats, centroids


class Components(NamedTuple):
    """:func:`cv2.connectedComponentsWithStats` of a mask as :func:`connected_components` gives it: the
    count, labels and statistics (px), the box of the foreground (left, top, px) and the centroids in it."""

    count: int
    labels: np.ndarray
    stats: np.ndarray
    left: int
    top: int
    box_centroids: np.ndarray

    def centroids(self, rows):
        """OpenCV's centroids of the components ``rows`` in the mask, px, to the bit.

        OpenCV divides each component's sum of coordinates by its area: the sums in the box are its
        centroids times the areas (exactly, once rounded: integers far below 2^52), shifted by the box's
        corner for each pixel.
        """
        area = self.stats[rows, cv2.CC_STAT_AREA, None].astype(float)
        return (np.rint(self.box_centroids[rows] * area) + np.array([self.left, self.top]) * area) / area


def connected_components(mask):
    """:func:`cv2.connectedComponentsWithStats` of a uint8 mask (8-connected), the same numbers for the
    components (not row 0, the background's), labelled within the box of the foreground
    (:func:`foreground_components`): a :class:`Components`, its labels and statistics in the mask's px."""
    left, top, box_labels, stats, centroids = foreground_components(mask)
    labels = np.zeros(mask.shape, np.int32)
    labels[top:top + box_labels.shape[0], left:left + box_labels.shape[1]] = box_labels
    stats[:, cv2.CC_STAT_LEFT] += left
    stats[:, cv2.CC_STAT_TOP] += top
    return Components(len(stats), labels, stats, left, top, centroids)


__all__ = ["Components", "connected_components", "cv2", "foreground_components"]
