"""Writing frames with a real encoder through PyAV (H.264 or HEVC in MP4/MOV/MKV, MPEG-4 or MJPEG in AVI)."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import av
import numpy as np

from .camera import stored_from_displayed

#: Containers that store timestamps per frame (variable timing) and a display matrix.
TIMESTAMPED_CONTAINERS = {".mp4", ".mov", ".mkv", ".m4v"}


def constant_rate_container(path: str | Path) -> bool:
    """True when the container writes frames at a constant rate (AVI)."""
    return Path(path).suffix.lower() not in TIMESTAMPED_CONTAINERS


class ClipWriter:
    """Encode displayed RGB frames into ``path``, stored rotated for the display matrix.

    Parameters
    ----------
    path : str or Path
        Output file; its suffix picks the container.
    width_px, height_px : int
        Displayed frame size (px).
    rotation_deg : int
        Counter-clockwise display rotation (0, 90, 180, 270); not possible in AVI.
    container_fps : Fraction
        Nominal frame rate written in the container (Hz).
    time_base : Fraction
        Seconds per timestamp tick.
    codec : str
        Encoder name ("libx264", "libx265", "mpeg4", "mjpeg").
    crf : int
        libx264 / libx265 constant rate factor.
    encoder_preset : str
        libx264 / libx265 speed preset.
    bit_depth : int
        Bits per sample, 8 or 10 (libx265 only: a phone's HDR video is 10-bit HEVC).
    sound : (phonesim.sound.SoundTrack, numpy.ndarray), optional
        A sound track and its samples (:func:`phonesim.sound.render_track`), muxed beside the frames.
    """

    def __init__(self, path, width_px: int, height_px: int, rotation_deg: int, container_fps: Fraction,
                 time_base: Fraction, codec: str = "libx264", crf: int = 18, encoder_preset: str = "veryfast",
                 bit_depth: int = 8, sound=None):
        if rotation_deg % 90:
            raise ValueError("rotation_deg must be a multiple of 90")
        if rotation_deg % 360 and constant_rate_container(path):
            raise ValueError(f"{Path(path).suffix} cannot store a display rotation; use .mp4 or .mov")
        if bit_depth not in (8, 10) or bit_depth == 10 and codec != "libx265":
            raise ValueError(f"bit_depth {bit_depth} with {codec}: 10 bits need libx265, else 8")
        self.rotation_deg = rotation_deg % 360
        self.container = av.open(str(path), mode="w")
        self.stream = self.container.add_stream(codec, rate=container_fps)
        stored_w, stored_h = (height_px, width_px) if self.rotation_deg in (90, 270) else (width_px, height_px)
        self.stream.width, self.stream.height = stored_w, stored_h
        self.stream.pix_fmt = "yuvj420p" if codec == "mjpeg" else "yuv420p10le" if bit_depth == 10 else "yuv420p"
        self.stream.codec_context.time_base = time_base
        self.time_base = time_base
        if codec == "libx264":
            # x264's macroblock-tree rate control reads uninitialised memory on these scenes (the same
            # frames encoded to files that differed with MALLOC_PERTURB_); without it every encode of a
            # seed gives the same file.  Phone hardware encoders have no macroblock tree either.
            self.stream.options = {"crf": str(crf), "preset": encoder_preset, "x264-params": "mbtree=0"}
        elif codec == "libx265":
            # one frame thread and no cu-tree, for the same file from every encode of a seed; tagged hvc1 as
            # phones tag it (FFmpeg's default hev1 is what QuickTime will not play)
            self.stream.options = {"crf": str(crf), "preset": encoder_preset,
                                   "x265-params": "log-level=error:frame-threads=1:cutree=0"}
            self.stream.codec_context.codec_tag = "hvc1"
        else:
            # about 0.3 bit per pixel: visually clean, like a camera's AVI
            self.stream.codec_context.bit_rate = int(0.3 * stored_w * stored_h * float(container_fps))
        if self.rotation_deg:
            self.stream.set_display_rotation(self.rotation_deg)
        # a sound track (phonesim.sound.SoundTrack, samples): its stream added before anything is muxed, its
        # samples encoded after the frames
        self.sound = sound
        if sound is not None:
            from .sound import add_track_stream

            self.sound_stream = add_track_stream(self.container, sound[0])

    def write(self, displayed_rgb: np.ndarray, pts: int) -> None:
        """Encode one displayed frame (uint8 RGB, rows x cols x 3) at timestamp ``pts`` (ticks)."""
        frame = av.VideoFrame.from_ndarray(stored_from_displayed(displayed_rgb, self.rotation_deg), format="rgb24")
        frame.pts = int(pts)
        frame.time_base = self.time_base
        for packet in self.stream.encode(frame):
            self.container.mux(packet)

    def close(self) -> None:
        """Flush the encoder and close the file."""
        for packet in self.stream.encode():
            self.container.mux(packet)
        if self.sound is not None:
            from .sound import write_track

            write_track(self.container, self.sound_stream, self.sound[1], self.sound[0])
        self.container.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
