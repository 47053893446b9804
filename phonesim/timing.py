"""Frame timing: which capture each written frame shows and when it is presented."""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from .config import FrameTiming

#: Time base (s per tick) of MP4/MOV timestamps: 90 kHz holds 24-240 fps and 30000/1001 exactly.
MP4_TIME_BASE = Fraction(1, 90000)


def as_fraction(rate_hz: Fraction | float) -> Fraction:
    """A frame rate as an exact fraction (a float 29.97002997 becomes 30000/1001)."""
    return Fraction(rate_hz).limit_denominator(1001)


@dataclass(frozen=True)
class FrameSchedule:
    """Per written frame: its capture and its presentation timestamp.

    Attributes
    ----------
    capture_index : ndarray of int
        Index of the capture (at the true rate) the frame shows.
    capture_time_s : ndarray
        Mid-exposure time of that capture (s, clip clock: the first nominal
        capture at 0).
    pts : ndarray of int
        Presentation timestamp in ticks of ``time_base``.
    time_base : Fraction
        Seconds per tick.
    is_duplicate : ndarray of bool
        True for a repeat of the previous frame's capture.
    container_fps : Fraction
        Nominal frame rate of the container (Hz; a slow-motion clip's is its capture rate over the slowing).
    capture_fps : Fraction
        True capture rate (Hz).
    """

    capture_index: np.ndarray
    capture_time_s: np.ndarray
    pts: np.ndarray
    time_base: Fraction
    is_duplicate: np.ndarray
    container_fps: Fraction
    capture_fps: Fraction

    @property
    def time_s(self) -> np.ndarray:
        """Presentation time of each frame (s)."""
        return self.pts * float(self.time_base)

    @classmethod
    def build(cls, timing: FrameTiming, duration_s: float, constant_rate: bool,
              rng: np.random.Generator) -> "FrameSchedule":
        """The schedule of a clip of ``duration_s`` (s).

        ``constant_rate`` (AVI) writes frames at consecutive ticks of
        1/container_fps whatever their capture times (so a dropped capture
        shifts the later frames' capture times against their presentation
        times); otherwise the timestamps are the capture times on a 90 kHz
        clock, repeats spread evenly between captures.
        """
        capture_fps = as_fraction(timing.capture_fps)
        repeats = int(timing.frames_per_capture)
        slow = int(timing.slow_motion)
        container_fps = capture_fps * repeats / slow
        period = 1.0 / float(capture_fps)
        n_captures = int(np.floor(duration_s * float(capture_fps))) + 1
        nominal = np.arange(n_captures) * period
        jitter = np.zeros(n_captures)
        if timing.pts_jitter_s > 0:
            jitter = np.clip(rng.normal(0.0, timing.pts_jitter_s, n_captures), -0.25 * period, 0.25 * period)
            jitter[0] = 0.0
        kept = np.ones(n_captures, dtype=bool)
        if timing.drop_probability > 0:
            kept[1:] = rng.random(n_captures - 1) >= timing.drop_probability
        capture_index = np.repeat(np.flatnonzero(kept), repeats)
        capture_time = (nominal + jitter)[capture_index]
        repeat_number = np.tile(np.arange(repeats), int(kept.sum()))
        if constant_rate:
            time_base = 1 / container_fps
            pts = np.arange(capture_index.size, dtype=np.int64)
        else:
            time_base = MP4_TIME_BASE
            shown = (capture_time + repeat_number * (period / repeats)) * slow  # slow motion: presented later
            pts = np.round(shown / float(time_base)).astype(np.int64)
        return cls(capture_index, capture_time, pts, time_base, repeat_number > 0, container_fps, capture_fps)
