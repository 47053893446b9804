"""Frames and their times from a video file, decoded with PyAV (FFmpeg) once per clip.

A clip is opened once (:class:`VideoFile`): a few frames spread over it are reached by seeking
(:meth:`VideoFile.samples`, for the background), then every frame is decoded once, in order, in
a second thread (:meth:`VideoFile.frames`). Frames come as the phone shows them: BGR, with the
container's rotation (display matrix) applied; for the tracker, converted only where it reads them
(:class:`LazyFrame`). Times are the frames' presentation time stamps
(pts × time base), so variable frame timing, repeated and dropped frames keep their true instants
(:func:`frame_times`); the container's nominal rate is the fallback.
"""

from __future__ import annotations

import contextlib
import math
import operator
import os
import queue
import sys
import threading
import time
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path
from typing import NamedTuple

import av
import numpy as np
from av.video.reformatter import VideoReformatter

from ..errors import InputError, shown_path
from .opencv import cv2

#: A video with fewer frames is refused before its ball is looked for (its background would be the ball).
MIN_FRAMES = 10
#: Frames a container may declare beyond those decoded before the video counts as truncated: a
#: count estimated from the duration (Matroska) can be a frame or two off.
FRAME_COUNT_SLACK = 2
FRAME_COUNT_SLACK_FRACTION = 0.02

#: The most pixels a frame may have: DCI 4K, 4096 × 2160 (8.8 MP), so every 4K clip (UHD 3840 × 2160 too),
#: the largest a phone films. Memory grows with the frame (the decoded frames held ahead, the background's
#: samples, the tracker's working copies): a 3-frame UHD clip peaked at 0.82 GB, an 8K one (7680 × 4320) at
#: 2.8 GB, a 2-frame 8192 × 8192 one at 3.0 GB, so no frame above 4K can fit the 1000 MB a job has. A larger
#: frame is refused from its stream's size, before any frame is decoded. (Frames under it are tracked within a
#: job's memory by :data:`MAX_TRACKED_FRAME_PIXELS`.)
MAX_FRAME_PIXELS = 4096 * 2160
#: Frames of more pixels than this are tracked reduced by the least whole factor that brings them under it (a 4K
#: frame to 2048 × 1080, by FFmpeg's area average as they are decoded): the tracker's memory grows with the
#: pixels (`dropfit run` of 90 frames peaked at 680 MB at 1920 × 1080, 870 MB at 2560 × 1440 and 1.45-1.54 GB at
#: 3840 × 2160 and 4096 × 2160), and a ball filmed in 4K is tens of px across at half its size.
MAX_TRACKED_FRAME_PIXELS = 2560 * 1440

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


def check_frame_size(width, height, path):
    """InputError for frames of more than :data:`MAX_FRAME_PIXELS` (``width``, ``height``: px; 0 when unknown)."""
    if (width or 0) * (height or 0) > MAX_FRAME_PIXELS:
        raise InputError(f"{shown_path(path)}: its frames are {width} × {height} px ({width * height / 1e6:.1f} MP), "
                         f"more than the {MAX_FRAME_PIXELS / 1e6:.1f} MP (4096 × 2160) dropfit decodes "
                         f"(MAX_FRAME_PIXELS); scale the clip down to 4K or less, e.g. ffmpeg -i IN -vf "
                         f"scale=-2:2160 OUT")


def frame_reduction(width, height):
    """The whole factor frames of ``width`` × ``height`` px are tracked reduced by: the least that brings them
    under :data:`MAX_TRACKED_FRAME_PIXELS` (1 for frames under it).

    Examples
    --------
    >>> frame_reduction(1920, 1080), frame_reduction(4096, 2160), frame_reduction(7680, 4320)
    (1, 2, 3)
    """
    return max(1, math.ceil(math.sqrt(width * height / MAX_TRACKED_FRAME_PIXELS)))


def reduced_px(coded_px, factor):
    """A position in px of coded frames (pixel centres at whole numbers) in px of the frames reduced ``factor``
    times by area averaging: a reduced pixel's centre is the mean of the ``factor`` coded ones it averages.

    Examples
    --------
    >>> reduced_px(0.5, 2), reduced_px(2048.5, 2)
    (0.0, 1024.0)
    """
    return (coded_px - (factor - 1) / 2) / factor


def reduction_note(factor):
    """What a report says of frames tracked reduced ``factor`` times (:func:`frame_reduction`); empty for 1."""
    if factor == 1:
        return ""
    return (f"frames tracked reduced {factor} times each way as they were decoded (frames of more than "
            f"{MAX_TRACKED_FRAME_PIXELS / 1e6:.2g} MP, MAX_TRACKED_FRAME_PIXELS): px in track.csv and the report are "
            f"of the reduced frames (a coded position is {factor} × px + {(factor - 1) / 2:g}); give --ball-at-px, "
            f"--roi-px and --ball-radius-px in the clip's own px")


def check_frame_count(decoded, declared, path):
    """Raise InputError if fewer frames were decoded than the container declares (a truncated or
    damaged video), allowing :data:`FRAME_COUNT_SLACK` frames for a count estimated from the duration."""
    if declared >= 1 and decoded < declared - max(FRAME_COUNT_SLACK, FRAME_COUNT_SLACK_FRACTION * declared):
        raise InputError(f"{shown_path(path)}: the video is truncated or corrupt: only {decoded} of the "
                         f"{declared:.0f} frames its container declares could be decoded; copy or export it again")




def _configure_library_logging():
    """Keep FFmpeg's messages about damaged frames off the terminal; ``DROPFIT_VIDEO_LOG=1`` shows them."""
    av.logging.set_level(av.logging.WARNING if os.environ.get("DROPFIT_VIDEO_LOG") else av.logging.PANIC)


_configure_library_logging()

#: Codecs whose key frames for the background are decoded by a decoder of their own (:meth:`VideoFile._key_frames`).
SEPARATE_KEY_FRAME_CODECS = ("h264", "hevc")
#: Packets a decoder may take in after a frame's own before it hands the frame out (frames reordered into
#: presentation order: H.264 and HEVC hold at most 16).
REORDER_PACKETS = 16
#: FFmpeg's decoding threads at most (its own limit on the number it chooses: more cost memory and the first frame's
#: delay, a frame per thread).
MAX_DECODING_THREADS = 16
#: Decoded frames the decoding thread may hold ahead of the tracker: this many bytes of them, at least
#: DECODE_AHEAD_FRAMES (a 1280 × 720 clip's 0.2-0.3 s of decoding, as long as reading its scene takes).
DECODE_AHEAD_BYTES = 256 * 2**20
DECODE_AHEAD_FRAMES = 16
#: Clips with at least this many frames show their progress on a terminal (shorter ones take a second or two).
PROGRESS_MIN_FRAMES = 500
#: Least time between two updates of the progress line on a terminal, s.
PROGRESS_INTERVAL_S = 0.25

#: Pixel formats decoded frames of which are converted to BGR only where the tracker reads them
#: (:class:`LazyFrame`): planar 8-bit 4:2:0, whose 2 × 2 chroma blocks a quarter turn keeps whole.
LAZY_FORMATS = ("yuv420p", "yuvj420p")
#: A read of a :class:`LazyFrame` whose tile exceeds this fraction of the frame converts it whole.
LAZY_WHOLE_FRACTION = 0.25
#: Sizes of the tiles a :class:`LazyFrame` converts are multiples of this, px (a few dozen sizes per clip).
TILE_ALIGN_PX = 32
#: Bytes of the tiles (a frame, its buffers and converter, one per size) kept per thread, at most.
TILES_KEPT_BYTES = 32 * 2**20
#: cv2.rotate code that turns a coded frame into the displayed one, by counter-clockwise rotation in degrees.
_ROTATE_CODES = {90: cv2.ROTATE_90_COUNTERCLOCKWISE, 180: cv2.ROTATE_180, 270: cv2.ROTATE_90_CLOCKWISE}


def bgr_image(frame):
    """A decoded frame (av.VideoFrame) as BGR uint8, as coded (no rotation), by FFmpeg's converter.

    Not OpenCV's faster 4:2:0 conversion: its colours differ from FFmpeg's by up to 3 levels (rounding),
    and in the CI run made with it a blurred red ball's e moved by up to 0.017 and a tape's marks were
    hidden (phonesim ``red_blur_portrait``, ``yellow_green_tape``)."""
    return frame.to_ndarray(format="bgr24")


def upright(image, rotation_deg):
    """``image`` turned ``rotation_deg`` counter-clockwise (0, 90, 180 or 270: a display matrix's), as
    the phone shows it."""
    code = _ROTATE_CODES.get(rotation_deg)
    return image if code is None else cv2.rotate(image, code)


def shown_image(frame, rotation_deg):
    """A decoded frame (av.VideoFrame) as the phone shows it: BGR uint8 (:func:`bgr_image`), turned
    ``rotation_deg`` counter-clockwise (:func:`upright`)."""
    return upright(bgr_image(frame), rotation_deg)


def _plane_array(plane):
    """A frame's plane as a uint8 array (rows × width), a view of its buffer (no copy)."""
    return np.frombuffer(plane, np.uint8).reshape(plane.height, plane.line_size)[:, :plane.width]


class _AxisCut(NamedTuple):
    """How a tile is cut along one axis of a displayed frame (:func:`_axis_cut`)."""

    luma: slice | np.ndarray  # the luma rows (or columns) of the tile
    chroma: slice | np.ndarray  # ... and the chroma ones
    doubled: bool  # whether each luma row of ``luma`` is to be doubled
    keep: slice  # what of the converted tile was asked for
    count: int  # pixels asked for
    squeezed: bool  # asked for by an int: the axis is dropped

    def tile_length(self):
        """Pixels of the tile along the axis."""
        return 2 * self.count if self.doubled else self.luma.stop - self.luma.start


def _axis_cut(index, length):
    """How a tile is cut along one axis of a displayed frame for ``index`` (an int or a slice of positive
    step): an :class:`_AxisCut`; None for a slice of negative step.

    A run of neighbouring pixels widens to even bounds, so that it holds whole chroma blocks; pixels picked
    singly (a step > 1) are each doubled into a block of their own, with their own block's chroma."""
    squeezed = not isinstance(index, slice)
    if squeezed:
        position = operator.index(index)
        position += length if position < 0 else 0
        if not 0 <= position < length:
            raise IndexError(f"index {index} is out of bounds for an axis of size {length}")
        index = slice(position, position + 1)
    start, stop, step = index.indices(length)
    count = len(range(start, stop, step))
    if step < 1:
        return None
    if step == 1:
        low, high = start - start % 2, min(stop + stop % 2, length)
        return _AxisCut(slice(low, high), slice(low // 2, high // 2), False, slice(start - low, start - low + count),
                        count, squeezed)
    picked = np.arange(start, stop, step)
    return _AxisCut(picked, picked // 2, True, slice(0, 2 * count, 2), count, squeezed)


def _reflected(index, length):
    """``length - 1 - index`` for an index array or a slice of step 1 (a slice of step -1)."""
    if not isinstance(index, slice):
        return length - 1 - index
    stop = length - 1 - index.stop
    return slice(length - 1 - index.start, stop if stop >= 0 else None, -1)


def _gathered(plane, turns, rows, columns):
    """``numpy.rot90(plane, turns)[rows][:, columns]`` (slices of step 1 or index arrays), contiguous, read
    from ``plane`` in its own order (the turned view's rows are the plane's columns: slow to gather)."""
    height, width = plane.shape
    if turns == 1:
        rows, columns = columns, _reflected(rows, width)
    elif turns == 2:
        rows, columns = _reflected(rows, height), _reflected(columns, width)
    elif turns == 3:
        rows, columns = _reflected(columns, height), rows
    if isinstance(rows, slice) or isinstance(columns, slice):
        picked = plane[rows, columns]
    else:
        picked = plane[np.ix_(rows, columns)]
    return np.ascontiguousarray(picked.T if turns % 2 else picked)


class LazyFrame:
    """A decoded frame as the phone shows it (BGR uint8, rotation applied), converted only where it is read.

    Indexing the two image axes with ints or slices of positive step (``frame[y0:y1, x0:x1]``,
    ``frame[::16]``) gives the BGR pixels there, bit for bit those of :func:`bgr_image` and
    :func:`upright` applied to the whole frame: FFmpeg's converter maps each pixel from its own luma
    and the chroma of its 2 × 2 block, so a tile cut on even rows and columns of the (turned) planes
    converts as in the whole frame (a quarter turn keeps the blocks of a frame of even size), and
    pixels picked singly are each doubled into a block of their own. A tracker reads a few windows
    about the ball and a sparse grid of a frame: a fraction of its pixels, at a fraction of the cost
    of converting and turning all of them. A read whose tile would exceed
    ``LAZY_WHOLE_FRACTION`` of the frame converts the whole frame instead, kept until :meth:`release`;
    ``numpy.asarray(frame)`` gives the whole frame. Only planar 8-bit 4:2:0 frames of even size
    (:func:`lazily_convertible`); read a frame from one thread at a time (FFmpeg's converter of a
    frame is the frame's own).

    Parameters
    ----------
    frame : av.VideoFrame
        The decoded frame (kept: its planes are read in place).
    rotation_deg : int
        Counter-clockwise rotation that turns it as the phone shows it, degrees (0, 90, 180, 270).

    Attributes
    ----------
    shape : (int, int, int)
        Height, width (px) and 3 (BGR) of the frame as shown.
    nbytes : int
        Bytes of the frame once converted whole, B.
    """

    ndim = 3
    dtype = np.dtype(np.uint8)

    def __init__(self, frame, rotation_deg):
        self._frame, self._rotation_deg = frame, rotation_deg
        self._turns = rotation_deg // 90
        self._planes = [_plane_array(plane) for plane in frame.planes[:3]]
        for plane in self._planes:
            plane.flags.writeable = False  # read in place, and handed out (:attr:`luma`)
        height, width = self._planes[0].shape[::-1] if self._turns % 2 else self._planes[0].shape
        self.shape = (height, width, 3)
        self.nbytes = height * width * 3
        self._whole = None

    def __array__(self, dtype=None, copy=None):
        image = self._whole.copy() if self._whole is not None else shown_image(self._frame, self._rotation_deg)
        return image if dtype is None else image.astype(dtype)

    @property
    def luma(self):
        """The frame's luma plane as coded (not turned), uint8 (rows × columns), read-only, without conversion."""
        return self._planes[0]

    def whole(self):
        """The whole frame, BGR uint8, converted once and kept until :meth:`release`."""
        if self._whole is None:
            self._whole = shown_image(self._frame, self._rotation_deg)
        return self._whole

    def release(self):
        """Drop what was converted (the frame stays readable)."""
        self._whole = None

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        spatial, rest = (key + (slice(None), slice(None)))[:2], key[2:]
        height, width = self.shape[:2]
        rows, columns = cuts = [_axis_cut(index, length) for index, length in zip(spatial, (height, width))]
        if None in cuts or rows.count == 0 or columns.count == 0:
            # a reversed or empty read: what numpy gives, from the whole frame or (empty) from a stand-in
            source = self.whole() if None in cuts else np.broadcast_to(np.zeros((), np.uint8), self.shape)
            return np.array(source[key])
        if self._whole is not None or rows.tile_length() * columns.tile_length() > LAZY_WHOLE_FRACTION * height * width:
            return np.array(self.whole()[key])
        luma, blue, red = self._planes
        picked_luma = _gathered(luma, self._turns, rows.luma, columns.luma)
        picked_luma = np.repeat(picked_luma, 2, axis=0) if rows.doubled else picked_luma
        picked_luma = np.repeat(picked_luma, 2, axis=1) if columns.doubled else picked_luma
        tile = [picked_luma] + [_gathered(plane, self._turns, rows.chroma, columns.chroma) for plane in (blue, red)]
        image = _converted_tile(tile, self._frame)[rows.keep, columns.keep]
        image = image[:, 0] if columns.squeezed else image
        image = image[0] if rows.squeezed else image
        return image[(Ellipsis, *rest)] if rest else image


class _TileCache(threading.local):
    """Tiles kept by one thread (:func:`_converted_tile`): by size, and the bytes they hold."""

    def __init__(self):
        self.by_size, self.bytes = {}, 0


_tiles = _TileCache()


def _converted_tile(planes, source):
    """BGR uint8 of a 4:2:0 tile (luma 2m × 2n, chroma m × n each) converted as ``source``'s frames are.

    The tile is copied into a frame of a size rounded up to ``TILE_ALIGN_PX`` (its rows unpadded), one
    per size and thread, converted by a converter kept with it: making a frame and a converter costs
    several times a small tile's conversion. The padding converts too, and is cut off."""
    height, width = planes[0].shape
    size = (-(-width // TILE_ALIGN_PX) * TILE_ALIGN_PX, -(-height // TILE_ALIGN_PX) * TILE_ALIGN_PX)
    key = (*size, source.format.name, int(source.colorspace), int(source.color_range))
    if (entry := _tiles.by_size.get(key)) is None:
        tile = av.VideoFrame(*size, source.format.name)
        tile.colorspace, tile.color_range = source.colorspace, source.color_range
        buffers = [np.zeros((plane.height, plane.line_size), np.uint8) for plane in tile.planes]
        held = 2 * sum(buffer.nbytes for buffer in buffers) + 3 * size[0] * size[1]  # tile, buffers, its BGR
        if _tiles.bytes + held > TILES_KEPT_BYTES:
            _tiles.by_size.clear()
            _tiles.bytes = 0
        _tiles.bytes += held
        entry = _tiles.by_size[key] = (tile, buffers, VideoReformatter())
    tile, buffers, reformatter = entry
    for plane, buffer, pixels in zip(tile.planes, buffers, planes):
        buffer[:pixels.shape[0], :pixels.shape[1]] = pixels
        plane.update(buffer)
    return reformatter.reformat(tile, format="bgr24", threads=1).to_ndarray()[:height, :width]


def lazily_convertible(frame):
    """Whether a decoded frame can be a :class:`LazyFrame`: planar 8-bit 4:2:0, of even width and height."""
    return frame.format.name in LAZY_FORMATS and frame.width % 2 == 0 and frame.height % 2 == 0


@dataclass(frozen=True)
class ClipInfo:
    """What a video file says about itself.

    Attributes
    ----------
    path : pathlib.Path
        The file.
    width, height : int
        Size of the displayed frame (rotation applied), px.
    rotation_deg : int
        Counter-clockwise rotation that turns a coded frame into the displayed one (the display
        matrix), degrees: 0, 90, 180 or 270. A phone held upright usually stores 270 (its sensor's
        landscape frames, shown rotated clockwise by a quarter turn).
    codec : str
        The decoder's name (``h264``, ``hevc``, ``mjpeg``, ...).
    reduced_by : int
        The whole factor the frames are reduced by as they are decoded (:func:`frame_reduction`): width and
        height are of the reduced frames, the coded ones are this many times larger.
    container_fps : fractions.Fraction or None
        The container's nominal frame rate, frames/s (29.97 fps is 30000/1001); None when unknown.
    frame_count : int
        Frames the container declares (0 when it does not say).
    duration_s : float
        The stream's duration, s (NaN when unknown).
    """

    path: Path
    width: int
    height: int
    rotation_deg: int
    codec: str
    container_fps: Fraction | None
    frame_count: int
    duration_s: float
    reduced_by: int = 1


class VideoFile:
    """A video file opened once (``av.open``) for its background samples and one decoding pass.

    Use as a context manager. :meth:`samples` reaches a few frames spread over the clip by seeking,
    then :meth:`frames` decodes every frame once, in order, in a second thread ahead of the caller
    (FFmpeg releases the GIL while it decodes, and decodes with its own threads too).

    Parameters
    ----------
    path : str or pathlib.Path
        The video file (already checked to exist and be readable).

    Raises
    ------
    InputError
        When the file cannot be opened as a video, or not one frame of it can be decoded.
    """

    def __init__(self, path):
        self.path = Path(path)
        name = shown_path(path)
        unopenable = InputError(f"{name}: cannot be opened as a video: the file is damaged or not a video (a truncated "
                                f".mp4 or .mov lacks its index, which is written last); copy or export it again")
        try:
            self._container = av.open(str(path))
        except (av.FFmpegError, OSError) as error:
            raise unopenable from error
        try:
            if not self._container.streams.video:
                raise unopenable
            self._stream = stream = self._container.streams.video[0]
            stream.thread_type = "AUTO"  # FFmpeg's own decoding threads (frames or slices)
            stream.thread_count = _decoding_threads()
            rate = stream.average_rate or stream.guessed_rate
            fps = Fraction(rate) if rate else None
            time_base = stream.time_base
            duration_s = float(stream.duration * time_base) if stream.duration and time_base else (
                self._container.duration / av.time_base if self._container.duration else math.nan)
            declared = stream.frames or (round(duration_s * fps) if fps and math.isfinite(duration_s) else 0)
            check_frame_size(stream.codec_context.width, stream.codec_context.height, path)
            first = next(self._decoded(), None)
            if first is None:
                declared_text = f" of the {declared} its container declares" if declared >= 1 else ""
                raise InputError(f"{name}: no frame{declared_text} could be decoded: the video is empty, truncated "
                                 f"or corrupt; copy or export it again")
            check_frame_size(first.width, first.height, path)  # (a stream that did not say its size)
        except BaseException:
            self._container.close()
            raise
        self._first = first
        self._start_pts = stream.start_time if stream.start_time is not None else first.pts
        rotation = round((first.rotation or 0) / 90) * 90 % 360
        self._reduced_by = frame_reduction(first.width, first.height)
        coded_width, coded_height = self._reduced_size(first)
        height, width = (coded_width, coded_height) if rotation in (90, 270) else (coded_height, coded_width)
        self.info = ClipInfo(self.path, width, height, rotation, stream.codec_context.name, fps, int(declared),
                             duration_s, self._reduced_by)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        """Close the file."""
        self._container.close()

    _reduced_by = 1  # (until the first frame is seen)

    def _reduced_size(self, frame):
        """The coded size (width, height) of ``frame`` reduced :attr:`ClipInfo.reduced_by` times, px: even, so that
        4:2:0 chroma stays whole."""
        if self._reduced_by == 1:
            return frame.width, frame.height
        return (frame.width // self._reduced_by // 2 * 2, frame.height // self._reduced_by // 2 * 2)

    def _reduced(self, frame):
        """``frame`` reduced :attr:`ClipInfo.reduced_by` times by area averaging, in its own pixel format."""
        if self._reduced_by == 1:
            return frame
        width, height = self._reduced_size(frame)
        return frame.reformat(width=width, height=height, interpolation="AREA")

    def _decoded(self):
        """av.VideoFrame objects from the current position (reduced: :meth:`_reduced`), skipping packets the
        decoder refuses."""
        for packet in self._container.demux(self._stream):
            try:
                frames = packet.decode()
            except av.FFmpegError:  # a damaged frame: a gap in the times (a truncated file fails the count)
                continue
            yield from map(self._reduced, frames)

    def time_s(self, frame):
        """Presentation time of a decoded frame, s from the stream's start (NaN without a time stamp)."""
        if frame.pts is None or frame.time_base is None:
            return math.nan
        return float((frame.pts - self._start_pts) * frame.time_base)

    def image(self, frame):
        """The frame as the phone shows it: BGR uint8 (:func:`bgr_image`), rotation applied (:func:`upright`)."""
        return shown_image(frame, self.info.rotation_deg)

    def samples(self, count):
        """About ``count`` frames spread over the clip, for the background: (time s, BGR image) pairs.

        Reached by seeking, cheaply: with at least ``count`` key frames in the container's index,
        the spread key frames (one frame decoded each; every frame of an intra-only codec such as
        MJPEG is one); with fewer (long groups of pictures), frames spread over the index,
        decoded forward from the key frame before each and in one sweep where they share it (at
        worst the whole clip once). A container whose index holds fewer than ``count`` frames (none,
        or only those read so far: an AVI whose index was cut off, a short clip) is decoded once to
        the end, keeping frames at a doubling stride.
        """
        self._rewind()  # a seek reads an index kept at the file's end (Matroska's cues): until then it holds one entry
        entries = sorted(self._stream.index_entries, key=lambda entry: entry.timestamp)
        if len(entries) < count or self._first.pts is None:
            return self._samples_by_stride(count)
        keys = [position for position, entry in enumerate(entries) if entry.is_keyframe]
        targets = ([keys[i] for i in spread_indices(len(keys), count)] if len(keys) >= count
                   else list(spread_indices(len(entries), count)))
        # the index holds decoding time stamps; seeking and frames use presentation ones
        offset = self._first.pts - entries[0].timestamp
        if len(keys) >= count and self.info.codec in SEPARATE_KEY_FRAME_CODECS:
            by_key = self._key_frames([entries[k].timestamp + offset for k in targets])
            if by_key is not None:
                return by_key
        samples, decoder, position = [], None, -1
        for target in targets:
            key = max((k for k in keys if k <= target), default=0)
            if decoder is None or key > position:
                self._container.seek(entries[key].timestamp + offset, stream=self._stream, backward=True)
                decoder = self._decoded()
            wanted = entries[target].timestamp + offset
            frame = next((f for f in decoder if f.pts is not None and f.pts >= wanted), None)
            if frame is None:
                break
            samples.append((self.time_s(frame), self.image(frame)))
            position = target
        return samples

    def _key_frames(self, timestamps):
        """The first frames at or after ``timestamps`` (presentation time stamps; the index's times of key frames,
        which miss theirs by the reordering delay), each decoded from the key frame before it by a decoder of its
        own without frame threads, as (time s, BGR image) pairs; None when that decoder fails or a frame is not
        found.

        The clip's own decoder decodes with frame threads (:meth:`frames`): after a seek it must take in a
        packet per thread before the first frame comes out, so it decodes several frames for each key frame
        wanted (0.13 s against 0.08 s for 11 key frames of a 720p H.264 clip). Each frame's packets are read
        first, to its own (:meth:`_packets_to`), and the decoder is drained after them: fed packets until the
        frame came out, it decoded the frames it holds back for reordering too (0.066 → 0.049 s for the same 11).
        """
        return self._decoded_alone([self._packets_to(wanted) for wanted in timestamps])

    def _packets_to(self, wanted):
        """The presentation time stamp of the first frame at or after ``wanted`` (one) that decodes from the key
        frame a seek to ``wanted`` reaches, and the packets that decode it: from that key frame to the frame's
        own. Frames come in presentation order out of a decoder, up to ``REORDER_PACKETS`` packets after their
        own: the frame is the earliest of those packets, and not before the key frame (an open group of
        pictures starts with frames that refer to the group before it, which a decoder drops); None, and the
        packets read, when no packet is at or after ``wanted`` (the end of the clip)."""
        self._container.seek(wanted, stream=self._stream, backward=True)
        run, late = [], None
        for packet in self._container.demux(self._stream):
            if packet.size == 0 or (late is not None and (packet.is_keyframe or late == REORDER_PACKETS)):
                break
            run.append(packet)
            if late is not None:
                late += 1
            elif packet.pts is not None and packet.pts >= wanted:
                late = 0
        start = run[0].pts if run and run[0].is_keyframe and run[0].pts is not None else wanted
        target = min((packet.pts for packet in run if packet.pts is not None and packet.pts >= max(wanted, start)),
                     default=None)
        if target is None:
            return None, run
        return target, run[:next(position for position, packet in enumerate(run) if packet.pts == target) + 1]

    def _decoded_alone(self, runs):
        """For each (time stamp, packets) of :meth:`_packets_to`, the frame at that presentation time stamp decoded
        by a decoder of its own, as (time s, BGR image) pairs; None when the decoder fails or the frame is not
        there."""
        source = self._stream.codec_context
        try:
            decoder = av.CodecContext.create(source.name, "r")
            decoder.extradata = source.extradata
        except (av.FFmpegError, ValueError):
            return None
        samples = []
        for target, packets in runs:
            if target is None:
                return None
            decoder.flush_buffers()
            frame = None
            for packet in [*packets, None]:  # None: the frames still held are drained at the end
                try:
                    frame = next((frame for frame in decoder.decode(packet) if frame.pts == target), None)
                except av.FFmpegError:
                    return None
                if frame is not None:
                    break
            if frame is None:
                return None
            frame.time_base = self._stream.time_base  # (a frame drained from a decoder has none)
            samples.append((self.time_s(frame), self.image(self._reduced(frame))))
        return samples

    def _samples_by_stride(self, count):
        # from the start, where samples() has sought
        kept, stride = [], 1
        for index, frame in enumerate(self._decoded()):
            if index % stride == 0:
                kept.append((index, frame))
                if len(kept) > 2 * count:
                    stride *= 2
                    kept = [(i, f) for i, f in kept if i % stride == 0]
        return [(self.time_s(frame), self.image(frame)) for _, frame in kept]

    def _rewind(self):
        self._container.seek(self._first.pts if self._first.pts is not None else 0, stream=self._stream,
                             backward=True)

    def frames(self, progress=None, lazy=False):
        """Every frame once, in order, decoded in a second thread from now on: a :class:`DecodedFrames`.

        Parameters
        ----------
        progress : Progress, optional
            Told of each frame handed out, and finished at the end.
        lazy : bool
            Hand out frames that can be (:func:`lazily_convertible`) as :class:`LazyFrame` objects,
            converted where they are read, not whole in the decoding thread.
        """
        self._rewind()
        rotation = self.info.rotation_deg
        frames = ((self.time_s(frame), LazyFrame(frame, rotation) if lazy and lazily_convertible(frame)
                   else self.image(frame)) for frame in self._decoded())
        return DecodedFrames(frames, self.info.width * self.info.height * 3, f"decode {self.path.name}", progress)

    def frame(self, index):
        """The displayed BGR frame ``index`` (decoding from the start), or None past the end."""
        self._rewind()
        return next((self.image(frame) for position, frame in enumerate(self._decoded()) if position == index), None)


class DecodedFrames:
    """Frames decoded in a second thread ahead of the caller (:meth:`VideoFile.frames`).

    Decoding starts when the object is made, so that what the caller does before it takes the
    first frame (reading the scene from the background samples) overlaps it; the thread holds up
    to ``DECODE_AHEAD_BYTES`` of frames (at least ``DECODE_AHEAD_FRAMES``). Iterate once for
    (index, time s, BGR image) triples; leaving the iteration early, or :meth:`close` (also at the
    end of a ``with`` block), stops the thread.

    Parameters
    ----------
    frames : iterator of (float, numpy.ndarray)
        Time (s) and image of each frame, decoded as it is taken (in the second thread only).
    frame_bytes : int
        Bytes of one image.
    name : str
        The thread's name.
    progress : Progress, optional
        Told of each frame handed out, and finished at the end.
    """

    def __init__(self, frames, frame_bytes, name, progress=None):
        self._frames, self._progress = frames, progress
        self._handoff = queue.Queue(maxsize=max(DECODE_AHEAD_FRAMES, DECODE_AHEAD_BYTES // max(frame_bytes, 1)))
        self._halt = threading.Event()
        self._end = object()
        self._thread = threading.Thread(target=self._decode, daemon=True, name=name)
        self._thread.start()

    def _decode(self):
        try:
            for item in self._frames:
                while not self._halt.is_set():
                    try:
                        self._handoff.put(item, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if self._halt.is_set():
                    return
        finally:
            self._handoff.put(self._end)

    def __iter__(self):
        index = 0
        try:
            while (item := self._handoff.get()) is not self._end:
                yield (index, *item)
                index += 1
                if self._progress is not None:
                    self._progress.update(index)
        finally:
            self.close()
            if self._progress is not None:
                self._progress.finish(index)

    def close(self):
        """Stop decoding (frames not taken are dropped)."""
        self._halt.set()
        while self._thread.is_alive():
            with contextlib.suppress(queue.Empty):
                self._handoff.get(timeout=0.1)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class Progress:
    """How far decoding and tracking one clip has got.

    On a terminal (``stream.isatty()``), one line updated in place with ``\\r`` at most every
    ``PROGRESS_INTERVAL_S``: frames done of the declared total, frames/s and the time left. When
    done, one line: frames, seconds and frames/s. Where standard error is not a terminal (a log
    file) that summary is the only line written, for every clip: a log gets one line per clip, none
    per frame. On a terminal, clips shorter than ``total_min`` frames write nothing (they take well
    under a second).

    Parameters
    ----------
    label : str
        What is decoded (the file's name).
    total : int
        Frames expected (0 when unknown).
    stream : file, optional
        Where to write; standard error by default.
    total_min : int
        Fewer expected frames than this: silent on a terminal.
    clock : callable
        Seconds, monotonic (for tests).
    """

    def __init__(self, label, total, stream=None, total_min=PROGRESS_MIN_FRAMES, clock=time.monotonic):
        self.label, self.total = label, total
        self.stream = stream if stream is not None else sys.stderr
        self.clock = clock
        self.started = clock()
        self._shown = self.started
        self._tty = _is_terminal(self.stream)
        self.enabled = total >= total_min or not self._tty

    def update(self, done):
        """``done`` frames so far: refresh the terminal line when it is due."""
        if not (self._tty and self.enabled):
            return
        now = self.clock()
        if now - self._shown < PROGRESS_INTERVAL_S:
            return
        self._shown = now
        rate = done / max(now - self.started, 1e-9)
        left = f", {max(self.total - done, 0) / rate:.0f} s left" if self.total and rate > 0 else ""
        self.stream.write(f"\r{self.label}: {done}/{self.total} frames, {rate:.0f} frames/s{left}")
        self.stream.flush()

    def finish(self, done):
        """Write the one summary line: frames, seconds and frames/s."""
        if not self.enabled:
            return
        elapsed = self.clock() - self.started
        line = f"{self.label}: {done} frames in {elapsed:.1f} s ({done / max(elapsed, 1e-9):.0f} frames/s)"
        self.stream.write(("\r" + line + "\x1b[K\n") if self._tty else line + "\n")
        self.stream.flush()


def _is_terminal(stream):
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False


def _decoding_threads():
    """FFmpeg's decoding threads for a clip: one per CPU core this process may run on, at most
    ``MAX_DECODING_THREADS``. FFmpeg's own count (one more than the cores, at most 16) is made for a decoder that has
    the machine to itself; the tracker needs a share of it: on 2 cores the portrait phone clip of
    ``benchmarks/tracking_speed.py`` was tracked at 0.94 of the decode-only rate with 3 threads, 1.02 with 2."""
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return min(cores, MAX_DECODING_THREADS)


def spread_indices(count, samples):
    """Up to ``samples`` distinct indices in ``range(count)``, evenly spread from the first to the last."""
    return np.unique(np.round(np.linspace(0, count - 1, min(samples, count))).astype(int))


def frame_times(stamps_s, container_fps, capture_fps, path):
    """Frame times and how they were obtained.

    Parameters
    ----------
    stamps_s : array_like
        The frames' presentation times, s (NaN where a frame had none).
    container_fps : float or None
        The container's nominal rate, frames/s: the times when the stamps are missing or do not
        increase.
    capture_fps : float or None
        The camera's capture rate, frames/s, for a slow-motion file whose stamps are in playback
        time: they are scaled by ``container_fps / capture_fps``.
    path : str or pathlib.Path
        The video, for messages.

    Returns
    -------
    (numpy.ndarray, str)
        Times, s, and how they were obtained.
    """
    count = len(stamps_s)
    index = np.arange(count, dtype=float)
    stamps = np.asarray(stamps_s, float)
    meaningful = np.all(np.isfinite(stamps)) and (count == 1 or np.all(np.diff(stamps) > 0))
    nominal = float(container_fps) if container_fps and math.isfinite(container_fps) and container_fps > 0 else None
    if meaningful:
        times, how = stamps, "container time stamps"
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
