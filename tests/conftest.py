"""Shared synthetic recordings with known ground truth."""

import os

import dropfit  # noqa: F401  (before NumPy: one BLAS thread, as in `dropfit run` and the workflow's jobs)
import numpy as np
import pytest

from dropfit.synth import sample_height_log, simulate_drop

# The tests run ``dropfit`` in subprocesses from temporary directories: a relative PYTHONPATH (the
# README's ``PYTHONPATH=src``) would point nowhere there, and they would run another installed copy.
if os.environ.get("PYTHONPATH"):
    os.environ["PYTHONPATH"] = os.pathsep.join(os.path.abspath(entry) if entry else entry
                                               for entry in os.environ["PYTHONPATH"].split(os.pathsep))

TENNIS = dict(drop_height_m=2.54, radius_m=0.0335, mass_kg=0.057)


@pytest.fixture(scope="session")
def tennis_truth():
    """ITF-like tennis ball from 254 cm with realistic air drag (C_d = 0.55)."""
    return simulate_drop(restitution_model={"kind": "constant", "e0": 0.775}, drag_coefficient=0.55, **TENNIS)


@pytest.fixture(scope="session")
def vacuum_truth():
    """The same ball without drag: flights are exact parabolas."""
    return simulate_drop(restitution_model={"kind": "constant", "e0": 0.775}, **TENNIS)


def sensor_log(truth, seed, sample_rate_hz=100.0, noise_m=0.001, offset_m=0.2, dropout_fraction=0.01):
    """The 100 Hz, 1 mm sensor of the accuracy requirements, seeded."""
    return sample_height_log(truth, np.random.default_rng(seed), sample_rate_hz, noise_m=noise_m,
                             offset_m=offset_m, dropout_fraction=dropout_fraction)
