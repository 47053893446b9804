"""Time of :func:`dropfit.analysis.analyse_bounces` against the length of a height log.

The committed steel-ball log (``data/synthetic/steel_ball.csv``: 10 s at 100 Hz, 24 impacts,
image rows scaled to m by gravity, as ``dropfit measure`` does) is cut after 2.5, 5 and 10 s and
each piece is analysed as ``dropfit analyse`` does (:func:`dropfit.analyse_trajectory`); the median of three runs is printed with the
time per impact, which stays about constant when the cost grows linearly with the flights.

BLAS threads matter on a busy machine: the fit's dense SVD slows down many times over when
OpenBLAS threads compete for the cores, so compare runs made with the same
``OPENBLAS_NUM_THREADS``.

    PYTHONPATH=src python benchmarks/analysis_speed.py
"""

import time
from pathlib import Path

import numpy as np

from dropfit import Ball, analyse_trajectory, measure_recording

LOG = Path(__file__).resolve().parent.parent / "data" / "synthetic" / "steel_ball.csv"
DURATIONS_S = (2.5, 5.0, 10.0)
RUNS = 3


def main():
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


if __name__ == "__main__":
    main()
