"""OpenCV for dropfit: imported here, once, with its own logging quietened.

dropfit uses OpenCV for image operations only (videos are decoded with PyAV in
:mod:`dropfit.video.decode`). Every dropfit module imports ``cv2`` from here, so OpenCV's log level
is set before it is first loaded and its warnings stay off the terminal, where dropfit says what
matters itself, in one line.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")

import cv2  # noqa: E402  (after the environment that configures it)

try:  # in case cv2 was imported before dropfit, when the environment came too late
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
except AttributeError:  # pragma: no cover - an OpenCV build without the logging module
    pass

__all__ = ["cv2"]
