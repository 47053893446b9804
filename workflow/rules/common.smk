# Helpers: check and load the config and the sample sheet (a problem stops the workflow before any job,
# one line per problem), group the recordings into the jobs that process them (chunks), and the
# handlers that clean up at the start and list the failed recordings at the end. No rules here.

import json
import math
import os
import re
import shlex
import shutil
import sys

import yaml
from jsonschema import Draft202012Validator

from dropfit.files import FAILED
from dropfit.settings import stage_arguments
from dropfit.stages import read_sample_sheet, recording_files, sample_sheet_lines
from dropfit.synth import scenario_recordings
from dropfit.video_synth import default_clips


def _schema(name):
    """The JSON schema ``workflow/schemas/<name>.schema.yaml``."""
    with open(os.path.join(workflow.basedir, "workflow", "schemas", f"{name}.schema.yaml")) as handle:
        return yaml.safe_load(handle)


def _schema_problems(record, schema, where, part="column"):
    """One line per way ``record`` breaks ``schema``: ``<where>, <part> <name>: <what is wrong>``."""
    problems = []
    for error in sorted(Draft202012Validator(schema).iter_errors(record), key=lambda error: list(error.path)):
        if error.validator == "required":
            missing = [name for name in error.validator_value if name not in error.instance]
            problems += [f"{where}, {part} {name}: missing" for name in missing]
        else:
            column = ".".join(map(str, error.path)) or "?"
            problems.append(f"{where}, {part} {column}: {error.message}")
    return problems


def _typed(value, kind):
    """A sample-sheet cell as the schema's type wants it (a number where it reads as one; else the text,
    which the schema then refuses)."""
    if kind in ("number", "integer"):
        try:
            number = float(value)
        except ValueError:
            return value
        return int(number) if kind == "integer" and number.is_integer() else number
    return value


def sample_sheet_problems(path, schema):
    """Every problem of the sample sheet at ``path``, one line each, naming the line of the file, the
    column and what is wrong (an empty list for a good sheet)."""
    if not os.path.isfile(path):
        return [f"{path}: sample sheet not found; set samples in config/config.yaml to your sheet's path"]
    lines = sample_sheet_lines(path)
    if not lines:
        return [f"{path}: empty; the first line names the columns, separated by tabs"]
    header = lines[0][1].split("\t")
    if len(header) == 1 and re.search(r"\S\s+\S", header[0]):
        return [f"{path}: line {lines[0][0]}: the column names are separated by spaces; separate them by tabs"]
    types = {name: spec.get("type") for name, spec in schema["properties"].items()}
    problems, seen = [], {}
    for number, line in lines[1:]:
        fields = line.split("\t")
        # a row may leave out its last, empty cells, unless it has runs of spaces where tabs belong
        spaced = any(len(re.findall(r"\S\s+(?=\S)", field)) >= 2 for field in fields)
        if len(fields) > len(header) or (len(fields) < len(header) and spaced):
            hint = ("spaces stand where a tab belongs; separate the columns by tabs" if spaced else
                    "give one tab-separated value per column (nothing between two tabs for none)")
            problems.append(f"{path}: line {number}: {len(fields)} values where the header names {len(header)} "
                            f"columns; {hint}")
            continue
        record = {name: _typed(value.strip(), types.get(name)) for name, value in zip(header, fields) if value.strip()}
        problems += _schema_problems(record, schema, f"{path}: line {number} ({record.get('sample_id', '?')})")
        seen.setdefault(record.get("sample_id"), []).append(number)
    for sample_id, numbers in seen.items():
        if sample_id is not None and len(numbers) > 1:
            problems.append(f"{path}: sample_id {sample_id} is on lines {', '.join(map(str, numbers))}; "
                            f"give each recording its own sample_id")
    return problems


def stop_on_problems(problems):
    """Print the problems, one line each, and stop the workflow (exit status 1) before any job."""
    if problems:
        print("\n".join(problems), file=sys.stderr)
        sys.exit(1)


def typed_command_line_values(config, schema):
    """``snakemake --config key=value`` passes ``false`` (and every value of ``key={a: 1}``) as text where a config
    file gives YAML's boolean and number: a value the schema does not allow as text is read as YAML reads it,
    in nested keys too."""
    for key, value in config.items():
        part = schema.get("properties", {}).get(key, {})
        kinds = part.get("type", [])
        if isinstance(value, dict):
            typed_command_line_values(value, part)
        elif isinstance(value, str) and "string" not in ([kinds] if isinstance(kinds, str) else kinds):
            try:
                config[key] = yaml.safe_load(value)
            except yaml.YAMLError:  # left as text: the schema's check names it
                pass


typed_command_line_values(config, _schema("config"))
stop_on_problems(_schema_problems(config, _schema("config"), "config", "key"))
stop_on_problems(sample_sheet_problems(config["samples"], _schema("samples")))
samples = read_sample_sheet(config["samples"])

with open(config["scenarios"]) as handle:
    scenarios = yaml.safe_load(handle)
stop_on_problems(_schema_problems(scenarios, _schema("scenarios"), config["scenarios"], "key"))

#: Every synthetic recording rule synth makes; a scenario with n drops makes n of them.
synthetic_recordings = list(scenario_recordings(scenarios["scenarios"]))
#: Where rules synth and synth_refsim write the synthetic height logs and their ground truth.
SYNTH_DIR = "results/synthetic"
#: Synthetic recordings made by the independent simulator refsim (rule synth_refsim; refsim.scenarios).
refsim_recordings = ["seed_example3_oblique"]

#: Where rule synth_video renders the default synthetic videos.
VIDEO_DIR = "results/video"
video_clips = list(default_clips())
#: Where rule synth_audio renders the synthetic drop-test sound.
AUDIO_DIR = "results/audio"

#: Recordings made by the synth rules, which are a job's input even before they exist.
MADE_RECORDINGS = ({f"{SYNTH_DIR}/{name}.csv" for name in synthetic_recordings + refsim_recordings}
                   | {f"{VIDEO_DIR}/{clip}.avi" for clip in video_clips} | {f"{AUDIO_DIR}/table_tennis_40cm.wav"})


def _alternatives(names):
    """Regex matching exactly one of ``names`` (for wildcard constraints); nothing when there are none (an
    empty alternation would match anything)."""
    return "|".join(re.escape(str(name)) for name in names) or "(?!)"


wildcard_constraints:
    scenario=_alternatives(synthetic_recordings),
    refsim_scenario=_alternatives(refsim_recordings),
    batch=_alternatives(samples["batch"].unique()),
    clip=_alternatives(video_clips),


# --- chunks: the recordings one job processes in one Python process ------------------------------

#: Most recordings per job, by group (config chunk_size overrides): a log takes about a second, a
#: video tens of seconds, so a job's start-up (about 2 s) is small beside either.
CHUNK_SIZE = {"logs": 100, "videos": 4} | (config.get("chunk_size") or {})


#: Jobs each group of recordings is spread over at least (config parallel_jobs). Not the cores of the
#: run: a cluster job plans the workflow again where it runs, and its chunks must be the submitter's.
PARALLEL_JOBS = int(config.get("parallel_jobs") or 2)


def chunked(sample_ids, most, parallel):
    """``sample_ids`` split in order into chunks of at most ``most``, as many as a multiple of ``parallel``
    (so that parallel jobs finish together) and never more than the recordings."""
    count = min(len(sample_ids), parallel * math.ceil(len(sample_ids) / (most * parallel)))
    return [sample_ids[i * len(sample_ids) // count:(i + 1) * len(sample_ids) // count] for i in range(count)]


#: Video recordings (kind video: tracked in the frames) and the others (height logs and sounds, kind
#: audio, a video's sound track included), in sheet order.
video_samples = list(samples.index[samples["kind"] == "video"])
log_samples = list(samples.index[samples["kind"] != "video"])
#: Chunk name → its sample ids: process_logs_<i> and process_videos_<i>.
chunks = {f"process_{group}_{i + 1}": members
          for group, members in (("logs", log_samples), ("videos", video_samples))
          for i, members in enumerate(chunked(members, int(CHUNK_SIZE[group]), PARALLEL_JOBS))}

#: The config of ``dropfit batch --config`` (JSON): the keys it maps onto dropfit's options.
BATCH_CONFIG = json.dumps({key: config[key] for key in ("gravity_m_s2", "latitude_deg", "altitude_m", "analysis",
                                                        "itf") if key in config}, sort_keys=True)

#: How each results file is shown in ``snakemake --report``: caption, category and figure label.
REPORTED = {"report.html": ("recording.rst", "Recordings", "report"),
            "report.png": ("figure.rst", "Recordings", "figure"),
            "contact_sheet.png": ("contact_sheet.rst", "What was tracked", "contact sheet")}


def chunk_outputs(members):
    """Every file the chunk writes, ``results/<sample_id>/<file>``, the reports marked for the report."""
    outputs = []
    for sample in members:
        for name in recording_files(samples.loc[sample, "kind"]):
            path = f"results/{sample}/{name}"
            if name in REPORTED:
                caption, category, figure = REPORTED[name]
                path = report(path, caption=f"../report/{caption}", category=category,
                              labels={"sample": sample, "figure": figure})
            outputs.append(path)
    return outputs


def chunk_inputs(members):
    """The chunk's recordings that exist or that a rule makes. A missing one is no input (it must not
    stop the workflow): ``dropfit batch`` writes the failure records that name it."""
    paths = [samples.loc[sample, "path"] for sample in members]
    return [path for path in paths if os.path.exists(path) or os.path.normpath(path) in MADE_RECORDINGS]


def chunk_runtime(members):
    """Minutes a chunk's job may take (a cluster's time limit): 10, and 6 s per log, 3 min per video."""
    videos = sum(samples.loc[sample, "kind"] == "video" for sample in members)
    return 10 + math.ceil(0.1 * (len(members) - videos) + 3 * videos)


def chunk_rows(members):
    """The chunk's sample-sheet rows as JSON: a parameter, so that a changed row reruns its chunk."""
    return samples.loc[members].to_json(orient="records")


# --- batch outputs -----------------------------------------------------------------------------


def all_reports(wildcards):
    """HTML report of every sample."""
    return expand("results/{sample}/report.html", sample=samples.index)


def all_fits(wildcards):
    """fit.json of every sample, for the batch summary."""
    return expand("results/{sample}/fit.json", sample=samples.index)


def all_qc_reports(wildcards):
    """QC report of every batch."""
    return expand("results/batch/qc_{batch}.html", batch=samples["batch"].unique())


def batch_samples(wildcards):
    """Sample-sheet rows (pandas.DataFrame) of the recordings of ``wildcards.batch``."""
    return samples[samples["batch"] == wildcards.batch]


def batch_fits(wildcards):
    """fit.json of every recording of the batch, in sample-sheet order."""
    return expand("results/{sample}/fit.json", sample=batch_samples(wildcards).index)


def batch_ball_ids(wildcards):
    """Ball id of every recording of the batch, in the order of :func:`batch_fits`, shell-quoted."""
    return " ".join(shlex.quote(str(ball)) for ball in batch_samples(wildcards)["ball_id"])


def output_directory(wildcards, output):
    """Directory of a rule's first output (for commands that take a directory)."""
    return os.path.dirname(output[0])


def qc_args(wildcards):
    """``dropfit qc`` options: the ITF rebound test limits (m), from the config, shell-quoted."""
    return " ".join(shlex.quote(argument) for argument in stage_arguments("qc", config))


# --- handlers ----------------------------------------------------------------------------------

#: A temporary file of dropfit's (``.<name>.<random><suffix>`` beside its output) or directory
#: (``.dropfit-run.<pid>@<host>.<random>``; ``.dropfit-run.<random>`` of an older dropfit), left behind only by a
#: job that was killed.
TEMPORARY = re.compile(r"^\.(dropfit-run\.(\d+@[A-Za-z0-9-]+\.)?[a-z0-9_]{8}|.+\.[a-z0-9_]{8}(\.[A-Za-z0-9]+)?)$")


def remove_leftovers():
    """Remove what killed jobs left under results/ (temporary files), and the QC pages of batches
    that are no longer in the sample sheet."""
    for directory, names, files in os.walk("results"):
        for name in [name for name in names if TEMPORARY.match(name)]:
            shutil.rmtree(os.path.join(directory, name), ignore_errors=True)
            names.remove(name)
        for name in files:
            if TEMPORARY.match(name):
                os.remove(os.path.join(directory, name))
    batches = set(samples["batch"])
    pages = re.compile(r"^qc_(.+?)(\.html|\.png|_balls\.csv)$")
    for name in os.listdir("results/batch") if os.path.isdir("results/batch") else []:
        match = pages.match(name)
        if match and match.group(1) not in batches:
            os.remove(os.path.join("results/batch", name))


def failed_recordings():
    """sample_id → reason of every recording of the sheet whose fit.json is a failure record."""
    failed = {}
    for sample in samples.index:
        try:
            with open(f"results/{sample}/fit.json", encoding="utf-8") as handle:
                record = json.load(handle)
        except (OSError, ValueError):  # not made: its job failed, which snakemake reports
            continue
        if isinstance(record, dict) and record.get("status") == FAILED:
            failed[sample] = record.get("error", "")
    return failed


def list_failed_recordings():
    """Print the failed recordings, one line each with the reason; exit 1 if there are any and the
    config's fail_on_failed_recordings is true (its default)."""
    failed = failed_recordings()
    if not failed:
        return
    lines = [f"{len(failed)} of {len(samples)} recordings failed (see results/batch/summary.html):"]
    lines += [f"  {sample}: {reason}" for sample, reason in failed.items()]
    strict = config.get("fail_on_failed_recordings", True)
    if strict:
        lines.append("exit status 1; set fail_on_failed_recordings: false in the config to exit 0 all the same")
    print("\n".join(lines), file=sys.stderr)
    if strict:
        sys.exit(1)
