"""Rule synth: every scenario of the scenarios file → its height log and ground truth, in one process."""

import sys
from pathlib import Path

from dropfit.stages import synth

with open(snakemake.log[0], "w", encoding="utf-8") as log:  # noqa: F821 — given by snakemake
    sys.stderr = sys.stdout = log
    for log_path, truth_path in zip(snakemake.output.logs, snakemake.output.truths):  # noqa: F821
        synth(snakemake.input.scenarios, Path(log_path).name.removesuffix(".csv"), log_path, truth_path)  # noqa: F821
        print(f"wrote {log_path} and {truth_path}")
