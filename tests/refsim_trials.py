"""Coverage trials against refsim, a second generator written independently of ``dropfit.synth``.

Shared by ``benchmarks/refsim_coverage.py`` (the full run, its CSV and chart) and
``tests/test_refsim_coverage.py`` (the slow assertion and a fast check of this harness).

One trial is one seeded recording of one scenario (:data:`SCENARIOS`):

1. :func:`draw` draws its parameters from the seed: drop height, the contact law's stiffness and
   damping (so e(v) and the contact time) within the preset's plausible range, C_d, g (a site's
   gravity, 9.780–9.832 m/s²), noise, sample rate where the scenario has a range, the sampling phase
   and the sensor's zero;
2. :func:`simulate_recording` integrates the drop with :func:`refsim.simulate` (flights *and*
   contacts, e falling with speed, quadratic drag in every phase) and records it with
   :func:`refsim.record.record` the way the scenario's sensor does (point of the ball, unit, noise,
   jitter);
3. the log is written as a user's CSV (:func:`refsim.record.write_csv`) and analysed by
   :func:`run_dropfit` twice, once with the floor given (``floor_m``, the floor's height in the
   log's frame) and once without: exactly the workflow's stages ``measure`` → ``analyse`` → ``fit``
   on files, with the ball's radius, mass and type and g = the simulator's g;
4. :func:`match_impacts` matches each analysed impact to the simulated one by touchdown time, and
   :func:`impact_pairs` pairs (value, se, truth) per impact for ``e``, ``h_after_m`` (the centre's
   rebound rise above the contact height), ``v_in_m_s`` and ``v_out_m_s`` (at touchdown and at
   lift-off), and, with the floor given, ``t_contact_s`` where dropfit says ``contact_resolvable``.

:func:`coverage_table` gives per (scenario, floor, quantity) the fraction of pairs with
|value − truth| ≤ 1.96 se and the mean and sd of z = (value − truth)/se.

Every random number comes from ``numpy.random.default_rng`` seeded by (scenario, seed).
"""

from __future__ import annotations

import math
import tempfile
import time
import traceback
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

import refsim
from refsim.contact import HertzDamped, HuntCrossley, LinearSpringDamper
from refsim.record import record, write_csv

#: |z| below this counts as covered by the 95 % interval.
Z95 = 1.959964
#: The per-impact quantities paired with the truth: dropfit's impacts.csv column → (its se column, refsim's column).
IMPACT_QUANTITIES = {
    "e": ("e_se", "e"),
    "h_after_m": ("h_after_se_m", "h_after_m"),
    "v_in_m_s": ("v_in_se_m_s", "v_in_m_s"),
    "v_out_m_s": ("v_out_se_m_s", "v_out_m_s"),
}
#: The quantities the coverage requirement names (e, rebound heights, speeds).
ASSERTED_QUANTITIES = tuple(IMPACT_QUANTITIES)
#: A site's gravity: WGS84 normal gravity spans 9.780 (equator) to 9.832 m/s² (poles).
GRAVITY_RANGE_M_S2 = (9.780, 9.832)
#: The simulation runs this long past a log that ends before the ball rests (s): longer than any
#: flight's rise there, so that every rebound height has its truth.
SIMULATED_PAST_LOG_S = 1.0
#: The columns of the pairs table.
PAIR_COLUMNS = ["scenario", "seed", "floor", "quantity", "impact", "true_impact", "value", "se", "truth"]
#: Where the floor is: given to dropfit (``floor_m``) or not.
FLOOR_CONDITIONS = ("given", "unknown")


@dataclass(frozen=True)
class Scenario:
    """A family of recordings; every range is drawn from uniformly per seed (factors log-uniformly).

    ``stiffness_factor`` and ``damping_factor`` multiply the preset's contact law (K and C, K and
    α, or k and c); ``noise`` is in the log's unit; ``rate_hz`` a range or one rate; ``point`` the
    point of the ball the sensor follows; ``duration_after_rest_s`` how long the log runs on after
    the rest, capped at ``max_duration_s`` after the release.
    """

    preset: str
    drop_height_m: tuple
    rate_hz: tuple
    noise: tuple
    unit: str
    ball_type: str
    point: str = "centre"
    stiffness_factor: tuple = (0.85, 1.18)
    damping_factor: tuple = (0.9, 1.1)
    drag_coefficient: tuple = (0.4, 0.6)
    sensor_zero_m: tuple = (-0.05, 0.30)  # the sensor's reading at the floor (metric logs), m
    px_per_m: float | None = None
    floor_row_px: tuple = (900.0, 1100.0)
    jitter_frac: float = 0.0
    lost_frac: float = 0.0
    h_rest_m: float = 1e-5
    duration_after_rest_s: float = 0.5
    max_duration_s: float = 12.0
    description: str = ""


#: The scenarios. Contact-law ranges keep each ball plausible (tennis: e = 0.73–0.78 at 7.06 m/s,
#: the ITF window; steel on stone 0.87–0.93 at 3 m/s; table tennis 0.86–0.92, the ITTF window).
SCENARIOS = {
    "tennis_100hz": Scenario(
        "tennis", (1.0, 2.54), (100.0, 100.0), (0.8e-3, 1.2e-3), "m", "tennis",
        description="tennis ball (Hertz–Kuwabara–Kono), 1.0–2.54 m, centre at 100 Hz in m, ~1 mm noise"),
    "tennis_500hz": Scenario(
        "tennis", (1.0, 2.54), (500.0, 500.0), (0.8e-3, 1.2e-3), "m", "tennis",
        description="the same at 500 Hz"),
    "steel_500hz": Scenario(
        "steel", (0.3, 0.5), (500.0, 500.0), (0.1, 0.3), "mm", "steel", stiffness_factor=(0.8, 1.25),
        damping_factor=(0.85, 1.15), max_duration_s=3.0,
        description="steel ball on stone (Hertz–KK), 0.3–0.5 m, centre at 500 Hz in mm, 0.1–0.3 mm noise, 3 s"),
    "rubber_200hz": Scenario(
        "rubber", (0.5, 1.5), (200.0, 200.0), (0.3, 1.0), "mm", "rubber", stiffness_factor=(0.8, 1.25),
        damping_factor=(0.8, 1.2), h_rest_m=1e-4, max_duration_s=5.0,
        description="solid rubber ball (Hunt–Crossley, e → 1 at low speed), 0.5–1.5 m, centre at 200 Hz in mm, "
                    "0.3–1 mm noise, 5 s"),
    "table_tennis_100_200hz": Scenario(
        "table_tennis", (0.3, 1.0), (100.0, 200.0), (0.3, 1.0), "mm", "table_tennis", damping_factor=(0.8, 1.2), h_rest_m=2e-4,
        max_duration_s=6.0, description="table-tennis ball (linear contact, strong drag k ≈ 0.14/m), 0.3–1.0 m, centre at "
                    "100–200 Hz in mm, 0.3–1 mm noise"),
    "marble_px_200fps": Scenario(
        "marble_paper", (0.1, 0.3), (200.0, 200.0), (0.2, 0.5), "px", "marble", stiffness_factor=(0.8, 1.25),
        damping_factor=(0.8, 1.2), px_per_m=2500.0, jitter_frac=0.02, lost_frac=0.01, h_rest_m=2e-4,
        max_duration_s=4.0,
        description="glass marble on paper (Hunt–Crossley, e 0.8 → 0.55 with speed), 0.1–0.3 m, tracked centre "
                    "at 200 fps in image rows (px, 2500 px/m, scale given), 0.2–0.5 px noise, 2 % jitter, "
                    "1 % lost frames"),
    "tennis_bottom_1_2khz": Scenario(
        "tennis", (1.0, 2.54), (1000.0, 2000.0), (0.05, 0.2), "mm", "tennis", point="bottom", jitter_frac=0.05,
        sensor_zero_m=(0.0, 0.005),
        description="tennis ball, 1.0–2.54 m, its bottom (a laser on the floor) at 1–2 kHz in mm, 0.05–0.2 mm "
                    "noise, 5 % jitter"),
}


# ------------------------------------------------------------------------------------------------
# Drawing and simulating one recording
# ------------------------------------------------------------------------------------------------
def trial_rng(scenario_name, seed):
    """The seeded generator of one trial (distinct streams per scenario)."""
    return np.random.default_rng([zlib.crc32(scenario_name.encode()), int(seed)])


def draw(scenario_name, seed):
    """The parameters of trial ``seed`` of scenario ``scenario_name`` (a dict of plain numbers)."""
    scenario = SCENARIOS[scenario_name]
    rng = trial_rng(scenario_name, seed)

    def uniform(bounds):
        return float(rng.uniform(*bounds)) if bounds[1] > bounds[0] else float(bounds[0])

    def log_uniform(bounds):
        return float(np.exp(rng.uniform(np.log(bounds[0]), np.log(bounds[1]))))

    rate = uniform(scenario.rate_hz)
    return {
        "drop_height_m": uniform(scenario.drop_height_m),
        "stiffness_factor": log_uniform(scenario.stiffness_factor),
        "damping_factor": log_uniform(scenario.damping_factor),
        "drag_coefficient": uniform(scenario.drag_coefficient),
        "gravity_m_s2": uniform(GRAVITY_RANGE_M_S2),
        "rate_hz": rate,
        "noise": uniform(scenario.noise),
        # the recording starts 0.2–0.5 s before the release, at any phase of the sample clock
        "lead_s": 0.2 + 0.3 * float(rng.random()),
        "sensor_zero_m": uniform(scenario.sensor_zero_m),
        "floor_row_px": uniform(scenario.floor_row_px),
        "record_seed": int(rng.integers(2**31)),
    }


def ball_of(scenario, parameters):
    """The preset ball with the drawn contact law and drag coefficient."""
    ball = refsim.preset(scenario.preset)
    law, fk, fd = ball.contact, parameters["stiffness_factor"], parameters["damping_factor"]
    if isinstance(law, HertzDamped):
        law = HertzDamped(law.K * fk, law.C * fd)
    elif isinstance(law, HuntCrossley):
        law = HuntCrossley(law.K * fk, law.alpha * fd, law.n)
    elif isinstance(law, LinearSpringDamper):
        law = LinearSpringDamper(law.k * fk, law.c * fd)
    else:  # pragma: no cover - a new law
        raise TypeError(f"no scaling for {type(law).__name__}")
    from dataclasses import replace

    return replace(ball.with_contact(law), drag_coefficient=parameters["drag_coefficient"])


@dataclass
class Recording:
    """A simulated recording: the log as written, the truth, and what a user's sample sheet says."""

    log: pd.DataFrame
    truth: object  # refsim.Truth
    ball: object  # refsim.Ball
    floor_m: float  # the floor's height in the log's frame (m, after the scale for a px log)
    scale_m_per_px: float | None
    height_reference: str  # the point of the ball the log follows: centre, bottom or top
    parameters: dict


def simulate_recording(scenario_name, seed):
    """Simulate and record trial ``seed`` of ``scenario_name`` (see the module docstring)."""
    scenario = SCENARIOS[scenario_name]
    p = draw(scenario_name, seed)
    ball = ball_of(scenario, p)
    # simulated past the log's end, so that the truth knows the apex of a flight the log cuts short
    truth = refsim.simulate(ball, p["drop_height_m"], g_m_s2=p["gravity_m_s2"], h_rest_m=scenario.h_rest_m,
                            t_end_s=scenario.max_duration_s + SIMULATED_PAST_LOG_S)
    end = min(truth.rest_time_s + scenario.duration_after_rest_s if truth.status == "rest" else truth.t_end_s,
              scenario.max_duration_s)
    start = truth.t_release_s - p["lead_s"]
    options = dict(point=scenario.point, unit=scenario.unit, noise_sd=p["noise"], jitter_frac=scenario.jitter_frac,
                   lost_frac=scenario.lost_frac, lost_run=(1, 3), rng=p["record_seed"])
    if scenario.unit == "px":
        options.update(px_per_m=scenario.px_per_m, floor_row_px=p["floor_row_px"])
        scale = -1.0 / scenario.px_per_m  # image rows point down
        floor = p["floor_row_px"] * scale  # the floor's row, in m in the log's (scaled) frame
    else:
        options.update(floor_offset_m=p["sensor_zero_m"])
        scale, floor = None, p["sensor_zero_m"]
    log = record(truth, p["rate_hz"], t_start_s=start, duration_s=end - start, **options)
    return Recording(log, truth, ball, floor, scale, scenario.point, p)


# ------------------------------------------------------------------------------------------------
# Running dropfit
# ------------------------------------------------------------------------------------------------
@dataclass
class DropfitRun:
    """What dropfit wrote for one recording: the impacts table, the analysis summary and the fit result
    (None when the fit stage failed)."""

    impacts: pd.DataFrame
    summary: dict
    fit: dict | None


class StageFailed(Exception):
    """A dropfit stage refused the recording or crashed: ``stage``, the one-line ``message``, and what
    the earlier stages wrote (``run``: the impacts table and the analysis summary when only the fit
    failed, else None)."""

    def __init__(self, stage, message, run=None):
        super().__init__(f"{stage}: {message}")
        self.stage, self.message, self.run = stage, message, run


def run_dropfit(log_path, directory, *, ball_radius_m, ball_mass_kg, ball_type, gravity_m_s2, floor_m=None,
                scale_m_per_px=None, height_reference="centre"):
    """Analyse one height log exactly as the workflow does; the one place that calls dropfit.

    ``stages.measure`` → ``stages.analyse`` (drag ``auto``, the config's default) → ``stages.fit`` on
    files in ``directory``, with the sample sheet's ball radius (m), mass (kg), type, scale (m/px,
    negative for image rows), floor (m, in the log's frame; None: unknown), the point of the ball the
    log follows (``height_reference``) and g (m/s²).

    Raises
    ------
    StageFailed
        Where a stage refuses the recording (dropfit's one-line message) or crashes (the exception and
        where it was raised).
    """
    import json

    from dropfit import stages
    from dropfit.settings import Ball, Settings

    directory = Path(directory)
    ball = Ball(radius_m=ball_radius_m, mass_kg=ball_mass_kg, type=ball_type)
    settings = Settings(scale_m_per_px=scale_m_per_px, gravity_m_s2=gravity_m_s2, floor_m=floor_m,
                        height_reference=height_reference, drag="auto")
    trajectory, impacts, flights = directory / "trajectory.nc", directory / "impacts.csv", directory / "flights.csv"
    analysis, fitted = directory / "analysis.json", directory / "fit.json"
    with _stage("measure"):
        stages.measure(log_path, trajectory, ball, settings, sample_id=Path(log_path).stem)
    with _stage("analyse"):
        stages.analyse(trajectory, impacts, flights, analysis, settings)
    run = DropfitRun(pd.read_csv(impacts), json.loads(analysis.read_text()), None)
    with _stage("fit", run):
        stages.fit(analysis, impacts, fitted, settings, ball_type=ball_type)
    run.fit = json.loads(fitted.read_text())
    return run


class _stage:
    """Context: turn any exception of a dropfit stage into :class:`StageFailed` with a one-line message."""

    def __init__(self, name, run=None):
        self.name, self.run = name, run

    def __enter__(self):
        return self

    def __exit__(self, kind, error, tb):
        if error is None or not isinstance(error, Exception):
            return False
        from dropfit.errors import InputError

        message = str(error) if isinstance(error, InputError) else \
            f"internal error: {type(error).__name__}: {error} ({_where(error)})"
        raise StageFailed(self.name, " ".join(message.split()), self.run) from error


# ------------------------------------------------------------------------------------------------
# Matching and pairing
# ------------------------------------------------------------------------------------------------
#: An analysed touchdown matches a simulated one when it lies within this fraction of the shorter
#: of the simulated flights before and after it (so it cannot be taken for a neighbour).
MATCH_FRACTION_OF_FLIGHT = 0.3


def match_impacts(t_analysed, true_impacts, t_release_s):
    """Index (into ``true_impacts``) of the simulated impact each analysed touchdown belongs to, -1 for none.

    Each analysed touchdown goes to the nearest simulated touchdown (``t_touchdown_s``) if it lies within
    :data:`MATCH_FRACTION_OF_FLIGHT` of the shorter of that impact's neighbouring flights; a simulated
    impact claimed twice keeps the nearer analysed one.
    """
    t_analysed = np.asarray(t_analysed, dtype=float)
    touchdown = true_impacts["t_touchdown_s"].to_numpy(dtype=float)
    liftoff = true_impacts["t_liftoff_s"].to_numpy(dtype=float)
    flight_before = touchdown - np.concatenate([[t_release_s], liftoff[:-1]])
    flight_after = np.concatenate([touchdown[1:], [np.inf]]) - liftoff
    window = MATCH_FRACTION_OF_FLIGHT * np.minimum(flight_before, flight_after)
    match = np.full(t_analysed.size, -1)
    if touchdown.size == 0:
        return match
    for i, t in enumerate(t_analysed):
        j = int(np.argmin(np.abs(touchdown - t)))
        if abs(touchdown[j] - t) <= window[j]:
            match[i] = j
    for j in np.unique(match[match >= 0]):
        claimants = np.flatnonzero(match == j)
        if claimants.size > 1:
            keep = claimants[np.argmin(np.abs(t_analysed[claimants] - touchdown[j]))]
            match[claimants[claimants != keep]] = -1
    return match


def impact_pairs(impacts, true_impacts, match, floor_given):
    """(quantity, impact, true_impact, value, se, truth) of every matched analysed impact.

    ``t_contact_s`` (dropfit's ``t_contact_ms`` against refsim's ``contact_time_s``, δ = 0 to δ = 0) is
    paired only with the floor given and where dropfit marks the contact resolvable. A value or se
    that dropfit leaves empty stays in (it covers nothing); a truth refsim does not know (NaN) would
    be an error of this harness, and raises.
    """
    rows = []
    for i, j in enumerate(match):
        if j < 0:
            continue
        row, true = impacts.iloc[i], true_impacts.iloc[j]
        for column, (se_column, true_column) in IMPACT_QUANTITIES.items():
            rows.append((column, int(row["impact"]), j + 1, float(row[column]), float(row[se_column]),
                         float(true[true_column])))
        if floor_given and _true(row.get("contact_resolvable")):
            rows.append(("t_contact_s", int(row["impact"]), j + 1, 1e-3 * float(row["t_contact_ms"]),
                         1e-3 * float(row["t_contact_se_ms"]), float(true["contact_time_s"])))
    pairs = pd.DataFrame(rows, columns=["quantity", "impact", "true_impact", "value", "se", "truth"])
    unknown = pairs[~np.isfinite(pairs["truth"].to_numpy(dtype=float))]
    if not unknown.empty:
        raise ValueError(f"refsim has no truth for {unknown[['quantity', 'true_impact']].values.tolist()}")
    return pairs


def _true(flag):
    if isinstance(flag, str):
        return flag.strip().lower() in ("true", "1", "yes")
    return bool(flag) if flag is not None and not (isinstance(flag, float) and math.isnan(flag)) else False


# ------------------------------------------------------------------------------------------------
# One trial
# ------------------------------------------------------------------------------------------------
@dataclass
class TrialResult:
    """Pairs of all analyses of one recording, and one row per analysis (floor given / unknown)."""

    pairs: pd.DataFrame
    recordings: list = field(default_factory=list)


def trial(scenario_name, seed, directory=None, floors=FLOOR_CONDITIONS):
    """Simulate trial ``seed`` of ``scenario_name``, write its CSV, analyse it with each floor condition.

    Returns
    -------
    TrialResult
        ``pairs``: the rows of :func:`impact_pairs` with ``scenario``, ``seed`` and ``floor`` columns;
        ``recordings``: per floor condition a dict with ``status`` (``ok`` or ``failed``),
        ``message``, ``n_simulated`` (impacts whose touchdown lies in the log), ``n_analysed``,
        ``n_matched``, ``n_unmatched`` (analysed impacts that match no simulated one), the seconds
        spent simulating and analysing, and the drawn parameters.
    """
    scenario = SCENARIOS[scenario_name]
    with tempfile.TemporaryDirectory(dir=directory) as work:
        work = Path(work)
        start = time.perf_counter()
        rec = simulate_recording(scenario_name, seed)
        simulate_s = time.perf_counter() - start
        log_path = work / f"{scenario_name}_{seed}.csv"
        write_csv(rec.log, log_path, comments=[f"refsim {scenario.preset} ball, {scenario.point} of the ball, "
                                               f"{rec.parameters['rate_hz']:.1f} Hz (seed {seed})"])
        t_end_log = float(rec.log.iloc[-1, 0])
        true_impacts = rec.truth.impacts
        true_impacts = true_impacts[true_impacts["t_touchdown_s"] <= t_end_log].reset_index(drop=True)
        frames, rows = [], []
        for floor in floors:
            out = work / floor
            out.mkdir()
            info = {"scenario": scenario_name, "seed": seed, "floor": floor, "status": "ok", "stage": "", "message": "",
                    "n_simulated": len(true_impacts), "n_analysed": 0, "n_matched": 0, "n_unmatched": 0,
                    "simulate_s": simulate_s, **rec.parameters}
            start = time.perf_counter()
            run = None
            try:
                run = run_dropfit(log_path, out, ball_radius_m=rec.ball.radius_m, ball_mass_kg=rec.ball.mass_kg,
                                  ball_type=scenario.ball_type, gravity_m_s2=rec.truth.g_m_s2,
                                  floor_m=rec.floor_m if floor == "given" else None,
                                  scale_m_per_px=rec.scale_m_per_px, height_reference=rec.height_reference)
            except StageFailed as failure:
                # the workflow keeps what the earlier stages wrote: with only the fit failed, impacts.csv is there
                info.update(status="failed", stage=failure.stage, message=failure.message.replace(str(work), "<tmp>"))
                run = failure.run
            if run is not None:
                match = match_impacts(run.impacts["t_touchdown_s"], true_impacts, rec.truth.t_release_s)
                pairs = impact_pairs(run.impacts, true_impacts, match, floor == "given")
                frames.append(pairs.assign(scenario=scenario_name, seed=seed, floor=floor))
                info.update(n_analysed=len(run.impacts), n_matched=int(np.count_nonzero(match >= 0)),
                            n_unmatched=int(np.count_nonzero(match < 0)), drag_model=run.summary.get("drag_model"),
                            model=run.fit["restitution"]["model"] if run.fit else None,
                            notes=" | ".join(run.summary.get("notes") or []))
            info["analyse_s"] = time.perf_counter() - start
            rows.append(info)
    pairs = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=PAIR_COLUMNS)
    return TrialResult(pairs[PAIR_COLUMNS], rows)


def _where(error):
    """file:line of the innermost frame of ``error``'s traceback."""
    frames = traceback.extract_tb(error.__traceback__)
    return f"{Path(frames[-1].filename).name}:{frames[-1].lineno}" if frames else "?"


def _trial_job(arguments):
    return trial(*arguments)


def run_trials(jobs, workers=1, directory=None):
    """Run the trials ``jobs`` ((scenario, seed) pairs), in ``workers`` processes.

    Returns
    -------
    (pandas.DataFrame, pandas.DataFrame)
        All pairs, and one row per analysed recording and floor condition.
    """
    jobs = [(name, seed, directory) for name, seed in jobs]
    if workers > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        # one BLAS thread per worker: the workers already use the cores (set before numpy loads in them)
        with _single_thread_blas(), ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) \
                as pool:
            results = list(pool.map(_trial_job, jobs, chunksize=1))
    else:
        results = [_trial_job(job) for job in jobs]
    frames = [result.pairs for result in results if len(result.pairs)]
    pairs = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(columns=PAIR_COLUMNS)
    recordings = pd.DataFrame([row for result in results for row in result.recordings])
    return pairs, recordings


class _single_thread_blas:
    """Context: the environment of spawned workers asks OpenBLAS, MKL and OpenMP for one thread."""

    NAMES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")

    def __enter__(self):
        import os

        self.saved = {name: os.environ.get(name) for name in self.NAMES}
        os.environ.update({name: "1" for name in self.NAMES})

    def __exit__(self, *exc):
        import os

        for name, value in self.saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


# ------------------------------------------------------------------------------------------------
# Tables
# ------------------------------------------------------------------------------------------------
def coverage_table(pairs, keys=("scenario", "floor", "quantity")):
    """Per ``keys``: ``n`` pairs, ``n_recordings``, ``coverage`` (fraction with |z| ≤ 1.96), ``mean_z``
    and ``sd_z`` of z = (value − truth)/se, ``mean_error`` (value − truth, in the quantity's unit) and
    ``median_se``, ``n_no_interval`` (pairs without a finite value and se, counted as not covered), and
    ``coverage_se``, the standard error of the coverage with the recordings as clusters (impacts of one
    recording share flights and the drag)."""
    z = (pairs["value"] - pairs["truth"]) / pairs["se"]
    table = pairs.assign(z=z, covered=(np.abs(z) <= Z95).astype(float))
    keys = [key for key in keys if key in table]
    rows = []
    for key, group in table.groupby(keys, sort=False):
        per_recording = group.groupby("seed")["covered"].agg(["sum", "size"]) if "seed" in group else None
        rows.append({**dict(zip(keys, key if isinstance(key, tuple) else (key,))), "n": len(group),
                     "n_recordings": len(per_recording) if per_recording is not None else np.nan,
                     "coverage": group["covered"].mean(), "mean_z": group["z"].mean(), "sd_z": group["z"].std(),
                     "mean_error": (group["value"] - group["truth"]).mean(), "median_se": group["se"].median(),
                     "n_no_interval": int((~np.isfinite(group["z"])).sum()),
                     "coverage_se": _cluster_se(per_recording) if per_recording is not None else np.nan})
    return pd.DataFrame(rows)


def _cluster_se(per_recording):
    """Standard error of a ratio of sums over clusters (covered / pairs per recording)."""
    covered, size = per_recording["sum"].to_numpy(float), per_recording["size"].to_numpy(float)
    k = covered.size
    if k < 2:
        return np.nan
    ratio = covered.sum() / size.sum()
    residual = covered - ratio * size
    return float(np.sqrt(k / (k - 1) * np.sum(residual**2)) / size.sum())


def recordings_table(recordings):
    """Per scenario and floor: recordings run, failed (of them at the fit stage, whose impacts are still
    paired), and impacts simulated (touchdown within the log), analysed, matched per recording
    and unmatched in all; mean seconds to simulate and to analyse."""
    rows = []
    for (scenario, floor), group in recordings.groupby(["scenario", "floor"], sort=False):
        ok = group[group["status"] == "ok"]
        rows.append({"scenario": scenario, "floor": floor, "recordings": len(group),
                     "failed": int((group["status"] == "failed").sum()),
                     "failed_at_fit": int(((group["status"] == "failed") & (group["stage"] == "fit")).sum()),
                     "impacts_simulated_mean": group["n_simulated"].mean(),
                     "impacts_analysed_mean": ok["n_analysed"].mean() if len(ok) else np.nan,
                     "impacts_matched_mean": ok["n_matched"].mean() if len(ok) else np.nan,
                     "unmatched_total": int(ok["n_unmatched"].sum()),
                     "simulate_s_mean": group["simulate_s"].mean(), "analyse_s_mean": group["analyse_s"].mean()})
    return pd.DataFrame(rows)


def failure_messages(recordings):
    """Per scenario, floor, status and stage: each kind of message (numbers replaced by N), how many
    recordings got it, their seeds and one example."""
    import re

    columns = ["scenario", "floor", "status", "stage", "kind", "recordings", "seeds", "example"]
    failed = recordings[recordings["status"] != "ok"]
    if failed.empty:
        return pd.DataFrame(columns=columns)
    failed = failed.assign(kind=failed["message"].map(lambda text: re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "N",
                                                                           str(text))))
    rows = [(*key, len(group), " ".join(str(seed) for seed in group["seed"]), group["message"].iloc[0])
            for key, group in failed.groupby(["scenario", "floor", "status", "stage", "kind"], sort=False)]
    return pd.DataFrame(rows, columns=columns)
