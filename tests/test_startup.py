"""What each ``dropfit`` process pays before its work: the command line loads no video, sound, plotting or
scipy.stats module, and the cheap exact replacements for scipy.stats agree with closed forms."""

import subprocess
import sys

import numpy as np
import pytest

from dropfit.numerics import chi2_tail, normal_quantile, running_min, t_quantile

from helpers import CALL_TIMEOUT_S

#: Modules a height log's stages never use, and that cost most of a second to import between them.
HEAVY_MODULES = ("cv2", "av", "matplotlib", "scipy.stats", "soundfile")


@pytest.mark.parametrize("module", ["dropfit.cli", "dropfit"])
def test_import_loads_no_heavy_module(module):
    """A fresh interpreter importing the command line (or the package) has none of HEAVY_MODULES loaded."""
    code = f"import sys, {module}; print(' '.join(m for m in {HEAVY_MODULES!r} if m in sys.modules))"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=CALL_TIMEOUT_S)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == []


def test_quantiles_match_closed_forms():
    """Normal, t and χ² functions against closed forms: the t distribution with 1 degree of freedom is
    Cauchy, with 2 it is (2p − 1)/√(2p(1 − p)); the χ² tail with 2 degrees of freedom is exp(−x/2)."""
    p = np.array([0.6, 0.9, 0.975, 0.999])
    assert normal_quantile(0.975) == pytest.approx(1.959963984540054, rel=1e-14)
    assert normal_quantile(0.5) == 0.0
    np.testing.assert_allclose(t_quantile(p, 1), np.tan(np.pi * (p - 0.5)), rtol=1e-12)
    np.testing.assert_allclose(t_quantile(p, 2), (2 * p - 1) / np.sqrt(2 * p * (1 - p)), rtol=1e-12)
    x = np.array([0.1, 1.0, 7.5, 40.0])
    np.testing.assert_allclose(chi2_tail(x, 2), np.exp(-x / 2), rtol=1e-12)
    # non-integer degrees of freedom (the misfit test's effective count): between its integer neighbours
    assert chi2_tail(3.0, 2.0) < chi2_tail(3.0, 2.5) < chi2_tail(3.0, 3.0)


@pytest.mark.parametrize("half_width", [0, 1, 3, 40])
def test_running_min_is_the_window_minimum(half_width):
    """The linear-time running minimum equals the minimum of each window taken directly (ties, ends)."""
    values = np.round(np.random.default_rng(half_width).normal(size=257), 1)  # rounded: many ties
    direct = [values[max(0, i - half_width): i + half_width + 1].min() for i in range(values.size)]
    np.testing.assert_array_equal(running_min(values, half_width), direct)
