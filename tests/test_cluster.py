"""The workflow through a real SLURM cluster (slow): the one-node cluster of ``.ci/start-slurm`` runs the
jobs of ``snakemake --profile workflow/profiles/cluster`` on the small batch of ``.test/cluster/``, and
the fits equal those of a local run of the same recordings. Without SLURM the test fails and says why."""

import json
import os
import re
import shutil
import signal
import subprocess
from importlib.util import find_spec
from pathlib import Path

import pandas as pd
import pytest

REPO = Path(__file__).resolve().parents[1]
#: Time limit of one workflow run (about 3 min through the cluster on a busy 2-core machine).
RUN_TIMEOUT_S = 600  # s
#: Time limit of one SLURM query.
QUERY_TIMEOUT_S = 30  # s
CONFIG = ".test/cluster/config.yaml"
#: What snakemake prints for each job it hands to SLURM.
SUBMITTED = re.compile(r"^Job \d+ has been submitted with SLURM jobid (\d+) \(log: (.+)\)\.$", re.MULTILINE)


def slurm_problem():
    """Why this machine cannot run the workflow through SLURM (str), or None when it can."""
    if find_spec("snakemake_executor_plugin_slurm") is None:
        return "snakemake-executor-plugin-slurm is not installed; pip install -e '.[cluster]'"
    if shutil.which("sinfo") is None or shutil.which("sbatch") is None:
        return "SLURM's commands (sinfo, sbatch) are not installed; start the cluster with .ci/start-slurm"
    try:
        states = subprocess.run(["sinfo", "-h", "-o", "%t"], capture_output=True, text=True, timeout=QUERY_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return f"sinfo did not answer in {QUERY_TIMEOUT_S} s; start the cluster with .ci/start-slurm"
    if states.returncode != 0:
        return f"sinfo failed ({states.stderr.strip()}); start the cluster with .ci/start-slurm"
    if not {"idle", "mix", "alloc"} & set(states.stdout.split()):
        return f"no SLURM node can take jobs (sinfo: {states.stdout.split()}); start the cluster with .ci/start-slurm"
    return None


def workflow_copy(destination):
    """The Snakefile, workflow/, config/, data/ and .test/cluster/ copied to a new ``destination``; its path."""
    destination.mkdir()
    shutil.copy2(REPO / "Snakefile", destination / "Snakefile")
    for name in ("workflow", "config", "data", ".test/cluster"):
        shutil.copytree(REPO / name, destination / name, ignore=shutil.ignore_patterns("__pycache__"))
    # a checkout gives the committed logs and scenarios.yaml arbitrary mtimes, and a synth job would
    # remake a log that looks older (same bytes): not what this test is about
    scenarios = (destination / "data" / "synthetic" / "scenarios.yaml").stat().st_mtime
    for path in (destination / "data" / "synthetic").glob("*.csv"):
        os.utime(path, (scenarios + 1, scenarios + 1))
    return destination


def run_snakemake(roots_and_profiles):
    """Run ``snakemake --profile P … --configfile .test/cluster/config.yaml`` in each root at once, with its
    profiles; return each run's (exit status, output)."""
    runs = []
    try:
        for root, profiles in roots_and_profiles:
            arguments = [argument for profile in profiles for argument in ("--profile", profile)]
            with open(root / "snakemake.out", "w", encoding="utf-8") as out:
                runs.append(subprocess.Popen([shutil.which("snakemake"), *arguments, "--configfile", CONFIG],
                                             cwd=root, stdout=out, stderr=subprocess.STDOUT))
        statuses = [run.wait(timeout=RUN_TIMEOUT_S) for run in runs]
    finally:
        for run in runs:  # on a timeout: an interrupted snakemake cancels its SLURM jobs (scancel)
            if run.poll() is None:
                run.send_signal(signal.SIGINT)
                try:
                    run.wait(timeout=QUERY_TIMEOUT_S)
                except subprocess.TimeoutExpired:
                    run.kill()
    return [(status, (root / "snakemake.out").read_text(encoding="utf-8"))
            for status, (root, _) in zip(statuses, roots_and_profiles)]


def outputs(text):
    """Every file named on the ``output:`` lines of the jobs snakemake describes in ``text``, but those of
    local rules (which run where snakemake runs)."""
    files, local = set(), False
    for line in text.splitlines():
        header = re.match(r"^(local)?(rule|checkpoint) \S+:$", line)
        if header:
            local = bool(header[1])
        elif line.startswith("    output: ") and not local:
            files.update(line.removeprefix("    output: ").split(", "))
    return files


def minutes(limit):
    """Minutes of a SLURM time limit written ``[days-][hours:]minutes:seconds``."""
    days, _, clock = limit.rpartition("-")
    seconds = 0
    for part in clock.split(":"):
        seconds = 60 * seconds + int(part)
    return (int(days or 0) * 86400 + seconds) // 60


def e_and_se(root, sample):
    """(e, se) of the constant restitution law and of the first impact in the sample's fit.json."""
    fit = json.loads((root / "results" / sample / "fit.json").read_text(encoding="utf-8"))
    restitution = fit["restitution"]
    return [(restitution[key]["value"], restitution[key]["se"]) for key in ("e", "e1")]


@pytest.mark.slow
def test_workflow_through_slurm_matches_a_local_run(tmp_path):
    """Every file of the run was made in a SLURM job (each job COMPLETED in SLURM's own words, in the run's
    directory, with the memory and time limit the workflow asked for; its log names the files it made); e
    and its standard error equal those of a local run."""
    problem = slurm_problem()
    if problem:
        pytest.fail(f"SLURM is not available: {problem}")
    local_root, cluster_root = (workflow_copy(tmp_path / name) for name in ("local", "cluster"))
    # both at once: the cluster run mostly waits for SLURM
    (status, output), (local_status, local_output) = run_snakemake([
        (cluster_root, ["workflow/profiles/cluster", ".test/cluster/profile"]),
        (local_root, ["workflow/profiles/default"])])
    assert status == 0, output[-3000:]
    assert local_status == 0, local_output[-3000:]

    submitted = dict(SUBMITTED.findall(output))
    assert submitted, output[-3000:]
    states = subprocess.run(["squeue", "--states=all", "--noheader", "--format=%i|%T|%Z|%m|%l",
                             "--jobs=" + ",".join(submitted)], capture_output=True, text=True,
                            timeout=QUERY_TIMEOUT_S)
    assert states.returncode == 0, states.stderr
    reported = {job: (state, workdir, memory, minutes(limit))
                for job, state, workdir, memory, limit in (line.split("|") for line in states.stdout.split())}
    # each job COMPLETED in the run's directory, with the memory and time the workflow asked for
    logs = {job: Path(log).read_text(encoding="utf-8") for job, log in submitted.items()}
    asked = {job: dict(re.findall(r"\b(mem_mb|runtime)=(\d+)", log.split("resources: ")[1].splitlines()[0]))
             for job, log in logs.items()}
    assert reported == {job: ("COMPLETED", str(cluster_root.resolve()), f"{asked[job]['mem_mb']}M",
                              int(asked[job]["runtime"])) for job in submitted}
    # every file the run made outside local rules was made in a SLURM job (whatever the rules and groups)
    made_in_slurm = set().union(*(outputs(log) for log in logs.values()))
    assert outputs(output) == made_in_slurm
    samples = pd.read_csv(REPO / ".test" / "cluster" / "samples.tsv", sep="\t")["sample_id"]
    assert {f"results/{sample}/fit.json" for sample in samples} <= made_in_slurm

    for sample in samples:
        assert e_and_se(cluster_root, sample) == e_and_se(local_root, sample)
