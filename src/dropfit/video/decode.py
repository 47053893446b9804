"""Frames and their times from a video file.
"""

from __future__ import annotations

import queue
import threading

import numpy as np

from ..errors import InputError, shown_path
from .opencv import cv2

#: A video with fewer frames is refused before its ball is looked for (its background would be the ball).
MIN_FRAMES = 10
#: Frames a container may declare beyond those decoded before the video counts as truncated: a
#: count estimated from the duration (Matroska) can be a frame or two off.
FRAME_COUNT_SLACK = 2
FRAME_COUNT_SLACK_FRACTION = 0.02

#: Files that are not videos, by their first bytes: (signature, what it is).
_NOT_VIDEOS = [(b"\x89PNG", "a PNG image"), (b"\xff\xd8\xff", "a JPEG image"), (b"GIF8", "a GIF image"),
               (b"%PDF", "a PDF document"), (b"PK\x03\x04", "a ZIP archive or spreadsheet"),
               (b"CDF\x01", "a NetCDF file"), (b"\x89HDF", "a NetCDF-4/HDF5 file")]


def check_video_file(path):
    """InputError for a video file that is empty, or plainly another kind of file (an image, a text file)."""
    name = shown_path(path)
    with open(path, "rb") as handle:
        head = handle.read(4096)
    if not head:
        raise InputError(f"{name}: the file is empty (0 bytes): not a video; copy or export it again")
    for signature, what in _NOT_VIDEOS:
        if head.startswith(signature):
            raise InputError(f"{name}: is {what}, not a video; give the video file")
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:
        return
    if not any(ord(char) < 32 and char not in "\t\r\n" for char in text):
        raise InputError(f"{name}: is a text file, not a video (a height log must have the suffix .csv); give the "
                         f"video file")


def check_frame_count(decoded, declared, path):
    """Raise InputError if fewer frames were decoded than the container declares (a truncated or
    damaged video), allowing :data:`FRAME_COUNT_SLACK` frames for a count estimated from the duration."""
    if declared >= 1 and decoded < declared - max(FRAME_COUNT_SLACK, FRAME_COUNT_SLACK_FRACTION * declared):
        raise InputError(f"{shown_path(path)}: the video is truncated or corrupt: only {decoded} of the "
                         f"{declared:.0f} frames its container declares could be decoded; copy or export it again")




class FrameReader(threading.Thread):
    """Decode frames ahead of the tracker, at most ``depth`` of them; iterate for (frame, time_ms)."""

    def __init__(self, capture, depth=16):
        super().__init__(daemon=True)
        self._capture = capture
        self._queue = queue.Queue(maxsize=depth)
        self._halt = threading.Event()

    def run(self):
        try:
            while not self._halt.is_set():
                ok, frame = self._capture.read()
                if not ok:
                    break
                item = (frame, self._capture.get(cv2.CAP_PROP_POS_MSEC))
                while not self._halt.is_set():
                    try:
                        self._queue.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
        finally:
            self._queue.put(None)

    def __iter__(self):
        while True:
            item = self._queue.get()
            if item is None:
                return
            yield item

    def close(self):
        """Stop decoding and wait for the thread."""
        self._halt.set()
        while self.is_alive():
            try:
                self._queue.get(timeout=0.1)
            except queue.Empty:
                pass


def spread_indices(count, samples):
    return np.unique(np.round(np.linspace(0, count - 1, min(samples, count))).astype(int))



def _read_samples(capture, indices):
    samples = []
    for index in indices:
        if not capture.set(cv2.CAP_PROP_POS_FRAMES, int(index)):
            return []
        ok, frame = capture.read()
        if not ok:
            return []
        samples.append(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame)
    return samples


def video_samples(path, frame_count, samples):
    """Grey frames spread over a video file and their indices: by seeking (cheap for MJPG AVI)."""
    if frame_count >= 1:
        indices = spread_indices(int(frame_count), samples)
        # OpenCV's own MJPEG reader seeks cheaply, but reads only AVI files (asked for another, it warns)
        backends = (cv2.CAP_OPENCV_MJPEG, cv2.CAP_ANY) if str(path).lower().endswith(".avi") else (cv2.CAP_ANY,)
        for backend in backends:
            capture = cv2.VideoCapture(str(path), backend)
            try:
                if capture.isOpened():
                    frames = _read_samples(capture, indices)
                    if len(frames) == len(indices):
                        return list(indices), frames
            finally:
                capture.release()
    # unknown length or no seeking: decode everything, keeping frames at a doubling stride
    capture = cv2.VideoCapture(str(path))
    kept, stride, index = [], 1, 0
    try:
        while True:
            ok, frame = capture.read()
            if not ok:
                break
            if index % stride == 0:
                kept.append((index, cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY) if frame.ndim == 3 else frame))
                if len(kept) > 2 * samples:
                    stride *= 2
                    kept = [(i, f) for i, f in kept if i % stride == 0]
            index += 1
    finally:
        capture.release()
    return [i for i, _ in kept], [f for _, f in kept]



def frame_times(stamps_ms, container_fps, capture_fps, path):
    """Frame times, s, and how they were obtained."""
    count = len(stamps_ms)
    index = np.arange(count, dtype=float)
    stamps = np.asarray(stamps_ms, float)
    meaningful = (np.all(np.isfinite(stamps)) and (count == 1 or (np.all(np.diff(stamps) > 0) and stamps[-1] > 0)))
    nominal = container_fps if container_fps and np.isfinite(container_fps) and container_fps > 0 else None
    if meaningful:
        times, how = stamps / 1000.0, "container time stamps"
        if capture_fps:
            if nominal is None:
                return index / capture_fps, f"frame index / capture_fps {capture_fps:g}"
            times, how = times * nominal / capture_fps, f"container time stamps × {nominal:g} / {capture_fps:g} fps"
        return times, how
    if capture_fps:
        return index / capture_fps, f"frame index / capture_fps {capture_fps:g}"
    if nominal is None:
        raise InputError(f"{shown_path(path)}: the video has neither frame time stamps nor a frame rate; pass capture_fps")
    return index / nominal, f"frame index / container rate {nominal:g} fps"


