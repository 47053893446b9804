"""Coverage of dropfit's 95 % intervals against refsim, a second, independently written generator.

For each scenario of ``tests/refsim_trials.py`` (tennis ball at 100 and 500 Hz, steel ball at 500 Hz,
rubber ball, table-tennis ball with its strong drag, glass marble tracked in px, tennis ball logged by
its bottom at 1–2 kHz) it simulates N seeded recordings with refsim (numerically integrated flights
and contacts; e falls with the impact speed), writes each as a user's CSV and analyses it with dropfit
exactly as the workflow does, with the floor given and with it unknown. Per scenario, floor condition
and quantity (per impact e, rebound height h_after_m, v_in, v_out, and the contact time where dropfit
resolves it) it reports how often |value − truth| ≤ 1.96 se, the mean and sd of z = (value − truth)/se,
and per scenario the recordings that failed (with their messages) and the impacts analysed against
those simulated.

    PYTHONPATH=$PWD/src:$PWD python benchmarks/refsim_coverage.py [N] [--workers W] [--scenarios a,b]

Writes ``benchmarks/refsim_coverage.csv`` (the coverage table), ``benchmarks/refsim_coverage_recordings.csv``
(impacts and failures per scenario and floor), ``benchmarks/refsim_coverage_failures.csv`` (each kind of
failure message) and the chart ``benchmarks/refsim_coverage.png``, and prints the README's tables;
``--pairs`` also keeps every pair in ``benchmarks/refsim_coverage_pairs.csv.gz``; ``--markdown``
prints the README's tables and redraws the chart from the CSVs already written.
"""

import argparse
import os
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))  # the shared trial module (tests/refsim_trials.py)

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

import refsim_trials  # noqa: E402

BAND = (0.90, 0.98)
QUANTITY_LABELS = {"e": "e", "h_after_m": "rebound height", "v_in_m_s": "v_in", "v_out_m_s": "v_out",
                   "t_contact_s": "contact time"}


def chart(table, summary, path):
    """Coverage per quantity × scenario, one panel per floor condition, with the 90–98 % band; below,
    the mean ± sd of z on a symmetric-log axis."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenarios = list(dict.fromkeys(summary["scenario"]))
    quantities = [q for q in QUANTITY_LABELS if q in set(table["quantity"])]
    fig, axes = plt.subplots(2, 2, figsize=(14, 9), sharex=True, sharey="row", gridspec_kw={"height_ratios": [3, 2]})
    width = 0.8 / len(quantities)
    colours = plt.get_cmap("tab10").colors
    for column, floor in enumerate(refsim_trials.FLOOR_CONDITIONS):
        top, bottom = axes[0, column], axes[1, column]
        top.axhspan(100 * BAND[0], 100 * BAND[1], color="0.85", zorder=0, label="90–98 % band")
        top.axhline(95, color="0.5", lw=0.8, ls="--", zorder=0)
        for k, quantity in enumerate(quantities):
            rows = table[(table["floor"] == floor) & (table["quantity"] == quantity)].set_index("scenario")
            x = np.array([i + (k - (len(quantities) - 1) / 2) * width for i in range(len(scenarios))])
            coverage = np.array([rows["coverage"].get(s, np.nan) for s in scenarios]) * 100
            error = np.array([rows["coverage_se"].get(s, np.nan) for s in scenarios]) * 100 * 1.96
            top.bar(x, coverage, width * 0.9, color=colours[k], label=QUANTITY_LABELS[quantity], zorder=2)
            top.errorbar(x, coverage, yerr=error, fmt="none", ecolor="k", lw=0.8, capsize=2, zorder=3)
            mean = np.array([rows["mean_z"].get(s, np.nan) for s in scenarios])
            sd = np.array([rows["sd_z"].get(s, np.nan) for s in scenarios])
            bottom.errorbar(x, mean, yerr=sd, fmt="o", color=colours[k], ms=4, capsize=2)
        for i, scenario in enumerate(scenarios):
            row = summary[(summary["scenario"] == scenario) & (summary["floor"] == floor)].iloc[0]
            if row["failed"]:
                top.text(i, 101, f"{row['failed']:.0f}/{row['recordings']:.0f} failed", ha="center", va="bottom",
                         fontsize=7, color="firebrick")
        top.set_ylim(0, 106)
        top.set_title(f"floor {floor}")
        top.tick_params(labelleft=True)
        bottom.tick_params(labelleft=True)
        if column == 0:
            top.set_ylabel("95 % intervals covering the truth (%)")
        bottom.axhspan(-1, 1, color="0.9", zorder=0)
        bottom.axhline(0, color="0.5", lw=0.8)
        bottom.set_yscale("symlog", linthresh=2)
        bottom.set_ylim(-12, 300)
        bottom.set_yticks([-10, -2, -1, 0, 1, 2, 10, 100])
        bottom.set_yticklabels(["−10", "−2", "−1", "0", "1", "2", "10", "100"])
        if column == 0:
            bottom.set_ylabel("z = (value − truth)/se: mean ± sd")
        bottom.set_xticks(range(len(scenarios)))
        bottom.set_xticklabels(scenarios, rotation=25, ha="right", fontsize=8)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper center", ncol=len(labels), fontsize=9, bbox_to_anchor=(0.5, 0.955))
    fig.suptitle("dropfit against refsim (numerically integrated contacts, e falling with speed, drag): "
                 "coverage of the 95 % intervals (error bars: ±1.96 cluster se)", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.93))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _pct(value):
    return "–" if not np.isfinite(value) else f"{100 * value:.1f} %"


def _number(value, digits=1):
    return "–" if not np.isfinite(value) or value == 0 and digits == 2 else f"{value:.{digits}f}"


def markdown(table, summary):
    """The README's tables: coverage per scenario × quantity with the floor given and unknown (coverage,
    pairs, mean ± sd of z; **bold** outside 90–98 %), then recordings and impacts per scenario."""
    lines = ["| scenario | quantity | floor given: coverage | pairs | z mean ± sd | floor unknown: coverage | pairs "
             "| z mean ± sd |", "|---|---|---|---|---|---|---|---|"]
    for scenario in dict.fromkeys(summary["scenario"]):
        rows = table[table["scenario"] == scenario]
        for quantity in QUANTITY_LABELS:
            cells = []
            for floor in refsim_trials.FLOOR_CONDITIONS:
                row = rows[(rows["floor"] == floor) & (rows["quantity"] == quantity)]
                if row.empty:
                    cells += ["–", "0", ""]
                    continue
                row = row.iloc[0]
                text = _pct(row["coverage"])
                if not BAND[0] <= row["coverage"] <= BAND[1]:
                    text = f"**{text}**"
                cells += [text, f"{row['n']:.0f}", f"{row['mean_z']:+.2f} ± {row['sd_z']:.2f}"]
            if cells[1] == "0" and cells[4] == "0":
                continue
            lines.append(f"| {scenario} | {QUANTITY_LABELS[quantity]} | " + " | ".join(cells) + " |")
    lines += ["", "| scenario | floor | recordings | failed | impacts simulated | analysed | per recording "
                  "s (simulate, analyse) |", "|---|---|---|---|---|---|---|"]
    for _, row in summary.iterrows():
        lines.append(f"| {row['scenario']} | {row['floor']} | {row['recordings']} | {row['failed']} | "
                     f"{_number(row['impacts_simulated_mean'])} | {_number(row['impacts_analysed_mean'])} | "
                     f"{_number(row['simulate_s_mean'], 2)}, {_number(row['analyse_s_mean'], 2)} |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("trials", nargs="?", type=int, default=200, help="seeded recordings per scenario")
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--scenarios", default=",".join(refsim_trials.SCENARIOS))
    parser.add_argument("--out", default=str(HERE / "refsim_coverage"), help="path prefix of the outputs")
    parser.add_argument("--pairs", action="store_true", help="also write every pair (gzip CSV)")
    parser.add_argument("--markdown", action="store_true",
                        help="print the README tables and redraw the chart from the CSVs already written (no trials)")
    args = parser.parse_args()
    if args.markdown:
        table, summary = pd.read_csv(f"{args.out}.csv"), pd.read_csv(f"{args.out}_recordings.csv")
        chart(table, summary, f"{args.out}.png")
        print(markdown(table, summary))
        return
    names = args.scenarios.split(",")
    start = time.perf_counter()
    pairs, recordings = refsim_trials.run_trials([(name, seed) for name in names for seed in range(args.trials)],
                                                 workers=args.workers)
    wall = time.perf_counter() - start
    table = refsim_trials.coverage_table(pairs)
    summary = refsim_trials.recordings_table(recordings)
    failures = refsim_trials.failure_messages(recordings)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=HERE).stdout.strip()
    dirty = subprocess.run(["git", "status", "--porcelain", "--", "src"], capture_output=True, text=True,
                           cwd=HERE).stdout.strip()
    print(f"{args.trials} seeded recordings per scenario, {len(names)} scenarios, {args.workers} workers: "
          f"{wall:.0f} s wall; dropfit at {commit}{' (src modified)' if dirty else ''}")
    with pd.option_context("display.width", 250, "display.max_columns", 30, "display.max_colwidth", 160):
        print(summary.to_string(index=False, float_format=lambda x: f"{x:.3g}"))
        print(table.to_string(index=False, float_format=lambda x: f"{x:.4g}"))
        if not failures.empty:
            print(failures.drop(columns="kind").to_string(index=False))
    prefix = Path(args.out)
    table.to_csv(f"{prefix}.csv", index=False, float_format="%.6g")
    summary.to_csv(f"{prefix}_recordings.csv", index=False, float_format="%.4g")
    failures.to_csv(f"{prefix}_failures.csv", index=False)
    if args.pairs:
        pairs.to_csv(f"{prefix}_pairs.csv.gz", index=False, float_format="%.10g")
    chart(table, summary, f"{prefix}.png")
    print(markdown(table, summary))


if __name__ == "__main__":
    main()
