"""Speed against accuracy of the four estimators of e (:mod:`dropfit.estimators`).

Every estimator runs on the same seeded synthetic height logs (``dropfit.synth.synthesize`` on the
scenarios of ``data/synthetic/scenarios.yaml``, logged in metres), chosen to show where each one
breaks down:

* ``tennis, drag, 100 Hz``   — the ITF tennis ball of ``tennis_itf`` (C_d = 0.55, 1 mm noise, 1 % dropouts);
* ``steel ball, 100 Hz``     — ``steel_ball``: 0.5 m drop, drag almost nil (k = 0.002 /m), first 4 s;
* ``steel ball, 30 Hz``      — the same sampled at 30 Hz;
* ``steel ball, 5 mm noise`` — the same at 100 Hz with 5 mm noise;
* ``table tennis, strong drag`` — ``table_tennis_drag`` (k = 0.14 /m, terminal speed 8.4 m/s), first 5 s.

The steel and table-tennis logs are cut to their first 7–8 impacts (the bundled ones run to rest,
30–50 impacts): the drag fit's time grows with the number of flights and would dominate the run
on the whole logs; the scored impacts are the same.

What each estimator is given: the log (time s, height m); ``peak heights`` also gets the true contact
height (floor + radius, as an ITF rig measures it: the method cannot find it); the others find it
themselves. Errors are e_estimated − e_true per impact, against the generator's per-impact e, over
impacts 2 to 6 (the first impact has no flight-time ratio; later, lower bounces are not measured by
every method) and all seeds. An estimate is matched to the true impact nearest in time (within
50 ms); a true impact of 2–6 with no finite estimate counts as missed, and so do all five of a log
that the estimator refuses (``InputError``; the count of refused logs is reported).

Wall time is that of one call on one log (its own segmentation included). All four run side by side
on the same log, in rotating order, REPEATS times each; the time of an estimator is the median over
repeats and logs, and the ratio is to the fastest estimator of that scenario in this run.

Output: a printed table, ``benchmarks/estimators.csv`` (one row per scenario × estimator: median
wall time in ms, ratio to the fastest, RMS and bias of the e error, largest |error|, median reported
standard error, impacts scored and missed, logs refused) and ``benchmarks/estimators.png`` (wall time against RMS
error, log-log).

Run (about 15 s on a quiet 2-core machine; seeded, the errors are reproducible, the times are not):

    PYTHONPATH=src python benchmarks/estimators.py [SEEDS] [REPEATS]

(defaults 12 seeds per scenario, 5 repeats).
"""

from __future__ import annotations

import copy
import csv
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from dropfit.errors import InputError
from dropfit.estimators import drag_fit, flight_time_ratio, parabola_fit, peak_heights
from dropfit.synth import synthesize

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "benchmarks"
SCENARIOS_YAML = ROOT / "data" / "synthetic" / "scenarios.yaml"
#: Impacts scored: 2 to 6.
SCORED_IMPACTS = range(2, 7)
#: An estimate belongs to the nearest true impact if it is this close in time (s).
MATCH_WINDOW_S = 0.05

SCENARIOS = {
    # name: (scenario in scenarios.yaml, log duration in s or None to keep, sensor settings replaced)
    "tennis, drag, 100 Hz": ("tennis_itf", None, {}),
    "steel ball, 100 Hz": ("steel_ball", 4.0, {}),
    "steel ball, 30 Hz": ("steel_ball", 4.0, {"sample_rate_hz": 30}),
    "steel ball, 5 mm noise": ("steel_ball", 4.0, {"noise_m": 0.005}),
    "table tennis, strong drag": ("table_tennis_drag", 5.0, {}),
}

ESTIMATORS = {
    "peak heights": lambda t, y, contact: peak_heights(t, y, contact),
    "flight-time ratio": lambda t, y, contact: flight_time_ratio(t, y),
    "parabola fit": lambda t, y, contact: parabola_fit(t, y),
    "drag fit (dropfit default)": lambda t, y, contact: drag_fit(t, y),
}


def scenario_spec(base, duration_s, sensor_changes):
    """A scenario of scenarios.yaml, maybe shorter, with its sensor changed and the log in metres."""
    spec = copy.deepcopy(yaml.safe_load(SCENARIOS_YAML.read_text(encoding="utf-8"))["scenarios"][base])
    spec["sensor"].update(sensor_changes, unit="m")
    if duration_s is not None:
        spec["duration_s"] = duration_s
    return spec


def score(estimate, truth_impacts):
    """Errors of the scored impacts (list) and how many scored impacts have no estimate."""
    true_times = np.array([impact["t_s"] for impact in truth_impacts])
    errors = {}
    for t_impact, e in zip(estimate["t_impact_s"], estimate["e"]):
        nearest = int(np.argmin(np.abs(true_times - t_impact)))
        number = nearest + 1
        if np.isfinite(e) and abs(true_times[nearest] - t_impact) < MATCH_WINDOW_S and number in SCORED_IMPACTS:
            errors[number] = e - truth_impacts[nearest]["e"]
    return list(errors.values()), len(SCORED_IMPACTS) - len(errors)


def run_scenario(spec, seeds, repeats):
    """Per estimator: wall times (s), e errors, reported standard errors and missed impacts."""
    results = {name: {"seconds": [], "errors": [], "se": [], "missed": 0, "refused": 0} for name in ESTIMATORS}
    names = list(ESTIMATORS)
    for seed in range(seeds):
        log, record = synthesize(spec, seed)
        t, y = log["time_s"].to_numpy(), log["y_m"].to_numpy()
        contact = record["contact_height_in_log_frame_m"]
        per_log = {name: [] for name in names}
        for repeat in range(repeats):
            shift = (seed + repeat) % len(names)  # rotate the order so that no estimator always runs first
            for name in names[shift:] + names[:shift]:
                start = time.perf_counter()
                try:
                    estimate = ESTIMATORS[name](t, y, contact)
                except InputError:
                    estimate = None
                per_log[name].append(time.perf_counter() - start)
                if repeat == 0 and estimate is None:
                    results[name]["refused"] += 1
                    results[name]["missed"] += len(SCORED_IMPACTS)
                elif repeat == 0:
                    errors, missed = score(estimate, record["impacts"])
                    results[name]["errors"].extend(errors)
                    results[name]["missed"] += missed
                    results[name]["se"].extend(estimate["e_se"].to_numpy()[:6])
        for name in names:
            results[name]["seconds"].append(statistics.median(per_log[name]))
    return results


def summarise(scenario, results):
    rows = []
    medians = {name: statistics.median(r["seconds"]) for name, r in results.items()}
    fastest = min(medians.values())
    for name, r in results.items():
        errors = np.asarray(r["errors"])
        se = np.asarray(r["se"])
        rows.append({
            "scenario": scenario,
            "estimator": name,
            "wall_time_ms": 1e3 * medians[name],
            "time_ratio_to_fastest": medians[name] / fastest,
            "e_error_rms": float(np.sqrt(np.mean(errors**2))) if errors.size else np.nan,
            "e_error_bias": float(np.mean(errors)) if errors.size else np.nan,
            "e_error_max_abs": float(np.max(np.abs(errors))) if errors.size else np.nan,
            "e_se_median": float(np.nanmedian(se)) if np.isfinite(se).any() else np.nan,
            "impacts_scored": int(errors.size),
            "impacts_missed": r["missed"],
            "logs_refused": r["refused"],
        })
    return rows


FORMATS = {"wall_time_ms": ".4g", "time_ratio_to_fastest": ".3g", "e_error_rms": ".3e", "e_error_bias": ".3e",
           "e_error_max_abs": ".3e", "e_se_median": ".3e"}


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 12
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    began = time.perf_counter()
    rows = []
    print(f"{seeds} seeded logs per scenario, {repeats} timed repeats per estimator and log, impacts "
          f"{SCORED_IMPACTS.start}-{SCORED_IMPACTS.stop - 1} scored\n")
    header = f"{'scenario':<26} {'estimator':<27} {'time ms':>8} {'ratio':>6} {'RMS e err':>10} {'bias':>10} " \
             f"{'max |err|':>10} {'median se':>10} {'scored':>6} {'missed':>6} {'refused':>7}"
    print(header)
    print("-" * len(header))
    for scenario, (base, duration, changes) in SCENARIOS.items():
        for row in summarise(scenario, run_scenario(scenario_spec(base, duration, changes), seeds, repeats)):
            rows.append(row)
            print(f"{row['scenario']:<26} {row['estimator']:<27} {row['wall_time_ms']:>8.3g} "
                  f"{row['time_ratio_to_fastest']:>6.3g} {row['e_error_rms']:>10.2e} {row['e_error_bias']:>10.2e} "
                  f"{row['e_error_max_abs']:>10.2e} {row['e_se_median']:>10.2e} {row['impacts_scored']:>6} "
                  f"{row['impacts_missed']:>6} {row['logs_refused']:>7}", flush=True)
    with open(OUT / "estimators.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        for row in rows:
            writer.writerow({key: format(value, FORMATS[key]) if key in FORMATS else value
                             for key, value in row.items()})
    plot(rows)
    print(f"\nwrote {OUT / 'estimators.csv'} and {OUT / 'estimators.png'}")
    print(f"benchmark run time: {time.perf_counter() - began:.0f} s")


COLOURS = {"peak heights": "C1", "flight-time ratio": "C2", "parabola fit": "C0", "drag fit (dropfit default)": "k"}
OPEN = {"flight-time ratio"}
MARKERS = {"tennis, drag, 100 Hz": "o", "steel ball, 100 Hz": "s", "steel ball, 30 Hz": "v",
           "steel ball, 5 mm noise": "D",
           "table tennis, strong drag": "^"}


def plot(rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(8, 5.6), constrained_layout=True)
    for row in rows:
        colour = COLOURS[row["estimator"]]
        # open markers for the flight-time ratio: it often lands on the peak heights' point
        face = "none" if row["estimator"] in OPEN else colour
        ax.scatter(row["wall_time_ms"], row["e_error_rms"], facecolors=face, edgecolors=colour, linewidths=1.3,
                   marker=MARKERS[row["scenario"]], s=55, alpha=0.85, zorder=3)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time per log, median  [ms]")
    ax.set_ylabel("RMS error of e over impacts 2–6 and seeds  [–]")
    ax.set_title("estimators of e: speed against accuracy on the same synthetic logs", fontsize=10)
    ax.grid(alpha=0.3, which="both", lw=0.4)
    times = [r["wall_time_ms"] for r in rows]
    ax.set_xlim(min(times) / 2, max(times) * 3)
    estimator_handles = [Line2D([], [], color=c, marker="o", ls="", label=e,
                                markerfacecolor="none" if e in OPEN else c) for e, c in COLOURS.items()]
    scenario_handles = [Line2D([], [], color="0.4", marker=m, ls="", label=s) for s, m in MARKERS.items()]
    fig.legend(handles=estimator_handles + scenario_handles, fontsize=8, loc="outside lower center", ncol=3)
    fig.savefig(OUT / "estimators.png", dpi=110)


if __name__ == "__main__":
    main()
