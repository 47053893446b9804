"""Accuracy and speed of the height-log analysis over seeded synthetic recordings.

For each scenario (an ITF tennis ball from 254 cm with and without air drag, sampled at 100 Hz with
1 mm noise and 1 % dropouts) it analyses N seeded logs as the workflow does
(:func:`dropfit.analyse_recording` with the ball's radius, mass and type) and prints, against the generator's truth:
the worst per-impact e error among impacts resolved to se ≤ 0.0015, the worst mean-e error, the
worst apex-height error, the spread of the normalised e errors (should be 1), the coverage of the
95 % interval of the mean e, how often drag was fitted, and the median analysis time.

    python benchmarks/log_accuracy.py [N]
"""

import sys
import time

import numpy as np

from dropfit import analyse_recording
from dropfit.heightlog import make_trajectory
from dropfit.restitution import constant_restitution
from dropfit.synth import sample_height_log, simulate_drop

E_TRUE = 0.775


def run(drag_coefficient, trials):
    truth = simulate_drop(2.54, 0.0335, {"kind": "constant", "e0": E_TRUE}, mass_kg=0.057,
                          drag_coefficient=drag_coefficient)
    worst_e, worst_mean, worst_h, z, covered, drag, seconds = 0.0, 0.0, 0.0, [], 0, 0, []
    for seed in range(trials):
        log = sample_height_log(truth, np.random.default_rng(seed), 100.0, noise_m=0.001, offset_m=0.2,
                                dropout_fraction=0.01)
        start = time.perf_counter()
        trajectory = make_trajectory(log["time_s"].to_numpy(), log["y_m"].to_numpy(), f"seed {seed}", "synthetic log")
        analysis = analyse_recording(trajectory, ball_radius_m=0.0335, ball_mass_kg=0.057, ball_type="tennis").analysis
        seconds.append(time.perf_counter() - start)
        impacts = analysis.impacts
        true = truth.impacts.iloc[impacts["impact"].to_numpy() - 1]  # numbered from the release
        error = impacts["e"].to_numpy() - true["e"].to_numpy()
        resolved = impacts["e_se"].to_numpy() <= 0.0015
        worst_e = max(worst_e, np.max(np.abs(error[resolved])))
        z.extend(error / impacts["e_se"].to_numpy())
        worst_h = max(worst_h, np.max(np.abs(impacts["h_after_m"].to_numpy() - true["rebound_height_m"].to_numpy())))
        mean = constant_restitution(impacts["e"].to_numpy(), analysis.e_covariance)["e"]
        worst_mean = max(worst_mean, abs(mean["value"] - E_TRUE))
        covered += mean["ci95"][0] <= E_TRUE <= mean["ci95"][1]
        drag += analysis.summary["drag_model"] == "quadratic"
    return {"max |e error| resolved": worst_e, "max |mean e error|": worst_mean, "max |h error| mm": 1e3 * worst_h,
            "std(e error / se)": float(np.std(z)), "95% coverage": covered / trials, "drag fitted": drag / trials,
            "median time ms": 1e3 * float(np.median(seconds))}


def main():
    trials = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    print(f"{trials} seeded logs per scenario, 100 Hz, 1 mm noise, 1 % dropouts")
    for name, cd in (("tennis, C_d = 0.55", 0.55), ("tennis, no drag", 0.0)):
        row = run(cd, trials)
        print(name + ": " + ", ".join(f"{key} {value:.4g}" for key, value in row.items()))


if __name__ == "__main__":
    main()
