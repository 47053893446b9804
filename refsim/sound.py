"""The sound of a simulated drop: what a microphone beside the floor records, with the exact impact times.

Written from the physics of the bounce alone (it shares no code with dropfit's onset detector). Each
touchdown of a :func:`refsim.simulate` truth starts a click: a few short decaying resonances of the
ball's shell and the floor (random frequencies 1.5-9 kHz, decay times 0.3-3 ms) whose amplitude grows
with the impact speed (∝ v_in^1.5: the force pulse of a harder hit is higher and shorter). The
recording adds what makes real ones hard: a room echo (one or two delayed, attenuated, low-passed
copies), an optional second click just after the first (a double click: a rattle or a spinning ball
touching twice), white background noise, low-frequency hum, and a microphone that clips.

The click starts at the touchdown plus the sound's travel time from the floor to the microphone
(``mic_distance_m`` / 343 m/s), the same for every impact. Everything random comes from one seeded
generator.

>>> import refsim
>>> from refsim.sound import render_sound
>>> truth = refsim.simulate("table_tennis", drop_height_m=0.5, t_end_s=4.0)
>>> sound = render_sound(truth, rate_hz=44100, seed=0)
>>> sound.samples.shape, sound.onsets_s[:2]   # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

SPEED_OF_SOUND_M_S = 343.0


@dataclass
class SoundOptions:
    """How the recording is made (all times in s, levels relative to full scale 1).

    Attributes
    ----------
    rate_hz : float
        Sample rate in Hz.
    peak_level : float
        Peak amplitude of the loudest click before clipping (full scale = 1).
    noise_level : float
        Standard deviation of the white background noise (full scale = 1).
    hum_level : float
        Amplitude of a 50 Hz hum with harmonics.
    echo_delays_s, echo_gains : tuple of float
        Delay (s) and relative amplitude of each room echo.
    double_click_probability : float
        Chance that an impact has a second, weaker click 0.2-1.5 ms after the first.
    clip_level : float
        The microphone clips at ± this level (full scale = 1); 1 = no clipping beyond the format's.
    mic_distance_m : float
        Distance from the impact point to the microphone (m).
    lead_s, tail_s : float
        Silence recorded before the release and after the last impact (s).
    channels : int
        1 (mono) or 2 (stereo: the second channel a slightly delayed, quieter copy).
    """

    rate_hz: float = 44100.0
    peak_level: float = 0.5
    noise_level: float = 0.002
    hum_level: float = 0.0
    echo_delays_s: tuple = (0.0047, 0.0113)
    echo_gains: tuple = (0.35, 0.15)
    double_click_probability: float = 0.0
    clip_level: float = 1.0
    mic_distance_m: float = 0.3
    lead_s: float = 0.2
    tail_s: float = 0.3
    channels: int = 1


@dataclass
class Sound:
    """A rendered recording and its truth.

    Attributes
    ----------
    samples : numpy.ndarray
        Shape (n,) or (n, channels), float in [−1, 1].
    rate_hz : float
        Sample rate in Hz.
    onsets_s : numpy.ndarray
        The true start of each click on the recording's clock (s): touchdown + travel time.
    impacts : pandas.DataFrame
        The truth's impacts (touchdown, lift-off, v_in, v_out, e, heights) with ``onset_s`` added.
    truth : object
        The :class:`refsim.ball.Truth` rendered.
    options : SoundOptions
    """

    samples: np.ndarray
    rate_hz: float
    onsets_s: np.ndarray
    impacts: pd.DataFrame
    truth: object
    options: SoundOptions = field(default_factory=SoundOptions)


def _click(rng, rate_hz, duration_s=0.02):
    """One click's waveform (peak 1): two to four decaying resonances, each starting at phase zero so
    that the click starts from silence at its first sample and rises within a fraction of a period."""
    n = int(duration_s * rate_hz)
    t = np.arange(n) / rate_hz
    wave = np.zeros(n)
    for _ in range(rng.integers(2, 5)):
        frequency = rng.uniform(1500.0, 9000.0)
        decay = rng.uniform(0.3e-3, 3e-3)
        wave += rng.uniform(0.3, 1.0) * np.exp(-t / decay) * np.sin(2 * np.pi * frequency * t)
    return wave / np.max(np.abs(wave))


def _add(signal, wave, start_s, rate_hz):
    """Add ``wave`` to ``signal`` starting at time ``start_s`` (s), at sub-sample precision (the wave
    is evaluated by linear interpolation on the shifted grid)."""
    position = start_s * rate_hz
    first = int(np.ceil(position))
    grid = np.arange(first, min(first + wave.size + 1, signal.size))
    offset = grid - position  # samples after the start, fractional
    signal[grid] += np.interp(offset, np.arange(wave.size), wave, left=0.0, right=0.0)


def _lowpass(wave, rate_hz, cutoff_hz):
    """A one-pole low-pass (the air and the walls absorb the highs of an echo)."""
    from scipy.signal import lfilter

    alpha = 1.0 - np.exp(-2 * np.pi * cutoff_hz / rate_hz)
    return lfilter([alpha], [1.0, alpha - 1.0], wave)


def render_sound(truth, options=None, seed=0, **overrides):
    """The microphone's recording of a simulated drop.

    Parameters
    ----------
    truth : refsim.ball.Truth
        A simulated drop (:func:`refsim.simulate`).
    options : SoundOptions, optional
        How it is recorded; ``overrides`` replace fields of it.
    seed : int
        Seed of every random choice.

    Returns
    -------
    Sound
    """
    options = options or SoundOptions()
    if overrides:
        options = SoundOptions(**{**options.__dict__, **overrides})
    rng = np.random.default_rng(seed)
    rate = options.rate_hz
    impacts = truth.impacts.copy()
    travel = options.mic_distance_m / SPEED_OF_SOUND_M_S
    onsets = impacts["t_touchdown_s"].to_numpy() + travel + options.lead_s - truth.t_release_s
    impacts["onset_s"] = onsets
    duration = onsets[-1] + options.tail_s if onsets.size else options.lead_s + options.tail_s
    signal = np.zeros(int(np.ceil(duration * rate)) + 1)
    loudest = impacts["v_in_m_s"].max() if onsets.size else 1.0
    for onset, speed in zip(onsets, impacts["v_in_m_s"]):
        amplitude = options.peak_level * (speed / loudest) ** 1.5
        wave = amplitude * _click(rng, rate)
        _add(signal, wave, onset, rate)
        if rng.random() < options.double_click_probability:
            _add(signal, rng.uniform(0.2, 0.6) * amplitude * _click(rng, rate), onset + rng.uniform(0.2e-3, 1.5e-3),
                 rate)
        for delay, gain in zip(options.echo_delays_s, options.echo_gains):
            _add(signal, gain * _lowpass(wave, rate, 3000.0), onset + delay, rate)
    t = np.arange(signal.size) / rate
    if options.hum_level:
        signal += options.hum_level * (np.sin(2 * np.pi * 50 * t) + 0.3 * np.sin(2 * np.pi * 150 * t + 1.0))
    signal += rng.normal(0.0, options.noise_level, signal.size)
    signal = np.clip(signal, -options.clip_level, options.clip_level)
    if options.channels == 2:
        other = np.zeros_like(signal)
        _add(other, 0.7 * signal, 0.4e-3, rate)  # the second microphone 14 cm further away
        signal = np.column_stack([signal, np.clip(other + rng.normal(0.0, options.noise_level, signal.size),
                                                  -options.clip_level, options.clip_level)])
    return Sound(samples=np.clip(signal, -1.0, 1.0), rate_hz=rate, onsets_s=onsets, impacts=impacts, truth=truth,
                 options=options)


def write_sound(sound, path, subtype=None):
    """Write a :class:`Sound` with soundfile (WAV, FLAC or OGG by the suffix; 16-bit PCM for WAV/FLAC)."""
    import soundfile

    soundfile.write(str(path), sound.samples, int(round(sound.rate_hz)), subtype=subtype)


#: The bundled synthetic recording of the workflow: a table-tennis ball dropped from 40 cm beside a phone
#: in a room, with an echo, a few double clicks, some hum and a microphone that clips on the first click.
DEFAULT_RECORDING = {"ball": "table_tennis", "drop_height_m": 0.4, "t_end_s": 6.0,
                     "options": {"rate_hz": 44100.0, "peak_level": 0.9, "noise_level": 0.003, "hum_level": 0.01,
                                 "double_click_probability": 0.2, "clip_level": 0.6}}


def main(argv=None):
    """``python -m refsim.sound --out X.wav --truth X.truth.json [--seed N]``: the default recording."""
    import argparse
    import json

    from .ball import simulate

    parser = argparse.ArgumentParser(description="render the bundled synthetic drop-test sound and its truth")
    parser.add_argument("--out", required=True, help="sound file to write (.wav, .flac or .ogg)")
    parser.add_argument("--truth", required=True, help="ground truth to write (JSON)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    spec = DEFAULT_RECORDING
    truth = simulate(spec["ball"], drop_height_m=spec["drop_height_m"], t_end_s=spec["t_end_s"])
    sound = render_sound(truth, SoundOptions(**spec["options"]), seed=args.seed)
    write_sound(sound, args.out)
    record = {"seed": args.seed, **spec, "g_m_s2": truth.g_m_s2, "drag_k_1_m": truth.drag_k_1_m,
              "release_time_s": sound.options.lead_s,
              "onsets_s": sound.onsets_s.tolist(), "e": sound.impacts["e"].tolist(),
              "v_in_m_s": sound.impacts["v_in_m_s"].tolist()}
    with open(args.truth, "w", encoding="utf-8") as handle:
        json.dump(record, handle, indent=1)


if __name__ == "__main__":
    main()
