"""Impact times from sound: each click found, timed at its onset below one sample interval, with a
standard error; the clicks that belong to one bouncing ball picked out of echoes, double clicks and noise.

The steps follow the signal:

1. :func:`click_envelope` — the channels averaged, low frequencies (hum, handling, wind) removed by a
   zero-phase high-pass, the Hilbert envelope smoothed by a short centred window (zero phase: the
   onset is not delayed);
2. :func:`find_rises` — candidate clicks: where the envelope in the next millisecond rises well above
   both the noise floor and the level of the preceding milliseconds (so a click on the ringing or
   the echo of the one before still counts, while the ringing itself does not); rises within
   :data:`MERGE_S` of one another are one click (a double click is timed at its first);
3. :func:`time_onset` — each candidate timed where the tangent to its envelope's leading edge, taken
   where the edge crosses 30 % of the rise to the click's peak, meets the level before it, plus half
   the smoothing window (the tangent of a smoothed step meets the level half a window early); its
   standard error from the envelope's noise over the edge's slope; a faint candidate just before a
   much louder one is that click's pre-echo (lossy codecs) and is dropped (:func:`distinct_clicks`);
4. :func:`select_bounces` — the longest chain of candidates whose successive intervals shrink as a
   bouncing ball's do (each interval 0.3-1.15 of the one before, the ratio changing little; dynamic
   programming over pairs),
   between chains of equal length, those of candidates heard first after a silence (a room echo
   repeats the clicks' intervals a fixed delay later) and louder (:func:`click_preference`): echoes,
   talk and knocks fall out;
5. :func:`timing_jitter` — the scatter of the intervals about a smoothly shrinking sequence, the part
   of the timing error that the noise alone does not explain (clicks of different shapes), added to
   every onset.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..errors import InputError
from ..numerics import robust_sigma

#: Cut-off of the high-pass before the envelope, Hz: below the ring of any ball or floor.
HIGHPASS_HZ = 300.0
#: Width of the centred window that smooths the envelope, s.
SMOOTH_S = 0.2e-3
#: How far ahead a rise is looked for, s.
AHEAD_S = 1.0e-3
#: How far after its start a click's first peak is looked for, s.
PEAK_SEARCH_S = 3.0e-3
#: The level before a rise is the mean envelope between these times before it, s.
BEHIND_S = (3.0e-3, 0.3e-3)
#: A rise is a candidate click when the envelope ahead exceeds the level before it by this factor of
#: that level above the floor (plus two noise spreads)...
RISE_FACTOR = 3.0
#: ...and stands this many noise spreads above the floor.
MIN_SNR = 5.0
#: The click's leading edge is followed where it crosses this fraction of the rise to its peak: high
#: enough to stand clear of the noise and of the pre-echo of a lossy codec (AAC, MP3, Vorbis spread
#: up to a tenth of a click over the milliseconds before it), low enough to stay on the first rise of a
#: click that rises in steps.
CROSSING = 0.3
#: ...and at least this many noise spreads above the level before it.
NOISE_MARGIN = 4.0
#: Rises closer than this to the previous one are the same click (a double click, a rattle), s.
MERGE_S = 2.0e-3
#: A rise followed within this time (s) by one this many times louder is part of that click: the pre-echo
#: of a lossy codec reaches back up to a block (AAC: 1024-2048 samples, 23-46 ms at 44.1 kHz).
PRE_ECHO_S = 25e-3
PRE_ECHO_RATIO = 1.5
#: Each interval of a bouncing ball is this fraction of the one before: e² > 0.09, up to 1 and the timing
#: noise of the shortest intervals (0.3 ms on 20 ms). A ball's flights never lengthen: at 1.15 a noise blip
#: 19 ms after a faint impact that was not heard ended a chain (ratio 1.11) and read e 37 se high.
INTERVAL_RATIO = (0.3, 1.05)
#: Cost of a change of the interval ratio along a chain, per unit of |ln(ratio / previous ratio)|.
RATIO_CHANGE_PENALTY = 1.0
#: A room's echoes arrive within this time after their click, s (a path 5 m longer; a bounce interval is
#: longer than this until the last, faint bounces).
ECHO_WINDOW_S = 15e-3
#: Candidates kept for the chain search (the loudest).
MAX_CANDIDATES = 400
#: Samples per second of the envelope kept for the report.
REPORT_ENVELOPE_HZ = 2000.0


@dataclass
class Onsets:
    """The impacts heard in a recording.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per impact: ``impact`` (from 1), ``time_s`` (onset on the file's clock), ``time_se_s``,
        ``time_noise_se_s`` (the noise's part), ``peak`` (envelope peak, full scale 1), ``snr``
        (peak above the floor in noise spreads), ``clipped`` (the microphone saturated).
    candidates : pandas.DataFrame
        Every candidate click (``time_s``, ``peak``, ``selected``).
    jitter_s : float
        Timing scatter of the clicks beyond the noise's (s).
    noise_floor : float
        Median envelope (full scale 1).
    envelope_time_s, envelope : numpy.ndarray
        The envelope at :data:`REPORT_ENVELOPE_HZ` (maximum over each block), for the report.
    rate_hz : float
        Sample rate of the recording.
    """

    table: pd.DataFrame
    candidates: pd.DataFrame
    jitter_s: float
    noise_floor: float
    envelope_time_s: np.ndarray
    envelope: np.ndarray
    rate_hz: float


def click_envelope(samples, rate_hz):
    """Smoothed Hilbert envelope of the high-passed mono sound (full scale 1).

    Parameters
    ----------
    samples : numpy.ndarray
        Shape (n,) or (n, channels), full scale ±1.
    rate_hz : float
        Sample rate in Hz.
    """
    from scipy.ndimage import uniform_filter1d
    from scipy.signal import butter, hilbert, sosfiltfilt

    mono = np.asarray(samples, dtype=float)
    mono = mono.mean(axis=1) if mono.ndim == 2 else mono
    mono = mono - mono.mean()
    if rate_hz > 4 * HIGHPASS_HZ:
        mono = sosfiltfilt(butter(4, HIGHPASS_HZ, "highpass", fs=rate_hz, output="sos"), mono)
    width = max(3, int(round(SMOOTH_S * rate_hz)) | 1)
    return uniform_filter1d(np.abs(hilbert(mono)), width, mode="nearest")


def find_rises(envelope, rate_hz):
    """Indices where a click starts: the first sample of each run where the envelope ahead rises well
    above the level before it and above the noise (runs within :data:`MERGE_S` merged).

    Returns
    -------
    starts : numpy.ndarray
        Sample indices, increasing.
    floor, spread : float
        The envelope's noise floor (median) and spread (robust σ), full scale 1.
    behind : numpy.ndarray
        The level before each sample (mean envelope :data:`BEHIND_S` before it), full scale 1.
    """
    from scipy.ndimage import maximum_filter1d

    floor = float(np.median(envelope))
    spread = max(robust_sigma(envelope), 1e-12)
    ahead_n = max(3, int(round(AHEAD_S * rate_hz)) | 1)
    ahead = maximum_filter1d(envelope, ahead_n, origin=-(ahead_n // 2), mode="nearest")
    far, near = (max(1, int(round(s * rate_hz))) for s in BEHIND_S)
    cumulative = np.concatenate([[0.0], np.cumsum(envelope)])
    index = np.arange(envelope.size)
    lo, hi = np.clip(index - far, 0, None), np.clip(index - near, 0, None)
    behind = np.where(hi > lo, (cumulative[hi] - cumulative[lo]) / np.maximum(hi - lo, 1), floor)
    rising = (ahead - behind > RISE_FACTOR * (behind - floor + 2 * spread)) & (ahead - floor > MIN_SNR * spread)
    # the first milliseconds have no level before them to rise from, and hold the filters' edge: a noise
    # blip there was taken for a click and led a chain of bounces (no ball lands that soon after the start)
    rising[:far] = False
    starts = np.flatnonzero(rising & ~np.r_[False, rising[:-1]])
    merged = []
    for start in starts:
        if not merged or start - merged[-1] > MERGE_S * rate_hz:
            merged.append(start)
    return np.asarray(merged, dtype=int), floor, spread, behind


def distinct_clicks(onsets_s, peaks):
    """Which timed candidates are clicks of their own: not the pre-echo of a much louder click that
    follows within :data:`PRE_ECHO_S` (a lossy codec spreads a click's noise over the block before it),
    and not a second timing of a click already timed (two rises that found the same onset).

    Parameters
    ----------
    onsets_s, peaks : numpy.ndarray
        Onset times (s, increasing) and the sound's peak over the first :data:`AHEAD_S` +
        :data:`MERGE_S` after each onset (all frequencies, full scale 1).

    Returns
    -------
    numpy.ndarray
        Boolean mask of the candidates kept.
    """
    keep = np.ones(onsets_s.size, bool)
    for i in range(onsets_s.size):
        later = (onsets_s > onsets_s[i]) & (onsets_s - onsets_s[i] <= PRE_ECHO_S)
        if np.any(later & (peaks > PRE_ECHO_RATIO * peaks[i])):
            keep[i] = False
        elif i and keep[:i].any() and onsets_s[i] - onsets_s[:i][keep[:i]].max() < MERGE_S:
            keep[i] = False
    return keep


def time_onset(envelope, start, level_before, rate_hz, spread):
    """Onset time of one click, in samples from the first, and its standard error from the noise.

    The envelope's first upward crossing of :data:`CROSSING` of the rise from ``level_before`` to the
    peak (within :data:`PEAK_SEARCH_S` after the rises merged at ``start``) is found; the tangent there, extrapolated down to
    ``level_before``, gives the onset, plus half the smoothing window (the tangent of a smoothed step
    meets the level half a window early).

    Returns
    -------
    (float, float, float)
        Onset (samples, fractional), its standard error (samples), the peak of the envelope.
    """
    search = max(3, int(round(PEAK_SEARCH_S * rate_hz)))
    # a rise merged into this one (MERGE_S) may be the click itself, after a codec's pre-echo
    stop = min(envelope.size, start + search + int(round(MERGE_S * rate_hz)) + 1)
    peak_index = start + int(np.argmax(envelope[start:stop]))
    peak = float(envelope[peak_index])
    # well above the noise too: on a faint click 30 % of the rise is within the noise's reach
    level = min(level_before + max(CROSSING * (peak - level_before), NOISE_MARGIN * spread), peak)
    # the first crossing after the rise began: a double click is timed at its first click even when
    # the second is the louder
    first = min(max(start - search // 4, 1), max(peak_index, 1))
    stretch = envelope[first - 1:peak_index + 1]
    upward = np.flatnonzero((stretch[1:] >= level) & (stretch[:-1] < level))
    # an upward crossing: a stretch that starts above the level (a pre-echo) is not the click's edge
    above = first + int(upward[0]) if upward.size else peak_index
    below = max(above - 1, 0)
    slope = max(float(envelope[above] - envelope[below]), 1e-12)
    width = max(3, int(round(SMOOTH_S * rate_hz)) | 1)
    # within the stretch searched: a flat or falling edge (a click at the very start) cannot move it out
    onset = float(np.clip(below + (level_before - envelope[below]) / slope, max(start - search, 0), peak_index))
    onset += 0.5 * (width - 1)
    # the noise on the two samples of the tangent (the level before is a mean over many samples)
    noise_se = spread * np.sqrt(2.0) / slope
    return float(onset), float(noise_se), peak


def click_preference(onsets_s, peaks):
    """How much each candidate is preferred in a chain (1 to 1.6): a candidate that no other precedes
    within :data:`ECHO_WINDOW_S` gets 0.5 more (an echo follows its click at a fixed delay, so the chain
    of echoes keeps the intervals of the chain of clicks; the one heard first is the click), and up to
    0.1 more for its loudness (a knock in the silence before the drop is fainter than the ball)."""
    gaps = np.diff(onsets_s, prepend=-np.inf)
    return 1.0 + 0.5 * (gaps > ECHO_WINDOW_S) + 0.1 * peaks / peaks.max()


def select_bounces(times_s, weights, typical_ratio=None):
    """The chain of times whose successive intervals shrink like a bouncing ball's: the longest, and
    among long ones the one whose interval ratios change least.

    Dynamic programming over pairs of candidates: a chain ending (i, j) grows by k when the ratio of
    its intervals (t_k − t_j)/(t_j − t_i) lies in :data:`INTERVAL_RATIO`; it gains the weight of k less
    :data:`RATIO_CHANGE_PENALTY` × |ln| of how much that ratio differs from the chain's previous one
    (e hardly changes from one impact to the next: a knock before the drop, or an echo taken for a
    click, makes the ratio jump).

    Parameters
    ----------
    times_s : numpy.ndarray
        Candidate times (s), increasing.
    weights : numpy.ndarray
        Preference of each candidate (1 to 2: the chain's length first).
    typical_ratio : float, optional
        The interval ratio a chain's first step is compared with (a first pass's median): without it
        the first step is free, and a knock before the first impact can stand in for it.

    Returns
    -------
    numpy.ndarray
        Indices of the chosen candidates, increasing (all of them when fewer than three).
    """
    n = times_s.size
    if n < 3:
        return np.arange(n)
    low, high = INTERVAL_RATIO
    score = np.full((n, n), -np.inf)  # best chain ending with the pair (i, j)
    last_ratio = np.full((n, n), np.nan if typical_ratio is None else typical_ratio)  # its last interval ratio
    parent = np.full((n, n), -1)
    upper = np.triu(np.ones((n, n), bool), 1)
    score[upper] = (weights[:, None] + weights[None, :])[upper]
    for j in range(1, n - 1):
        before = times_s[j] - times_s[:j]  # interval from each i < j
        after = times_s[j + 1:] - times_s[j]  # to each k > j
        ratio = after[None, :] / before[:, None]
        allowed = (ratio >= low) & (ratio <= high) & np.isfinite(score[:j, j])[:, None]
        if not allowed.any():
            continue
        change = np.abs(np.log(ratio / last_ratio[:j, j][:, None]))
        candidates = score[:j, j][:, None] - RATIO_CHANGE_PENALTY * np.nan_to_num(change, nan=0.0)
        candidates = np.where(allowed, candidates, -np.inf)
        best_i = np.argmax(candidates, axis=0)
        columns = np.arange(after.size)
        best = candidates[best_i, columns] + weights[j + 1:]
        better = best > score[j, j + 1:]
        score[j, j + 1:][better] = best[better]
        parent[j, j + 1:][better] = best_i[better]
        last_ratio[j, j + 1:][better] = ratio[best_i, columns][better]
    i, j = np.unravel_index(np.argmax(np.where(upper, score, -np.inf)), score.shape)
    chain = [j, i]
    while parent[i, j] >= 0:
        i, j = parent[i, j], i
        chain.append(i)
    return np.asarray(chain[::-1])


def timing_jitter(times_s, noise_se_s):
    """Timing scatter (s) of the onsets beyond the noise's (clicks of different shapes), from how far the
    intervals stray from a smoothly shrinking sequence.

    The second difference of the logarithm of the intervals is near zero for a bouncing ball (a
    constant e makes it zero; drag and e(v) change it slowly); onset errors ε make it
    ε-weighted sums whose variance is σ² Σ c², with c the coefficients of the four onsets involved. σ
    comes from the robust spread of the differences scaled by √Σc², less the noise's part. With fewer
    than six intervals nothing can be said: 0.
    """
    intervals = np.diff(times_s)
    if intervals.size < 6:
        return 0.0
    before, middle, after = intervals[:-2], intervals[1:-1], intervals[2:]
    second = np.log(after) - 2 * np.log(middle) + np.log(before)
    # coefficients of the onsets n-1, n, n+1, n+2 in the second difference (to first order)
    scale = np.sqrt(1 / before**2 + (1 / before + 2 / middle) ** 2 + (2 / middle + 1 / after) ** 2 + 1 / after**2)
    scatter = robust_sigma(second / scale)
    noise = float(np.median(noise_se_s))
    return float(np.sqrt(max(scatter**2 - noise**2, 0.0)))


def detect_impacts(samples, rate_hz, start_s=0.0, source="recording"):
    """Impact times of a bouncing ball from its sound.

    Parameters
    ----------
    samples, rate_hz
        As :func:`click_envelope`.
    start_s : float
        Time of the first sample (s).
    source : str
        Name of the recording for messages.

    Returns
    -------
    Onsets

    Raises
    ------
    dropfit.errors.InputError
        When fewer than three impacts are heard.
    """
    envelope = click_envelope(samples, rate_hz)
    starts, floor, spread, behind = find_rises(envelope, rate_hz)
    if starts.size > MAX_CANDIDATES:
        keep = np.sort(np.argsort([-envelope[s:s + int(AHEAD_S * rate_hz) + 1].max() for s in starts])[:MAX_CANDIDATES])
        starts = starts[keep]
    timed = np.array([time_onset(envelope, start, behind[start], rate_hz, spread) for start in starts]).reshape(-1, 3)
    # the loudness of each click's first milliseconds from its onset, all frequencies: a pre-echo's own,
    # without the click that follows it (the high-passed envelope can make an echo louder than the thump)
    early = int(round((AHEAD_S + MERGE_S) * rate_hz))
    mono = np.asarray(samples, dtype=float)
    broadband = np.abs((mono.mean(axis=1) if mono.ndim == 2 else mono) - mono.mean())
    early_peak = np.array([broadband[int(onset):int(onset) + early].max() for onset in timed[:, 0]])
    order = np.argsort(timed[:, 0], kind="stable")
    timed = timed[order][distinct_clicks(timed[order, 0] / rate_hz, early_peak[order])]
    onset, noise_se, peak = timed.T
    preference = click_preference(onset / rate_hz, peak) if onset.size else np.zeros(0)
    chosen = select_bounces(onset / rate_hz, preference)
    if chosen.size >= 4:  # again, each chain's first step held to the ratio of the chain found
        intervals = np.diff(onset[chosen])
        chosen = select_bounces(onset / rate_hz, preference, float(np.median(intervals[1:] / intervals[:-1])))
    candidates = pd.DataFrame({"time_s": start_s + onset / rate_hz, "peak": peak,
                               "selected": np.isin(np.arange(peak.size), chosen)})
    if chosen.size < 3:
        raise InputError(f"{source}: {chosen.size} impact{'' if chosen.size == 1 else 's'} heard as a bouncing ball "
                         f"({starts.size} clicks above the noise); at least three are needed: record closer to the "
                         f"floor, in a quieter room, or a drop with more bounces")
    times = onset[chosen] / rate_hz
    jitter = timing_jitter(times, noise_se[chosen] / rate_hz)
    clipping_level = 0.999 * np.max(np.abs(samples))
    clipped = [bool(np.any(np.abs(samples[int(o): int(o + AHEAD_S * rate_hz) + 1]) >= clipping_level))
               for o in onset[chosen]]
    table = pd.DataFrame({
        "impact": np.arange(1, chosen.size + 1),
        "time_s": start_s + times,
        "time_se_s": np.hypot(noise_se[chosen] / rate_hz, jitter),
        "time_noise_se_s": noise_se[chosen] / rate_hz,
        "peak": peak[chosen],
        "snr": (peak[chosen] - floor) / spread,
        "clipped": clipped,
    })
    block = max(1, int(round(rate_hz / REPORT_ENVELOPE_HZ)))
    usable = envelope.size // block * block
    reduced = envelope[:usable].reshape(-1, block).max(axis=1)
    return Onsets(table=table, candidates=candidates, jitter_s=jitter, noise_floor=floor,
                  envelope_time_s=start_s + (np.arange(reduced.size) * block + 0.5 * block) / rate_hz,
                  envelope=reduced, rate_hz=float(rate_hz))
