"""Coverage of dropfit's 95 % intervals of e on phonesim's phone clips (an independent clip generator).

Each preset of ``tests/test_phone_clips.py`` is rendered at half size for several seeds (H.264 or MPEG-4
through PyAV, byte for byte the same file for a seed) and analysed as a user would, with the ball's
radius, mass and kind and the preset's scale option. No ball flies with the drag of its kind's nominal C_d,
which dropfit may hold (a real ball's differs): the even seeds' ball has 1.1 times the preset's C_d, the odd
seeds' 0.9 times (``DRAG_COEFFICIENT_FACTORS``; the kinds' C_d standard errors are 10.6–10.9 %). Each analysed impact is matched to the generator's
impact with the nearest touchdown time; z = (e − e_true) / se with se from the 95 % interval.

    PYTHONPATH=$PWD/src:$PWD python benchmarks/phone_coverage.py [--seeds 0-11] [--workers 2]

Writes ``benchmarks/phone_coverage.csv`` (one row per impact, or per refused clip with its message),
``benchmarks/phone_coverage_summary.csv`` (per preset: clips, refusals, impacts, coverage, mean z,
largest |z|, largest rebound-height error, rebound heights inside their 95 % interval) and the chart ``benchmarks/phone_coverage.png``.
"""

import argparse
import sys
import tempfile
import time
from multiprocessing import Pool
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))  # phone_clip, as the tests render the presets

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

#: The presets and the option each is analysed with (as in tests/test_phone_clips.py).
PRESET_OPTIONS = {
    "tennis_aruco_tilted": {"marker_size_m": 0.08},
    "green_board_avi": {},
    "yellow_green_tape": {},
    "yellow_flicker_portrait_120": {"ruler_tick_m": 0.01},
    "red_blur_portrait": {},
    "white_pingpong_mov": {},
}
Z95 = 1.959963984540054
#: The ball's C_d relative to its phonesim preset's, for even and odd seeds.
DRAG_COEFFICIENT_FACTORS = (1.1, 0.9)


def clip_rows(job):
    """Render one preset and seed, analyse it, and return its rows (a refusal is one row with the message)."""
    import dataclasses

    import phonesim
    import refsim

    import dropfit
    from dropfit.errors import InputError
    from helpers import phone_clip

    preset, seed = job
    start = time.perf_counter()
    ball = phonesim.PRESETS[preset].ball
    factor = DRAG_COEFFICIENT_FACTORS[seed % 2]
    ball = dataclasses.replace(ball, drag_coefficient=factor * refsim.preset(ball.model).drag_coefficient)
    with tempfile.TemporaryDirectory() as directory:
        path, truth = phone_clip(preset, directory, seed=seed, downscale=0.5, ball=ball)
        physics = truth["physics"]
        base = {"preset": preset, "seed": seed, "drag_k_true_per_m": physics["drag_k_1_m"]}
        try:
            result = dropfit.analyse_recording(path, ball_radius_m=physics["radius_m"], ball_mass_kg=physics["mass_kg"],
                                               ball_type=physics["ball_model"], **PRESET_OPTIONS[preset])
        except InputError as error:
            return [dict(base, refusal=str(error).replace(str(path), path.name), seconds=time.perf_counter() - start)]
    true = pd.DataFrame(physics["impacts"])
    touchdowns = true["t_touchdown_s"].to_numpy()
    rows = []
    for _, impact in result.impacts.iterrows():
        nearest = int(np.argmin(np.abs(touchdowns - impact["t_touchdown_s"])))
        se = (impact["e_ci95_high"] - impact["e_ci95_low"]) / (2 * Z95)
        e_true = float(true["e"].iloc[nearest])
        rows.append(dict(base, impact=int(impact["impact"]), true_impact=nearest + 1, e=impact["e"], e_se=se,
                         e_true=e_true, z=(impact["e"] - e_true) / se if se > 0 else np.nan,
                         h_after_error_mm=1e3 * (impact["h_after_m"] - true["h_after_m"].iloc[nearest]),
                         h_after_se_mm=1e3 * impact["h_after_se_m"],
                         drag_k_per_m=result.analysis.summary["drag_k_per_m"],
                         calibration=result.trajectory.attrs.get("calibration")))
    seconds = time.perf_counter() - start
    return [dict(row, seconds=seconds) for row in rows]


def summary_of(table):
    """Per preset: clips, refusals, impacts with an e, coverage of the 95 % interval, mean and largest |z|."""
    rows = []
    for preset, group in table.groupby("preset", sort=False):
        measured = group.dropna(subset=["z"])
        inside = (measured["z"].abs() <= Z95)
        rows.append({"preset": preset, "clips": group["seed"].nunique(),
                     "refused": int(group["refusal"].notna().sum()) if "refusal" in group else 0,
                     "impacts": len(measured), "inside": int(inside.sum()),
                     "coverage": inside.mean() if len(measured) else np.nan,
                     "mean_z": measured["z"].mean(), "max_abs_z": measured["z"].abs().max(),
                     "max_abs_h_error_mm": measured["h_after_error_mm"].abs().max(),
                     "h_inside": int((measured["h_after_error_mm"].abs() <= Z95 * measured["h_after_se_mm"]).sum()),
                     "impacts_not_first": int((measured["impact"] != measured["true_impact"]).sum())})
    return pd.DataFrame(rows)


def draw(table, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    measured = table.dropna(subset=["z"])
    presets = list(dict.fromkeys(table["preset"]))
    fig, ax = plt.subplots(figsize=(9, 4.5), layout="constrained")
    rng = np.random.default_rng(0)  # horizontal jitter only
    for index, preset in enumerate(presets):
        z = measured.loc[measured["preset"] == preset, "z"].to_numpy()
        ax.plot(index + rng.uniform(-0.2, 0.2, z.size), z, "o", ms=4, alpha=0.7)
    ax.axhspan(-Z95, Z95, color="0.9", zorder=0, label="95 % interval")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xticks(range(len(presets)), presets, rotation=15, fontsize=8)
    ax.set_ylabel("z = (e − e_true) / se")
    ax.set_title("phonesim clips at half size: e per impact against the generator's truth", loc="left")
    ax.legend(loc="upper right", fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-11", help="seeds, as first-last (inclusive)")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args(argv)
    first, last = (int(part) for part in args.seeds.split("-"))
    jobs = [(preset, seed) for preset in PRESET_OPTIONS for seed in range(first, last + 1)]
    with Pool(args.workers) as pool:
        rows = [row for clip in pool.imap(clip_rows, jobs) for row in clip]
    table = pd.DataFrame(rows)
    table.to_csv(HERE / "phone_coverage.csv", index=False, float_format="%.6g")
    summary = summary_of(table)
    summary.to_csv(HERE / "phone_coverage_summary.csv", index=False, float_format="%.4g")
    draw(table, HERE / "phone_coverage.png")
    print(summary.to_string(index=False))
    measured = table.dropna(subset=["z"])
    print(f"all: {int((measured['z'].abs() <= Z95).sum())} of {len(measured)} impacts inside their 95 % interval")


if __name__ == "__main__":
    main()
