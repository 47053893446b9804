"""dropfit: ball drop tests to trustworthy numbers.

The public API: analyse a recording as the workflow does (:func:`analyse_recording`, giving a
:class:`RecordingResult`, with every option in :class:`Settings`); simulate and sample a drop test,
read a height log, analyse the bounces, and estimate e (constant, or the model of e chosen by
evidence) with the theory checks and the ITF verdict.
"""

__version__ = "0.1.0"

import os

# dropfit's matrices are small: BLAS threads do not speed its fits, and they make the last digits depend on the
# core count (a workflow job runs on one thread, `dropfit run` had two: impacts.csv differed at 1e-12). Every
# process that imports dropfit before NumPy computes on one BLAS thread, unless the user says otherwise.
for _variable in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

from .analysis import BounceAnalysis, analyse_bounces
from .errors import InputError
from .heightlog import read_height_log, trajectory_from_log
from .impulse import (BallOnBlock, CentralImpact, average_force, ball_on_block, central_impact,
                      half_sine_peak_force, impulse)
from .pipeline import analyse_recording, analyse_trajectory, measure_recording
from .restitution import constant_restitution, itf_rebound, itf_verdict, theory_checks
from .result import Parameter, RecordingResult
from .settings import Ball, Settings
from .speed_dependence import fit_restitution_models
from .synth import DropTruth, sample_height_log, simulate_drop, synthesize

__all__ = [
    "Ball",
    "BallOnBlock",
    "BounceAnalysis",
    "CentralImpact",
    "DropTruth",
    "InputError",
    "Parameter",
    "RecordingResult",
    "Settings",
    "analyse_bounces",
    "analyse_recording",
    "analyse_trajectory",
    "average_force",
    "ball_on_block",
    "central_impact",
    "constant_restitution",
    "fit_restitution_models",
    "half_sine_peak_force",
    "impulse",
    "itf_rebound",
    "itf_verdict",
    "measure_recording",
    "read_height_log",
    "sample_height_log",
    "simulate_drop",
    "synthesize",
    "theory_checks",
    "trajectory_from_log",
]
