"""Speed against accuracy of calibrating the damper c of the seed's ball contact (Example 4).

The seed chapter calibrates c of the unilateral spring-damper F = max(0, k δ + c δ̇) so that a tennis
ball (m = 0.057 kg, R = 0.033 m, k = 3e4 N/m, g = 9.81 m/s²) dropped from H = 2.54 m comes back with
e = 0.745: ``brentq(lambda c: drop_test(c)[0] - 0.745, 0.1, 80)``, where ``drop_test`` is a
pure-Python semi-implicit Euler loop at dt = 2 µs over the whole fall. This benchmark runs, side by
side in one process, every method below calibrating c for e = 0.745 its own way:

* ``seed Euler``            — the seed's ``drop_test`` (copied) inside brentq; dt = 2 µs is the
  baseline, other dt are the same code with another step.
* ``Euler from touchdown``  — the same Euler loop started at touchdown (δ = 0, speed v₀ = √(2gH))
  instead of at rest at H + R, which skips the fall and so affords smaller steps.
* ``solve_ivp RK45`` / ``solve_ivp DOP853`` — scipy.integrate.solve_ivp from touchdown with v₀,
  gravity included, terminal event at lift-off (δ = 0 falling), rtol in {1e-3, 1e-6, 1e-9, 1e-12} and
  atol = 1e-3·rtol, inside the same brentq (same bracket, default tolerances) as the seed.
* ``dropfit closed form``   — ``dropfit.contact.calibrate_damping`` (brentq on the closed-form e(c)).

Truth is dropfit's closed form: c_ref = calibrate_damping(m, k, v₀, 0.745, g) and its exact contact
time t_c,ref from ``simulate_linear_contact``. For each method, with c_method its calibrated damper:

* error in e = |e_exact(c_method) − 0.745|, e_exact being the closed-form e at c_method;
* error in contact time = |t_c reported by the method's own simulation at c_method − t_c,ref| (s).

Because the dropfit row is measured against dropfit itself, the script also checks the truth
independently: DOP853 at rtol = 1e-13, integrated in two smooth pieces (up to the force zero, then
free flight in closed form), evaluated at c_ref.

Wall time is the whole calibration (brentq with all its simulations, plus the final simulation at the
calibrated c that gives the contact time, as the seed does), after one untimed warm-up run; the
median of at least 5 timed repeats (up to 51 for methods faster than 20 ms), or of 3 repeats for
methods whose single calibration takes longer than 2 s.

Output: a printed table, the speed ratio (seed time / dropfit time) and the accuracy ratios
(seed error / dropfit error, with dropfit's error floored at machine epsilon times the value when
it is zero to machine precision), whether the targets (≥ 300× faster, ≥ 100× more accurate) are met,
``benchmarks/contact_calibration.csv`` (columns method, setting, wall_time_s, error_e,
error_contact_time_s; raw errors, so 0 means exact to machine precision) and
``benchmarks/contact_calibration.png`` (wall time against the two errors, log-log; errors that are
zero are drawn at the machine-epsilon floor).

Run (about 45 s; deterministic, nothing random):

    python benchmarks/contact_calibration.py
"""

from __future__ import annotations

import csv
import statistics
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.integrate import solve_ivp  # noqa: E402
from scipy.optimize import brentq  # noqa: E402

from dropfit.contact import LinearContact, calibrate_damping, simulate_linear_contact  # noqa: E402

M, K, R, H, G = 0.057, 3e4, 0.033, 2.54, 9.81
E_TARGET = 0.745
V0 = float(np.sqrt(2.0 * G * H))
BRACKET = (0.1, 80.0)  # the seed's brentq bracket, used by every simulation-based method
EPS = np.finfo(float).eps
OUT = Path(__file__).resolve().parent
SEED_DT = 2e-6

EULER_WHOLE_FALL_DT = [20e-6, 5e-6, SEED_DT, 1e-6, 0.5e-6]
EULER_TOUCHDOWN_DT = [2e-6, 1e-7, 1e-8]
ODE_METHODS = ["RK45", "DOP853"]
ODE_RTOLS = [1e-3, 1e-6, 1e-9, 1e-12]


# --- the seed's method (Example 4), copied; dt is a parameter so that other steps can be run -----------

def drop_test(c, m=M, k=K, R=R, H=H, g=G, dt=SEED_DT):
    y, v, t = H + R, 0.0, 0.0
    hist, inside = [], False
    while True:
        delta = R - y
        F = max(k*delta - c*v, 0.0) if delta > 0 else 0.0     # pushes, never pulls
        if delta > 0 and not inside:
            inside, v_in = True, v
        if inside:
            hist.append((t, delta, F, v))
            if delta <= 0:
                h_arr = np.array(hist)
                return -v/v_in, h_arr
        v += dt*(F/m - g)
        y += dt*v
        t += dt


def calibrate_seed_euler(dt):
    """The seed's calibration at step dt: (c, contact time in s from the seed's own history)."""
    c_cal = brentq(lambda c: drop_test(c, dt=dt)[0] - E_TARGET, *BRACKET)
    _, hist = drop_test(c_cal, dt=dt)
    return c_cal, hist[-1, 0] - hist[0, 0]


# --- the same Euler loop, started at touchdown with the exact impact speed ------------------------------

def drop_test_from_touchdown(c, m=M, k=K, R=R, v0=V0, g=G, dt=SEED_DT):
    y, v, t = R, -v0, 0.0
    hist, v_in = [], -v0
    while True:
        delta = R - y
        F = max(k*delta - c*v, 0.0) if delta > 0 else 0.0
        hist.append((t, delta, F, v))
        if delta <= 0 and t > 0:
            return -v/v_in, np.array(hist)
        v += dt*(F/m - g)
        y += dt*v
        t += dt


def calibrate_euler_from_touchdown(dt):
    c_cal = brentq(lambda c: drop_test_from_touchdown(c, dt=dt)[0] - E_TARGET, *BRACKET)
    _, hist = drop_test_from_touchdown(c_cal, dt=dt)
    return c_cal, hist[-1, 0] - hist[0, 0]


# --- solve_ivp from touchdown, event at lift-off -----------------------------------------------------------

def ode_contact(c, method, rtol):
    """(e, contact time in s) of one impact by solve_ivp; state (δ, δ̇) from (0, v₀), gravity included."""
    def rhs(_, state):
        delta, rate = state
        force = K * delta + c * rate
        if delta <= 0.0 or force < 0.0:  # pushes, never pulls
            force = 0.0
        return [rate, G - force / M]

    def liftoff(_, state):
        return state[0]

    liftoff.terminal, liftoff.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 0.05), [0.0, V0], method=method, rtol=rtol, atol=1e-3 * rtol, events=liftoff)
    if sol.t_events[0].size == 0:  # never lifts off within 50 ms: e = 0
        return 0.0, np.inf
    return -sol.y_events[0][0][1] / V0, sol.t_events[0][0]


def calibrate_ode(method, rtol):
    c_cal = brentq(lambda c: ode_contact(c, method, rtol)[0] - E_TARGET, *BRACKET)
    return c_cal, ode_contact(c_cal, method, rtol)[1]


# --- dropfit -----------------------------------------------------------------------------------------------

def calibrate_dropfit():
    c_cal = calibrate_damping(M, K, V0, E_TARGET, G)
    return c_cal, simulate_linear_contact(LinearContact(K, c_cal), M, V0, G).contact_time_s


# --- independent check of the truth ------------------------------------------------------------------------

def independent_check(c):
    """(e, contact time) at c by DOP853 at rtol 1e-13 on the smooth pushing phase, then free flight exactly."""
    def rhs(_, state):
        return [state[1], G - (K * state[0] + c * state[1]) / M]

    def force_zero(_, state):
        return K * state[0] + c * state[1]

    force_zero.terminal, force_zero.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 0.05), [0.0, V0], method="DOP853", rtol=1e-13, atol=1e-18, events=force_zero)
    t1 = sol.t_events[0][-1]
    delta, rate = sol.y_events[0][-1]
    # free phase δ = δ1 + r1 τ + g τ²/2 (force g k τ²/2 + (k r1 + c g) τ stays ≤ 0 until lift-off here)
    tau = (-rate - np.sqrt(rate**2 - 2.0 * G * delta)) / G
    reengage = -2.0 * (K * rate + c * G) / (K * G)
    assert tau < reengage, "the contact re-engages before lift-off; the check needs more phases"
    return -(rate + G * tau) / V0, t1 + tau


# --- benchmark ---------------------------------------------------------------------------------------------

def timed(calibrate):
    """(median wall time in s, number of timed repeats, result) of a calibration, after a warm-up run."""
    start = time.perf_counter()
    result = calibrate()
    first = time.perf_counter() - start
    repeats = 3 if first > 2.0 else (51 if first < 0.02 else 5)
    seconds = []
    for _ in range(repeats):
        start = time.perf_counter()
        calibrate()
        seconds.append(time.perf_counter() - start)
    return statistics.median(seconds), repeats, result


def exact(c):
    return simulate_linear_contact(LinearContact(K, c), M, V0, G, n_points=3)


def main():
    began = time.perf_counter()
    c_ref = calibrate_damping(M, K, V0, E_TARGET, G)
    tc_ref = exact(c_ref).contact_time_s
    e_check, tc_check = independent_check(c_ref)
    print(f"truth: c_ref = {c_ref:.15g} N·s/m, e_exact(c_ref) = {exact(c_ref).e:.17g}, t_c,ref = {tc_ref:.15g} s")
    print(f"independent check at c_ref (DOP853 rtol 1e-13, split at the force zero): "
          f"|e - 0.745| = {abs(e_check - E_TARGET):.2e}, |t_c - t_c,ref| = {abs(tc_check - tc_ref):.2e} s\n")

    cases = []
    for dt in EULER_WHOLE_FALL_DT:
        setting = f"dt = {dt * 1e6:g} us, whole fall" + (" (seed baseline)" if dt == SEED_DT else "")
        cases.append(("seed Euler", setting, lambda dt=dt: calibrate_seed_euler(dt)))
    for dt in EULER_TOUCHDOWN_DT:
        cases.append(("Euler from touchdown", f"dt = {dt * 1e6:g} us, contact only",
                      lambda dt=dt: calibrate_euler_from_touchdown(dt)))
    for method in ODE_METHODS:
        for rtol in ODE_RTOLS:
            cases.append((f"solve_ivp {method}", f"rtol = {rtol:g}, atol = {1e-3 * rtol:g}",
                          lambda method=method, rtol=rtol: calibrate_ode(method, rtol)))
    cases.append(("dropfit closed form", "calibrate_damping", calibrate_dropfit))

    rows = []
    header = f"{'method':<22} {'setting':<36} {'repeats':>7} {'wall_time_s':>12} {'c (N s/m)':>18} " \
             f"{'error_e':>10} {'error_t_c_s':>11}"
    print(header)
    print("-" * len(header))
    for method, setting, calibrate in cases:
        wall, repeats, (c_cal, tc) = timed(calibrate)
        error_e = abs(exact(c_cal).e - E_TARGET)
        error_tc = abs(tc - tc_ref)
        rows.append(dict(method=method, setting=setting, wall_time_s=wall, error_e=error_e,
                         error_contact_time_s=error_tc))
        print(f"{method:<22} {setting:<36} {repeats:>7} {wall:>12.4g} {c_cal:>18.15g} {error_e:>10.2e} "
              f"{error_tc:>11.2e}", flush=True)

    seed = next(r for r in rows if r["method"] == "seed Euler" and "seed baseline" in r["setting"])
    ours = next(r for r in rows if r["method"] == "dropfit closed form")
    floor_e, floor_tc = EPS * E_TARGET, EPS * tc_ref
    ours_e, ours_tc = max(ours["error_e"], floor_e), max(ours["error_contact_time_s"], floor_tc)
    speed = seed["wall_time_s"] / ours["wall_time_s"]
    accuracy_e = seed["error_e"] / ours_e
    accuracy_tc = seed["error_contact_time_s"] / ours_tc
    print(f"\nspeed ratio (seed Euler dt = 2 us / dropfit): {seed['wall_time_s']:.4g} s / "
          f"{ours['wall_time_s']:.4g} s = {speed:.0f}x  -> target >= 300x {'MET' if speed >= 300 else 'NOT MET'}")
    note_e = " (dropfit error floored at eps*e)" if ours["error_e"] < floor_e else ""
    note_tc = " (dropfit error floored at eps*t_c)" if ours["error_contact_time_s"] < floor_tc else ""
    print(f"accuracy ratio in e: {seed['error_e']:.3g} / {ours_e:.3g} = {accuracy_e:.3g}x{note_e}  "
          f"-> target >= 100x {'MET' if accuracy_e >= 100 else 'NOT MET'}")
    print(f"accuracy ratio in contact time: {seed['error_contact_time_s']:.3g} s / {ours_tc:.3g} s = "
          f"{accuracy_tc:.3g}x{note_tc}  -> target >= 100x {'MET' if accuracy_tc >= 100 else 'NOT MET'}")

    with open(OUT / "contact_calibration.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=["method", "setting", "wall_time_s", "error_e",
                                                    "error_contact_time_s"])
        writer.writeheader()
        for row in rows:
            writer.writerow({**row, **{key: f"{row[key]:.6e}" for key in
                                       ("wall_time_s", "error_e", "error_contact_time_s")}})
    plot(rows, seed, floor_e, floor_tc)
    print(f"\nwrote {OUT / 'contact_calibration.csv'} and {OUT / 'contact_calibration.png'}")
    print(f"benchmark run time: {time.perf_counter() - began:.0f} s")


STYLE = {"seed Euler": ("C3", "o"), "Euler from touchdown": ("C1", "s"), "solve_ivp RK45": ("C0", "^"),
         "solve_ivp DOP853": ("C2", "v"), "dropfit closed form": ("k", "*")}


def short_label(row):
    setting = row["setting"]
    if row["method"] == "dropfit closed form":
        return "dropfit"
    if "Euler" in row["method"]:
        dt = setting.split(",")[0].replace("dt = ", "").replace(" us", "µs")
        return ("Euler " if row["method"] == "seed Euler" else "Euler td ") + dt + \
            (" (seed)" if "seed baseline" in setting else "")
    return row["method"].split()[-1] + " " + setting.split(",")[0].replace("rtol = ", "")


def plot(rows, seed, floor_e, floor_tc):
    fig, axes = plt.subplots(1, 2, figsize=(9, 4.8), constrained_layout=True)
    for ax, key, floor, ylabel in [(axes[0], "error_e", floor_e, "error in e, |e(c) − 0.745|  [–]"),
                                   (axes[1], "error_contact_time_s", floor_tc, "error in contact time  [s]")]:
        # the target box: ≥ 300× faster and ≥ 100× more accurate than the seed
        ax.fill_between([1e-9, seed["wall_time_s"] / 300], 1e-30, seed[key] / 100, color="0.9", zorder=0,
                        label="target: ≥300× faster, ≥100× more accurate than seed")
        for method in STYLE:
            chosen = [r for r in rows if r["method"] == method]
            if not chosen:
                continue
            color, marker = STYLE[method]
            x = [r["wall_time_s"] for r in chosen]
            y = [max(r[key], floor) for r in chosen]
            ax.scatter(x, y, color=color, marker=marker, s=70 if marker == "*" else 30, label=method, zorder=3)
            for r, xi, yi in zip(chosen, x, y):
                text = short_label(r) + (" (0: at ε floor)" if r[key] < floor else "")
                ax.annotate(text, (xi, yi), xytext=(4, 3), textcoords="offset points", fontsize=6, color=color)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time of the calibration  [s]")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3, which="both", lw=0.4)
        values = [max(r[key], floor) for r in rows]
        ax.set_ylim(min(values) / 5, max(values) * 5)
        times = [r["wall_time_s"] for r in rows]
        ax.set_xlim(min(times) / 3, max(times) * 8)
    axes[0].set_title("calibrating c for e = 0.745: error in e", fontsize=9)
    axes[1].set_title("contact time at the calibrated c", fontsize=9)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="outside lower center", ncol=3)
    fig.savefig(OUT / "contact_calibration.png", dpi=120)


if __name__ == "__main__":
    main()
