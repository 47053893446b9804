"""Turn a :class:`refsim.ball.Truth` into what a sensor's or tracker's file contains.

:func:`record` samples the truth at a given rate (with timing jitter, a start
offset such as a Unix epoch, dropped rows), logs one point of the ball
(bottom, centre or top) in m, cm, mm or image pixels (axis down), adds
Gaussian (optionally lag-1 correlated) noise, rounds to a resolution, adds
tracker jumps and lost samples (empty cells).  :func:`write_csv` writes it.

The hand phase before the release and a catch at the end are part of the
truth (see :func:`refsim.ball.simulate` with ``hand=`` / ``catch=``); the
recording simply samples them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
from scipy.signal import lfilter

from .ball import Truth

__all__ = ["Jumps", "RecordInfo", "record", "write_csv"]

_UNIT_SCALE = {"m": 1.0, "cm": 100.0, "mm": 1000.0}


@dataclass(frozen=True)
class Jumps:
    """Tracker jumps: runs of consecutive samples displaced by a constant offset.

    Parameters
    ----------
    n : int or (int, int)
        Number of jumps in the recording (a fixed number, or an inclusive
        range drawn uniformly).
    length : (int, int)
        Inclusive range of the run length in samples (1-6).
    size : (float, float) or None
        Range of the offset's magnitude in the **output unit** (e.g. px);
        the sign is random.  Default: (50, 200) px, converted with
        ``px_per_m`` for metric units if given, else (0.05, 0.2) m.
    """

    n: int | tuple[int, int] = (2, 5)
    length: tuple[int, int] = (1, 6)
    size: tuple[float, float] | None = None


@dataclass
class RecordInfo:
    """What :func:`record` did, sample by sample (before dropping rows: ``kept``).

    Attributes
    ----------
    t_true_s : ndarray
        True sampling instants (s, on the log's time base).
    t_logged_s : ndarray
        Times written to the log (s).
    y_true : ndarray
        Noise-free value of the logged point in the output unit.
    is_jump, is_lost, kept : ndarray of bool
        Sample was displaced by a tracker jump / written as an empty cell /
        kept in the log (not a dropped row).
    column : str
        Name of the value column (e.g. ``y_px``).
    settings : dict
        The arguments of :func:`record`.
    """

    t_true_s: np.ndarray
    t_logged_s: np.ndarray
    y_true: np.ndarray
    is_jump: np.ndarray
    is_lost: np.ndarray
    kept: np.ndarray
    column: str
    settings: dict = field(default_factory=dict)

    def to_frame(self) -> pd.DataFrame:
        """The per-sample information as a DataFrame (all samples, dropped ones too)."""
        return pd.DataFrame({"t_true_s": self.t_true_s, "t_logged_s": self.t_logged_s,
                             f"{self.column}_true": self.y_true, "is_jump": self.is_jump,
                             "is_lost": self.is_lost, "kept": self.kept})


def _rng(seed) -> np.random.Generator:
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(seed)


def _default_window(truth: Truth) -> tuple[float, float]:
    """Default (start, end) on the truth's reported time base, s."""
    if truth.hand is not None:
        start = truth.t_release_s - truth.hand.duration_s - 0.05
    else:
        start = truth.t_release_s - 0.25
    if truth.status == "rest":
        end = truth.rest_time_s + 1.0
    elif truth.status == "catch":
        end = truth.t_catch_s + 1.0
    else:
        end = truth.t_end_s
    return start, end


def record(truth: Truth, rate_hz: float, *, t_start_s: float | None = None, duration_s: float | None = None,
           point: str = "centre", unit: str = "m", px_per_m: float | None = None,
           floor_row_px: float | None = None, floor_offset_m: float = 0.0, time_offset_s: float = 0.0,
           time_unit: str = "s", jitter_frac: float = 0.0, timestamps: str = "actual", drop_frac: float = 0.0,
           lost_frac: float = 0.0, lost_run: tuple[int, int] = (1, 1), noise_sd: float = 0.0,
           noise_lag1: float = 0.0, resolution: float | None = None, jumps: Jumps | None = None,
           rng: np.random.Generator | int | None = 0, return_info: bool = False, horizontal: bool = False):
    """Sample a truth into a height log.

    Parameters
    ----------
    truth : Truth
        The simulated drop.
    rate_hz : float
        Nominal sample rate (Hz), e.g. 30 to 20000.
    t_start_s : float or None
        First nominal sample time on the truth's time base (s).  Default:
        just before the hand phase (or 0.25 s before the release).
    duration_s : float or None
        Length of the recording (s).  Default: to 1 s after the rest (or the
        catch), else to the truth's end.
    point : {"bottom", "centre", "top"}
        Which point of the ball is logged (bottom = max(floor, centre - R)).
    unit : {"m", "cm", "mm", "px"}
        Output unit.  Metric values are heights above the floor plus
        ``floor_offset_m``; pixels are image rows, axis down:
        ``row = floor_row_px - (y - floor) * px_per_m``.
    px_per_m : float or None
        Image scale (px/m); required for ``unit="px"``.
    floor_row_px : float or None
        Image row of the floor (px); required for ``unit="px"``.
    floor_offset_m : float
        Reading of the sensor (m) when the point is at the floor (the sensor
        zero not at the floor).  Metric units only.
    time_offset_s : float
        Added to the truth's times in the time column (s), e.g. 1.7e9 for a
        Unix epoch; use ``truth.shifted(time_offset_s)`` to compare.
    time_unit : {"s", "ms"}
        Unit of the time column (``time_s`` or ``time_ms``).
    jitter_frac : float
        Standard deviation of the sampling instants' jitter as a fraction of
        the interval 1/rate_hz (Gaussian, clipped at +-0.45 intervals).
    timestamps : {"actual", "nominal"}
        Whether the log shows the jittered true instants or the nominal grid
        (a clock that does not know its jitter).
    drop_frac : float
        Fraction of samples removed from the log altogether (rows missing).
    lost_frac : float
        Fraction of samples whose value is written as an empty cell.
    lost_run : (int, int)
        Inclusive range of the lengths of runs of lost samples.
    noise_sd : float
        Standard deviation of the Gaussian noise in the **output unit**.
    noise_lag1 : float
        Lag-1 autocorrelation of the noise (AR(1), marginal sd ``noise_sd``).
    resolution : float or None
        Round the values to multiples of this (output unit), e.g. 1 px or
        1 (mm) for an ultrasonic sensor.
    jumps : Jumps or None
        Tracker jumps.
    rng : numpy.random.Generator or int
        Random generator or seed (default 0: reproducible).
    return_info : bool
        Also return a :class:`RecordInfo`.
    horizontal : bool
        Also log the centre's horizontal position, column ``x_<unit>``: in
        m, cm or mm from x = 0, or in px as the image column ``x px_per_m``
        (axis right); its own Gaussian noise of ``noise_sd`` (drawn after
        everything else, so the heights are those of the same log without
        it), the same resolution, lost and dropped samples, no jumps.

    Returns
    -------
    pandas.DataFrame or (pandas.DataFrame, RecordInfo)
        Columns ``time_s`` (or ``time_ms``) and ``y_<unit>`` (and
        ``x_<unit>``); lost samples are NaN (written as empty cells by
        :func:`write_csv`).
    """
    if unit not in ("m", "cm", "mm", "px"):
        raise ValueError(f"unit must be m, cm, mm or px, got {unit!r}")
    if unit == "px" and (px_per_m is None or floor_row_px is None):
        raise ValueError("unit='px' needs px_per_m and floor_row_px")
    if timestamps not in ("actual", "nominal"):
        raise ValueError("timestamps must be 'actual' or 'nominal'")
    if not 0.0 <= noise_lag1 < 1.0:
        raise ValueError("noise_lag1 must be in [0, 1)")
    settings = dict(locals())
    settings.pop("truth")
    settings.pop("rng")
    g = _rng(rng)
    d_start, d_end = _default_window(truth)
    t0 = d_start if t_start_s is None else float(t_start_s)
    dur = (d_end - t0) if duration_s is None else float(duration_s)
    dt = 1.0 / rate_hz
    n = int(math.floor(dur * rate_hz + 1e-9)) + 1
    k = np.arange(n)
    t_nom = t0 + k * dt
    if jitter_frac > 0:
        jit = np.clip(g.normal(0.0, jitter_frac, n), -0.45, 0.45) * dt
    else:
        jit = np.zeros(n)
    t_true = t_nom + jit
    y_m = truth.y_point(t_true, point)

    if unit == "px":
        y_true = floor_row_px - (y_m - truth.floor_m) * px_per_m
    else:
        y_true = (y_m - truth.floor_m + floor_offset_m) * _UNIT_SCALE[unit]
    y = y_true.copy()

    if noise_sd > 0:
        e = g.normal(0.0, noise_sd, n)
        if noise_lag1 > 0:
            phi = noise_lag1
            e[1:] *= math.sqrt(1.0 - phi * phi)
            e = lfilter([1.0], [1.0, -phi], e)
        y = y + e

    is_jump = np.zeros(n, dtype=bool)
    if jumps is not None:
        nj = jumps.n if isinstance(jumps.n, (int, np.integer)) else int(g.integers(jumps.n[0], jumps.n[1] + 1))
        if jumps.size is not None:
            lo, hi = jumps.size
        elif unit == "px":
            lo, hi = 50.0, 200.0
        elif px_per_m is not None:
            lo, hi = 50.0 / px_per_m * _UNIT_SCALE[unit], 200.0 / px_per_m * _UNIT_SCALE[unit]
        else:
            lo, hi = 0.05 * _UNIT_SCALE[unit], 0.2 * _UNIT_SCALE[unit]
        placed = 0
        for _ in range(100 * max(nj, 1)):
            if placed >= nj:
                break
            L = int(g.integers(jumps.length[0], jumps.length[1] + 1))
            i0 = int(g.integers(1, max(n - L - 1, 2)))
            if is_jump[max(i0 - 2, 0): i0 + L + 2].any():
                continue
            off = g.uniform(lo, hi) * (1.0 if g.random() < 0.5 else -1.0)
            y[i0: i0 + L] += off
            is_jump[i0: i0 + L] = True
            placed += 1

    if resolution:
        y = np.round(y / resolution) * resolution

    is_lost = np.zeros(n, dtype=bool)
    if lost_frac > 0:
        target = int(round(lost_frac * n))
        for _ in range(100 * max(target, 1)):
            if is_lost.sum() >= target:
                break
            L = int(g.integers(lost_run[0], lost_run[1] + 1))
            i0 = int(g.integers(0, max(n - L, 1)))
            is_lost[i0: i0 + L] = True
        y[is_lost] = np.nan

    kept = np.ones(n, dtype=bool)
    if drop_frac > 0:
        nd = int(round(drop_frac * n))
        kept[g.choice(n, size=nd, replace=False)] = False

    t_logged = (t_true if timestamps == "actual" else t_nom) + time_offset_s
    t_col = t_logged if time_unit == "s" else t_logged * 1e3
    tname = "time_s" if time_unit == "s" else "time_ms"
    col = f"y_{unit}"
    log = pd.DataFrame({tname: t_col[kept], col: y[kept]})
    if horizontal:
        x = truth.x(t_true) * (px_per_m if unit == "px" else _UNIT_SCALE[unit])
        if noise_sd > 0:
            x = x + g.normal(0.0, noise_sd, n)
        if resolution:
            x = np.round(x / resolution) * resolution
        x[is_lost] = np.nan
        log[f"x_{unit}"] = x[kept]
    if not return_info:
        return log
    info = RecordInfo(t_true_s=t_true + time_offset_s, t_logged_s=t_logged, y_true=y_true, is_jump=is_jump,
                      is_lost=is_lost, kept=kept, column=col, settings=settings)
    return log, info


def write_csv(log: pd.DataFrame, path, comments: list[str] | None = None, float_format: str | None = None) -> None:
    """Write a log as CSV: optional ``# comment`` lines, a header, empty cells for NaN.

    Parameters
    ----------
    log : pandas.DataFrame
        Output of :func:`record`.
    path : str or path-like
        Destination file.
    comments : list of str or None
        Lines written first, each prefixed with ``# ``.
    float_format : str or None
        printf-style format of the numbers (e.g. ``"%.6f"``); default the
        shortest text that reads back to the same float.
    """
    with open(path, "w", newline="") as fh:
        for c in comments or []:
            fh.write(f"# {c}\n")
        log.to_csv(fh, index=False, na_rep="", lineterminator="\n", float_format=float_format)
