"""The result of one recording, in the manner of lmfit's ``ModelResult``: every reported quantity as a
:class:`Parameter` (value, standard error, 95 % interval, unit), the impacts and flights tables, the
analysis, the fit result (``fit.json``), what was left out and why, a plain-text report with fixed
sections, and an HTML table for notebooks.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from html import escape

import pandas as pd

from .analysis import se_column_name
from .files import json_ready
from .restitution import Z95

#: The sections of :meth:`RecordingResult.report`, always all of them and in this order.
REPORT_SECTIONS = ("Recording", "Data used and left out", "Coefficient of restitution", "Sound and picture",
                   "Restitution models", "Impacts", "Drag", "Contact", "Gravity and scale", "ITF", "Notes")
#: Per-impact parameters: name prefix → (impacts column, unit, factor to the unit, description).
IMPACT_PARAMETERS = {
    "e": ("e", "1", 1.0, "coefficient of restitution v_out/v_in of impact {n}"),
    "v_in": ("v_in_m_s", "m/s", 1.0, "impact speed of impact {n}"),
    "v_out": ("v_out_m_s", "m/s", 1.0, "rebound speed of impact {n}"),
    "rebound_height": ("h_after_m", "m", 1.0, "apex height after impact {n}, above the contact height"),
    "contact_time": ("t_contact_ms", "s", 1e-3, "contact time of impact {n}"),
}


@dataclass(frozen=True)
class Parameter:
    """One reported quantity (after lmfit's ``Parameter``).

    Attributes
    ----------
    name : str
        Its name in :attr:`RecordingResult.params` (a Python identifier).
    value, stderr : float
        Estimate and standard error, in ``unit``.
    ci95 : tuple of float
        The 95 % interval (low, high), in ``unit`` (normal, value ± 1.96 se, except where the fit
        result gives another: the interval of ``a`` in 1/e − 1 = a vᵖ is that of ln a).
    unit : str
        SI unit; ``"1"`` for a dimensionless quantity.
    description : str
        What it is, in words.
    """

    name: str
    value: float
    stderr: float
    ci95: tuple
    unit: str
    description: str = ""

    def __repr__(self):
        unit = "" if self.unit == "1" else f" {self.unit}"
        return (f"<Parameter {self.name!r}, value={_g(self.value)} +/- {_g(self.stderr, 2)}{unit}, "
                f"ci95=[{_g(self.ci95[0])}, {_g(self.ci95[1])}]>")


def _report():
    """:mod:`dropfit.report`, for its number formats (imported when used: it loads matplotlib)."""
    from . import report

    return report


def format_pm(value, se):
    """``value ± se`` as the HTML report writes it (:func:`dropfit.report.format_pm`)."""
    return _report().format_pm(value, se)


def _g(value, digits=6):
    """``value`` to ``digits`` significant figures, or the report's missing mark."""
    return _report().MISSING if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.{digits}g}"


def _parameter(name, estimate, description):
    """A :class:`Parameter` from a fit result's ``{value, se, ci95, unit}``."""
    nan = float("nan")
    value = estimate.get("value")
    se = estimate.get("se")
    ci95 = estimate.get("ci95") or [nan, nan]
    return Parameter(name, nan if value is None else float(value), nan if se is None else float(se),
                     tuple(nan if bound is None else float(bound) for bound in ci95), estimate.get("unit", "1"),
                     description)


@dataclass
class RecordingResult:
    """Everything dropfit reports about one recording (:func:`dropfit.analyse_recording`).

    Attributes
    ----------
    trajectory : xarray.Dataset
        The measured trajectory (``time`` s, ``y`` m) and its attributes.
    analysis : dropfit.analysis.BounceAnalysis
        Flights, impacts, covariances and the analysis summary.
    fit : dict
        The fit result, the content of ``fit.json`` (NaN where the file has null; :meth:`to_dict`
        gives the file's content exactly).
    settings : dropfit.settings.Settings
        The settings used.
    ball : dropfit.settings.Ball
        The ball as given (the trajectory's attributes hold what was used).
    params : dict of str to Parameter
        Every reported quantity: ``e`` (the headline: the chosen model's e at the first fitted
        impact's speed), the chosen model's parameters (``<model>_<parameter>``, e.g.
        ``constant_e0``, ``linear_slope_s_m``), per impact n ``e<n>``, ``v_in<n>``, ``v_out<n>``,
        ``rebound_height<n>`` and, where resolvable, ``contact_time<n>`` (s); ``drop_height``,
        ``contact_height``, ``drag_k``, ``gravity``, and where there are ``contact_stiffness``,
        ``contact_damping`` and ``itf_rebound``.
    notes : list of str
        Everything left out and why, and what was assumed.
    """

    trajectory: object
    analysis: object
    fit: dict
    settings: object
    ball: object
    params: dict = field(init=False, repr=False)
    notes: list = field(init=False, repr=False)

    def __post_init__(self):
        self.params = {parameter.name: parameter for parameter in _parameters(self.fit, self.analysis.impacts)}
        self.params.update({parameter.name: parameter for parameter in _fusion_parameters(self.fusion)})
        self.notes = _notes(self.fit, self.analysis.summary, self.trajectory.attrs)

    @property
    def impacts(self):
        """The impacts table (pandas.DataFrame; SI units in the column names; as ``impacts.csv``)."""
        return self.analysis.impacts

    @property
    def flights(self):
        """The flights table (pandas.DataFrame; as ``flights.csv``)."""
        return self.analysis.flights

    @property
    def best_values(self):
        """Parameter name → value."""
        return {name: parameter.value for name, parameter in self.params.items()}

    @property
    def name(self):
        """The sample id, or else the recording's file name."""
        source = str(self.fit.get("source") or "recording")
        return self.fit.get("sample_id") or source.replace("\\", "/").rsplit("/", 1)[-1]

    @property
    def fusion(self):
        """What the sound and the picture of a video with sound say together
        (:class:`dropfit.audio.fuse.SoundAndPicture`), or None for any other recording."""
        record = self.fit.get("sound_and_picture")
        if not record:
            return None
        from .audio.fuse import SoundAndPicture

        return SoundAndPicture.from_record(record)

    def to_dict(self):
        """The fit result exactly as ``fit.json`` holds it (JSON types; null for a missing number)."""
        return json.loads(json.dumps(json_ready(self.fit), allow_nan=False))

    def summary(self):
        """One line: the headline e with its model, the drop height and the ITF verdict."""
        restitution = self.fit["restitution"]
        e = self.params["e"]
        itf = self.fit["itf"]["verdict"]
        fusion = self.fusion
        fitted = f"{restitution['model']}, {restitution['n_impacts']} of {restitution['n_impacts_total']} impacts"
        if fusion is None:
            about = fitted
        elif fusion.source == "sound" and fusion.e_picture is not None:  # the picture's fit, the sound's e
            about = f"{fusion.headline()}; the picture's fit: {fitted}"
        else:
            about = f"{fitted}; {fusion.headline()}"
        return (f"{self.name}: e = {format_pm(e.value, e.stderr)} ({about}), drop height "
                f"{format_pm(self.params['drop_height'].value, self.params['drop_height'].stderr)} m"
                + ("" if itf == "not applicable" else f", ITF {itf}") + _scale_headline(self.fit.get("scale")))

    def report(self):
        """Plain-text report with the sections of :data:`REPORT_SECTIONS`, always all and in that order."""
        parts = []
        for title, body in zip(REPORT_SECTIONS, _sections(self)):
            parts.append(f"{title}\n{'-' * len(title)}\n{body.rstrip()}\n")
        return f"dropfit result: {self.name}\n{'=' * (16 + len(self.name))}\n\n" + "\n".join(parts)

    def _repr_html_(self):
        rows = "".join(
            f"<tr><td>{escape(p.name)}</td><td style='text-align:right'>{escape(_g(p.value))}</td>"
            f"<td style='text-align:right'>{escape(_g(p.stderr, 2))}</td>"
            f"<td style='text-align:right'>[{escape(_g(p.ci95[0]))}, {escape(_g(p.ci95[1]))}]</td>"
            f"<td>{escape('' if p.unit == '1' else p.unit)}</td><td>{escape(p.description)}</td></tr>"
            for p in self.params.values())
        notes = "".join(f"<li>{escape(note)}</li>" for note in self.notes)
        return (f"<div><p><b>{escape(self.summary())}</b></p>"
                f"<table><tr><th>name</th><th>value</th><th>standard error</th><th>95 % interval</th><th>unit</th>"
                f"<th>what</th></tr>{rows}</table>"
                + (f"<details><summary>{len(self.notes)} notes</summary><ul>{notes}</ul></details>" if notes else "")
                + "</div>")

    def __repr__(self):
        return f"<RecordingResult {self.summary()}; {len(self.params)} params, {len(self.notes)} notes>"


def _scale_headline(scale):
    """The headline's word on a px recording's heights: what they rest on when the scale is uncertain
    (more than :data:`dropfit.heightlog.MAX_GRAVITY_SCALE_RELATIVE_SE`) or g named another scale suspect;
    else nothing."""
    from .heightlog import MAX_GRAVITY_SCALE_RELATIVE_SE

    if not scale or not scale.get("heights"):
        return ""
    uncertain = (scale.get("rel_se") or 0.0) > MAX_GRAVITY_SCALE_RELATIVE_SE
    return f" ({scale['heights']})" if uncertain or scale.get("suspect") else ""


# --- parameters ------------------------------------------------------------------------------------

def _parameters(fit, impacts):
    restitution = fit["restitution"]
    model = restitution["model"]
    where = (f"impact {restitution['reference_impact']} at {restitution['reference_speed_m_s']:.3f} m/s")
    yield _parameter("e", restitution["e"], f"headline e: the {model} model's e at the first fitted impact's "
                                            f"speed ({where})")
    if model != "per_impact":  # its parameters are the impacts' own e, below
        for name, estimate in restitution["parameters"].items():
            yield _parameter(f"{model}_{name}", estimate, f"parameter {name} of the {model} model, {restitution['law']}")
    for row in impacts.to_dict("records"):
        n = int(row["impact"])
        for prefix, (column, unit, factor, description) in IMPACT_PARAMETERS.items():
            if prefix == "contact_time" and not _true(row.get("contact_resolvable")):
                continue
            value, se = row[column], row[se_column_name(column)]
            ci95 = (row[se_column_name(column, "ci95_low")], row[se_column_name(column, "ci95_high")])
            yield Parameter(f"{prefix}{n}", factor * float(value), factor * float(se),
                            tuple(factor * float(bound) for bound in ci95), unit, description.format(n=n))
    yield _parameter("drop_height", fit["drop_height_m"], "apex height of the drop above the contact height")
    yield _parameter("contact_height", fit["contact_height_m"],
                     "centre height of the ball at touchdown, above the recording's zero")
    yield _parameter("drag_k", fit["drag"]["k_per_m"], f"quadratic drag parameter k ({fit['drag']['model']})")
    config = fit.get("config") or {}
    gravity_se = config.get("gravity_se_m_s2")
    gravity_se = 0.0 if gravity_se is None else gravity_se
    g = config.get("gravity_m_s2")
    yield Parameter("gravity", float(g), float(gravity_se), (g - Z95 * gravity_se, g + Z95 * gravity_se),
                    "m/s2", f"g used (an input: {config.get('gravity_source') or 'given'})")
    contact = fit.get("contact_model")
    if contact:
        yield _parameter("contact_stiffness", contact["stiffness_n_m"], "stiffness k of the linear contact")
        yield _parameter("contact_damping", contact["damping_n_s_m"], "damping c of the linear contact")
    rebound = fit["itf"].get("rebound_m")
    if rebound:
        yield _parameter("itf_rebound", rebound, f"ITF rebound from {fit['itf']['limits']['drop_height_m']:g} m "
                                                 f"({rebound.get('method', '')})")


def _fusion_parameters(fusion):
    """A video with sound: ``e`` is the result's (combined, or one sensor's), beside ``e_picture``, ``e_sound``
    and ``e_combined`` where there are."""
    if fusion is None:
        return
    for name, estimate, description in (
            ("e", fusion.e, f"headline e, from {fusion.source}" + (f" ({fusion.verdict}: {fusion.flag})" if fusion.flag else "")),
            ("e_picture", fusion.e_picture, "headline e of the picture alone"),
            ("e_sound", fusion.e_sound, "headline e of the sound alone"),
            ("e_combined", fusion.e_combined, "inverse-variance combination of the picture's and the sound's e")):
        if estimate is not None:
            yield Parameter(name, estimate.value, estimate.se, estimate.ci95, "1", description)


def _true(flag):
    """An impacts-table flag read from memory or from a CSV (bool, text or missing)."""
    if isinstance(flag, str):
        return flag.strip().lower() in ("true", "1", "yes")
    return bool(flag) and not (isinstance(flag, float) and math.isnan(flag))


# --- notes -----------------------------------------------------------------------------------------

def _notes(fit, summary, attrs):
    """Everything left out of the result and why, and what was assumed, in words."""
    notes = []
    if attrs.get("n_dropouts"):
        notes.append(f"{attrs['n_dropouts']} samples are dropouts (no height): left out")
    if "frames" in attrs and "frames_usable" in attrs and attrs["frames"] > attrs["frames_usable"]:
        why = f": {attrs['frames_unclean']}" if attrs.get("frames_unclean") else " (see the tracking flags)"
        notes.append(f"{attrs['frames'] - attrs['frames_usable']} of {attrs['frames']} video frames not measured "
                     f"cleanly enough to use{why}")
    notes += [str(note) for note in summary.get("notes") or []]
    restitution = fit["restitution"]
    notes += [f"impact {item['impact']} left out of every fit: {item['note']}"
              for item in restitution.get("impacts_excluded") or []]
    notes += [f"restitution model {name} not fitted: {reason}" for name, reason in
              (restitution.get("not_fitted") or {}).items()]
    contact = fit.get("contact_time") or {}
    if not contact.get("resolvable"):
        notes.append(f"no contact times: {contact.get('why')}")
    elif not fit.get("contact_model"):
        notes.append("no contact model (k, c): the ball's mass is not known, or no resolved impact has 0 < e < 1")
    if fit["drag"].get("note"):
        notes.append(f"drag: {fit['drag']['note']}")
    if fit["itf"]["verdict"] == "not applicable":
        notes.append(f"no ITF verdict: {fit['itf'].get('why')}")
    for key in ("frames_note", "ruler_note", "target_note", "tilt_note", "floor_note", "gravity_calibration_failed"):
        if attrs.get(key):
            notes.append(f"{key.replace('_', ' ')}: {attrs[key]}")
    fusion = fit.get("sound_and_picture") or {}
    if fusion.get("flag"):
        notes.append(f"sound and picture, {'DISAGREE' if fusion.get('agree') is False else 'CHECK'}: {fusion['flag']}")
    notes += [f"sound and picture: {note}" for note in fusion.get("notes") or []]
    gravity = summary.get("gravity") or {}
    if gravity.get("source") and gravity.get("source") != "given":
        notes.append(gravity.get("note", ""))
    return [note for note in notes if note]


# --- the plain-text report -------------------------------------------------------------------------

def _estimate_text(estimate, unit=""):
    missing = _report().MISSING
    if not estimate or estimate.get("value") is None:
        return missing
    suffix = "" if unit in ("", "1") else f" {unit}"
    interval = _report().format_interval(estimate.get("ci95"), estimate.get("se"))
    return f"{format_pm(estimate['value'], estimate.get('se'))}{suffix} (95 % interval {interval}{suffix})"


def _lines(pairs):
    width = max(len(label) for label, _ in pairs)
    return "\n".join(f"{label.ljust(width)}  {value}" for label, value in pairs)


def _text_table(headers, rows):
    frame = pd.DataFrame(rows, columns=headers)
    return frame.to_string(index=False) if rows else "(none)"


def _sections(result):
    fit, summary, attrs = result.fit, result.analysis.summary, result.trajectory.attrs
    missing = _report().MISSING
    restitution = fit["restitution"]
    ball = fit.get("ball") or {}
    yield _lines([
        ("sample id", str(fit.get("sample_id") or missing)),
        ("source", str(fit.get("source") or missing)),
        ("SHA-256", str(fit.get("source_sha256") or missing)),
        ("ball", f"{ball.get('type') or missing}, radius {_g(ball.get('radius_m'))} m, mass {_g(ball.get('mass_kg'))} kg"),
        ("calibration", str(fit.get("calibration") or missing)),
        ("dropfit version", str(fit.get("dropfit_version"))),
    ])
    excluded = restitution.get("impacts_excluded") or []
    yield _lines([
        ("samples", _samples_text(result.trajectory)),
        ("release", f"{_g(summary.get('release_time_s'), 4)} s ({summary.get('hand_samples', 0)} samples "
                    f"before it left out)"),
        ("left out", f"{summary.get('tracking_jump_samples', 0)} tracking-jump samples, "
                     f"{summary.get('residual_outlier_samples', 0)} residual outliers"),
        ("flights fitted", str(len(result.flights))),
        ("impacts", f"{restitution['n_impacts']} of {restitution['n_impacts_total']} in the fits"
                    + ("" if not excluded else "; left out: " + ", ".join(str(item['impact']) for item in excluded))),
        ("impacts not measured", f"{summary.get('impacts_unmeasured') or 0} (a flight beside each too poorly filmed: "
                                 f"the reasons are in the notes)" if summary.get("impacts_unmeasured") else "none"),
    ])
    rows = [("model", f"{restitution['model']}: {restitution['law']} ({restitution['description']})"),
            ("e", _estimate_text(restitution["e"])),
            ("at", f"impact {restitution['reference_impact']}, {restitution['reference_speed_m_s']:.4g} m/s"),
            ("e1 measured", _estimate_text(restitution["e1"]))]
    rows += [(f"parameter {name}", _estimate_text(value, value.get("unit", ""))) for name, value in
             restitution["parameters"].items()]
    rows += [("goodness", f"chi2/dof = {_g(restitution.get('chi2'), 4)}/{restitution.get('dof')}, "
                          f"p = {_g(restitution.get('p_value'), 3)}: {restitution.get('verdict')}"),
             ("uncertainty", str(restitution.get("note") or missing)),
             ("why", str(restitution.get("why")))]
    yield _lines(rows)
    yield _sound_and_picture_text(result.fusion)
    models = fit["restitution_models"]
    yield _text_table(["", "model", "law", "e at v1", "chi2/dof", "p", "verdict", "Birge", "dBIC"], [
        ["*" if name == restitution["model"] else "", name, model["law"],
         format_pm(model["e_reference"]["value"], model["e_reference"]["se"]), _g(model.get("chi2_per_dof"), 3),
         _g(model.get("p_value"), 3), model["verdict"], _g(model.get("birge_factor"), 3), _g(model.get("delta_bic"), 3)]
        for name, model in models.items()])
    yield _text_table(["impact", "t_touchdown_s", "v_in_m_s", "v_out_m_s", "e", "h_after_m", "contact_ms", "in_fit"], [
        [int(row["impact"]), f"{row['t_touchdown_s']:.4f}", format_pm(row["v_in_m_s"], row["v_in_se_m_s"]),
         format_pm(row["v_out_m_s"], row["v_out_se_m_s"]), format_pm(row["e"], row["e_se"]),
         format_pm(row["h_after_m"], row["h_after_se_m"]),
         format_pm(row["t_contact_ms"], row["t_contact_se_ms"]) if _true(row.get("contact_resolvable")) else missing,
         _true(row.get("in_fit", True))]
        for row in result.impacts.to_dict("records")])
    drag = fit["drag"]
    yield _lines([("model", str(drag["model"])), ("k", _estimate_text(drag["k_per_m"], "1/m")),
                  ("BIC no drag / quadratic", f"{_g(drag.get('bic_no_drag'))} / {_g(drag.get('bic_quadratic_drag'))}"),
                  ("why", str(drag.get("why")))] + ([("note", drag["note"])] if drag.get("note") else []))
    contact, model = fit["contact_time"], fit.get("contact_model")
    rows = [("contact height", _estimate_text(fit["contact_height_m"], "m") + f" ({summary.get('contact_height_source')})"),
            ("contact times", ("resolved at " + str(contact.get("n_impacts")) + " impacts: " if contact["resolvable"]
                               else "not resolvable: ") + str(contact.get("why")))]
    if model:
        rows += [("k", _estimate_text(model["stiffness_n_m"], "N/m")), ("c", _estimate_text(model["damping_n_s_m"], "N s/m")),
                 ("model", model["model"])]
    yield _lines(rows)
    config = fit.get("config") or {}
    scale, time_base = fit.get("scale"), fit.get("time_base")
    rows = [("g", f"{_g(config.get('gravity_m_s2'), 7)} m/s2 ± {_g(config.get('gravity_se_m_s2'), 2)} "
                  f"({config.get('gravity_source') or 'given'})")]
    if scale:
        rows.append(("scale", f"{_g(scale['m_per_px'])} m/px ({scale.get('source')}), relative se "
                              f"{_g(scale.get('rel_se'), 3)}" + "".join(
                                  f"; {name} {100 * value:+.3f} %" for name, value in (scale.get("disagreement") or {}).items())))
        if scale.get("heights"):
            rows.append(("heights", str(scale["heights"])))
        rows.extend((f"suspect {name} scale", str(cause)) for name, cause in (scale.get("suspect") or {}).items())
    else:
        rows.append(("scale", str(fit.get("calibration") or missing)))
    if time_base:
        rows.append(("capture rate", f"{_g(time_base['capture_fps'])} frames/s ({time_base.get('source')}): "
                                     f"{time_base.get('note')}"))
    yield _lines(rows)
    itf = fit["itf"]
    rows = [("verdict", itf["verdict"])]
    if itf.get("rebound_m"):
        rows += [("rebound", _estimate_text(itf["rebound_m"], "m")), ("method", str(itf["rebound_m"].get("method")))]
    limits = itf.get("limits") or {}
    rows += [("limits", f"{_g(limits.get('rebound_min_m'))}–{_g(limits.get('rebound_max_m'))} m from "
                        f"{_g(limits.get('drop_height_m'))} m"), ("why", str(itf.get("why")))]
    yield _lines(rows)
    yield "\n".join(f"{number}. {note}" for number, note in enumerate(result.notes, 1)) or "none"


def _samples_text(trajectory):
    """The report's line on what was measured: a height log's or video's samples, a sound's impacts heard, a table's
    impact times given (it has no samples: no ``time``)."""
    impacts = trajectory["impact_time_s"].values if "impact_time_s" in trajectory else None
    if "time" not in trajectory.coords and "time" not in trajectory:
        span = f" over {impacts[-1] - impacts[0]:.4g} s" if impacts is not None and impacts.size else ""
        return f"{0 if impacts is None else impacts.size} impact times given{span} (a table: no samples)"
    time = trajectory["time"].values
    span = f" over {time[-1] - time[0]:.4g} s" if time.size else ""
    if impacts is not None:
        return f"{time.size} envelope samples of the sound{span}, {impacts.size} impacts heard"
    return f"{time.size}{span}, {trajectory.attrs.get('n_dropouts', 0)} dropouts"


def _sound_and_picture_text(fusion):
    """The report's section on a video's sound and picture together."""
    if fusion is None:
        return "not a video with a sound track: one sensor"

    def text(estimate):
        return _report().MISSING if estimate is None else format_pm(estimate.value, estimate.se)

    rows = [("e from", fusion.source), ("e", text(fusion.e)), ("e picture", text(fusion.e_picture)),
            ("e sound", text(fusion.e_sound)), ("e combined", text(fusion.e_combined)
                                                + ("" if fusion.e_combined is None else
                                                   f" (95 % interval {_g(fusion.e_combined.ci95[0], 4)}–"
                                                   f"{_g(fusion.e_combined.ci95[1], 4)})")),
            ("offset sound − picture", f"{_g(1e3 * fusion.offset_s, 4)} ± {_g(1e3 * fusion.offset_se_s, 2)} ms"),
            ("disagreement", f"{_g(fusion.headline_difference_se, 3)} se (paired e, picture − sound); chi2 "
                             f"{_g(fusion.chi2, 4)}/{fusion.dof}, p = {_g(fusion.p_value, 3)}"),
            ("verdict", fusion.verdict + (f": {fusion.flag}" if fusion.flag else ""))]
    if fusion.picture_refusal:
        rows.append(("picture refused", fusion.picture_refusal))
    if fusion.sound_refusal:
        rows.append(("sound gives no e", fusion.sound_refusal))
    table = _text_table(["impact seen", "impact heard", "t picture s", "t sound s", "e picture", "e sound",
                         "e combined", "difference se"], [
        [pair.impact_picture, pair.impact_sound, f"{pair.t_picture_s:.4f}", f"{pair.t_sound_s:.4f}",
         format_pm(pair.e_picture, pair.e_picture_se), format_pm(pair.e_sound, pair.e_sound_se),
         format_pm(pair.e_combined, pair.e_combined_se), _g(pair.difference_se, 3)] for pair in fusion.pairs])
    return _lines(rows) + "\n\n" + table + "".join(f"\n- {note}" for note in fusion.notes)
