"""Sound from a file: samples (full scale ±1, channels kept) and the sample rate.

WAV, FLAC and OGG are read with soundfile (libsndfile: exact samples, no resampling). M4A, AAC, MP3,
Opus and the sound track of a video are decoded with PyAV (FFmpeg), already dropfit's video decoder:
it decodes in-process and gives each decoded block's time stamp, so the samples of a video's sound track
are placed on the container's clock (the clock of the video's frames). A sound file's samples are
counted from its first, as a sound editor shows them: an MP3's demuxer stamps the first block with the
encoder's delay (25 ms for LAME at 44.1 kHz) although that block is the recording's start.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, shown_path

#: Suffixes read with soundfile.
SOUNDFILE_SUFFIXES = (".wav", ".flac", ".ogg", ".oga")
#: Suffixes of sound-only files decoded with PyAV.
PYAV_SUFFIXES = (".m4a", ".aac", ".mp3", ".opus", ".wma", ".caf")
#: Every suffix of a sound file dropfit reads.
AUDIO_SUFFIXES = SOUNDFILE_SUFFIXES + PYAV_SUFFIXES
#: A recording shorter than this has no bounce to hear, s.
MIN_DURATION_S = 0.05
#: The most samples (per channel) dropfit analyses: 2.5 minutes at 48 kHz. The analysis costs about 100 bytes a
#: sample (the envelope and its filters, all at the sample rate): `dropfit run` of 150 s at 48 kHz peaked at
#: 875 MB (benchmarks/reader_peaks.py), so that a job keeps within its 1000 MB.
MAX_SOUND_SAMPLES = 150 * 48_000
#: The most values (samples × channels) dropfit decodes: 150 s of stereo at 48 kHz (930 MB in `dropfit run`); each
#: channel more costs 8 bytes a sample until the channels are averaged.
MAX_SOUND_VALUES = 2 * MAX_SOUND_SAMPLES


@dataclass
class Sound:
    """Decoded sound.

    Attributes
    ----------
    samples : numpy.ndarray
        Shape (n, channels), float64, full scale ±1.
    rate_hz : float
        Samples per second.
    start_s : float
        Time of the first sample on the file's clock (s; 0 for a sound file, the stream's first time
        stamp for a video's sound track).
    codec : str
        What was decoded (format and subtype, or the codec's name).
    channel_note : str
        What was done with the channels, when they were not averaged (empty otherwise).
    """

    samples: np.ndarray
    rate_hz: float
    start_s: float = 0.0
    codec: str = ""
    channel_note: str = ""

    @property
    def duration_s(self):
        """Length of the recording in s."""
        return self.samples.shape[0] / self.rate_hz


def is_audio(path):
    """True if ``path`` names a sound file (by its suffix)."""
    return str(path).lower().endswith(AUDIO_SUFFIXES)


def read_sound(path):
    """Decode a sound file, or the sound track of a video, to :class:`Sound`.

    Parameters
    ----------
    path : str or pathlib.Path
        A sound file (:data:`AUDIO_SUFFIXES`) or a video with a sound track.

    Raises
    ------
    dropfit.errors.InputError
        For a missing, empty, damaged or silent file, or a video without sound.
    """
    name = shown_path(path)
    try:
        with open(path, "rb") as handle:
            head = handle.read(16)
    except OSError as error:
        raise InputError(f"{name}: cannot be read ({error.strerror or error}); check the path") from None
    if not head:
        raise InputError(f"{name}: the file is empty (0 bytes): not a recording; copy or export it again")
    if str(path).lower().endswith(SOUNDFILE_SUFFIXES):
        sound = _read_with_soundfile(path, name)
    else:
        sound = _read_with_pyav(path, name, container_clock=not str(path).lower().endswith(PYAV_SUFFIXES))
    if sound.samples.shape[0] < MIN_DURATION_S * sound.rate_hz:
        raise InputError(f"{name}: the recording lasts {sound.duration_s:.3g} s, too short to hold a bounce; "
                         f"record the whole drop")
    if not np.all(np.isfinite(sound.samples)):
        raise InputError(f"{name}: the sound holds samples that are not numbers (NaN or infinite); export it again")
    if not np.any(sound.samples):
        # red_ball_portrait.mp4: an AAC track of identical silent blocks, every sample 0 (no microphone, or muted)
        raise InputError(f"{name}: the sound track is digital silence (every sample is 0 over {sound.duration_s:.3g} s: "
                         f"recorded muted or without a microphone): no impact can be heard; record with the "
                         f"microphone on, or measure the picture alone")
    return _one_channel_if_they_cancel(sound)


#: Channels whose average keeps less than this share of the loudest one's RMS cancel (one is the other inverted): a
#: stereo file whose channels cancel averaged to 17 samples of ±1 LSB, and 7 impacts were heard of 56.
CANCELLING_CHANNELS_SHARE = 0.1


def _one_channel_if_they_cancel(sound):
    """The sound with its loudest channel alone where its channels cancel when averaged (one wired inverted, the
    analysis averages them): :data:`CANCELLING_CHANNELS_SHARE`."""
    if sound.samples.shape[1] < 2:
        return sound
    centred = sound.samples - sound.samples.mean(axis=0)
    rms = np.sqrt(np.mean(centred ** 2, axis=0))
    loudest = int(np.argmax(rms))
    if np.sqrt(np.mean(centred.mean(axis=1) ** 2)) >= CANCELLING_CHANNELS_SHARE * rms[loudest]:
        return sound
    note = (f"the {sound.samples.shape[1]} channels cancel when averaged (one is the other inverted): channel "
            f"{loudest + 1} alone is analysed")
    return dataclasses.replace(sound, samples=sound.samples[:, loudest:loudest + 1], channel_note=note)


def _read_with_soundfile(path, name):
    import soundfile

    try:
        info = soundfile.info(str(path))
        _check_size(name, info.frames, info.channels, info.samplerate)
        # no further than the bound: a header may understate the samples that follow it
        samples, rate = soundfile.read(str(path), frames=_most_samples(info.channels) + 1, dtype="float64",
                                       always_2d=True)
    except (RuntimeError, soundfile.LibsndfileError, ValueError) as error:
        raise InputError(f"{name}: cannot be read as sound: the file is damaged or not a {str(path).rsplit('.', 1)[-1]} "
                         f"file ({str(error).splitlines()[0] if str(error) else type(error).__name__}); export it again") \
            from None
    _check_size(name, samples.shape[0], samples.shape[1], rate, whole=False)
    return Sound(samples=samples, rate_hz=float(rate), codec=f"{info.format} {info.subtype}")


def _most_samples(channels):
    """The most samples per channel dropfit decodes of a sound of ``channels`` channels."""
    return min(MAX_SOUND_SAMPLES, MAX_SOUND_VALUES // max(channels, 1))


def _check_size(name, samples, channels, rate_hz, whole=True):
    """InputError for a sound of more than :data:`MAX_SOUND_SAMPLES` a channel or :data:`MAX_SOUND_VALUES` in all
    (``samples`` a channel: all of them if ``whole``, else those decoded before the bound stopped it)."""
    most = _most_samples(channels)
    if samples <= most:
        return
    bound = "MAX_SOUND_SAMPLES" if most == MAX_SOUND_SAMPLES else "MAX_SOUND_VALUES, samples × channels"
    length = f"{samples / rate_hz:.0f} s" if rate_hz > 0 else f"{samples:,} samples"
    raise InputError(f"{name}: the sound lasts {'' if whole else 'more than '}{length} of {channels} "
                     f"channel{'s' if channels != 1 else ''}, more than the {most:,} samples a channel "
                     f"({most / rate_hz:.0f} s at its {rate_hz:g} Hz) dropfit analyses ({bound}); cut it to the "
                     f"drops, e.g. ffmpeg -i IN -ss START -t 60 -ac 1 OUT.wav, and give each part")


def _read_with_pyav(path, name, container_clock):
    """Decode with PyAV; the first sample's time is the stream's first time stamp when ``container_clock``
    (a video's sound track), else 0 (a sound file)."""
    import av

    try:
        container = av.open(str(path))
    except (av.FFmpegError, OSError) as error:
        raise InputError(f"{name}: cannot be opened: the file is damaged or not a sound or video file "
                         f"({type(error).__name__}); export it again") from None
    with container:
        if not container.streams.audio:
            raise InputError(f"{name}: has no sound track; record with sound, or give the sound file")
        stream = container.streams.audio[0]
        blocks, start, decoded = [], None, 0
        try:
            for frame in container.decode(stream):
                if start is None and frame.pts is not None and frame.time_base is not None:
                    start = float(frame.pts * frame.time_base)
                block = frame.to_ndarray()
                # planar formats give (channels, n); packed ones (1, n × channels)
                block = block.T if frame.format.is_planar else block.reshape(-1, len(frame.layout.channels))
                blocks.append(_full_scale(block))
                rate = frame.sample_rate
                decoded += block.shape[0]  # counted as decoded: a container's duration may lie
                _check_size(name, decoded, block.shape[1], rate, whole=False)
        except av.FFmpegError as error:
            if not blocks:
                raise InputError(f"{name}: its sound track cannot be decoded ({type(error).__name__}); export it "
                                 f"again") from None
        if not blocks:
            raise InputError(f"{name}: its sound track is empty; record with sound")
        codec = stream.codec_context.name
    return Sound(samples=np.concatenate(blocks), rate_hz=float(rate), start_s=(start or 0.0) if container_clock else 0.0,
                 codec=codec)


def _full_scale(block):
    """Samples as float64, full scale ±1 (integer formats divided by their largest value)."""
    if np.issubdtype(block.dtype, np.integer):
        info = np.iinfo(block.dtype)
        half = (info.max + 1) / 2 if info.min == 0 else info.max + 1.0  # unsigned 8-bit is centred on 128
        return (block.astype(np.float64) - (half if info.min == 0 else 0.0)) / half
    return block.astype(np.float64)
