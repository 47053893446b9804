"""High-speed camera files: Photron MRAW with its CIHX/CIH metadata, read through pyMRAW.

The ``.cihx`` (XML) or ``.cih`` (text) file holds the recording's metadata, among them the frame
rate (``Record Rate(fps)``), the frame size and the bit depth; the ``.mraw`` beside it (same name)
holds the raw frames (8, 12 or 16 bit grey). Either file may be given.

The frames go through dropfit's ball tracker (:func:`dropfit.video.track.track_frames`), with the
times frame / rate. High-speed clips are short and usually backlit (a dark silhouette on a bright
backlight): the ball may never leave its own footprint, so the median of the frames cannot be the
background. The background is then the brightest each pixel is over the clip (the backlight where
the ball passes), with the backlight's level where the ball covers a pixel in every frame; a
lens-like ball's bright centre (light through the ball) is filled into its silhouette, whose outline
alone gives the centre.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import InputError, shown, shown_path
from .base import ImportedTrack
from .table import describe

SUFFIXES = (".cihx", ".cih", ".mraw")
#: A pixel darker than this fraction of its row's backlight is in a silhouette.
SILHOUETTE_FRACTION = 0.5
#: The foreground threshold of a backlit clip, as a fraction of the backlight's grey level.
BACKLIT_THRESHOLD_FRACTION = 0.08


def is_highspeed(path):
    """Whether ``path`` names a Photron file (by its suffix)."""
    return str(path).lower().endswith(SUFFIXES)


def _metadata_path(path):
    path = Path(path)
    if path.suffix.lower() != ".mraw":
        return path
    for suffix in (".cihx", ".cih", ".CIHX", ".CIH"):
        if path.with_suffix(suffix).exists():
            return path.with_suffix(suffix)
    raise InputError(f"{shown_path(path)}: the .cihx (or .cih) file with the frame rate is not beside the .mraw; keep "
                     f"both files from the camera together")


def read_frames(path):
    """The frames of a Photron recording as 8-bit grey, their times in s and the frame rate in frames/s.

    Raises
    ------
    InputError
        A missing or unreadable file, metadata without a frame rate, a .mraw without its .cihx.
    """
    import pyMRAW

    metadata = _metadata_path(path)
    if not metadata.exists():
        raise InputError(f"{shown_path(path)}: the file does not exist; check the path")
    try:
        images, info = pyMRAW.load_video(str(metadata))
    except Exception as error:  # noqa: BLE001 — pyMRAW raises anything on a damaged or foreign file
        raise InputError(f"{shown_path(path)}: is not a readable Photron MRAW/CIHX recording ({type(error).__name__}: "
                         f"{shown(error)}); give the .cihx and .mraw as saved by the camera") from None
    fps = info.get("Record Rate(fps)")
    if not fps or not np.isfinite(float(fps)) or float(fps) <= 0:
        raise InputError(f"{shown_path(path)}: the metadata give no frame rate (Record Rate(fps)); save the recording "
                         f"with its .cihx")
    images = np.asarray(images)
    if images.ndim != 3 or images.shape[0] < 3:
        raise InputError(f"{shown_path(path)}: holds {images.shape[0] if images.ndim == 3 else 0} grey frames; at least "
                         f"3 are needed")
    bits = int(info.get("EffectiveBit Depth") or info.get("Color Bit") or 8)
    grey = np.clip(np.rint(images.astype(np.float32) * (255.0 / (2 ** bits - 1))), 0, 255).astype(np.uint8)
    return grey, np.arange(grey.shape[0]) / float(fps), float(fps)


def backlit_scene(frames):
    """Frames with each silhouette's enclosed bright spots filled, and the background of a backlit clip.

    Returns
    -------
    (list of numpy.ndarray, dropfit.video.background.Background)
    """
    from scipy import ndimage

    from ..numerics import robust_sigma
    from ..video.background import MIN_THRESHOLD_GREY, NOISE_THRESHOLD_SIGMAS, Background

    brightest = frames.max(axis=0).astype(np.float32)
    median = np.median(frames, axis=0).astype(np.float32)
    light = np.percentile(brightest, 90, axis=1, keepdims=True)
    background = np.where(median < SILHOUETTE_FRACTION * light, brightest, median)  # static texture: the median
    background = np.where(background < SILHOUETTE_FRACTION * light, np.broadcast_to(light, background.shape),
                          background).astype(np.float32)
    filled = []
    for frame in frames:
        dark = frame < SILHOUETTE_FRACTION * light
        spots = ndimage.binary_fill_holes(dark) & ~dark
        frame = frame.copy()
        if spots.any():
            frame[spots] = np.median(frame[dark])
        filled.append(frame)
    unsaturated = (median >= SILHOUETTE_FRACTION * light) & (median < 255)
    residual = (frames[:, unsaturated].astype(np.float32) - background[unsaturated]).ravel()
    noise = float(robust_sigma(residual)) if residual.size else 0.0
    threshold = max(MIN_THRESHOLD_GREY, NOISE_THRESHOLD_SIGMAS * noise,
                    BACKLIT_THRESHOLD_FRACTION * float(np.median(light)))
    return filled, Background(background, max(noise, 1.0), threshold)


def track_highspeed(path):
    """The tracked table of a Photron recording (as :func:`dropfit.video.track.track_frames`) and its rate."""
    from ..video.track import track_frames

    frames, times, fps = read_frames(path)
    filled, background = backlit_scene(frames)
    return track_frames(filled, times, background=background, source=shown_path(path)), fps


def read_highspeed(path, options):
    """A Photron recording → :class:`ImportedTrack` of the tracked ball (image px, y down)."""
    from ..video.quality import speed_dependent_centre_error_px
    from ..video.track import usable_rows

    table, fps = track_highspeed(path)
    usable = usable_rows(table)
    if np.count_nonzero(usable) < 3:
        raise InputError(f"{shown_path(path)}: the ball is measured cleanly in only {np.count_nonzero(usable)} of "
                         f"{len(table)} frames; a backlit ball on a bright background is needed")
    x = np.where(usable, table["x_px"].to_numpy(), np.nan)
    y = np.where(usable, table["y_px"].to_numpy(), np.nan)
    mapping = describe(path, [f"Photron clip of {len(table)} frames at {fps:g} frames/s (from its metadata)",
                              f"ball tracked in {np.count_nonzero(usable)} [px, y down]"])
    return ImportedTrack(table["time_s"].to_numpy(), y, "px", "mraw", mapping, x, fps,
                         {"ball_radius_px": float(np.nanmedian(table["radius_px"].to_numpy()[usable])),
                          "speed_error_px": speed_dependent_centre_error_px("raw", y, table["time_s"].to_numpy(),
                                                                            table["blur_px"].to_numpy())})
