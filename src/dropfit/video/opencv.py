"""OpenCV for dropfit: imported here, once, with its own logging quietened, and a guard that keeps the
video libraries' messages off the terminal while frames are decoded.

OpenCV warns on every .mp4 that its MJPEG backend "is generally available but can't be used to capture
by name", and FFmpeg, libjpeg and OpenCV's AVI reader write a line for every damaged frame ("overread
6", "Failed to parse avi: index was not found") straight to the process's standard error. dropfit says
what matters itself, in one line (a truncated video: how many frames were decoded of how many the
container declares). Every dropfit module imports ``cv2`` from here, so the log levels are set before
OpenCV is first loaded. Set ``DROPFIT_VIDEO_LOG=1`` to see the libraries' messages again.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading

os.environ.setdefault("OPENCV_LOG_LEVEL", "ERROR")
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # AV_LOG_QUIET

import cv2  # noqa: E402  (after the environment that configures it)

try:  # in case cv2 was imported before dropfit, when the environment came too late
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
except AttributeError:  # pragma: no cover - an OpenCV build without the logging module
    pass

__all__ = ["cv2", "decoder_output_silenced"]

_lock = threading.Lock()
_depth = 0
_saved_fd = None


@contextlib.contextmanager
def decoder_output_silenced():
    """Send what native code writes to file descriptor 2 (standard error) to the null device meanwhile.

    The video libraries write there directly, past Python's ``sys.stderr``; so, while this is active,
    does any other thread of the process. Nested uses are fine.
    """
    global _depth, _saved_fd
    if os.environ.get("DROPFIT_VIDEO_LOG"):
        yield
        return
    with _lock:
        if _depth == 0:
            with contextlib.suppress(Exception):
                sys.stderr.flush()
            try:
                saved = os.dup(2)
                null = os.open(os.devnull, os.O_WRONLY)
            except OSError:  # no standard error to protect
                saved = None
            else:
                os.dup2(null, 2)
                os.close(null)
            _saved_fd = saved
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and _saved_fd is not None:
                os.dup2(_saved_fd, 2)
                os.close(_saved_fd)
                _saved_fd = None
