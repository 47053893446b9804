"""Cost of ``dropfit analyse`` against the length of a height log: wall time and peak memory.

Part 1, rows. The ``tennis_itf`` scenario of ``data/synthetic/scenarios.yaml`` (seed 1, 1 mm noise)
is sampled for 10 s at 1, 10 and 100 kHz: 10⁴, 10⁵ and 10⁶ rows. Each log is measured once
(``dropfit measure``) and analysed ``RUNS`` times as the workflow's job does, one ``dropfit analyse``
process each; the median wall time and the median peak resident memory of that process (its own
``ru_maxrss``, start-up included) are written to ``analysis_speed.csv`` and drawn in
``analysis_speed.png`` with the workflow profile's ``mem_mb`` (1000 MB). Time and memory should grow
linearly with the rows (the flights of a log over ``dropfit.analysis.flights.LONG_LOG_SAMPLES`` used
samples are fitted with a sparse Jacobian).

Part 2, impacts. The committed steel-ball log (``data/synthetic/steel_ball.csv``: 10 s at 100 Hz, 24
impacts) cut after 2.5, 5 and 10 s and analysed in this process (:func:`dropfit.analyse_trajectory`):
the time per impact stays about constant when the cost grows linearly with the flights (printed only).

BLAS threads matter on a busy machine: compare runs made with the same ``OPENBLAS_NUM_THREADS``.

    PYTHONPATH=src OPENBLAS_NUM_THREADS=1 python benchmarks/analysis_speed.py
"""

import csv
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from dropfit import Ball, analyse_trajectory, measure_recording

HERE = Path(__file__).resolve().parent
DATA = HERE.parent / "data" / "synthetic"
LOG = DATA / "steel_ball.csv"
DURATIONS_S = (2.5, 5.0, 10.0)
RUNS = 3
#: Sample rates (Hz) of the 10 s logs: 10⁴, 10⁵ and 10⁶ rows.
RATES_HZ = (1_000, 10_000, 100_000)
LOG_DURATION_S = 10.0
PROFILE_MEM_MB = 1000


def timed(command):
    """(wall time in s, peak resident memory in MB) of one process, which must succeed."""
    start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(process.pid, 0)
    seconds = time.perf_counter() - start
    process.returncode = os.waitstatus_to_exitcode(status)
    if process.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, command))} failed with status {process.returncode}")
    return seconds, usage.ru_maxrss / 1024.0  # ru_maxrss is in KiB on Linux


def rows_benchmark(directory):
    """One row per log length: rows, median wall time (s) and peak memory (MB) of ``dropfit analyse``."""
    scenario = yaml.safe_load((DATA / "scenarios.yaml").read_text())["scenarios"]["tennis_itf"]
    dropfit = [sys.executable, "-m", "dropfit"]
    rows = []
    for rate in RATES_HZ:
        scenario = {**scenario, "duration_s": LOG_DURATION_S, "sensor": {**scenario["sensor"], "sample_rate_hz": rate}}
        name = f"tennis_{rate}hz"
        scenarios = directory / f"{name}.yaml"
        scenarios.write_text(yaml.safe_dump({"scenarios": {name: scenario}}))
        log, trajectory = directory / f"{name}.csv", directory / f"{name}.nc"
        subprocess.run([*dropfit, "synth", "--scenarios", scenarios, "--name", name, "--log", log,
                        "--truth", directory / f"{name}.json"], check=True)
        subprocess.run([*dropfit, "measure", log, "--out", trajectory], check=True)
        runs = [timed([*dropfit, "analyse", trajectory, "--impacts", directory / "impacts.csv",
                       "--flights", directory / "flights.csv", "--summary", directory / "analysis.json"])
                for _ in range(RUNS)]
        seconds, memory = np.median(runs, axis=0)
        rows.append({"rows": int(rate * LOG_DURATION_S), "sample_rate_hz": rate, "runs": RUNS,
                     "median_wall_s": round(float(seconds), 2), "median_peak_rss_mb": round(float(memory), 1)})
        print(rows[-1], flush=True)
    return rows


def plot(rows, path):
    """Wall time and peak memory against rows, log-log, with a line of slope 1 through the first point."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = np.array([row["rows"] for row in rows], dtype=float)
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.6), constrained_layout=True)
    for axis, key, label in ((axes[0], "median_wall_s", "wall time of dropfit analyse (s)"),
                             (axes[1], "median_peak_rss_mb", "peak memory of the process (MB)")):
        value = np.array([row[key] for row in rows])
        axis.loglog(n, value, "o-", label="measured (median of %d)" % RUNS)
        axis.loglog(n, value[0] * n / n[0], ":", color="grey", label="linear in rows")
        axis.set_xlabel("rows of the height log")
        axis.set_ylabel(label)
    axes[1].axhline(PROFILE_MEM_MB, color="tab:red", lw=1, label="workflow profile mem_mb")
    for axis in axes:
        axis.legend(fontsize=8)
    fig.suptitle("dropfit analyse on 10 s tennis_itf logs at 1, 10 and 100 kHz", fontsize=10)
    fig.savefig(path, dpi=120)
    plt.close(fig)


def impacts_benchmark():
    """Part 2: time per impact of the steel-ball log cut after DURATIONS_S (printed)."""
    trajectory = measure_recording(LOG, Ball(radius_m=0.0125, mass_kg=0.0642, type="steel"))
    time_s = trajectory["time"].values
    print(f"{'log s':>6} {'impacts':>8} {'median s':>9} {'s/impact':>9}")
    for duration in DURATIONS_S:
        part = time_s <= duration
        seconds = []
        for _ in range(RUNS):
            start = time.perf_counter()
            result = analyse_trajectory(trajectory.isel(time=part))
            seconds.append(time.perf_counter() - start)
        median = float(np.median(seconds))
        n = result.summary["n_impacts"]
        print(f"{duration:6.1f} {n:8d} {median:9.3f} {median / n:9.4f}")


def main():
    with tempfile.TemporaryDirectory() as directory:
        rows = rows_benchmark(Path(directory))
    with open(HERE / "analysis_speed.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    plot(rows, HERE / "analysis_speed.png")
    impacts_benchmark()


if __name__ == "__main__":
    main()
