"""Impact times and e from sound: a phyphox-like threshold, an envelope threshold and dropfit, side by side.

Every method runs on the same seeded synthetic recordings rendered by ``refsim/sound.py`` (written
independently of dropfit: each touchdown of refsim's table-tennis ball starts a click of a few decaying
resonances, with a room echo 4.7 and 11.3 ms later, white noise and, per scenario, double clicks,
hum, a clipping microphone or AAC compression), drops from 0.3-1 m, 44.1 kHz:

* ``clean``       — echo and 0.002 noise only;
* ``noisy``       — noise 0.01 and 50 Hz hum;
* ``double clicks`` — a second click 0.2-1.5 ms after half of them;
* ``clipped``     — the microphone clips at 0.15 of full scale;
* ``AAC``         — the clean recording through PyAV's AAC encoder (.m4a), as phones store sound.

The methods:

* ``phyphox-like`` — phyphox's "(In)elastic collision": the loudest sample of each sound above a
  threshold (0.1 of the loudest click here, phyphox's default 0.1 of full scale scaled to the
  recording), at least 0.1 s after the previous one (its minimum delay), at most 6 impacts; e from
  the flight-time ratio T₍ₙ₊₁₎/Tₙ (phyphox's energy ratio is its square), no drag, no contact time;
* ``envelope threshold`` — the first sample where a 1 ms RMS envelope exceeds 8 noise σ, 20 ms dead
  time after; e from the flight-time ratio;
* ``dropfit`` — :func:`dropfit.analyse_recording` (onsets refined below a sample, the chain of clicks
  of a bouncing ball, flights with the ball's drag and contact time).

Impact-time error: each method's times against the true onsets (nearest within 5 ms; a true impact
among the first six with none counts as missed), less the method's median offset (a constant offset
cancels in every flight time); reported as the RMS flight-time error (difference of consecutive
errors). e error: e_estimated − e_true over impacts 2-5 (those phyphox reports). Wall time: one call
on one recording (dropfit's includes decoding the file and the whole analysis: what `dropfit run` does
before writing; the thresholds get the decoded samples), the three in rotating order, REPEATS times;
the median.

Output: a printed table, ``benchmarks/audio_onsets.csv`` and ``benchmarks/audio_onsets.png``.

Run (about a minute on a quiet 2-core machine; seeded):

    PYTHONPATH=src:. python benchmarks/audio_onsets.py [SEEDS] [REPEATS]

(defaults 10 seeds per scenario, 3 repeats).
"""

from __future__ import annotations

import csv
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import refsim
from refsim.sound import render_sound, write_sound

from dropfit import analyse_recording
from dropfit.audio.decode import read_sound
from dropfit.errors import InputError
from dropfit.numerics import robust_sigma

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks"
G = 9.81
BALL = {"ball_type": "table_tennis", "ball_radius_m": 0.02, "ball_mass_kg": 0.0027}
SCENARIOS = {
    "clean": {},
    "noisy": {"noise_level": 0.01, "hum_level": 0.05},
    "double clicks": {"double_click_probability": 0.5},
    "clipped": {"clip_level": 0.15},
    "AAC": {"aac": True},
}
SCORED = range(1, 5)  # impacts 2-5, 0-based


def phyphox_like(samples, rate_hz, threshold=0.1, min_delay_s=0.1, max_impacts=6):
    """Times (s) of the loudest sample of each sound above ``threshold`` × the loudest sample."""
    level = np.abs(samples)
    level = level.max(axis=1) if level.ndim == 2 else level
    above = np.flatnonzero(level > threshold * level.max())
    times, last = [], -np.inf
    for index in above:
        if index / rate_hz - last < min_delay_s:
            continue
        window = level[index:index + int(min_delay_s * rate_hz)]
        loudest = index + int(np.argmax(window[: int(0.005 * rate_hz)]))  # phyphox's block is a few ms
        times.append(loudest / rate_hz)
        last = index / rate_hz
        if len(times) == max_impacts:
            break
    return np.asarray(times)


def envelope_threshold(samples, rate_hz, factor=8.0, dead_s=0.02):
    """Times (s) where a 1 ms RMS envelope first exceeds ``factor`` noise σ, with a dead time after."""
    mono = samples.mean(axis=1) if samples.ndim == 2 else samples
    width = int(1e-3 * rate_hz)
    rms = np.sqrt(np.convolve(mono**2, np.ones(width) / width, mode="same"))
    above = np.flatnonzero(rms > np.median(rms) + factor * robust_sigma(rms))
    times, last = [], -np.inf
    for index in above:
        if index / rate_hz - last >= dead_s:
            times.append(index / rate_hz)
            last = index / rate_hz
    return np.asarray(times)


def ratio_e(times):
    """e per impact (from the second) from the flight-time ratio: e_n = T_n / T_(n-1)."""
    flights = np.diff(times)
    return np.r_[np.nan, flights[1:] / flights[:-1]]


def score(times, e, truth_onsets, truth_e):
    """(flight-time errors in s, e errors, impacts missed among the first six)."""
    if times.size == 0:
        return np.array([]), np.array([]), 6
    index = np.array([int(np.argmin(np.abs(truth_onsets - t))) for t in times])
    close = np.abs(times - truth_onsets[index]) < 5e-3
    errors = np.full(6, np.nan)
    e_errors = np.full(6, np.nan)
    for position, (i, ok) in enumerate(zip(index, close)):
        if ok and i < 6:
            errors[i] = times[position] - truth_onsets[i]
            e_errors[i] = e[position] - truth_e[i] if position < len(e) else np.nan
    missed = int(np.isnan(errors).sum())
    if missed == errors.size:
        return np.array([]), np.array([]), missed
    flight_errors = np.diff(errors - np.nanmedian(errors))
    return flight_errors[np.isfinite(flight_errors)], e_errors[list(SCORED)][np.isfinite(e_errors[list(SCORED)])], \
        missed


def recording(seed, options, directory):
    rng = np.random.default_rng(seed)
    truth = refsim.simulate("table_tennis", drop_height_m=rng.uniform(0.3, 1.0), t_end_s=4.0, g_m_s2=G)
    options = dict(options)
    aac = options.pop("aac", False)
    sound = render_sound(truth, seed=seed, mic_distance_m=0.0, **options)
    path = Path(directory) / (f"r{seed}.m4a" if aac else f"r{seed}.wav")
    if aac:
        encode_aac(path, sound.samples, sound.rate_hz)
    else:
        write_sound(sound, path)
    return path, sound, truth


def encode_aac(path, samples, rate_hz):
    import av

    with av.open(str(path), "w") as container:
        stream = container.add_stream("aac", rate=int(rate_hz), layout="mono")
        for start in range(0, samples.size, 1024):
            block = samples[start:start + 1024].astype(np.float32)[None, :]
            frame = av.AudioFrame.from_ndarray(block, format="flt", layout="mono")
            frame.sample_rate, frame.pts = int(rate_hz), start
            for packet in stream.encode(frame):
                container.mux(packet)
        for packet in stream.encode(None):
            container.mux(packet)


def main(seeds=10, repeats=3):
    rows = []
    with tempfile.TemporaryDirectory() as directory:
        for name, options in SCENARIOS.items():
            collected = {method: {"flight": [], "e": [], "missed": 0, "seconds": []} for method in METHODS}
            for seed in range(seeds):
                path, sound, truth = recording(seed, options, directory)
                decoded = read_sound(path)
                truth_e = truth.impacts["e"].to_numpy()
                order = list(METHODS)
                for repeat in range(repeats):
                    order = order[1:] + order[:1]
                    for method in order:
                        start = time.perf_counter()
                        try:
                            times, e = METHODS[method](path, decoded)
                        except InputError:
                            times, e = np.array([]), np.array([])
                        collected[method]["seconds"].append(time.perf_counter() - start)
                        if repeat == 0:
                            # a constant offset (a codec's delay, the clock's origin) is taken out by score
                            flight, e_error, missed = score(times, e, sound.onsets_s, truth_e)
                            collected[method]["flight"].extend(flight)
                            collected[method]["e"].extend(e_error)
                            collected[method]["missed"] += missed
            for method, data in collected.items():
                flight, e_error = np.asarray(data["flight"]), np.asarray(data["e"])
                rows.append({"scenario": name, "method": method,
                             "flight_time_rms_ms": 1e3 * float(np.sqrt(np.mean(flight**2))) if flight.size else np.nan,
                             "e_rms": float(np.sqrt(np.mean(e_error**2))) if e_error.size else np.nan,
                             "e_bias": float(np.mean(e_error)) if e_error.size else np.nan,
                             "missed_of_first_six": data["missed"], "recordings": seeds,
                             "median_ms": 1e3 * statistics.median(data["seconds"])})
    return rows


def run_phyphox_like(path, sound):
    times = phyphox_like(sound.samples, sound.rate_hz)
    return times, ratio_e(times)


def run_envelope_threshold(path, sound):
    times = envelope_threshold(sound.samples, sound.rate_hz)
    return times, ratio_e(times)


def run_dropfit(path, sound):
    result = analyse_recording(path, gravity_m_s2=G, **BALL)
    return result.impacts["t_touchdown_s"].to_numpy(), result.impacts["e"].to_numpy()


METHODS = {"phyphox-like": run_phyphox_like, "envelope threshold": run_envelope_threshold, "dropfit": run_dropfit}


def write(rows):
    with open(OUT / "audio_onsets.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({key: f"{value:.4g}" if isinstance(value, float) else value for key, value in row.items()})
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenarios = list(SCENARIOS)
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.5), layout="constrained")
    width = 0.27
    for position, method in enumerate(METHODS):
        picked = [next(row for row in rows if row["scenario"] == s and row["method"] == method) for s in scenarios]
        x = np.arange(len(scenarios)) + (position - 1) * width
        for axis, key in zip(axes, ("flight_time_rms_ms", "e_rms", "median_ms")):
            axis.bar(x, [row[key] for row in picked], width, label=method)
    for axis, label in zip(axes, ("flight-time error, RMS (ms)", "e error, RMS (1)", "wall time per recording (ms)")):
        axis.set_yscale("log")
        axis.set_xticks(np.arange(len(scenarios)), scenarios, rotation=20)
        axis.set_ylabel(label)
    axes[0].legend(fontsize=8)
    fig.suptitle("Impact times and e from sound: refsim table-tennis drops, 44.1 kHz (benchmarks/audio_onsets.py)")
    fig.savefig(OUT / "audio_onsets.png", dpi=100)


if __name__ == "__main__":
    arguments = [int(value) for value in sys.argv[1:]]
    result = main(*arguments)
    write(result)
    print(f"{'scenario':14s} {'method':19s} {'flight rms ms':>13s} {'e rms':>8s} {'e bias':>8s} {'missed':>6s} "
          f"{'ms/rec':>7s}")
    for row in result:
        print(f"{row['scenario']:14s} {row['method']:19s} {row['flight_time_rms_ms']:13.3f} {row['e_rms']:8.4f} "
              f"{row['e_bias']:8.4f} {row['missed_of_first_six']:6d} {row['median_ms']:7.1f}")
