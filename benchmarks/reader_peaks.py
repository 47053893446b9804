"""Peak memory of ``dropfit run`` on the largest input each bounded reader accepts, and just over each bound.

A workflow job has 1000 MB (``workflow/profiles/default``); each reader's bound is chosen so that the largest
input it accepts stays under it. Made here, in a temporary directory:

- height logs of :data:`dropfit.files.MAX_TABLE_LINES` lines: a tennis ball dropped from 0.5 m (e = 0.75,
  drag-free closed form, heights with 0.2 mm of seeded noise) logged at 1 MHz for one second, in dropfit's
  own columns and as a semicolon table with German names (the importers' path), and one line more;
- a Tracker project of :data:`dropfit.files.MAX_ARCHIVE_MEMBER_BYTES` of XML (empty tags, the most elements
  per byte);
- sound files of :data:`dropfit.audio.decode.MAX_SOUND_SAMPLES` samples at 48 kHz, mono and stereo (seeded
  noise and decaying 3 kHz clicks at a bouncing ball's impact times), and one second more.

Each runs ``python -m dropfit run`` in a new process that reports its peak resident memory (``VmHWM``).

Output: a printed table and ``benchmarks/reader_peaks.csv`` (columns input, bound, size, accepted, peak_mb,
wall_s, message). Run from the repository root (about 10-20 minutes on a shared 2-core machine, most of
it the two 10⁶-row logs):

    python benchmarks/reader_peaks.py
"""

from __future__ import annotations

import csv
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from dropfit.audio.decode import MAX_SOUND_SAMPLES
from dropfit.files import MAX_ARCHIVE_MEMBER_BYTES, MAX_TABLE_LINES

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))  # the peak-memory runner the bound tests use (tests/helpers.py)
G_M_S2 = 9.80665


def bouncing_heights(t, drop_m=0.5, e=0.75, radius_m=0.033):
    """Centre heights (m) of a ball dropped from rest at t = 0 from ``drop_m`` (bottom), drag-free, at ``t`` (s)."""
    impacts, speed = [np.sqrt(2 * drop_m / G_M_S2)], np.sqrt(2 * G_M_S2 * drop_m)
    while impacts[-1] < t[-1] and speed > 0.05:
        speed *= e
        impacts.append(impacts[-1] + 2 * speed / G_M_S2)
    impacts = np.array(impacts)
    flight = np.searchsorted(impacts, t)
    height = drop_m - 0.5 * G_M_S2 * t ** 2
    for index in range(1, impacts.size):
        inside = flight == index
        tau = t[inside] - impacts[index - 1]
        up = np.sqrt(2 * G_M_S2 * drop_m) * e ** index
        height[inside] = up * tau - 0.5 * G_M_S2 * tau ** 2
    return np.maximum(height, 0.0) + radius_m


def write_log(path, rows, header, separator):
    t = np.arange(rows) * 1e-6
    y = bouncing_heights(t) + np.random.default_rng(0).normal(0.0, 2e-4, rows)
    with open(path, "w", encoding="utf-8") as handle:
        handle.write(header + "\n")
        for start in range(0, rows, 100_000):
            handle.write("".join(f"{a:.6f}{separator}{b:.5f}\n" for a, b in zip(t[start:start + 100_000],
                                                                                 y[start:start + 100_000])))
    return path


def write_sound(path, samples, channels, rate_hz=48_000):
    import soundfile

    noise = np.random.default_rng(1).normal(0.0, 1e-3, samples)
    impact_s, speed = 0.5, 3.0
    click = np.arange(int(0.01 * rate_hz))
    while impact_s < samples / rate_hz - 0.1:
        start = int(impact_s * rate_hz)
        piece = 0.5 * np.exp(-click / (0.001 * rate_hz)) * np.sin(2 * np.pi * 3000 * click / rate_hz)
        noise[start:start + click.size] += piece[:noise.size - start]
        impact_s += 2 * speed / G_M_S2
        speed *= 0.9
        if speed < 0.3:  # the ball caught and dropped again, a second later
            speed, impact_s = 3.0, impact_s + 1.0
    soundfile.write(path, np.repeat(noise[:, None], channels, axis=1), rate_hz, subtype="PCM_16")
    return path


def write_project(path, size):
    head, tail = b"<?xml version='1.0' encoding='UTF-8'?>\n<object>", b"</object>\n"
    path.write_bytes(head + b"<a/>" * ((size - len(head) - len(tail)) // 4) + tail)
    return path


def measured(path, folder):
    from helpers import measured_dropfit

    started = time.perf_counter()
    done, peak_mb = measured_dropfit("run", path, "--out", folder / "out", cwd=folder, timeout_s=3600)
    wall = time.perf_counter() - started
    message = (done.stderr.strip().splitlines() or [""])[-1] if done.returncode else done.stdout.splitlines()[0]
    return done.returncode == 0, peak_mb, wall, message


def main():
    rows = []
    with tempfile.TemporaryDirectory() as temporary:
        folder = Path(temporary)
        inputs = [
            ("log, dropfit columns", "MAX_TABLE_LINES",
             lambda p: write_log(p, MAX_TABLE_LINES - 1, "time_s,y_m", ","), "log.csv"),
            ("log, German semicolon table", "MAX_TABLE_LINES",
             lambda p: write_log(p, MAX_TABLE_LINES - 1, "t (s);Höhe (m)", ";"), "table.csv"),
            ("log, one line over", "MAX_TABLE_LINES",
             lambda p: write_log(p, MAX_TABLE_LINES, "time_s,y_m", ","), "over.csv"),
            ("Tracker project, empty tags", "MAX_ARCHIVE_MEMBER_BYTES",
             lambda p: write_project(p, MAX_ARCHIVE_MEMBER_BYTES), "tags.trk"),
            ("sound, mono 48 kHz", "MAX_SOUND_SAMPLES", lambda p: write_sound(p, MAX_SOUND_SAMPLES, 1), "mono.wav"),
            ("sound, stereo 48 kHz", "MAX_SOUND_VALUES", lambda p: write_sound(p, MAX_SOUND_SAMPLES, 2), "stereo.wav"),
            ("sound, a second over", "MAX_SOUND_SAMPLES",
             lambda p: write_sound(p, MAX_SOUND_SAMPLES + 48_000, 1), "over.wav"),
        ]
        for name, bound, make, file_name in inputs:
            path = make(folder / file_name)
            accepted, peak_mb, wall, message = measured(path, folder)
            rows.append({"input": name, "bound": bound, "size": path.stat().st_size, "accepted": accepted,
                         "peak_mb": round(peak_mb), "wall_s": round(wall, 1), "message": message[:160]})
            print(f"{name:32s} {bound:26s} {rows[-1]['size'] / 2 ** 20:7.1f} MiB  "
                  f"{'accepted' if accepted else 'refused':8s} {peak_mb:6.0f} MB {wall:7.1f} s  {message[:100]}",
                  flush=True)
            path.unlink()
    with open(HERE / "reader_peaks.csv", "w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


if __name__ == "__main__":
    main()
