"""A video with sound: the impacts heard and the impacts seen, compared.

The video is tracked and analysed as any video (:func:`dropfit.pipeline.process_recording`), and its
sound track is analysed as a sound recording (:mod:`dropfit.audio.recording`), both on the
container's clock. Each impact seen is paired with the impact heard nearest to it after the offset
between the two clocks (the offset with the most pairs within :data:`PAIR_TOLERANCE_S`); the offset
reported is the weighted mean of the paired differences (:func:`dropfit.audio.fuse.fit_offset`), sound − video: the phone's audio/video offset plus
the sound's travel from the floor to the microphone (0.9 ms at 30 cm). The release the video sees,
moved onto the sound's clock, gives the sound its drop height and first impact's e. e from both sit
side by side. (``dropfit run`` measures a video with sound both ways and combines them:
:func:`dropfit.pipeline.measure_sound_and_picture`, :mod:`dropfit.audio.fuse`.)
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import InputError, shown_path
from ..numerics import robust_sigma
from ..pipeline import _picture_result, analyse_trajectory, fit_analysis
from ..settings import Ball, Settings
from .decode import read_sound
from .fuse import fit_offset
from .recording import sound_trajectory

#: An impact heard and an impact seen are the same when, after the clocks' offset, they are closer
#: than this (s): well below a bounce's flight time, well above a video's touchdown uncertainty.
PAIR_TOLERANCE_S = 0.02
#: The largest offset between a recording's sound and its frames (s): phones keep them within about 0.1 s;
#: clicks that pair with the impacts seen only further apart are other sounds.
MAX_OFFSET_S = 0.3


def pair_impacts(video_s, sound_s, tolerance_s=PAIR_TOLERANCE_S, max_offset_s=MAX_OFFSET_S):
    """Pair impact times seen and heard (s, each increasing) across an unknown clock offset (at most
    ``max_offset_s``).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Indices into ``video_s`` and ``sound_s`` of the pairs, for the offset (sound − video) that pairs
        the most (the smallest such offset on a tie); empty when none pairs within the largest offset.
    """
    best = (np.array([], int), np.array([], int))
    offsets = np.subtract.outer(np.asarray(sound_s, float), np.asarray(video_s, float)).ravel()
    for offset in sorted(offsets[np.abs(offsets) <= max_offset_s], key=abs):
        shifted = video_s + offset
        nearest = np.array([int(np.argmin(np.abs(sound_s - t))) for t in shifted])
        close = np.abs(sound_s[nearest] - shifted) < tolerance_s
        if close.sum() > best[0].size and np.unique(nearest[close]).size == close.sum():
            best = (np.flatnonzero(close), nearest[close])
    return best


def clicks_offset(video_s, clicks_s, tolerance_s=PAIR_TOLERANCE_S, max_offset_s=MAX_OFFSET_S):
    """The offset (sound − video, s) at which the impacts seen pair with the clicks heard, every click
    found (not only the chain chosen as bounces), and how many pair (:func:`pair_impacts`).

    Where the sound's chain of bounces pairs fewer than two impacts seen, the clicks can still show the
    clocks' offset: a chain that took a rattle or an echo for a bounce, or that a missed click broke,
    leaves the true impacts among its candidates.

    Returns
    -------
    (int, float)
        Pairs found and the median of their differences (s; NaN when none pair).
    """
    video_s, clicks_s = np.asarray(video_s, float), np.asarray(clicks_s, float)
    video_s, clicks_s = video_s[np.isfinite(video_s)], np.sort(clicks_s[np.isfinite(clicks_s)])
    if not video_s.size or not clicks_s.size:
        return 0, float("nan")
    seen, heard = pair_impacts(video_s, clicks_s, tolerance_s, max_offset_s)
    if not seen.size:
        return 0, float("nan")
    return int(seen.size), float(np.median(clicks_s[heard] - video_s[seen]))


def compare_sound_and_video(path, ball=None, settings=None, sample_id=None):
    """Impacts from the sound and from the tracked flights of one video, compared.

    Parameters
    ----------
    path : str or pathlib.Path
        A video with a sound track.
    ball : dropfit.settings.Ball, optional
    settings : dropfit.settings.Settings, optional

    Returns
    -------
    (pandas.DataFrame, dict)
        The impacts paired: ``impact_video``, ``impact_sound``, ``t_video_s``, ``t_sound_s`` (container
        clock), ``offset_s`` (sound − video), ``e_video``, ``e_video_se``, ``e_sound``, ``e_sound_se``;
        and the summary: the offset (median, robust spread, its standard error, s), the headline e of
        each with its standard error and interval, the number of impacts of each and paired.

    Raises
    ------
    dropfit.errors.InputError
        For a video without sound, one whose ball is not found, or impacts that cannot be paired.
    """
    ball = ball or Ball()
    settings = settings or Settings()
    name = shown_path(path)
    sound = read_sound(path)
    video = _picture_result(path, ball, settings, sample_id, None)  # the picture alone (run fuses both)
    attrs = {key: value for key, value in video.trajectory.attrs.items()
             if key.startswith(("ball_", "gravity_")) or key in ("sample_id", "dropfit_version")}
    heard_trajectory = sound_trajectory(path, attrs, sound=sound)
    seen = video.impacts
    heard_times = heard_trajectory["impact_time_s"].values
    seen_index, heard_index = pair_impacts(seen["t_touchdown_s"].to_numpy(), heard_times)
    if seen_index.size == 0:
        raise InputError(f"{name}: none of the {len(seen)} impacts seen pairs with one of the {heard_times.size} "
                         f"heard within {1e3 * PAIR_TOLERANCE_S:g} ms at any offset; check that the sound is of "
                         f"this drop")
    # the release the video saw (the drop's apex: a release at rest), on the sound's clock, gives the sound
    # its drop height and first e
    offsets = heard_times[heard_index] - seen["t_touchdown_s"].to_numpy()[seen_index]
    release = video.analysis.summary.get("drop_apex_time_s")
    if release is not None and np.isfinite(release) and release + np.median(offsets) < heard_times[0]:
        heard_trajectory.attrs["release_time_s"] = float(release + np.median(offsets))
    heard = analyse_trajectory(heard_trajectory, settings)
    heard_fit = fit_analysis(heard, heard_trajectory.attrs, settings)
    heard_impacts = heard.impacts
    pairs = pd.DataFrame({
        "impact_video": seen["impact"].to_numpy()[seen_index],
        "impact_sound": heard_impacts["impact"].to_numpy()[heard_index],
        "t_video_s": seen["t_touchdown_s"].to_numpy()[seen_index],
        "t_sound_s": heard_impacts["t_touchdown_s"].to_numpy()[heard_index],
    })
    pairs["offset_s"] = pairs["t_sound_s"] - pairs["t_video_s"]
    for source, table, index in (("video", seen, seen_index), ("sound", heard_impacts, heard_index)):
        pairs[f"e_{source}"] = table["e"].to_numpy()[index]
        pairs[f"e_{source}_se"] = table["e_se"].to_numpy()[index]
    offsets = pairs["offset_s"].to_numpy()
    spread = robust_sigma(offsets) if offsets.size > 2 else float(np.std(offsets))
    offset, offset_se = fit_offset(pairs["t_video_s"], seen["t_touchdown_se_s"].to_numpy()[seen_index],
                                   pairs["t_sound_s"], heard_impacts["t_touchdown_se_s"].to_numpy()[heard_index])
    summary = {
        "offset_s": offset,
        "offset_spread_s": float(spread),
        "offset_se_s": offset_se,
        "offset_note": "sound − video: the audio/video offset of the recording plus the sound's travel time "
                       "from the floor to the microphone (about 2.9 ms per m)",
        "e_video": video.fit["restitution"]["e"], "e_sound": heard_fit["restitution"]["e"],
        "model_video": video.fit["restitution"]["model"], "model_sound": heard_fit["restitution"]["model"],
        "n_impacts_video": len(seen), "n_impacts_sound": len(heard_impacts), "n_paired": int(offsets.size),
        "drop_height_video_m": video.fit["drop_height_m"], "drop_height_sound_m": heard_fit["drop_height_m"],
        "release_time_sound_s": heard_trajectory.attrs.get("release_time_s"),
    }
    return pairs, summary
