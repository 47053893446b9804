"""Sound and picture together: a video's impacts heard and seen on one clock, e from each and combined.

A video with a sound track is measured both ways (:func:`dropfit.pipeline.process_recording`): the
picture gives positions and heights (:mod:`dropfit.analysis`), the sound the impact times to a fraction
of a millisecond (:mod:`dropfit.audio.onsets`). Here, pure (no files):

1. :func:`fit_offset` — the impacts seen and heard are paired across the unknown offset between the two
   clocks (:func:`dropfit.audio.compare.pair_impacts`) and the offset (sound − picture, s) is the
   inverse-variance weighted mean of the paired differences, its standard error widened by the
   scatter (Birge ratio) when the differences scatter more than their errors;
2. :func:`fuse` — per paired impact, e of both with the inverse-variance weighted combination and the
   difference in standard errors; the agreement of the two sensors by a chi-square of the paired e
   (with both analyses' covariances) and of their headline e; the result's e: the combination where
   they agree (the restitution models fitted to every impact's combined e); where they disagree beyond
   their errors, the flag, and either the e of the sensor that is not suspect, where one can tell (a
   sound whose clicks pair with none of the impacts seen, or whose pairs' numbers jump — a click not
   heard —, or a sensor whose successive e jump beyond their errors while the other's do not — a missed
   click, a wrong tracking), or the combination with its interval widened to cover both.

A sensor that fails (the picture refused, the sound silent or noisy) leaves the other's e as the result,
and the record says so and why (:func:`one_sensor`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np

from ..numerics import chi2_tail
from ..restitution import Z95, estimate

#: Below this p-value of the chi-square of their agreement the sound and the picture disagree beyond their
#: errors (their 95 % intervals): flagged in the headline.
AGREEMENT_P = 0.05
#: Fewer pairs than this do not fit an offset: one pair always matches at some offset.
MIN_PAIRS = 2


@dataclass(frozen=True)
class Estimate:
    """A value with its standard error and 95 % interval (normal), dimensionless unless ``unit`` says."""

    value: float
    se: float
    unit: str = "1"

    @property
    def ci95(self):
        return tuple(self.record()["ci95"])

    def record(self):
        """As every estimate of the fit result (:func:`dropfit.restitution.estimate`)."""
        return estimate(self.value, self.se, self.unit)

    @classmethod
    def of(cls, record):
        """From a fit result's ``{value, se, ...}`` (None where it has no value)."""
        if not record or record.get("value") is None:
            return None
        value, se = record.get("value"), record.get("se")
        return cls(float(value), float("nan") if se is None else float(se), record.get("unit", "1"))


@dataclass(frozen=True)
class ImpactPair:
    """One impact seen and heard: its numbers in each analysis, its times (s, container clock) and e."""

    impact_picture: int
    impact_sound: int
    t_picture_s: float
    t_sound_s: float
    e_picture: float
    e_picture_se: float
    e_sound: float
    e_sound_se: float
    e_combined: float
    e_combined_se: float
    #: (e_picture − e_sound) over the standard error of the difference
    difference_se: float


@dataclass(frozen=True)
class SoundAndPicture:
    """What the sound and the picture of one video say, together.

    Attributes
    ----------
    source : str
        Where the result's e comes from: ``sound and picture`` (combined), ``picture`` or ``sound``.
    e : Estimate
        The result's e (the combination, or one sensor's).
    e_picture, e_sound : Estimate or None
        Each sensor's headline e (its chosen restitution model's), None where that sensor failed.
    e_combined : Estimate or None
        The inverse-variance combination of the two, widened when they disagree.
    offset_s, offset_se_s : float
        Sound − picture (s): the recording's audio/video offset plus the sound's travel to the microphone.
    pairs : tuple of ImpactPair
    chi2, dof, p_value : float, int, float
        The agreement of the paired e (with both covariances).
    headline_difference_se : float
        The generalised mean of the paired differences e_picture − e_sound over its standard error.
    agree : bool or None
        None where only one sensor measured.
    flag : str or None
        The disagreement in words, for the headline.
    suspect : str or None
        ``sound`` or ``picture`` when one can tell which is wrong; ``suspect_why``.
    picture_refusal, sound_refusal : str or None
        Why a sensor gave no e (its refusal, whole).
    notes : tuple of str
    """

    source: str
    e: Estimate
    e_picture: Estimate | None = None
    e_sound: Estimate | None = None
    e_combined: Estimate | None = None
    offset_s: float = float("nan")
    offset_se_s: float = float("nan")
    pairs: tuple = ()
    chi2: float = float("nan")
    dof: int = 0
    p_value: float = float("nan")
    headline_difference_se: float = float("nan")
    agree: bool | None = None
    flag: str | None = None
    suspect: str | None = None
    suspect_why: str | None = None
    picture_refusal: str | None = None
    sound_refusal: str | None = None
    notes: tuple = field(default_factory=tuple)

    def record(self):
        """JSON-ready (what fit.json and analysis.json hold as ``sound_and_picture``)."""
        out = {}
        for name, value in asdict(self).items():
            value = getattr(self, name)
            if isinstance(value, Estimate):
                out[name] = value.record()
            elif name == "pairs":
                out[name] = [{key: _number(item) for key, item in asdict(pair).items()} for pair in value]
            elif name == "notes":
                out[name] = list(value)
            else:
                out[name] = _number(value)
        return out

    @classmethod
    def from_record(cls, record):
        """Back from :meth:`record` (a fit.json read back)."""
        values = dict(record)
        for name in ("e", "e_picture", "e_sound", "e_combined"):
            values[name] = Estimate.of(values.get(name))
        values["pairs"] = tuple(ImpactPair(**{key: (float("nan") if item is None else item)
                                              for key, item in pair.items()}) for pair in values.get("pairs") or ())
        values["notes"] = tuple(values.get("notes") or ())
        for name in ("offset_s", "offset_se_s", "chi2", "p_value", "headline_difference_se"):
            values[name] = float("nan") if values.get(name) is None else float(values[name])
        return cls(**values)

    @property
    def verdict(self):
        """``agree``, ``DISAGREE`` (beyond their errors), ``CHECK`` (one sensor whose e jump) or ``one sensor``."""
        if self.agree:
            return "agree"
        if self.flag:
            return "DISAGREE" if self.agree is False else "CHECK"
        return "one sensor"

    def headline(self):
        """The words the headline line adds: the sensor(s) the e comes from, and any disagreement."""
        def text(estimate):
            return f"{estimate.value:.4g} ± {estimate.se:.2g}"

        if self.source == "sound and picture":
            words = (f"sound and picture combined: picture {text(self.e_picture)}, sound {text(self.e_sound)}, "
                     f"offset {1e3 * self.offset_s:.1f} ± {1e3 * self.offset_se_s:.1f} ms over {len(self.pairs)} "
                     f"impacts" if math.isfinite(self.offset_s) else
                     f"sound and picture combined: picture {text(self.e_picture)}, sound {text(self.e_sound)}")
        elif self.source == "picture" and self.suspect == "sound" or self.source == "sound" and self.suspect:
            words = f"from the {self.source}"
        elif self.source == "sound":
            words = "from the sound" + (" (the picture is refused)" if self.picture_refusal else "")
        else:
            words = "from the picture" + (f" (the sound: {_short(self.sound_refusal)})" if self.sound_refusal else "")
            if self.e_sound is not None:
                words = f"from the picture {text(self.e_picture)}; the sound gives {text(self.e_sound)}"
        if self.flag:
            words = f"{words}; {self.verdict}: {self.flag}"
        return words


def _number(value):
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return None if not math.isfinite(value) else float(value)
    return value


def _short(text, words=12):
    text = str(text).split(": ", 1)[-1]
    parts = text.split()
    return " ".join(parts[:words]) + (" …" if len(parts) > words else "")


def fit_offset(t_picture_s, t_picture_se_s, t_sound_s, t_sound_se_s):
    """The offset sound − picture (s) and its standard error (s) from paired impact times.

    The inverse-variance weighted mean of the paired differences; its standard error is that of the
    mean, times the Birge ratio √(χ²/(n − 1)) when the differences scatter more than their errors.
    """
    difference = np.asarray(t_sound_s, float) - np.asarray(t_picture_s, float)
    variance = np.asarray(t_picture_se_s, float) ** 2 + np.asarray(t_sound_se_s, float) ** 2
    variance = np.where(np.isfinite(variance) & (variance > 0), variance, np.nanmedian(variance) or 1e-6)
    weights = 1.0 / variance
    offset = float(np.sum(weights * difference) / np.sum(weights))
    se = float(np.sqrt(1.0 / np.sum(weights)))
    if difference.size > 1:
        chi2 = float(np.sum(weights * (difference - offset) ** 2))
        se *= max(1.0, math.sqrt(chi2 / (difference.size - 1)))
    return offset, se


def inverse_variance(values, ses):
    """(weighted mean, its standard error) of independent values with standard errors."""
    values, ses = np.asarray(values, float), np.asarray(ses, float)
    weights = 1.0 / ses**2
    return float(np.sum(weights * values) / np.sum(weights)), float(np.sqrt(1.0 / np.sum(weights)))


#: A sensor's e jump when a second difference of its successive e (e_n−1 − 2 e_n + e_n+1) exceeds this many of
#: its standard errors (its covariance kept): e that follow any smooth law of speed have second differences
#: near zero, a missed click or a wrong tracking about one impact gives one of several times the error.
JUMP_SE = 4.0
#: ...and exceeds this (1): a real ball's e changes with speed smoothly, its successive e's second differences
#: below 0.005 (refsim's tennis ball: 8e-4, which the sound's 1e-4 errors resolve), a detection error's are
#: tenths.
JUMP_MIN = 0.02


#: ...or a step between successive e exceeds this (1) and as many standard errors: a real ball's e changes by
#: a few hundredths from one impact to the next.
JUMP_STEP = 0.1


def _jumps(impacts, covariance):
    """True when a sensor's successive e jump beyond their errors: a second difference beyond :data:`JUMP_SE`
    standard errors and :data:`JUMP_MIN`, or a step beyond as many and :data:`JUMP_STEP` (covariance kept);
    False when they do not, or there are too few to tell."""
    e = impacts["e"].to_numpy(float)
    keep = np.isfinite(e) & np.isfinite(impacts["e_se"].to_numpy(float))
    if "in_fit" in impacts:
        keep &= impacts["in_fit"].astype(bool).to_numpy()
    rows = np.flatnonzero(keep)
    if rows.size < 2:
        return False
    covariance = np.nan_to_num(np.asarray(covariance, float)[np.ix_(rows, rows)])
    for order, least in ((1, JUMP_STEP), (2, JUMP_MIN)):
        if rows.size <= order:
            continue
        operator = np.diff(np.eye(rows.size), n=order, axis=0)
        values = operator @ e[rows]
        variance = np.diag(operator @ covariance @ operator.T)
        # only differences of neighbouring impacts (no impact between them left out)
        neighbours = rows[order:] - rows[:-order] == order
        if np.any(neighbours & (np.abs(values) > JUMP_SE * np.sqrt(np.clip(variance, 1e-30, None)))
                  & (np.abs(values) > least)):
            return True
    return False


def jump_flag(sensor, impacts, covariance):
    """The words of a sensor's e that jump (:func:`_jumps`), or None."""
    if not _jumps(impacts, covariance):
        return None
    shown = ", ".join(f"{value:.3g}" for value in impacts["e"].to_numpy(float) if np.isfinite(value))
    cause = ("a click missed or one that is not an impact" if sensor == "sound" else
             "a wrong tracking about an impact")
    return f"the {sensor}'s successive e jump beyond their errors ({shown}): {cause}?"


def combined_series(picture_impacts, picture_e_covariance, sound_impacts, sound_e_covariance, picture_index,
                    sound_index):
    """Every impact's e from both sensors: paired impacts weighted by their inverse variances, the others from
    the one sensor that measured them, numbered as the picture numbers them (the sound's numbers moved by the
    pairs' shift).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray, numpy.ndarray)
        Impact numbers, impact speeds (m/s; the picture's where it has one), e (1) and their covariance:
        A_p C_p A_pᵀ + A_s C_s A_sᵀ for the combination's weights A (the sensors' errors are independent).
    """
    def usable(impacts):
        keep = np.isfinite(impacts["e"].to_numpy(float)) & np.isfinite(impacts["e_se"].to_numpy(float))
        if "in_fit" in impacts:
            keep &= impacts["in_fit"].astype(bool).to_numpy()
        return keep

    picture_ok, sound_ok = usable(picture_impacts), usable(sound_impacts)
    shift = (int(np.median(picture_impacts["impact"].to_numpy()[picture_index]
                           - sound_impacts["impact"].to_numpy()[sound_index])) if len(picture_index) else 0)
    rows = {}  # impact number → (picture row or None, sound row or None)
    for i in np.flatnonzero(picture_ok):
        rows[int(picture_impacts["impact"].iloc[i])] = [i, None]
    for j in np.flatnonzero(sound_ok):
        number = int(sound_impacts["impact"].iloc[j]) + shift
        if number in rows and rows[number][0] is not None and not any(
                p == rows[number][0] and q == j for p, q in zip(picture_index, sound_index)):
            continue  # the picture's impact of that number is not this click: keep the picture's
        rows.setdefault(number, [None, None])[1] = j
    numbers = np.array(sorted(rows), dtype=int)
    a_p = np.zeros((numbers.size, len(picture_impacts)))
    a_s = np.zeros((numbers.size, len(sound_impacts)))
    speeds = np.zeros(numbers.size)
    for k, number in enumerate(numbers):
        i, j = rows[number]
        var_p = float(picture_impacts["e_se"].iloc[i]) ** 2 if i is not None else np.inf
        var_s = float(sound_impacts["e_se"].iloc[j]) ** 2 if j is not None else np.inf
        if i is not None:
            a_p[k, i] = 1.0 if j is None else var_s / (var_p + var_s)
        if j is not None:
            a_s[k, j] = 1.0 if i is None else var_p / (var_p + var_s)
        speeds[k] = float(picture_impacts["v_in_m_s"].iloc[i]) if i is not None and np.isfinite(
            picture_impacts["v_in_m_s"].iloc[i]) else float(sound_impacts["v_in_m_s"].iloc[j])
    e = a_p @ np.nan_to_num(picture_impacts["e"].to_numpy(float)) + a_s @ np.nan_to_num(
        sound_impacts["e"].to_numpy(float))
    covariance = (a_p @ np.nan_to_num(np.asarray(picture_e_covariance, float)) @ a_p.T
                  + a_s @ np.nan_to_num(np.asarray(sound_e_covariance, float)) @ a_s.T)
    return numbers, speeds, e, covariance


def fuse(picture_impacts, picture_e_covariance, picture_fit, sound_impacts, sound_e_covariance, sound_fit,
         picture_index, sound_index, offset=(float("nan"), float("nan")), notes=()):
    """The sound and the picture of one video together (:class:`SoundAndPicture`).

    Parameters
    ----------
    picture_impacts, sound_impacts : pandas.DataFrame
        Each analysis' impacts (``impact``, ``t_touchdown_s``, ``v_in_m_s``, ``e``, ``e_se``, ``in_fit``).
    picture_e_covariance, sound_e_covariance : numpy.ndarray
        Each analysis' covariance of its impacts' e (rows of the impacts tables).
    picture_fit, sound_fit : dict
        Each fit result (its ``restitution`` headline e and ``restitution_models``).
    picture_index, sound_index : numpy.ndarray
        Rows of the paired impacts in each table (:func:`dropfit.audio.compare.pair_impacts`).
    offset : (float, float)
        Sound − picture and its standard error (s; :func:`fit_offset`), NaN when not fitted.

    Returns
    -------
    SoundAndPicture
        The agreement: the paired e's chi-square with both covariances and the generalised mean of their
        differences in standard errors (``headline_difference_se``); flagged beyond :data:`AGREEMENT_P`.
        The combined e: the restitution models (:func:`dropfit.speed_dependence.fit_restitution_models`)
        fitted to :func:`combined_series`, the chosen one's e at its reference impact.
    """
    from ..speed_dependence import fit_restitution_models

    notes = list(notes)
    picture_index, sound_index = np.asarray(picture_index, int), np.asarray(sound_index, int)
    e_picture = Estimate.of(picture_fit["restitution"]["e"])
    e_sound = Estimate.of(sound_fit["restitution"]["e"])
    pairs = []
    for i, j in zip(picture_index, sound_index):
        ep, eps = float(picture_impacts["e"].iloc[i]), float(picture_impacts["e_se"].iloc[i])
        es, ess = float(sound_impacts["e"].iloc[j]), float(sound_impacts["e_se"].iloc[j])
        both = all(np.isfinite([ep, eps, es, ess])) and eps > 0 and ess > 0
        # (an e its own sensor leaves out of its fits, a detection error, is compared but never combined)
        fitted = both and _in_fit(picture_impacts, i) and _in_fit(sound_impacts, j)
        combined, combined_se = inverse_variance([ep, es], [eps, ess]) if fitted else (float("nan"), float("nan"))
        pairs.append(ImpactPair(int(picture_impacts["impact"].iloc[i]), int(sound_impacts["impact"].iloc[j]),
                                float(picture_impacts["t_touchdown_s"].iloc[i]),
                                float(sound_impacts["t_touchdown_s"].iloc[j]), ep, eps, es, ess, combined,
                                combined_se, (ep - es) / math.hypot(eps, ess) if both else float("nan")))
    # the agreement of the paired e, each sensor's correlations kept
    usable = [k for k, pair in enumerate(pairs) if np.isfinite(pair.difference_se)
              and _in_fit(picture_impacts, picture_index[k]) and _in_fit(sound_impacts, sound_index[k])]
    chi2, dof, p, z = float("nan"), 0, float("nan"), float("nan")
    mean_difference = float("nan")
    if usable:
        rows_p, rows_s = picture_index[usable], sound_index[usable]
        difference = np.array([pairs[k].e_picture - pairs[k].e_sound for k in usable])
        covariance = (np.asarray(picture_e_covariance)[np.ix_(rows_p, rows_p)]
                      + np.asarray(sound_e_covariance)[np.ix_(rows_s, rows_s)])
        precision = np.linalg.pinv(covariance)
        chi2 = float(difference @ precision @ difference)
        dof = len(usable)
        p = float(chi2_tail(chi2, dof))
        information = float(np.ones(dof) @ precision @ np.ones(dof))
        mean_difference = float(np.ones(dof) @ precision @ difference) / information
        z = mean_difference * math.sqrt(information)
    # no pair at all, or too few where both sensors have several impacts: the clicks are not the impacts seen
    unpaired = bool(len(picture_impacts) and len(sound_impacts)) and (
        not pairs or len(pairs) < MIN_PAIRS <= min(len(picture_impacts), len(sound_impacts)))
    if e_picture is None or e_sound is None:
        source = "picture" if e_picture is not None else "sound"
        return SoundAndPicture(source, e_picture or e_sound, e_picture, e_sound, None, *offset, tuple(pairs), chi2,
                               dof, p, z, notes=tuple(notes))
    if not usable:  # no impact with an e from both: their headline e compared
        mean_difference = e_picture.value - e_sound.value
        z = mean_difference / math.hypot(e_picture.se, e_sound.se)
        notes.append("no impact has an e from both sensors: their headline e are compared (of different impacts)")
    combined = Estimate(*inverse_variance([e_picture.value, e_sound.value], [e_picture.se, e_sound.se]))
    if usable:
        numbers, speeds, series, covariance = combined_series(picture_impacts, picture_e_covariance, sound_impacts,
                                                              sound_e_covariance, picture_index, sound_index)
        models = fit_restitution_models(speeds, series, covariance, numbers)
        headline = models["headline"]["e"]
        combined = Estimate(float(headline["value"]), float(headline["se"]))
        notes.append(f"combined e: the {models['chosen']} model fitted to {numbers.size} impacts' e, each the "
                     f"inverse-variance combination of the picture's and the sound's where both measured it, at "
                     f"impact {models['reference']['impact']}")
    disagree = bool(unpaired or (np.isfinite(p) and p < AGREEMENT_P) or abs(z) > Z95)
    if not disagree:
        return SoundAndPicture("sound and picture", combined, e_picture, e_sound, combined, *offset, tuple(pairs),
                               chi2, dof, p, z, True, notes=tuple(notes))
    # a disagreement: which is suspect, if one can tell
    from .compare import MAX_OFFSET_S

    suspect = why = None
    shifts = sorted({pair.impact_picture - pair.impact_sound for pair in pairs})
    sound_jumps, picture_jumps = _jumps(sound_impacts, sound_e_covariance), _jumps(picture_impacts, picture_e_covariance)
    if unpaired:
        suspect, why = "sound", (f"the {len(sound_impacts)} impacts heard do not pair with the {len(picture_impacts)} "
                                 f"seen at any one offset up to {MAX_OFFSET_S:g} s (fewer than {MIN_PAIRS} pairs): the "
                                 f"clicks chosen are not the impacts filmed (other sounds, or impacts the picture "
                                 f"does not show)")
    elif len(shifts) > 1:
        jump = next(pair for pair in pairs if pair.impact_picture - pair.impact_sound != shifts[0])
        suspect, why = "sound", (f"the impacts heard skip one seen: impact {jump.impact_picture} seen pairs with "
                                 f"impact {jump.impact_sound} heard, so a click before it was not heard and a "
                                 f"flight-time ratio is broken (two flights read as one)")
    elif sound_jumps and not picture_jumps:
        suspect, why = "sound", (f"the sound's successive e jump beyond {JUMP_SE:g} of their standard errors while "
                                 f"the picture's do not: a flight-time ratio broken by a missed or spurious click")
    elif picture_jumps and not sound_jumps:
        suspect, why = "picture", (f"the picture's successive e jump beyond {JUMP_SE:g} of their standard errors "
                                   f"while the sound's do not: a wrong tracking about an impact")
    birge = math.sqrt(chi2 / dof) if dof else 1.0
    widened = Estimate(combined.value, max(combined.se * max(birge, abs(z), 1.0), abs(mean_difference) / 2.0))
    if dof:
        apart = (f"{abs(z):.1f} se apart over {dof} impacts paired (picture − sound {mean_difference:+.3g}; chi2 "
                 f"{chi2:.1f}/{dof}, p = {p:.2g})")
    else:
        apart = f"{abs(z):.1f} se apart (no impact paired)"
    flag = f"sound {e_sound.value:.4g} ± {e_sound.se:.2g} and picture {e_picture.value:.4g} ± {e_picture.se:.2g}, {apart}"
    if suspect:
        flag += f"; the {suspect} is suspect: {why}"
        trusted = "picture" if suspect == "sound" else "sound"
        result = e_picture if trusted == "picture" else e_sound
        notes.append(f"the e is the {trusted}'s: the {suspect} disagrees and is suspect ({why})")
        source = trusted
    else:
        flag += "; neither can be told wrong: the combined interval is widened to cover both"
        result, source = widened, "sound and picture"
        notes.append("sound and picture disagree and neither can be told wrong: the combined e's standard error is "
                     "scaled by the larger of the Birge ratio and the difference in standard errors, and is at least "
                     "half their difference")
    return SoundAndPicture(source, result, e_picture, e_sound, widened, *offset, tuple(pairs), chi2, dof, p, z,
                           False, flag, suspect, why, notes=tuple(notes))


def _in_fit(impacts, row):
    return "in_fit" not in impacts or bool(impacts["in_fit"].iloc[row])


def one_sensor(source, fit, picture_refusal=None, sound_refusal=None, notes=(), impacts=None, covariance=None):
    """The record of a video measured by one sensor only: ``source`` (``picture`` or ``sound``) gives the e
    and the other's refusal (its reason, whole) is kept; with its ``impacts`` and their e ``covariance``, e
    that jump are flagged (:func:`jump_flag`)."""
    e = Estimate.of(fit["restitution"]["e"])
    notes = list(notes)
    flag = jump_flag(source, impacts, covariance) if impacts is not None else None
    if source == "sound":
        notes.append("the picture gives no e" + (f": {picture_refusal}" if picture_refusal else "")
                     + "; the e is the sound's (impact times only: heights from the flight times and g)")
    else:
        notes.append("the sound gives no e" + (f": {sound_refusal}" if sound_refusal else "")
                     + "; the e is the picture's")
    return SoundAndPicture(source, e, e if source == "picture" else None, e if source == "sound" else None,
                           flag=flag, suspect=source if flag else None, suspect_why=flag,
                           picture_refusal=picture_refusal, sound_refusal=sound_refusal, notes=tuple(notes))


def has_sound_track(path):
    """True when ``path`` is a media file with a sound stream (a video's sound track); False for a file PyAV
    cannot open (its reader says why)."""
    import av

    try:
        with av.open(str(path)) as container:
            return len(container.streams.audio) > 0
    except (av.FFmpegError, OSError, ValueError):
        return False


def slow_motion_factor(path, capture_fps=None):
    """How many times slower than captured the video ``path`` presents its frames: ``capture_fps`` (given, or
    told by gravity) over the file's frame rate; 1 without a capture rate or within 5 % of the file's. Its
    sound track is slowed with the frames, as phones store slow motion."""
    import av

    if not capture_fps:
        return 1.0
    try:
        with av.open(str(path)) as container:
            rate = container.streams.video[0].average_rate
    except (av.FFmpegError, OSError, IndexError):
        return 1.0
    factor = float(capture_fps) / float(rate) if rate else 1.0
    return factor if np.isfinite(factor) and factor > 1.05 else 1.0


def on_capture_clock(sound, factor):
    """A slow-motion video's sound (:class:`dropfit.audio.decode.Sound`) on the capture clock: the same samples,
    ``factor`` times as many per second, its start ``factor`` times earlier."""
    import dataclasses

    return dataclasses.replace(sound, rate_hz=sound.rate_hz * factor, start_s=sound.start_s / factor)
