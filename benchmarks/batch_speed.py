"""Batch throughput of the workflow: wall time per recording for batches of height logs and of videos.

In a temporary directory holding a copy of the workflow (Snakefile, workflow/, config/), a generated
sample sheet names N recordings, every row the same committed height log
(``data/synthetic/tennis_lot_A_ball1_drop1.csv``: 254 cm drop, 2 bounces, 100 Hz) under its own
sample_id, all in one batch; ``snakemake --cores 2`` then makes every file of every recording (trajectory,
impacts, flights, analysis, fit, report page and figure), the batch summary and the QC page, from no
results. Timed is the whole command (Snakemake's start-up and planning included), per batch size N
(10, 64, 100 and 1000 by default), the median over the repeats where repeated. The videos are N copies
of the 2000 fps close-up of the default synthetic clips (``contact_2000fps_closeup``, 60 frames of
640 × 480), rendered once beforehand and not timed.

Snakemake's start-up (``snakemake --version``, median of 3) is measured too: it is part of every batch, and
on a machine where SLURM's client tools are installed but no controller answers, the SLURM executor
plugin waits up to 10 s at each start for ``scontrol show config`` (the benchmark prints a warning then).

For comparison, in the same run: one ``dropfit analyse`` call (a new process: start-up, imports, the
analysis of that log's trajectory, made beforehand by ``dropfit measure``), called 16 times in a row;
its median. The issue's targets: 64 logs cost no more than 16 single ``dropfit analyse`` calls, 1000
logs well under 10 minutes on 2 cores, and the cost linear in the number of recordings (the per-recording
time flat in N).

Output: a printed table, ``benchmarks/batch_speed.csv`` (columns case, recordings, repeats, wall_s,
wall_per_recording_s; wall_s the median) and ``benchmarks/batch_speed.png`` (wall time per recording
against N, log x; the 16-call comparison as a line).

Run (about 18 minutes on a shared 2-core machine; the 1000-log batch takes half):

    python benchmarks/batch_speed.py [--sizes 10 64 100 1000] [--videos 10] [--repeats 3]

Run it from the repository root with ``PYTHONPATH=src`` (or dropfit installed): the jobs run the
``dropfit`` on the PATH and the Python of this process.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

ROOT = Path(__file__).resolve().parent.parent
OUT_CSV = ROOT / "benchmarks" / "batch_speed.csv"
OUT_PNG = ROOT / "benchmarks" / "batch_speed.png"
#: The height log every row of a log batch names.
LOG = "data/synthetic/tennis_lot_A_ball1_drop1.csv"
#: The short video every row of a video batch names (a default synthetic clip).
CLIP = "contact_2000fps_closeup"
#: Columns of the generated sample sheets: the lot's tennis ball.
BALL = {"ball_type": "tennis", "ball_radius_m": 0.0335, "ball_mass_kg": 0.057, "batch": "bench"}
#: Single dropfit analyse calls timed for the comparison.
SINGLE_CALLS = 16
#: Largest log batch repeated (the larger ones run once: on a shared machine, the 1000-log batch once).
REPEATED_UP_TO = 64


def write_sheet(path, count, recording, kind, name):
    """A sample sheet of ``count`` rows, all ``recording``, sample ids ``<name>_<i>``."""
    rows = [{"sample_id": f"{name}_{i:04d}", "kind": kind, "path": recording, **BALL} for i in range(count)]
    pd.DataFrame(rows).to_csv(path, sep="\t", index=False)


def timed(command, cwd):
    """Wall time in s of ``command`` (list) in ``cwd``; a failure stops the benchmark with its output."""
    start = time.perf_counter()
    result = subprocess.run(command, cwd=cwd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - start
    if result.returncode != 0:
        sys.exit(f"{' '.join(command)} failed:\n{result.stderr[-3000:]}")
    return wall


def workflow_wall(work, sheet, cores):
    """Wall time in s of the workflow on ``sheet`` from no results."""
    for name in ("results", ".snakemake"):
        shutil.rmtree(work / name, ignore_errors=True)
    return timed(["snakemake", "--cores", str(cores), "--config", f"samples={sheet}", "--quiet", "all"], work)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 64, 100, 1000], help="log batch sizes")
    parser.add_argument("--videos", type=int, default=10, help="videos in the video batch (0: none)")
    parser.add_argument("--repeats", type=int, default=3, help=f"repeats of batches up to {REPEATED_UP_TO}")
    parser.add_argument("--cores", type=int, default=2, help="snakemake --cores")
    args = parser.parse_args(argv)

    from dropfit.video_synth import make_default_videos

    rows = []
    with tempfile.TemporaryDirectory(prefix="dropfit-batch-speed.") as directory:
        work = Path(directory)
        shutil.copy2(ROOT / "Snakefile", work / "Snakefile")
        for name in ("workflow", "config", "data"):
            shutil.copytree(ROOT / name, work / name, ignore=shutil.ignore_patterns("__pycache__"))
        (work / "bench").mkdir()

        # the comparison: single dropfit analyse calls on the log's trajectory
        timed(["dropfit", "measure", LOG, "--out=bench/one.nc", "--ball-radius-m=0.0335", "--ball-mass-kg=0.057"],
              work)
        calls = [timed(["dropfit", "analyse", "bench/one.nc", "--impacts=bench/i.csv", "--flights=bench/f.csv",
                        "--summary=bench/a.json"], work) for _ in range(SINGLE_CALLS)]
        single = statistics.median(calls)
        rows.append({"case": "single dropfit analyse", "recordings": 1, "repeats": SINGLE_CALLS, "wall_s": single,
                     "wall_per_recording_s": single})
        print(f"dropfit analyse, one call: {single:.2f} s (median of {SINGLE_CALLS}); "
              f"{SINGLE_CALLS} calls: {SINGLE_CALLS * single:.1f} s")

        # Snakemake's own start-up, in every batch's wall time: on a machine with SLURM's client tools but no
        # controller answering, the SLURM executor plugin waits up to 10 s for `scontrol show config` here
        startup = statistics.median(timed(["snakemake", "--version"], work) for _ in range(3))
        rows.append({"case": "snakemake --version", "recordings": 0, "repeats": 3, "wall_s": startup,
                     "wall_per_recording_s": float("nan")})
        print(f"snakemake start-up: {startup:.2f} s (median of 3)"
              + ("; SLURM's scontrol does not answer: every snakemake run waits for it" if startup > 5 else ""))

        cases = [("height logs", size, LOG, "height_log") for size in args.sizes]
        if args.videos:
            make_default_videos(work / "bench", names=[CLIP])
            cases.append(("videos", args.videos, f"bench/{CLIP}.avi", "video"))
        for case, size, recording, kind in cases:
            sheet = f"bench/{kind}_{size}.tsv"
            write_sheet(work / sheet, size, recording, kind, kind)
            repeats = args.repeats if size <= REPEATED_UP_TO and kind == "height_log" else 1
            walls = [workflow_wall(work, sheet, args.cores) for _ in range(repeats)]
            wall = statistics.median(walls)
            rows.append({"case": case, "recordings": size, "repeats": repeats, "wall_s": wall,
                         "wall_per_recording_s": wall / size})
            print(f"{case:>12} {size:5d}: {wall:7.1f} s, {wall / size:6.3f} s per recording "
                  f"(median of {repeats}: {', '.join(f'{w:.1f}' for w in walls)})")

    table = pd.DataFrame(rows)
    table.to_csv(OUT_CSV, index=False, float_format="%.4g")
    logs = table[table["case"] == "height logs"].set_index("recordings")
    if 64 in logs.index:
        verdict = "met" if logs.loc[64, "wall_s"] <= SINGLE_CALLS * single else "NOT met"
        print(f"64 logs: {logs.loc[64, 'wall_s']:.1f} s against {SINGLE_CALLS} single calls "
              f"{SINGLE_CALLS * single:.1f} s: target {verdict}")
    if 1000 in logs.index:
        print(f"1000 logs: {logs.loc[1000, 'wall_s'] / 60:.1f} min (target: well under 10 min)")
    plot(table, single)


def plot(table, single):
    """Wall time per recording against batch size, with the single-call comparison."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5), layout="constrained")
    for case, marker in (("height logs", "o"), ("videos", "s")):
        part = table[table["case"] == case]
        if len(part):
            ax.plot(part["recordings"], part["wall_per_recording_s"], marker=marker, label=f"workflow, {case}")
    ax.axhline(single, color="grey", linestyle="--", label="one dropfit analyse call (new process)")
    ax.axhline(SINGLE_CALLS * single / 64, color="grey", linestyle=":",
               label=f"target for 64 logs: {SINGLE_CALLS} analyse calls / 64")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("recordings in the batch")
    ax.set_ylabel("wall time per recording (s), snakemake --cores 2")
    ax.set_title("dropfit workflow: batch throughput")
    ax.legend(fontsize=8)
    fig.savefig(OUT_PNG, dpi=110)


if __name__ == "__main__":
    main()
