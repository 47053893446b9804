"""The sound track of a clip: an impact sound at each contact, room noise, and an offset between the
sound's clock and the frames', muxed into the clip (AAC or 16-bit PCM, MP4/MOV/MKV/AVI) through PyAV.

The clicks come from :func:`refsim.sound.render_sound` (the physics of the bounce: a click at each
touchdown whose loudness grows with the impact speed, room echoes, hum, background noise); this module
only moves them onto the container's clock and writes them. A click of impact n starts at

    t_touchdown,n + offset_s + mic_distance_m / 343 m/s

on the clip's clock (the frames' times), so ``offset_s`` is the phone's audio/video offset, the sound
− the video, and the truth (:func:`sound_truth`) holds every click's onset. ``missed_impacts`` leaves
impacts silent (a click too faint to be heard), ``extra_clicks_s`` adds clicks that are not impacts
(a knock, the hand), ``silent`` records the room only.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from fractions import Fraction
from types import SimpleNamespace

import av
import numpy as np
import pandas as pd

from refsim.sound import SPEED_OF_SOUND_M_S, SoundOptions, render_sound

#: Samples per frame handed to the encoder (AAC's frame size).
BLOCK_SAMPLES = 1024


@dataclass(frozen=True)
class SoundTrack:
    """How the clip's sound is recorded and stored.

    Attributes
    ----------
    offset_s : float
        The sound's clock minus the frames' (s): a click is stamped this much after its touchdown (plus
        the sound's travel time).
    codec : str
        ``aac`` (as phones record) or ``pcm_s16le`` (16-bit PCM).
    rate_hz : int
        Sample rate (Hz).
    options : refsim.sound.SoundOptions
        The recording (levels, echoes, noise, hum, microphone distance); ``lead_s``/``tail_s`` are
        replaced by the clip's length.
    missed_impacts : tuple of int
        Impacts (numbered from 1) whose click is left out.
    extra_clicks_s : tuple of float
        Times (s, clip clock) of clicks that are not impacts, as loud as the loudest impact's.
    silent : bool
        No clicks at all: the room's noise only.
    """

    offset_s: float = 0.0
    codec: str = "aac"
    rate_hz: int = 48000
    options: SoundOptions = field(default_factory=lambda: SoundOptions(noise_level=0.003, hum_level=0.005))
    missed_impacts: tuple = ()
    extra_clicks_s: tuple = ()
    silent: bool = False


def render_track(impacts, duration_s, track, seed=0, slow_motion=1):
    """The samples (mono, full scale 1, first sample at clip time 0) and the truth of every click.

    Parameters
    ----------
    impacts : pandas.DataFrame
        refsim's impacts (``impact``, ``t_touchdown_s`` on the clip clock, ``v_in_m_s``).
    duration_s : float
        Length of the track (s).
    track : SoundTrack
    seed : int
    slow_motion : int
        The clip presents its captures this many times slower (:class:`phonesim.FrameTiming`): the sound
        is slowed with it (stretched in time, every frequency lowered), as phones store slow motion.

    Returns
    -------
    (numpy.ndarray, pandas.DataFrame)
        The samples, and one row per click written: ``impact`` (0 for an extra click), ``t_touchdown_s``,
        ``onset_s`` (s, the clip's presentation clock: a slow-motion clip's onsets are ``slow_motion`` times
        later than on the capture clock).
    """
    impacts = impacts.reset_index(drop=True)
    heard = impacts[~impacts["impact"].isin(track.missed_impacts)]
    times = heard["t_touchdown_s"].to_numpy(float) + track.offset_s
    speeds = heard["v_in_m_s"].to_numpy(float)
    numbers = heard["impact"].to_numpy(int)
    if track.extra_clicks_s:
        times = np.r_[times, np.asarray(track.extra_clicks_s, float)]
        speeds = np.r_[speeds, np.full(len(track.extra_clicks_s), speeds.max() if speeds.size else 1.0)]
        numbers = np.r_[numbers, np.zeros(len(track.extra_clicks_s), int)]
    order = np.argsort(times)
    times, speeds, numbers = times[order], speeds[order], numbers[order]
    travel = track.options.mic_distance_m / SPEED_OF_SOUND_M_S
    keep = (times > 0.0) & (times + travel < duration_s - 0.03)
    if track.silent:
        keep[:] = False
    times, speeds, numbers = times[keep], speeds[keep], numbers[keep]
    clicks = SimpleNamespace(impacts=pd.DataFrame({"t_touchdown_s": times, "v_in_m_s": speeds}), t_release_s=0.0)
    last = times[-1] + travel if times.size else 0.0
    options = replace(track.options, rate_hz=float(track.rate_hz), lead_s=0.0, tail_s=max(duration_s - last, 0.0),
                      channels=1)
    sound = render_sound(clicks, options, seed=seed)
    samples = np.zeros(int(round(duration_s * track.rate_hz)))
    n = min(samples.size, sound.samples.size)
    samples[:n] = sound.samples[:n]
    if times.size == 0:  # render_sound's silence is as long as its lead and tail: the room's noise all along
        samples = np.clip(np.random.default_rng(seed).normal(0.0, options.noise_level, samples.size), -1.0, 1.0)
    truth = pd.DataFrame({"impact": numbers, "t_touchdown_s": times - track.offset_s,
                          "onset_s": sound.onsets_s[:times.size] if times.size else times})
    if slow_motion != 1:  # the same samples played slower: stretched onto slow_motion times as many
        stretched = np.arange(samples.size * slow_motion) / slow_motion
        samples = np.interp(stretched, np.arange(samples.size), samples)
        truth["onset_s"] = truth["onset_s"] * slow_motion
    return samples, truth


def add_track_stream(container, track):
    """Add a mono sound stream of ``track.codec`` to an output container, before anything is muxed."""
    rate = int(track.rate_hz)
    stream = container.add_stream(track.codec, rate=rate, layout="mono")
    stream.codec_context.time_base = Fraction(1, rate)
    if track.codec == "aac":
        stream.codec_context.bit_rate = 128000
    return stream


def write_track(container, stream, samples, track):
    """Encode the samples into ``stream`` (:func:`add_track_stream`), first sample at pts 0 (after the video's
    packets, before the container is closed)."""
    rate = int(track.rate_hz)
    if track.codec == "aac":
        data, layout_format = samples.astype(np.float32)[None, :], "fltp"
    else:
        data, layout_format = np.clip(np.round(samples * 32767), -32768, 32767).astype(np.int16)[None, :], "s16"
    for first in range(0, data.shape[1], BLOCK_SAMPLES):
        block = data[:, first:first + BLOCK_SAMPLES]
        if block.shape[1] < BLOCK_SAMPLES and track.codec == "aac":
            block = np.pad(block, ((0, 0), (0, BLOCK_SAMPLES - block.shape[1])))
        frame = av.AudioFrame.from_ndarray(np.ascontiguousarray(block), format=layout_format, layout="mono")
        frame.sample_rate, frame.pts, frame.time_base = rate, first, Fraction(1, rate)
        for packet in stream.encode(frame):
            container.mux(packet)
    for packet in stream.encode():
        container.mux(packet)
