# Helpers: load and validate the config, the sample sheet and the synthetic scenarios, and build
# the per-sample command-line options of the dropfit stages from them (dropfit.settings maps the
# config keys and sample-sheet columns onto dropfit's options, whose defaults live in
# dropfit.settings.Settings). No rules here.

import os
import re
import shlex

import pandas as pd
import yaml
from snakemake.utils import validate


validate(config, schema="../schemas/config.schema.yaml")

samples = pd.read_csv(
    config["samples"],
    sep="\t",
    dtype={"sample_id": str, "kind": str, "path": str, "ball_type": str, "batch": str, "ball_id": str},
    comment="#",
)
validate(samples, schema="../schemas/samples.schema.yaml")
samples = samples.set_index("sample_id", drop=False)
if not samples.index.is_unique:
    raise ValueError(f"duplicate sample_id in {config['samples']}")
# the optional grouping columns: a recording without a ball is a ball of its own, one without a batch
# belongs to the batch "unbatched"
samples["ball_id"] = samples.get("ball_id", pd.Series(dtype=str)).reindex(samples.index).fillna(samples["sample_id"])
samples["batch"] = samples.get("batch", pd.Series(dtype=str)).reindex(samples.index).fillna("unbatched")

with open(config["scenarios"]) as handle:
    scenarios = yaml.safe_load(handle)
validate(scenarios, schema="../schemas/scenarios.schema.yaml")


from dropfit.settings import stage_arguments
from dropfit.synth import scenario_recordings
from dropfit.video_synth import default_clips

#: Every synthetic recording the synth jobs make; a scenario with n drops makes n of them.
synthetic_recordings = list(scenario_recordings(scenarios["scenarios"]))

#: Synthetic recordings made by the independent simulator refsim (rule synth_refsim; refsim.scenarios).
refsim_recordings = ["seed_example3_oblique"]

#: Where rule synth_video renders the default synthetic videos.
VIDEO_DIR = "results/video"
video_clips = list(default_clips())
#: Where rule synth_audio renders the synthetic drop-test sound.
AUDIO_DIR = "results/audio"


def _alternatives(names):
    """Regex matching exactly one of ``names`` (for wildcard constraints); none, when there are none (an
    empty alternation would match anything: a sheet without videos made measure and measure_video ambiguous)."""
    return "|".join(re.escape(str(name)) for name in names) or "(?!)"


from dropfit.videolog import is_video

#: Samples whose recording is a video: its measure job also writes the tracked table (track.csv), and
#: an overlay job draws what was tracked on its frames (contact_sheet.png), refused clips included; a
#: video of kind audio is measured by its sound track.
video_samples = [sample for sample in samples.index
                 if is_video(samples.loc[sample, "path"]) and samples.loc[sample, "kind"] != "audio"]
log_samples = [sample for sample in samples.index if sample not in video_samples]


wildcard_constraints:
    sample=_alternatives(samples.index),
    scenario=_alternatives(synthetic_recordings),
    refsim_scenario=_alternatives(refsim_recordings),
    batch=_alternatives(samples["batch"].unique()),
    clip=_alternatives(video_clips),


def sample_row(wildcards):
    """Sample-sheet row (pandas.Series) of ``wildcards.sample``."""
    return samples.loc[wildcards.sample]


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


def recording_path(wildcards):
    """The sample's raw recording (column ``path``)."""
    return sample_row(wildcards)["path"]


def measure_input(wildcards):
    """The recording as the measure job's input, if it exists or a rule makes it.

    A missing recording must not stop the batch: the job then runs without input, and
    ``dropfit measure`` writes the failure record that names the missing file.
    """
    path = recording_path(wildcards)
    synthetic = {f"data/synthetic/{name}.csv" for name in synthetic_recordings + refsim_recordings}
    synthetic |= {f"{VIDEO_DIR}/{clip}.avi" for clip in video_clips} | {f"{AUDIO_DIR}/table_tennis_40cm.wav"}
    if os.path.exists(path) or os.path.normpath(path) in synthetic:
        return path
    return []


def _stage_options(stage, wildcards=None):
    """``--flag value`` options of ``dropfit <stage>`` for the sample (or, without ``wildcards``, for the
    batch), shell-quoted: the config and the sample-sheet row mapped onto dropfit's options
    (``dropfit.settings.stage_arguments``). An option left out of both is not passed, so the stage
    uses dropfit's default (``dropfit.settings.Settings``)."""
    row = sample_row(wildcards) if wildcards is not None else None
    return " ".join(shlex.quote(argument) for argument in stage_arguments(stage, config, row))


def measure_args(wildcards):
    """``dropfit measure`` options: ball radius (m), mass (kg) and type, scale (m/px), ruler tick (m),
    floor (m), capture rate (frames/s), and the site: g (m/s²) or latitude (°) and altitude (m)."""
    return _stage_options("measure", wildcards)


def analyse_args(wildcards):
    """``dropfit analyse`` options: drag mode and the site: g (m/s²) or latitude (°) and altitude (m)."""
    return _stage_options("analyse", wildcards)


def fit_args(wildcards):
    """``dropfit fit`` options: ball type and the ITF rebound test limits and tolerance (m)."""
    return _stage_options("fit", wildcards)


def qc_args(wildcards):
    """``dropfit qc`` options: the ITF rebound test limits (m), from the config."""
    return _stage_options("qc")


def contact_sheet(wildcards):
    """A video's contact sheet, which its report shows (none for a height log)."""
    return f"results/{wildcards.sample}/contact_sheet.png" if wildcards.sample in video_samples else []


def contact_sheet_option(wildcards, input):
    """``--contact-sheet <png>`` of ``dropfit report`` for a video, else nothing."""
    return f"--contact-sheet {shlex.quote(str(input.contact_sheet))}" if input.contact_sheet else ""
