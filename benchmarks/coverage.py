"""Coverage of every reported 95 % interval over seeded synthetic height logs.

For each scenario of :data:`dropfit.coverage.SCENARIOS` it analyses N seeded logs (seeds 0 … N−1)
and prints, per quantity, how often the 95 % interval covered the generator's truth, and the mean
and spread of (value − truth)/se (0 and 1 when the standard errors are right), and how often each
drag model and e(v) law was chosen. It writes the table
to ``benchmarks/coverage.csv``.

With ``--videos N`` it instead renders, tracks and analyses N small seeded clips
(:func:`dropfit.coverage.video_trial`, scale and floor given), lists those dropfit refuses, and writes
``benchmarks/video_coverage.csv``.

    python benchmarks/coverage.py [N]
    python benchmarks/coverage.py --videos [N]
"""

import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from dropfit.coverage import SCENARIOS, coverage_table, log_trial, video_trial
from dropfit.errors import InputError


def videos(trials):
    start = time.perf_counter()
    pairs, refused = [], []
    with tempfile.TemporaryDirectory() as directory:
        for seed in range(trials):
            try:
                pairs.append(video_trial(seed, directory))
            except InputError as error:  # refused, as the workflow would refuse it
                refused.append(f"seed {seed}: {error}")
    table = coverage_table(pd.concat(pairs))
    print(f"{trials} seeded clips; {(time.perf_counter() - start) / trials:.2f} s per clip (render, track, analyse)")
    print(f"{len(refused)} refused" + "".join(f"\n  {line}" for line in refused))
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3f}"))
    table.to_csv(Path(__file__).with_name("video_coverage.csv"), index=False, float_format="%.4f")


def main():
    if "--videos" in sys.argv:
        arguments = [a for a in sys.argv[1:] if a != "--videos"]
        videos(int(arguments[0]) if arguments else 200)
        return
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    frames, seconds, choices = [], {}, {}
    for name, scenario in SCENARIOS.items():
        start = time.perf_counter()
        for seed in range(trials):
            pairs, fitted = log_trial(scenario, seed)
            frames.append(pairs.assign(scenario=name))
            chosen = (fitted["drag"]["model"], fitted["restitution"]["model"])
            choices.setdefault(name, {}).setdefault(chosen, 0)
            choices[name][chosen] += 1
        seconds[name] = (time.perf_counter() - start) / trials
    table = coverage_table(pd.concat(frames))
    print(f"{trials} seeded logs per scenario; seconds per log: "
          + ", ".join(f"{name} {value:.3f}" for name, value in seconds.items()))
    for name, counts in choices.items():
        print(f"{name}: chosen (drag, e(v)) " + ", ".join(f"{key}: {count}" for key, count in counts.items()))
    print(table.to_string(index=False, float_format=lambda x: f"{x:.3f}"))
    table.to_csv(Path(__file__).with_suffix(".csv"), index=False, float_format="%.4f")


if __name__ == "__main__":
    main()
