"""Detection errors: impacts that the ball cannot have made as measured, told from the bounce sequence itself.

A bounce takes energy: e ≤ 1, and each flight is shorter than the one before (T_{n+1} = e_n T_n, drag
shortens it more). An impact whose e exceeds 1, or whose flight outlasts the one before, was not
measured as it happened: an impact missed (two flights heard as one), a spurious one (a sound within a
flight, splitting it in two), a hand or a tracking error. Such an impact is a *detection error*: it stays
in the impacts table with its reason (``detection_error`` true, ``in_fit`` false, the reason in ``note``),
is left out of every fit, and the report draws it apart.

With impact times a wrong event spoils both flights it bounds, so both impacts that use them. A flight
belongs to the sequence when its ratio to a neighbouring flight is the sequence's typical ratio (of the
ratios below 1, the median of their largest cluster: :func:`typical_ratio`) to :data:`FLIGHT_RATIO_TOLERANCE` or three standard errors; one that
agrees with neither neighbour is out of the sequence. An event that splits a flight is found by merging:
a flight out of the sequence whose sum with a neighbour is in it was split by the event between them
(:func:`spurious_events`); that event is left out and the flight it split is whole again. A flight
merged from two (an impact missed) cannot be split back: the impacts on both of its ends are left out.

Pure functions: no files.
"""

from __future__ import annotations

import numpy as np

#: A flight is in the sequence when its ratio to a neighbour is the typical ratio to within this, in ln
#: (16 %): a ball's e changes by a few % from one impact to the next; an impact missed makes a flight
#: 1 + e times as long (ln 1.3 and more), a spurious one makes one of its two parts half as long or less.
FLIGHT_RATIO_TOLERANCE = 0.15
#: ... or to within this many standard errors of the ratio's logarithm (short flights timed coarsely).
FLIGHT_RATIO_SIGMAS = 3.0
#: The words that mark every detection error's note (the report and the counts find them by the column).
DETECTION_ERROR = "detection error"


def typical_ratio(flight_s):
    """A bouncing ball's e as its flights show it, undisturbed by a few wrong ones: of the ratios of
    consecutive flights (each over the one before) below 1, the largest cluster within
    :data:`FLIGHT_RATIO_TOLERANCE` of one of them, its median; NaN without a ratio below 1. In a short
    sequence a wrong event leaves as many wrong ratios as right ones (a flight merged from two: 1 + e, then
    e²/(1 + e), beside e), and their plain median is neither; a tie goes to the largest cluster's ratio, as
    the wrong ones below 1 fall short of e (e²/(1 + e) after a merged flight, f e before a flight split at
    a fraction f of it)."""
    flight_s = np.asarray(flight_s, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = flight_s[1:] / flight_s[:-1]
    logs = np.log(ratios[np.isfinite(ratios) & (ratios > 0) & (ratios < 1)])
    if not logs.size:
        return np.nan
    support = (np.abs(logs[:, None] - logs[None, :]) <= FLIGHT_RATIO_TOLERANCE).sum(axis=1)
    pick = np.max(logs[support == support.max()])
    return float(np.exp(np.median(logs[np.abs(logs - pick) <= FLIGHT_RATIO_TOLERANCE])))


def flights_out_of_sequence(flight_s, flight_se_s=None):
    """Whether each flight (s, consecutive; NaN where not measured) agrees with neither measured neighbour's
    typical ratio (:func:`typical_ratio`): an impact missed or spurious on one of its ends. Fewer than
    three flights, or no ratio below 1, tell nothing: all False (e > 1 still flags an impact)."""
    flight_s = np.asarray(flight_s, float)
    n = flight_s.size
    out = np.zeros(n, bool)
    typical = typical_ratio(flight_s)
    if n < 3 or not np.isfinite(typical):
        return out
    se = np.zeros(n) if flight_se_s is None else np.nan_to_num(np.asarray(flight_se_s, float))
    with np.errstate(divide="ignore", invalid="ignore"):
        deviation = np.abs(np.log(flight_s[1:] / flight_s[:-1]) - np.log(typical))
        spread = np.hypot(se[1:] / flight_s[1:], se[:-1] / flight_s[:-1])
    judged = np.isfinite(deviation)
    agrees = judged & (flight_s[1:] < flight_s[:-1]) & (deviation <= np.maximum(FLIGHT_RATIO_TOLERANCE, FLIGHT_RATIO_SIGMAS * np.nan_to_num(spread)))
    held, seen = np.zeros(n, bool), np.zeros(n, int)
    held[1:] |= agrees
    held[:-1] |= agrees
    seen[1:] += judged  # how many measured neighbours judge a flight
    seen[:-1] += judged
    out = (seen == 2) & ~held  # disagreeing on both sides
    # a flight judged by one neighbour only (the ends, or beside a gap) is to blame for their disagreement
    # only if that neighbour is not itself out: the flight after a merged one is not
    for j in np.flatnonzero((seen == 1) & ~held):
        neighbour = j - 1 if j > 0 and judged[j - 1] else j + 1
        out[j] = held[neighbour]
    return out


def spurious_events(times_s, times_se_s=None):
    """Positions of the events among ``times_s`` (impact times, s, increasing) that split a flight in two.

    A flight out of the sequence (:func:`flights_out_of_sequence`), or one of two of which the second
    outlasts the first (a flight split near its middle has parts alike, whose ratio near 1 passes for a
    lively ball's), whose sum with a neighbouring flight agrees with the flights on both sides of the sum (the typical ratio to within the tolerance) was split
    by the event between the two; the best such merge (the smallest disagreement) is made and the search
    repeated until no merge helps.
    """
    times = np.asarray(times_s, float)
    se = np.zeros(times.size) if times_se_s is None else np.nan_to_num(np.asarray(times_se_s, float))
    kept = np.arange(times.size)
    removed = []
    while kept.size >= 5:
        flight = np.diff(times[kept])
        flight_se = np.hypot(se[kept][1:], se[kept][:-1])
        suspect = flights_out_of_sequence(flight, flight_se)
        outlasting = flight[1:] > flight[:-1]  # a flight longer than the one before: one of the two is wrong
        suspect[1:] |= outlasting
        suspect[:-1] |= outlasting
        typical = typical_ratio(flight)
        best = None
        for j in np.flatnonzero(suspect):
            for other in (j - 1, j + 1):
                if not 0 <= other < flight.size:
                    continue
                first = min(j, other)
                merged = np.concatenate([flight[:first], [flight[j] + flight[other]], flight[first + 2:]])
                around = [merged[first] / merged[first - 1]] if first > 0 else []
                around += [merged[first + 1] / merged[first]] if first + 1 < merged.size else []
                if not around:
                    continue
                disagreement = float(np.max(np.abs(np.log(around) - np.log(typical))))
                if disagreement <= FLIGHT_RATIO_TOLERANCE and (best is None or disagreement < best[0]):
                    best = (disagreement, first + 1)  # the event between flights first and first + 1
        if best is None:
            break
        removed.append(int(kept[best[1]]))
        kept = np.delete(kept, best[1])
    return sorted(removed)


def detection_reasons(e, flight_before_s=None, flight_after_s=None, out_before=None, out_after=None):
    """The detection error of each impact, "" where none: e > 1, the flight after it outlasting the one
    before, or (with impact times) a flight before or after it out of the sequence.

    Parameters
    ----------
    e : array_like
        Each impact's e (1), NaN where not measured.
    flight_before_s, flight_after_s : array_like, optional
        The flight before and after each impact, s (NaN where there is none).
    out_before, out_after : array_like of bool, optional
        Whether that flight is out of the sequence (:func:`flights_out_of_sequence`).

    Returns
    -------
    numpy.ndarray of str
        Each impact's reason, a note of its own (it says that the impact is left out of every fit).
    """
    e = np.asarray(e, float)
    n = e.size
    before = np.full(n, np.nan) if flight_before_s is None else np.asarray(flight_before_s, float)
    after = np.full(n, np.nan) if flight_after_s is None else np.asarray(flight_after_s, float)
    out_before = np.zeros(n, bool) if out_before is None else np.asarray(out_before, bool)
    out_after = np.zeros(n, bool) if out_after is None else np.asarray(out_after, bool)
    reasons = np.full(n, "", dtype=object)
    for i in range(n):
        found = []
        if np.isfinite(after[i]) and np.isfinite(before[i]) and after[i] > before[i]:
            found.append(f"the flight after it ({after[i]:.3g} s) outlasts the one before ({before[i]:.3g} s)")
        elif out_after[i] or out_before[i]:
            which = "after" if out_after[i] else "before"
            flight = after[i] if out_after[i] else before[i]
            found.append(f"the flight {which} it ({flight:.3g} s) is out of the sequence of the others")
        energy = np.isfinite(e[i]) and e[i] > 1.0
        if energy or found:
            head = f"e > 1 ({e[i]:.3g}): {DETECTION_ERROR}, an impact cannot give the ball energy" if energy \
                else f"{DETECTION_ERROR}"
            reasons[i] = (f"{head}{'; ' if energy and found else ': ' if found else ''}{', '.join(found)} (a missed or "
                          f"spurious impact, a hand or a tracking error); left out of every fit")
    return reasons
