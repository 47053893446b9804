"""Per-recording HTML report with its figure, and the batch summary table.

The report figures are drawn here and only here (the failure-record PNG of :mod:`dropfit.files`
and a video's contact sheet, drawn on its frames by :mod:`dropfit.video.overlay`, aside). Every output is written whole or not at all (:func:`dropfit.files.atomic_output`).
"""

from __future__ import annotations

import base64
import functools
import io
import math
import os
from collections import Counter
from datetime import datetime, timezone
from html import escape
from pathlib import Path
from urllib.parse import quote

import matplotlib
import matplotlib.figure
import matplotlib.ticker
import matplotlib.transforms

matplotlib.use("Agg")  # reports are made in batch jobs without a display

import matplotlib.pyplot as plt  # noqa: E402  (must follow matplotlib.use)
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from . import __version__  # noqa: E402
from .errors import shown  # noqa: E402
from .files import atomic_output  # noqa: E402
from .physics import flight_height  # noqa: E402
from .restitution import Z95  # noqa: E402
from .speed_dependence import (DELTA_BIC_INDISTINGUISHABLE, LAWS, MODELS, P_QUESTIONABLE, P_REJECTED,  # noqa: E402
                               p_value_phrase, p_value_text, predict_e)

MISSING = "—"

BATCH_COLUMNS = ["sample_id", "status", "ball_type", "n_impacts", "restitution_model", "e", "e_se", "e_ci95_low",
                 "e_ci95_high", "e_speed_m_s", "e1", "e1_se", "drop_height_m", "itf_rebound_m", "itf_rebound_se_m",
                 "itf_verdict", "drag_model", "e_from", "sound_picture_flag", "error"]

_CSS = """
body { font-family: system-ui, sans-serif; max-width: 70em; margin: 1em auto; padding: 0 1em; color: #222; }
body.wide { max-width: none; padding: 0 0.5em; }
h1, h2, p, li, dd { overflow-wrap: anywhere; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.5em; overflow-wrap: break-word; }
td.reason { overflow-wrap: anywhere; }
td.pm { text-align: right; font-variant-numeric: tabular-nums; }
.nowrap { white-space: nowrap; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
th { background: #eee; }
table.batch { font-size: 0.85em; }
dl { display: grid; grid-template-columns: max-content minmax(0, 1fr); gap: 0.2em 1em; }
dt { font-weight: bold; }
dd { margin: 0; }
.run { background: #f4f4f8; border: 1px solid #ccd; border-radius: 0.3em; padding: 0.3em 0.8em; font-size: 0.9em; }
.words { color: #444; }
.verdict { display: inline-block; font-size: 1.6em; font-weight: bold; padding: 0.2em 0.8em; border-radius: 0.3em; }
.verdict-pass { background: #c8f0c8; }
.verdict-fail { background: #f6c6c6; }
.verdict-indeterminate { background: #f6e6b0; }
.verdict-not-applicable { background: #e4e4e4; }
.verdict-not-analysed { background: #e4e4e4; }
.verdict-not-judged { background: #e4e4e4; }
.verdict-cell { padding: 0 0.4em; border-radius: 0.2em; }
tr.failed td { background: #fbe0e0; }
code { word-break: break-all; }
img { max-width: 100%; }
"""


# --- formatting ---------------------------------------------------------------------------------

def _missing(value):
    """True for None or NaN (how absent values arrive from JSON, CSV and pandas)."""
    return value is None or (pd.api.types.is_scalar(value) and bool(pd.isna(value)))


def _text(value):
    """Escaped text of a value, or the missing mark."""
    return MISSING if _missing(value) or value == "" else escape(str(value))


def _num(value, fmt):
    """``value`` formatted with ``fmt`` (e.g. ``".3f"``), or the missing mark."""
    return MISSING if _missing(value) else format(float(value), fmt)


def _quantity(value, scale, fmt, unit):
    """``value * scale`` formatted with ``fmt`` and followed by ``unit``, or the missing mark."""
    return MISSING if _missing(value) else f"{format(scale * float(value), fmt)} {unit}"


def _decimals(se):
    """Decimals that show a standard error ``se`` to two significant figures."""
    return max(0, 1 - math.floor(math.log10(se)))


def format_pm(value, se):
    """``value ± se`` with the standard error to two significant figures and the value to match.

    Parameters
    ----------
    value, se : float or None
        Estimate and its standard error, in the same unit (the caller adds the unit).

    Returns
    -------
    str
        E.g. ``"0.745073 ± 0.000068"``; the value alone (4 significant figures) when ``se`` is
        missing or zero; the missing mark when ``value`` is missing.
    """
    if _missing(value):
        return MISSING
    if _missing(se) or se <= 0:
        return f"{value:.4g}"
    digits = _decimals(se)
    return f"{value:.{digits}f} ± {se:.{digits}f}"


def format_interval(ci, se):
    """A 95 % interval ``[low, high]`` with as many decimals as :func:`format_pm` gives."""
    if ci is None or any(_missing(bound) for bound in ci):
        return MISSING
    digits = _decimals(se) if not _missing(se) and se > 0 else 4
    return f"[{ci[0]:.{digits}f}, {ci[1]:.{digits}f}]"


def _estimate(est, unit=""):
    """An estimate dict (value, se, ci95) as ``value ± se unit (95 %: [low, high])``."""
    if not est or _missing(est.get("value")):
        return MISSING
    suffix = f" {unit}" if unit else ""
    return (f"{format_pm(est['value'], est.get('se'))}{suffix} "
            f"(95 % interval {format_interval(est.get('ci95'), est.get('se'))}{suffix})")


def _number_cell(html):
    """(content, CSS class) of a number cell: kept on one line, but ``value ± se`` may put ``± se`` on a
    line of its own (a table of many such columns still fits the page)."""
    if " ± " not in html:
        return html, "num"
    value, se = html.split(" ± ", 1)
    return f'<span class="nowrap">{value}</span> <span class="nowrap">± {se}</span>', "pm"


def _table(headers, rows):
    """HTML table; ``headers`` are plain text, cells already-escaped HTML (numbers right-aligned)."""
    head = "".join(f"<th>{escape(header)}</th>" for header in headers)
    body = "".join(
        "<tr>" + "".join('<td class="{1}">{0}</td>'.format(*_number_cell(cell)) if numeric else f"<td>{cell}</td>"
                         for cell, numeric in row) + "</tr>\n"
        for row in rows)
    return f"<table>\n<tr>{head}</tr>\n{body}</table>"


def _png_img(png, alt):
    """``<img>`` element with the PNG bytes embedded as base64 (``alt`` is plain text)."""
    return f'<img alt="{escape(alt)}" src="data:image/png;base64,{base64.b64encode(png).decode("ascii")}">'


def _html_page(title, intro_html, body_html, fits, wide=False):
    """A self-contained HTML page: ``title`` (plain text) as title and heading, the run stamp of ``fits``
    (:func:`run_html`), then the intro and body; ``wide`` lets a wide table use the window's width."""
    body_class = " class='wide'" if wide else ""
    return (f"<!doctype html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n"
            f"<meta name='viewport' content='width=device-width, initial-scale=1'>\n"
            f"<title>{escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body{body_class}>\n"
            f"<h1>{escape(title)}</h1>\n{run_html(fits)}\n{intro_html}\n{body_html}\n</body>\n</html>\n")


def _sections_html(sections):
    """``<h2>`` headed sections from (plain-text title, HTML content) pairs."""
    return "\n".join(f"<h2>{escape(title)}</h2>\n{content}" for title, content in sections)


def _definitions(items):
    """HTML definition list from (plain-text term, already-escaped HTML description) pairs."""
    return "<dl>\n" + "".join(f"<dt>{escape(term)}</dt><dd>{description}</dd>\n"
                              for term, description in items) + "</dl>"


# --- the run: when, which dropfit, which settings ----------------------------------------------

def _ball_setting(fit):
    ball = fit.get("ball") or {}
    return (f"{_text(ball.get('type'))}, radius {_quantity(ball.get('radius_m'), 1e3, '.1f', 'mm')}, "
            f"mass {_quantity(ball.get('mass_kg'), 1e3, '.1f', 'g')}")


def _gravity_setting(config):
    g = config.get("gravity_m_s2")
    return MISSING if _missing(g) else (f"{escape(format_pm(g, config.get('gravity_se_m_s2')))} m/s² "
                                        f"({_text(config.get('gravity_source') or 'given')})")


def _itf_setting(config):
    return (f"rebound {_num(config.get('itf_rebound_min_m'), '.2f')}–{_num(config.get('itf_rebound_max_m'), '.2f')} m "
            f"from a {_num(config.get('itf_drop_height_m'), '.2f')} m drop (drop heights within "
            f"±{_num(config.get('itf_drop_height_tolerance_m'), '.2f')} m measured, others predicted)")


_DRAG_OPTIONS = {"auto": "auto: fitted where the BIC asks for it (a video: combined with that of the ball kind, "
                         "where known)", "off": "off: never fitted", "on": "on: always fitted"}

#: The settings every page shows: label and the HTML text of one fit result's value.
_SETTINGS = [
    ("Ball", _ball_setting),
    ("g", lambda fit: _gravity_setting(fit.get("config") or {})),
    ("Drag option", lambda fit: _text(_DRAG_OPTIONS.get((fit.get("config") or {}).get("drag"),
                                                        (fit.get("config") or {}).get("drag")))),
    ("ITF window", lambda fit: _itf_setting(fit.get("config") or {})),
    ("Fitted by", lambda fit: f"dropfit {_text(fit.get('dropfit_version'))}"),
]


def _analysed(fits):
    """The fit results among ``fits`` (failure records and stray JSON left out)."""
    return [fit for fit in fits if fit.get("status", "ok") != "failed" and isinstance(fit.get("config"), dict)]


def run_html(fits, now=None):
    """The run stamp every page carries: when the page was made, by which dropfit, and the settings
    the numbers were made with (from the fit results' ``config`` and provenance).

    Parameters
    ----------
    fits : list of dict
        The fit results the page shows (one for a recording's report); failure records are left out.
        A setting that differs between recordings is listed with how many have each value.
    now : datetime.datetime, optional
        The time to show (default: now, UTC).

    Returns
    -------
    str
        An HTML ``<section class="run">``.
    """
    now = now or datetime.now(timezone.utc)
    analysed = _analysed(fits)
    items = [("Made", f"{now:%Y-%m-%d %H:%M} UTC by dropfit {escape(__version__)}")]
    if not analysed:
        items.append(("Settings", "none to show: no recording was analysed"))
    for label, text_of in _SETTINGS if analysed else []:
        counts = Counter(text_of(fit) for fit in analysed)
        if len(counts) == 1:
            items.append((label, next(iter(counts))))
        else:
            items.append((label, "differs: " + "; ".join(f"{value} ({count} recording{'s' * (count != 1)})"
                                                          for value, count in counts.most_common())))
    return f'<section class="run">\n{_definitions(items)}\n</section>'


# --- plain words beside the statistics ----------------------------------------------------------

#: Kass & Raftery (1995), "Bayes factors", J. Am. Stat. Assoc. 90, 773: the evidence a BIC difference
#: (≈ 2 ln of the Bayes factor) gives, from its lower bound up.
_BIC_EVIDENCE = [(10.0, "very strong"), (6.0, "strong"), (2.0, "positive"), (0.0, "weak")]


def bic_words(delta_bic, better, worse):
    """A BIC difference in plain words.

    Parameters
    ----------
    delta_bic : float
        BIC of ``worse`` minus BIC of ``better`` (1, ≥ 0).
    better, worse : str
        What the lower and the higher BIC belong to (plain text).

    Returns
    -------
    str
        E.g. "ΔBIC 12: very strong evidence for the linear law over the constant one" (the Kass &
        Raftery scale); the missing mark without a difference.
    """
    if _missing(delta_bic):
        return MISSING
    return f"ΔBIC {delta_bic:.1f}: {bic_strength(delta_bic)} evidence for {better} over {worse}"


def bic_strength(delta_bic):
    """How strong the evidence of a BIC difference ``delta_bic`` (≥ 0) is: "weak", "positive", "strong" or
    "very strong" (Kass & Raftery)."""
    return next(words for bound, words in _BIC_EVIDENCE if delta_bic >= bound)


def model_bic_words(delta_bic):
    """What a model's ΔBIC to the chosen model says: evidence against it (> 0); below 0 (a lower BIC) it
    was passed over because its χ² test rejects it or cannot judge it."""
    if delta_bic < 0:
        return f"{bic_strength(-delta_bic)} evidence for it by its BIC, but its χ² test does not accept it"
    return f"{bic_strength(delta_bic)} evidence against it"


def scatter_words(model):
    """What a model's χ² test says about the scatter of the data about it, in plain words.

    Parameters
    ----------
    model : dict
        A model record with ``dof`` and ``p_value`` (the upper tail of its χ²).

    Returns
    -------
    str
        E.g. "the scatter is what the errors predict" (P_QUESTIONABLE ≤ p ≤ 1 − P_REJECTED), "somewhat
        larger" (questionable), "far larger" (rejected), "smaller" (p > 1 − P_REJECTED).
    """
    p_value, dof = model.get("p_value"), model.get("dof")
    if not dof or _missing(p_value):
        return "no degrees of freedom left: the scatter cannot be judged"
    if p_value < P_REJECTED:
        return ("the scatter is far larger than the errors predict (the law misses the data, or the errors are "
                "too small)")
    if p_value < P_QUESTIONABLE:
        return "the scatter is somewhat larger than the errors predict"
    if p_value > 1.0 - P_REJECTED:
        return "the scatter is smaller than the errors predict (the errors may be too large)"
    return "the scatter is what the errors predict"


def agreement_words(measured, measured_se, predicted, predicted_se):
    """How a measured value compares with a theory's prediction, in plain words.

    Parameters
    ----------
    measured, predicted : float
        The two values, in the same unit.
    measured_se, predicted_se : float or None
        Their standard errors (missing ones count as 0).

    Returns
    -------
    str
        "agrees within the errors" when the difference is within 1.96 combined standard errors, else
        e.g. "8.0 % lower than predicted (61 se)"; the missing mark if either value is missing.
    """
    if _missing(measured) or _missing(predicted) or predicted == 0:
        return MISSING
    se = math.hypot(0.0 if _missing(measured_se) else measured_se, 0.0 if _missing(predicted_se) else predicted_se)
    difference = measured - predicted
    if se > 0 and abs(difference) <= Z95 * se:
        return "agrees within the errors"
    direction = "lower" if difference < 0 else "higher"
    beyond = f" ({abs(difference) / se:.0f} se)" if se > 0 else ""
    return f"{100 * abs(difference / predicted):.1f} % {direction} than predicted{beyond}"


def recording_name(fit, trajectory):
    """What a recording's report is titled by: its sample id, else its file's name (``dropfit run`` without
    ``--sample-id``)."""
    source = trajectory.attrs.get("source")
    return fit.get("sample_id") or trajectory.attrs.get("sample_id") or (Path(source).name if source else "")


# --- figure -------------------------------------------------------------------------------------

def _png_bytes(fig):
    """The figure as PNG bytes (110 dpi); the figure is closed."""
    buffer = io.BytesIO()
    # zlib level 3, not 6: the log's report figure 0.18 -> 0.15 CPU-s, its PNG 124 -> 142 kB
    fig.savefig(buffer, format="png", dpi=110, pil_kwargs={"compress_level": 3})
    plt.close(fig)
    return buffer.getvalue()


def _flight_curves(trajectory, flights, analysis):
    """Fitted height of each flight on its fit window, and the fit residuals of the samples in it.

    Returns
    -------
    curves : list of (numpy.ndarray, numpy.ndarray)
        Time (s) and fitted height (m, sensor zero) of each flight on a fine grid, only where there
        are data (a close-up of one contact does not show the fall it was fitted from).
    residual_t, residual_m : numpy.ndarray
        Times (s) and residuals (m, measured − fitted) of the samples used in the fits.
    """
    t = trajectory["time"].values
    y = trajectory["y"].values
    k, g = analysis["drag_k_per_m"], analysis["gravity_m_s2"]
    curves, residual_t, residual_m = [], [], []
    measured = t[np.isfinite(y)]
    for row in flights.itertuples(index=False):
        grid = np.linspace(max(row.t_start_s, measured.min()), min(row.t_end_s, measured.max()), 200)
        curves.append((grid, flight_height(grid, row.t_apex_s, row.y_apex_m, k, g)))
        inside = (t > row.t_start_s) & (t < row.t_end_s) & np.isfinite(y)
        residual_t.append(t[inside])
        residual_m.append(y[inside] - flight_height(t[inside], row.t_apex_s, row.y_apex_m, k, g))
    return curves, np.concatenate(residual_t), np.concatenate(residual_m)


def speed_panel(fit, impacts, n_grid=200):
    """What panel (c) of the report figure draws: every impact's e against its speed and the chosen model.

    Parameters
    ----------
    fit : dict
        Fit result (``restitution`` and ``restitution_models``).
    impacts : pandas.DataFrame
        Impacts table (``impact``, ``v_in_m_s``, ``e``, ``e_se``).
    n_grid : int
        Points of the curve.

    Returns
    -------
    dict
        ``model`` (the chosen model, ``fit["restitution"]["model"]``), ``title``; per impact
        ``speed_m_s`` (m/s), ``e`` and ``e_ci95_half`` (1.96 se) (1), ``in_fit`` (bool),
        ``detection_error`` (bool: a missed or spurious impact, never drawn as an ordinary point); and
        ``curve``: None for ``per_impact`` (the points alone), else ``speed_m_s`` (a grid over the
        fitted impacts' speeds, m/s), ``e`` and its 95 % band ``low``, ``high`` (1) of the chosen
        law, with the legend's ``label`` and ``band_label``.
    """
    restitution = fit["restitution"]
    model = restitution["model"]
    speeds = impacts["v_in_m_s"].to_numpy(dtype=float)
    fitted = impacts["impact"].isin(restitution["impacts_used"]).to_numpy()
    panel = {"model": model, "speed_m_s": speeds, "e": impacts["e"].to_numpy(dtype=float),
             "e_ci95_half": Z95 * impacts["e_se"].to_numpy(dtype=float), "in_fit": fitted, "curve": None,
             "detection_error": detection_errors(impacts),
             "title": "(c) e per impact: no law describes these impacts" if model == "per_impact"
             else "(c) e per impact and the chosen law"}
    if model == "per_impact":
        return panel
    low, high = speeds[fitted].min(), speeds[fitted].max()
    grid = np.linspace(low - 0.05 * (high - low + 0.1), high + 0.05 * (high - low + 0.1), n_grid)
    e, se = predict_e(fit["restitution_models"][model], grid)
    widened = restitution["birge_factor"]
    value = f" = {format_pm(restitution['e']['value'], restitution['e']['se'])}" if model == "constant" else ""
    panel["curve"] = {"speed_m_s": grid, "e": e, "low": e - Z95 * se, "high": e + Z95 * se,
                      "label": f"chosen: {LAWS[model]}{value}",
                      "band_label": "95 % band" + (f" (widened {widened:.2g}×: misfit)" if widened > 1 else "")}
    return panel


def _decimal_log_axis(axes):
    """A logarithmic y axis with plain decimal tick labels (0.5, 1, 2) rather than powers of ten such as 2×10⁰."""
    axes.set_yscale("log")
    axes.yaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    axes.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda value, _: f"{value:g}"))
    axes.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())


def detection_errors(impacts):
    """Whether each impact is a detection error (its ``detection_error`` column; False without one)."""
    if "detection_error" not in impacts:
        return np.zeros(len(impacts), bool)
    return impacts["detection_error"].map(lambda flag: str(flag).strip().lower() in ("true", "1", "yes")).to_numpy()


#: How a detection error is drawn: a hollow grey marker, never an ordinary point.
DETECTION_ERROR_STYLE = {"fmt": "D", "ms": 5, "capsize": 2, "color": "0.55", "mfc": "white",
                         "label": "detection error: left out"}


def _draw_speed_panel(ax_e, fit, impacts):
    """Draw panel (c), e per impact against its speed and the chosen law (:func:`speed_panel`), on ``ax_e``."""
    panel = speed_panel(fit, impacts)
    wrong = panel["detection_error"]
    fitted, left_out = panel["in_fit"], ~panel["in_fit"] & ~wrong
    ax_e.errorbar(panel["speed_m_s"][fitted], panel["e"][fitted], yerr=panel["e_ci95_half"][fitted], fmt="o", ms=4,
                  capsize=3, color="tab:blue", label="per impact (±1.96 se)")
    if left_out.any():
        ax_e.errorbar(panel["speed_m_s"][left_out], panel["e"][left_out], yerr=panel["e_ci95_half"][left_out],
                      fmt="o", ms=4, capsize=3, color="tab:blue", mfc="white", label="left out of the fits")
    if (wrong & np.isfinite(panel["e"])).any():
        ax_e.errorbar(panel["speed_m_s"][wrong], panel["e"][wrong], yerr=panel["e_ci95_half"][wrong],
                      **DETECTION_ERROR_STYLE)
    curve = panel["curve"]
    if curve:
        ax_e.plot(curve["speed_m_s"], curve["e"], "-", color="tab:orange", lw=1.2, label=curve["label"])
        ax_e.fill_between(curve["speed_m_s"], curve["low"], curve["high"], color="tab:orange", alpha=0.25,
                          label=curve["band_label"])
    ax_e.set_xlabel("impact speed vᵢₙ (m/s)")
    ax_e.set_ylabel("coefficient of restitution e (1)")
    ax_e.set_title(panel["title"], loc="left")
    ax_e.legend(loc="best", fontsize=8)


@functools.cache
def _report_figure():
    """The four-panel report figure and its axes (trajectory, residuals, e, heights), made once per process
    and drawn again for each recording, so that a batch does not build the axes and their ticks anew for
    every log (0.1 of 0.25 CPU-s a figure); on its own Agg canvas, outside pyplot's bookkeeping."""
    fig = matplotlib.figure.Figure(figsize=(11, 11))
    FigureCanvasAgg(fig)
    # fixed margins, not a layout engine: the constrained layout measured every label of the four panels
    # again for each recording, a fifth of a batch's time per log
    grid = fig.add_gridspec(3, 2, height_ratios=[2.2, 1, 2], left=0.075, right=0.985, bottom=0.05, top=0.945,
                            hspace=0.3, wspace=0.22)
    ax_traj = fig.add_subplot(grid[0, :])
    return fig, (ax_traj, fig.add_subplot(grid[1, :], sharex=ax_traj), fig.add_subplot(grid[2, 0]),
                 fig.add_subplot(grid[2, 1]))


def _report_figure_axes():
    """:func:`_report_figure`, emptied of the last recording's artists, legends and data limits."""
    fig, axes = _report_figure()
    for ax in axes:
        for artist in [*ax.lines, *ax.collections, *ax.patches, *ax.texts]:
            artist.remove()
        ax.containers.clear()
        if ax.get_legend() is not None:
            ax.get_legend().remove()
        ax.dataLim = matplotlib.transforms.Bbox.null()  # the next recording's data set the limits afresh (as
        ax.ignore_existing_data_limits = True  # Axes.clear does: a log axis keeps its smallest positive value)
        ax.set_autoscale_on(True)
    return fig, axes


@plt.rc_context({"axes.titley": 1.0})  # titles at a set height: not placed above each axis's ticks at every draw
def _figure_png(trajectory, flights, impacts, analysis, fit):
    """The four-panel report figure as PNG bytes."""
    t = trajectory["time"].values
    contact = analysis["contact_height_m"]
    height = trajectory["y"].values - contact
    dropout = trajectory["quality"].values == 1
    curves, residual_t, residual_m = _flight_curves(trajectory, flights, analysis)

    fig, (ax_traj, ax_res, ax_e, ax_h) = _report_figure_axes()
    # the sample id is the user's text: drawn literally (a "$" must not start mathtext) and short
    fig.suptitle(f"dropfit: {shown(recording_name(fit, trajectory))}", fontsize=14,
                 parse_math=False)

    ax_traj.plot(t, height, ".", ms=2.5, color="0.35", label="measured")
    for index, (grid_t, grid_y) in enumerate(curves):
        ax_traj.plot(grid_t, grid_y - contact, "-", lw=1.2, color="tab:blue",
                     label="fitted flights" if index == 0 else None)
    if dropout.any():
        # Dropouts have no height: mark them on the time axis where they happened.
        ax_traj.plot(t[dropout], np.zeros(dropout.sum()), "|", ms=14, mew=1.5, color="tab:red",
                     label=f"dropouts ({dropout.sum()})")
    ax_traj.axhline(0.0, color="0.6", lw=0.8)
    ax_traj.set_ylabel("height above contact height (m)")
    ax_traj.set_title("(a) trajectory", loc="left")
    ax_traj.legend(loc="upper right")
    ax_traj.tick_params(labelbottom=False)

    ax_res.plot(residual_t, 1e3 * residual_m, ".", ms=2.5, color="tab:blue")
    ax_res.axhline(0.0, color="0.4", lw=0.8)
    ax_res.set_xlabel("time (s)")
    ax_res.set_ylabel("residual (mm)")
    ax_res.set_title(f"(b) fit residuals (noise {1e3 * analysis['noise_m']:.2g} mm)", loc="left")

    _draw_speed_panel(ax_e, fit, impacts)

    heights = pd.DataFrame(fit["theory"]["heights"])
    h0 = fit["drop_height_m"]
    if h0.get("value") is not None and np.isfinite(h0["value"]):
        bounce = np.concatenate([[0], heights["bounce"]])
        ax_h.errorbar(bounce, np.concatenate([[h0["value"]], heights["measured_m"]]),
                      yerr=Z95 * np.concatenate([[h0["se"]], heights["measured_se_m"]]), fmt="o", ms=4, capsize=3,
                      color="tab:blue", label="measured apex hₙ")
        ax_h.plot(bounce, np.concatenate([[h0["value"]], heights["predicted_m"]]), "-", color="tab:orange",
                  label="e²ⁿh₀ (constant e, no drag)")
    else:  # flight 0 followed a bounce that was not found: no drop height to start from
        ax_h.errorbar(heights["bounce"], heights["measured_m"], yerr=Z95 * heights["measured_se_m"], fmt="o", ms=4,
                      capsize=3, color="tab:blue", label="measured apex hₙ (no drop height)")
    _decimal_log_axis(ax_h)
    ax_h.set_xlabel("bounce number n (count)")
    ax_h.set_ylabel("apex height above contact hₙ (m)")
    ax_h.set_title("(d) apex heights", loc="left")
    ax_h.xaxis.get_major_locator().set_params(integer=True)
    ax_h.legend(loc="best", fontsize=8)

    return _png_bytes(fig)


def _sound_figure_png(trajectory, impacts, fit):
    """The report figure of a sound recording (PNG bytes): (a) the click envelope with the impacts heard
    and the clicks left out, (b) the flight times, (c) e per impact against speed, (d) the rises."""
    fig = plt.figure(figsize=(13, 9), layout="constrained")
    grid = fig.add_gridspec(2, 3, height_ratios=[1, 1])
    ax_sound = fig.add_subplot(grid[0, :])
    ax_flight, ax_e, ax_h = (fig.add_subplot(grid[1, column]) for column in range(3))
    fig.suptitle(f"dropfit: {shown(recording_name(fit, trajectory))}", fontsize=14,
                 parse_math=False)
    times = trajectory["impact_time_s"].values
    if "envelope" in trajectory:
        envelope = trajectory["envelope"].values
        ax_sound.plot(trajectory["time"].values, envelope, "-", lw=0.6, color="0.35", label="click envelope")
        left_out = trajectory["candidate_time_s"].values[trajectory["candidate_selected"].values == 0]
        top = float(envelope.max())
        ax_sound.plot(left_out, np.full(left_out.size, 1.05 * top), "v", ms=5, color="tab:orange",
                      label=f"clicks left out: echoes, double clicks, noise ({left_out.size})")
        ax_sound.plot(times, np.full(times.size, 1.12 * top), "v", ms=6, color="tab:blue",
                      label=f"impacts heard ({times.size})")
        ax_sound.set_ylim(top=1.35 * top)
        ax_sound.set_ylabel("envelope (full scale 1)")
        ax_sound.set_xlabel("time (s)")
        ax_sound.set_title("(a) the sound: impacts timed at their onsets", loc="left")
        ax_sound.legend(loc="upper right", fontsize=8, ncols=3)
    else:
        ax_sound.plot(times, np.ones(times.size), "|", ms=30, color="tab:blue", label="impact times given")
        ax_sound.set_xlabel("time (s)")
        ax_sound.set_yticks([])
        ax_sound.set_title("(a) the impact times of the table", loc="left")
    flight = impacts["flight_time_after_s"].to_numpy(dtype=float)
    flight_se = impacts["flight_time_after_se_s"].to_numpy(dtype=float)
    flagged = detection_errors(impacts)
    wrong = flagged & np.r_[flagged[1:], False]  # a flight between two detection errors: the one heard wrong
    ax_flight.errorbar(impacts["impact"][~wrong], 1e3 * flight[~wrong], yerr=1e3 * Z95 * flight_se[~wrong], fmt="o",
                       ms=3, capsize=2, color="tab:blue")
    if (wrong & np.isfinite(flight)).any():
        ax_flight.errorbar(impacts["impact"][wrong], 1e3 * flight[wrong], yerr=1e3 * Z95 * flight_se[wrong],
                           **DETECTION_ERROR_STYLE)
        ax_flight.legend(loc="best", fontsize=8)
    ax_flight.set_xlabel("impact n (count)")
    ax_flight.set_ylabel("flight time after impact n (ms)")
    ax_flight.set_title("(b) flight times (±1.96 se)", loc="left")

    _draw_speed_panel(ax_e, fit, impacts)

    rise, rise_se = impacts["h_after_m"].to_numpy(dtype=float), impacts["h_after_se_m"].to_numpy(dtype=float)
    ax_h.errorbar(impacts["impact"][~wrong], 1e3 * rise[~wrong], yerr=1e3 * Z95 * rise_se[~wrong], fmt="o", ms=4,
                  capsize=3, color="tab:blue", label="rise after impact n (from its flight time)")
    if (wrong & np.isfinite(rise)).any():
        ax_h.errorbar(impacts["impact"][wrong], 1e3 * rise[wrong], yerr=1e3 * Z95 * rise_se[wrong],
                      **DETECTION_ERROR_STYLE)
    drop = fit.get("drop_height_m") or {}
    if drop.get("value") is not None and np.isfinite(drop["value"]):
        ax_h.errorbar([0], [1e3 * drop["value"]], yerr=[1e3 * Z95 * drop["se"]], fmt="s", ms=5, capsize=3,
                      color="tab:green", label="drop (from the release)")
    _decimal_log_axis(ax_h)
    ax_h.set_xlabel("impact n (count)")
    ax_h.set_ylabel("rise above the contact height (mm)")
    ax_h.set_title("(d) rebound heights", loc="left")
    ax_h.legend(loc="best", fontsize=8)
    return _png_bytes(fig)


# --- per-recording report -----------------------------------------------------------------------

def _section_recording(fit):
    ball = fit.get("ball") or {}
    ball_text = (f"{_text(ball.get('type'))}, radius {_quantity(ball.get('radius_m'), 1e3, '.1f', 'mm')}, "
                 f"mass {_quantity(ball.get('mass_kg'), 1e3, '.1f', 'g')}")
    return _definitions([
        ("Sample id", _text(fit.get("sample_id"))),
        ("Source file", _text(fit.get("source"))),
        ("SHA-256", f"<code>{_text(fit.get('source_sha256'))}</code>"),
        ("Ball", ball_text),
        ("Calibration", _text(fit.get("calibration"))),
        *_scale_rows(fit.get("scale"), fit.get("time_base")),
        ("dropfit version", _text(fit.get("dropfit_version"))),
    ])


def _scale_rows(scale, time_base):
    """Definition rows for a px recording's scale (with the other scales' disagreement) and a video's time base."""
    rows = []
    if scale:
        others = ", ".join(f"{name} {100 * value:+.2f} %" for name, value in (scale.get("disagreement") or {}).items())
        rows.append(("Scale", f"{_num(scale['m_per_px'] * 1e3, '.5f')} mm/px from {_text(scale.get('source'))}, "
                              f"relative standard error {_num(100 * scale.get('rel_se', 0.0), '.3f')} %"
                              + (f"; other scales differ by {escape(others)}" if others else "")))
        if scale.get("heights"):
            rows.append(("Heights", _text(scale["heights"])))
        for name, cause in (scale.get("suspect") or {}).items():
            rows.append((f"Suspect {_text(name)} scale", _text(f"{cause}; g arbitrates: the flights fall with g "
                                                              f"through the {scale.get('source')} scale")))
        for key, label in (("ruler_note", "Ruler"), ("target_note", "Plane target"), ("tilt_note", "Camera tilt")):
            if scale.get(key):
                rows.append((label, _text(scale[key])))
    if time_base:
        rows.append(("Capture rate", f"{_num(time_base['capture_fps'], '.6g')} frames/s "
                                     f"({_text(time_base.get('source'))}): {_text(time_base.get('note'))}"))
    return rows


def _contact_sheet_html(png):
    """For a video: the contact sheet of what was tracked (:mod:`dropfit.video.overlay`), if there is one."""
    if png is None:
        return ""
    return ("<p>What was tracked: frames at the release, the apexes, around every impact and at the end, the "
            "ball's circle coloured by its quality flag, the fitted flights, the floor and a scale bar.</p>\n"
            + _png_img(png, "contact sheet of the video with the tracked ball"))


_PARAMETER_LABELS = {"e0": "e₀", "slope_s_m": "a", "coefficient": "b", "a": "a", "exponent": "p"}


def _parameter_label(name):
    """How a model parameter is named on the page (``e_3`` is impact 3's own e)."""
    return f"e of impact {name[2:]}" if name.startswith("e_") else _PARAMETER_LABELS[name]


def _unit(estimate):
    """The unit of an estimate dict as shown after its value (none for dimensionless)."""
    unit = estimate.get("unit", "1")
    return "" if unit == "1" else unit


def _goodness(model):
    """χ²/dof, p and the verdict of a model record, as text."""
    if not model.get("dof"):
        return f"χ² = {_num(model.get('chi2'), '.3g')}, no degrees of freedom: {model.get('verdict')}"
    return (f"χ²/dof = {_num(model.get('chi2'), '.4g')}/{model['dof']} = {_num(model.get('chi2_per_dof'), '.3g')}, "
            f"{p_value_phrase(model['p_value'])}: {model.get('verdict')}")


def _impacts_used(restitution):
    """How many impacts entered the fits, and the ones left out with the analysis' notes."""
    used = f"{restitution['n_impacts']} of {restitution['n_impacts_total']}"
    excluded = restitution.get("impacts_excluded") or []
    if not excluded:
        return f"{used} (all)"
    return used + "; left out of every fit: " + "; ".join(
        f"impact {item['impact']} ({escape(item['note'])})" for item in excluded)


def _model_name(name):
    """A restitution model as named in sentences: its name and law."""
    return f"'{name}' ({LAWS[name]})"


def _evidence(fit):
    """The chosen model's BIC against every other model fitted and not rejected, in plain words."""
    models = fit["restitution_models"]
    chosen = fit["restitution"]["model"]
    others = sorted((name for name, model in models.items()
                     if name != chosen and model.get("verdict") != "rejected" and not _missing(model.get("bic"))),
                    key=lambda name: models[name]["bic"])
    if not others or _missing(models[chosen].get("bic")):
        return "no other model to compare with"
    lines = []
    for name in others:
        difference = models[name]["bic"] - models[chosen]["bic"]
        better, worse = (chosen, name) if difference >= 0 else (name, chosen)
        lines.append(bic_words(abs(difference), _model_name(better), _model_name(worse)))
    return "<br>".join(escape(line) for line in lines)


def _section_result(fit):
    """The headline: the chosen model with its parameters and e at the first fitted impact's speed."""
    restitution = fit["restitution"]
    model = restitution["model"]
    e = restitution["e"]
    headline = (f"<strong>{escape(format_pm(e['value'], e['se']))}</strong> "
                f"(95 % interval {escape(format_interval(e.get('ci95'), e['se']))})")
    where = f"impact {restitution['reference_impact']} at {restitution['reference_speed_m_s']:.3f} m/s"
    rows = [("Model", f"<strong>{escape(restitution['law'])}</strong>: {escape(restitution['description'])}")]
    if model == "constant":
        rows.append(("Coefficient of restitution e", headline))
    elif model == "per_impact":
        rows.append(("e per impact", "; ".join(
            f"{escape(_parameter_label(name))}: {escape(format_pm(value['value'], value['se']))}"
            for name, value in restitution["parameters"].items())))
        rows.append((f"e₁ ({where})", headline))
    else:
        rows += [(_parameter_label(name), escape(_estimate(value, _unit(value))))
                 for name, value in restitution["parameters"].items()]
        rows.append((f"e at the first impact's speed ({where})", headline))
        e1 = restitution["e1"]
        rows.append(("e₁ measured", escape(format_pm(e1["value"], e1["se"]))))
    rows += [
        ("Goodness of fit", f"{escape(_goodness(restitution))}; <span class='words'>"
                            f"{escape(scatter_words(restitution))}</span>"),
        ("Evidence", _evidence(fit)),
        ("Uncertainty", _text(restitution.get("note"))),
        ("Why this model", _text(restitution.get("why"))),
        ("Impacts used", _impacts_used(restitution)),
    ]
    return _definitions(rows)


def _section_models(fit):
    """Every restitution model with its test, verdict and ΔBIC; the chosen one marked."""
    models = fit["restitution_models"]
    restitution = fit["restitution"]
    chosen = restitution["model"]
    rows = []
    for name in MODELS:
        model = models.get(name)
        if model is None:
            continue
        if name == "per_impact":
            parameters = "one e per impact (impacts table)"
        else:
            parameters = "; ".join(f"{_parameter_label(key)} = {_estimate(value, _unit(value))}"
                                   for key, value in model["parameters"].items())
        reference = model["e_reference"]
        scatter = scatter_words(model)
        delta = model["delta_bic"]
        evidence = ("" if _missing(delta) else "lowest BIC" if delta == 0 else model_bic_words(delta))
        rows.append([(("▶ " if name == chosen else "") + escape(name), False), (escape(model["law"]), False),
                     (escape(parameters), False), (escape(format_pm(reference["value"], reference["se"])), True),
                     (_num(model.get("chi2_per_dof"), ".3g"), True), (escape(p_value_text(model["p_value"])), True),
                     (f"{_text(model['verdict'])}: <span class='words'>{escape(scatter)}</span>", False),
                     (_num(model["birge_factor"], ".3g"), True),
                     (f"{_num(delta, '.1f')} <span class='words'>{escape(evidence)}</span>", False)])
    not_fitted = "".join(f"<li>{escape(name)} ({escape(LAWS[name])}): not fitted, {escape(reason)}</li>\n"
                         for name, reason in restitution.get("not_fitted", {}).items())
    rules = (f"Each model is tested by its own χ²: it fits for p ≥ {P_QUESTIONABLE:g}; it is questionable for "
             f"{P_REJECTED:g} ≤ p < {P_QUESTIONABLE:g} and rejected for p < {P_REJECTED:g}, and in both cases its "
             f"uncertainty is widened by the Birge ratio √(χ²/dof). A rejected model is never the headline. "
             f"Of the others, the simplest within ΔBIC < {DELTA_BIC_INDISTINGUISHABLE:g} of the lowest BIC is "
             f"chosen (ΔBIC is to that lowest). e at v₁ is each model's e at the first fitted impact's speed, "
             f"{restitution['reference_speed_m_s']:.3f} m/s.")
    return (f"<p>Chosen: <b>{escape(chosen)}</b> ({escape(LAWS[chosen])}). {_text(restitution.get('why'))}</p>\n"
            + _table(["model", "law", "parameters (95 % interval)", "e at v₁ (1)", "χ²/dof (1)", "p-value (1)",
                      "verdict", "Birge factor (1)", "ΔBIC (1)"], rows)
            + (f"\n<ul>\n{not_fitted}</ul>" if not_fitted else "") + f"\n<p>{escape(rules)}</p>")


def _section_sound_and_picture(record):
    """A video with sound (:class:`dropfit.audio.fuse.SoundAndPicture`): where the e comes from, e from each
    sensor and combined, the clocks' offset, the impacts seen and heard, and any disagreement."""
    from .audio.fuse import SoundAndPicture

    fusion = SoundAndPicture.from_record(record)

    def text(estimate):
        if estimate is None:
            return MISSING
        low, high = estimate.ci95
        return escape(f"{format_pm(estimate.value, estimate.se)} (95 % interval {low:.4g}–{high:.4g})")

    verdict = fusion.verdict
    items = [("e comes from", _text(fusion.source)), ("e", text(fusion.e)), ("e from the picture", text(fusion.e_picture)),
             ("e from the sound", text(fusion.e_sound)), ("e combined", text(fusion.e_combined)),
             ("offset sound − picture", escape(f"{_num(1e3 * fusion.offset_s, '.2f')} ± "
                                               f"{_num(1e3 * fusion.offset_se_s, '.2f')} ms over {len(fusion.pairs)} "
                                               f"impacts paired")),
             ("disagreement", escape(f"{_num(fusion.headline_difference_se, '.2f')} standard errors (paired e, picture − sound); "
                                     f"paired e: chi2 {_num(fusion.chi2, '.3g')} over {fusion.dof}, p = "
                                     f"{_num(fusion.p_value, '.3g')}")),
             ("verdict", f'<span class="verdict verdict-{"pass" if fusion.agree else "fail"}">{verdict}</span>'
                         + (f" {escape(fusion.flag)}" if fusion.flag else ""))]
    if fusion.picture_refusal:
        items.append(("picture refused", _text(fusion.picture_refusal)))
    if fusion.sound_refusal:
        items.append(("sound gives no e", _text(fusion.sound_refusal)))
    rows = [[(_text(pair.impact_picture), True), (_text(pair.impact_sound), True), (_num(pair.t_picture_s, ".4f"), True),
             (_num(pair.t_sound_s, ".4f"), True), (escape(format_pm(pair.e_picture, pair.e_picture_se)), True),
             (escape(format_pm(pair.e_sound, pair.e_sound_se)), True),
             (escape(format_pm(pair.e_combined, pair.e_combined_se)), True), (_num(pair.difference_se, ".2f"), True)]
            for pair in fusion.pairs]
    table = _table(["impact seen", "impact heard", "picture (s)", "sound (s)", "e picture", "e sound", "e combined",
                    "difference (se)"], rows) if rows else ""
    notes = "".join(f"<li>{escape(note)}</li>" for note in fusion.notes)
    return _definitions(items) + table + (f"<ul>{notes}</ul>" if notes else "")


def _section_itf(fit):
    itf = fit["itf"]
    verdict = itf["verdict"]
    badge = f'<p><span class="verdict verdict-{escape(verdict.replace(" ", "-"))}">{escape(verdict.upper())}</span></p>'
    limits = itf.get("limits") or {}
    limits_text = (f"rebound between {_num(limits.get('rebound_min_m'), '.2f')} m and "
                   f"{_num(limits.get('rebound_max_m'), '.2f')} m from a {_num(limits.get('drop_height_m'), '.2f')} m "
                   f"drop ({_text(limits.get('source'))})")
    if verdict == "not applicable":
        return badge + _definitions([("Why", _text(itf.get("why"))), ("Limits", limits_text)])
    rebound = itf.get("rebound_m") or {}
    return badge + _definitions([
        ("Rebound", escape(_estimate(rebound, "m"))),
        ("Method", _text(rebound.get("method"))),
        ("Limits", limits_text),
        ("Decision rule", _text(itf.get("why"))),
    ])


def _drag_evidence(drag):
    """The BIC of the flights with and without drag in plain words."""
    without, with_drag = drag.get("bic_no_drag"), drag.get("bic_quadratic_drag")
    if _missing(without) or _missing(with_drag):
        return f"not compared: {drag.get('why') or 'the drag was fixed by the --drag option'}"
    if with_drag < without:
        return bic_words(without - with_drag, "quadratic drag", "none")
    return bic_words(with_drag - without, "no drag", "quadratic drag")


def _section_drag(fit):
    drag = fit["drag"]
    return _definitions([
        ("Model", _text(drag.get("model"))),
        ("k", escape(_estimate(drag.get("k_per_m"), "1/m"))),
        ("BIC, no drag", _num(drag.get("bic_no_drag"), ".1f")),
        ("BIC, quadratic drag", _num(drag.get("bic_quadratic_drag"), ".1f")),
        ("Evidence", escape(_drag_evidence(drag))),
        ("Why", _text(drag.get("why"))),
    ] + ([("Note", _text(drag["note"]))] if drag.get("note") else []))


def _against_prediction(measured, predicted):
    """A value measured without a standard error against a predicted estimate dict, in words (escaped)."""
    predicted = predicted or {}
    return escape(agreement_words(measured, None, predicted.get("value"), predicted.get("se")))


def _section_theory(fit):
    theory = fit["theory"]
    rows = [[(_text(h["bounce"]), True),
             (escape(format_pm(h["measured_m"], h["measured_se_m"])), True),
             (escape(format_pm(h["predicted_m"], h["predicted_se_m"])), True),
             (_num(None if _missing(h["measured_m"]) or _missing(h["predicted_m"])
                   else h["measured_m"] / h["predicted_m"], ".3f"), True),
             (escape(agreement_words(h["measured_m"], h["measured_se_m"], h["predicted_m"], h["predicted_se_m"])),
              False)]
            for h in theory["heights"]]
    heights = ("<p>The seed's prediction hₙ = e²ⁿh₀ takes one e for every impact and no air: drag lowers "
               "the measured heights below it, an e that changes with speed bends them away from it.</p>\n"
               + _table(["bounce n", "measured hₙ (m)", "predicted e²ⁿh₀ (m)", "measured / predicted (1)",
                         "in words"], rows))
    total = theory["total_bouncing_time"]
    if total.get("predicted_to_last_impact"):  # the time ends at a counted impact (the last heard)
        last = f"impact {total['impacts_counted']}"
        start, series, infinite = (("the first impact", "T₁(1 + e + … + eᴺ⁻²)", "after the first impact, T₁/(1 − e)")
                                   if total.get("from_first_impact") else
                                   ("release", "t₀(1 + 2Σeᵏ)", "t∞ = t₀(1 + e)/(1 − e)"))
        rows = [(f"Time from {start} to {last} (the last heard), measured", f"{_num(total.get('measured_s'), '.3f')} s"),
                (f"Time to {last}, predicted {series}", escape(_estimate(total["predicted_to_last_impact"], "s"))),
                ("Measured against predicted", _against_prediction(total.get("measured_s"),
                                                                   total["predicted_to_last_impact"])),
                (f"Total bouncing time {infinite}, predicted",
                 escape(_estimate(total.get("predicted_after_first_impact") or total.get("predicted"), "s")))]
    else:
        rows = [("Total bouncing time, measured", f"{_num(total.get('measured_s'), '.3f')} s"),
                ("Total bouncing time t∞, predicted", escape(_estimate(total.get("predicted"), "s"))),
                ("Measured against predicted", _against_prediction(total.get("measured_s"), total.get("predicted")))]
    times = _definitions(rows + [("Note", _text(total.get("note")))])
    return heights + "\n" + times


def _section_contact(fit, impacts):
    contact = fit["contact_time"]
    if not contact["resolvable"]:
        modelled = contact.get("contact_time_1m_s")
        model = (f"<p>Contact time at 1 m/s from the flights alone: {escape(_estimate(modelled, 's'))}; "
                 f"exponent β = {escape(_estimate(contact.get('exponent')))}.</p>") if modelled else ""
        return f"<p>Not resolvable: {_text(contact.get('why'))}.</p>" + model
    resolved = impacts[impacts["contact_resolvable"].astype(bool)]
    rows = [[(_text(row.impact), True), (escape(format_pm(row.t_contact_ms, row.t_contact_se_ms)), True)]
            for row in resolved.itertuples(index=False)]
    table = f"<p>{_text(contact.get('why'))}.</p>\n" + _table(["impact", "contact time (ms)"], rows)
    model = fit.get("contact_model")
    if not model:
        return table + "<p>No contact model fitted: the ball's mass is not known.</p>"
    return table + "<h3>Contact model</h3>\n" + _definitions([
        ("Model", _text(model["model"])),
        ("k", escape(_estimate(model["stiffness_n_m"], "N/m"))),
        ("c", escape(_estimate(model["damping_n_s_m"], "N s/m"))),
        ("Impacts used", _text(model["n_impacts"])),
        ("How", _text(model["why"])),
    ]) + "\n" + _png_img(_contact_png(model), "force and penetration of the fitted contact")


def _contact_png(model):
    """Force–time and penetration–time curves (PNG bytes) of the fitted linear contact at the first
    resolved impact's speed."""
    from .contact import LinearContact, simulate_contact

    stiffness, damping = model["stiffness_n_m"]["value"], model["damping_n_s_m"]["value"]
    result = simulate_contact(LinearContact(stiffness, damping), model["mass_kg"], model["impact_speed_m_s"],
                              model["gravity_m_s2"])
    fig, force_axis = plt.subplots(figsize=(6.5, 3.0))
    force_axis.plot(1e3 * result.time_s, result.force_n, color="C3", lw=2, label="contact force F")
    force_axis.set_xlabel("time after touchdown (ms)")
    force_axis.set_ylabel("contact force F (N)")
    force_axis.grid(alpha=0.3)
    depth_axis = force_axis.twinx()
    depth_axis.plot(1e3 * result.time_s, 1e3 * result.penetration_m, color="C0", ls="--", label="penetration δ")
    depth_axis.set_ylabel("penetration δ (mm)")
    # one legend for both axes, low in the middle where both curves are high (a figure legend hid the right axis)
    handles = force_axis.get_legend_handles_labels()[0] + depth_axis.get_legend_handles_labels()[0]
    force_axis.legend(handles=handles, loc="lower center", fontsize=9)
    force_axis.set_title(f"fitted contact at v_in = {model['impact_speed_m_s']:.2f} m/s", fontsize=10)
    fig.tight_layout()
    return _png_bytes(fig)


def _section_impacts(impacts):
    """The impacts table; for a sound recording also when each impact was heard and the flight after it."""
    heard = "flight_time_after_s" in impacts
    rows = [[(_text(row.impact), True)]
            + ([(_num(row.t_touchdown_s, ".4f"), True),
                (escape(format_pm(1e3 * row.flight_time_after_s, 1e3 * row.flight_time_after_se_s)), True)]
               if heard else [])
            + [(_num(row.v_in_m_s, ".3f"), True),
               (_num(row.v_out_m_s, ".3f"), True),
               (escape(format_pm(row.e, row.e_se)), True),
               (_num(row.e_height, ".4f"), True),
               (_num(row.flight_time_ratio, ".4f"), True),
               (escape(format_pm(row.h_after_m, row.h_after_se_m)), True)]
            for row in impacts.itertuples(index=False)]
    return _table(["impact"] + (["heard at (s)", "flight after ± se (ms)"] if heard else [])
                  + ["v_in (m/s)", "v_out (m/s)", "e ± se (1)", "e from heights (1)", "flight-time ratio (1)",
                     "h_after ± se (m)"], rows)


def _path_png(trajectory, flights, analysis, fit):
    """The path y(x) of a 2-D recording (PNG bytes): the samples, the fitted flights drawn along the measured
    x, and where the seed's u t∞ ends the bouncing, measured from the release."""
    t, x = trajectory["time"].values, trajectory["x"].values
    contact = analysis["contact_height_m"]
    measured = np.isfinite(x) & np.isfinite(trajectory["y"].values)
    curves, _, _ = _flight_curves(trajectory, flights, analysis)
    fig, ax = plt.subplots(figsize=(9.5, 3.6), layout="constrained")
    ax.plot(x[measured], trajectory["y"].values[measured] - contact, ".", ms=2.5, color="0.35", label="measured")
    for index, (grid_t, grid_y) in enumerate(curves):
        ax.plot(np.interp(grid_t, t[measured], x[measured]), grid_y - contact, "-", lw=1.2, color="tab:blue",
                label="fitted flights (along the measured x)" if index == 0 else None)
    distance = fit["theory"].get("horizontal_distance")
    if distance and not _missing(distance["predicted"]["value"]):
        release = np.interp(analysis["drop_apex_time_s"], t[measured], x[measured])
        ax.axvline(release + distance["predicted"]["value"], color="tab:orange", ls="--", lw=1,
                   label=f"u t∞ after the release: {format_pm(distance['predicted']['value'], distance['predicted']['se'])} m")
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_xlabel("horizontal position x (m)")
    ax.set_ylabel("height above contact height (m)")
    ax.set_title("path y(x)", loc="left")
    ax.legend(loc="upper right", fontsize=8)
    return _png_bytes(fig)


def _section_oblique(fit, impacts, path_png):
    """Oblique bounces: each impact's tangential velocities, angles above the floor and the check
    tan θ′ = e tan θ, the distance u t∞ and the path y(x)."""
    rows = [[(_text(row.impact), True),
             (escape(format_pm(row.vx_in_m_s, row.vx_in_se_m_s)), True),
             (escape(format_pm(row.vx_out_m_s, row.vx_out_se_m_s)), True),
             (escape(format_pm(row.tangential_ratio, row.tangential_ratio_se)), True),
             (escape(format_pm(row.theta_in_deg, row.theta_in_se_deg)), True),
             (escape(format_pm(row.theta_out_deg, row.theta_out_se_deg)), True),
             (escape(format_pm(row.tan_theta_out, row.tan_theta_out_se)), True),
             (escape(format_pm(row.e_tan_theta_in, row.e_tan_theta_in_se)), True),
             (_text(row.angle_check), False)]
            for row in impacts.itertuples(index=False)]
    table = _table(["impact", "vx_in (m/s)", "vx_out (m/s)", "vx_out / vx_in (1)", "θ in (°)", "θ′ out (°)",
                    "tan θ′ (1)", "e tan θ (1)", "check"], rows)
    distance = fit["theory"].get("horizontal_distance") or {}
    travel = _definitions([
        ("Horizontal speed at the release u", escape(_estimate(distance.get("release_speed"), "m/s"))),
        ("Distance while bouncing u t∞, predicted", escape(_estimate(distance.get("predicted"), "m"))),
        ("Distance from the release to rest, measured", f"{_num(distance.get('measured_m'), '.3f')} m"),
        ("Measured against predicted", _against_prediction(distance.get("measured_m"), distance.get("predicted"))),
        ("Note", _text(distance.get("note"))),
    ]) if distance else ""
    return ("<p>Angles of the velocity above the floor; on a smooth floor the tangential velocity is kept and "
            "tan θ′ = e tan θ (e from the normal components alone).</p>\n" + table + "\n" + travel
            + ("\n" + _png_img(path_png, "path y(x)") if path_png else ""))


def _section_notes(fit):
    """The samples left out (the hand's, tracking jumps, outliers of the fit) and every note of the analysis."""
    data = fit.get("data") or {}
    counts = _definitions([
        ("Held or moved by hand", f"{_text(data.get('hand_samples'))} samples, until the release at "
                                  f"{_num(data.get('release_time_s'), '.4f')} s"),
        ("Tracking jumps", f"{_text(data.get('tracking_jump_samples'))} samples left out"),
        ("Outliers of the flight fit", f"{_text(data.get('residual_outlier_samples'))} samples left out"),
        ("Noise", f"{_num(1e3 * data['noise_m'] if data.get('noise_m') is not None else None, '.3g')} mm"),
    ])
    notes = fit.get("notes") or []
    listed = "<ul>" + "".join(f"<li>{escape(str(note))}</li>" for note in notes) + "</ul>" if notes else \
        "<p>No notes: every sample after the release entered the fits.</p>"
    return counts + "\n" + listed


def recording_report_html(trajectory, flights, impacts, fit, png, contact_sheet_png=None, path_png=None):
    """The self-contained per-recording HTML report.

    Parameters
    ----------
    trajectory : xarray.Dataset
        The measured trajectory (only its attributes are used here).
    flights, impacts : pandas.DataFrame
        Flights and impacts tables of the analysis.
    fit : dict
        Fit result.
    png : bytes
        The report figure, embedded as base64.
    contact_sheet_png : bytes, optional
        A video's contact sheet (PNG), embedded under the recording.
    path_png : bytes, optional
        A 2-D recording's path y(x) (PNG), embedded in its section on oblique bounces.

    Returns
    -------
    str
        The HTML page.
    """
    sample_id = recording_name(fit, trajectory)
    sections = [
        ("Recording", _section_recording(fit) + _contact_sheet_html(contact_sheet_png)),
        ("Result", _section_result(fit)),
    ] + ([("Sound and picture", _section_sound_and_picture(fit["sound_and_picture"]))]
         if fit.get("sound_and_picture") else []) + [
        ("Restitution models", _section_models(fit)),
        ("ITF verdict", _section_itf(fit)),
        ("Drag", _section_drag(fit)),
        ("Theory checks", _section_theory(fit)),
        ("Contact time", _section_contact(fit, impacts)),
        ("Data used and notes", _section_notes(fit)),
        ("Impacts table", _section_impacts(impacts)),
    ] + ([("Oblique bounces (2-D motion)", _section_oblique(fit, impacts, path_png))]
         if "vx_in_m_s" in impacts else []) + [
        ("Figure", _png_img(png, f"dropfit figure for {sample_id}")),
    ]
    intro = (f"<p>Impacts heard in the sound ({len(impacts)}); every flight's time is the interval between two "
             f"impacts less a contact time, and its rise and speeds follow from it with the ball's drag.</p>"
             if "impact_time_s" in trajectory else
             f"<p>Heights are of the ball centre above the contact height "
             f"({escape(_estimate(fit.get('contact_height_m'), 'm'))} above the sensor zero); "
             f"{len(flights)} flights fitted.</p>")
    fusion = fit.get("sound_and_picture")
    if fusion:  # a video with sound: where the headline e comes from, and any disagreement, first
        from .audio.fuse import SoundAndPicture

        intro = f"<p><b>e {escape(SoundAndPicture.from_record(fusion).headline())}</b></p>" + intro
    return _html_page(f"dropfit report: {sample_id}", intro, _sections_html(sections), [fit])


def write_recording_report(trajectory, flights, impacts, analysis, fit, html_path, figure_path, contact_sheet_png=None):
    """Write the report figure (PNG) and the self-contained HTML report of one recording.

    Parameters
    ----------
    trajectory : xarray.Dataset
        Dimension ``time`` (s); ``y`` (m, ball centre above the sensor zero, NaN at dropouts) and
        ``quality`` (0 ok, 1 dropout); or a sound recording's impact times
        (:func:`dropfit.audio.recording.sound_trajectory`).
    flights, impacts : pandas.DataFrame
        Flights and impacts tables written by the analyse stage.
    analysis : dict
        Analysis summary (contact height in m, drag ``k`` in 1/m, gravity in m/s², noise in m).
    fit : dict
        Fit result (e, theory checks, ITF verdict, provenance).
    html_path, figure_path : str or pathlib.Path
        Where to write the HTML report and the PNG figure.
    contact_sheet_png : bytes, optional
        A video's contact sheet (PNG, :func:`dropfit.stages.overlay`), shown in the report.
    """
    sound = "impact_time_s" in trajectory
    png = _sound_figure_png(trajectory, impacts, fit) if sound else _figure_png(trajectory, flights, impacts, analysis,
                                                                                  fit)
    path_png = _path_png(trajectory, flights, analysis, fit) if "x" in trajectory and "vx_in_m_s" in impacts else None
    with atomic_output(figure_path) as tmp:
        tmp.write_bytes(png)
    with atomic_output(html_path) as tmp:
        tmp.write_text(recording_report_html(trajectory, flights, impacts, fit, png, contact_sheet_png, path_png),
                       encoding="utf-8")


def failure_page_html(message, figure_png=None):
    """The page of a recording that could not be analysed: its one-line reason, the run stamp and, for a
    refused video, the contact sheet of what was tracked (``figure_png``, PNG bytes)."""
    figure = "" if figure_png is None else "<p>What was tracked:</p>\n" + _png_img(figure_png,
                                                                                   "contact sheet of the video")
    return _html_page("dropfit: analysis failed", f"<p>{_text(message)}</p>", figure, [])


# --- batch summary ------------------------------------------------------------------------------

def _batch_row(fit):
    """One summary row from a fit result or a failure record."""
    if fit.get("status") == "failed":
        return {"sample_id": fit.get("sample_id"), "status": "failed", "error": fit.get("error")}
    restitution = fit["restitution"]
    e, e1 = restitution["e"], restitution.get("e1") or {}
    fusion = fit.get("sound_and_picture") or {}
    e = fusion.get("e") or e  # a video with sound: the result's e (combined, or one sensor's)
    rebound = fit["itf"].get("rebound_m") or {}
    ci = e.get("ci95") or [None, None]
    return {
        "sample_id": fit.get("sample_id"), "status": fit.get("status", "ok"),
        "ball_type": (fit.get("ball") or {}).get("type"), "n_impacts": restitution.get("n_impacts"),
        "restitution_model": restitution.get("model"),
        "e": e.get("value"), "e_se": e.get("se"), "e_ci95_low": ci[0], "e_ci95_high": ci[1],
        "e_speed_m_s": restitution.get("reference_speed_m_s"), "e1": e1.get("value"), "e1_se": e1.get("se"),
        "drop_height_m": (fit.get("drop_height_m") or {}).get("value"),
        "itf_rebound_m": rebound.get("value"), "itf_rebound_se_m": rebound.get("se"),
        "itf_verdict": fit["itf"].get("verdict"), "drag_model": fit["drag"].get("model"),
        "e_from": fusion.get("source"), "sound_picture_flag": fusion.get("flag"),
    }


def batch_rows(fits, extras=None):
    """Summary table of a batch: one row per recording, failed ones with their message.

    Parameters
    ----------
    fits : list of dict
        Fit results (``fit.json``), or failure records ``{"status": "failed", "error": ...,
        "sample_id": ...}``.
    extras : pandas.DataFrame, optional
        Free columns of the sample sheet by ``sample_id`` (:func:`sample_sheet_extras`), carried into
        the table after :data:`BATCH_COLUMNS` (empty where a recording is not in the sheet).

    Returns
    -------
    pandas.DataFrame
        Columns :data:`BATCH_COLUMNS`: impacts fitted, the chosen restitution model, its e at the
        first fitted impact's speed (for a constant e, e; for ``per_impact``, e₁) with se and 95 %
        interval (1), that speed ``e_speed_m_s`` (m/s), the first fitted impact's own e ``e1`` with
        se (1), drop height and ITF rebound with its se (m); NaN where not applicable (e.g. every
        number of a failed recording); then the columns of ``extras``.
    """
    table = pd.DataFrame([_batch_row(fit) for fit in fits], columns=BATCH_COLUMNS)
    numeric = ["e", "e_se", "e_ci95_low", "e_ci95_high", "e_speed_m_s", "e1", "e1_se", "drop_height_m",
               "itf_rebound_m", "itf_rebound_se_m"]
    table[numeric] = table[numeric].astype(float)
    table["n_impacts"] = table["n_impacts"].astype("Int64")
    if extras is not None and len(extras.columns):
        table = table.join(extras, on="sample_id")
    return table


#: Sample-sheet columns the workflow reads besides the options' own (:data:`dropfit.settings.OPTIONS`).
WORKFLOW_SHEET_COLUMNS = ("sample_id", "path", "batch", "ball_id")


def sample_sheet_extras(sheet):
    """The free columns of a sample sheet: those the workflow does not read (surface, temperature, …).

    Parameters
    ----------
    sheet : pandas.DataFrame
        The sample sheet (:func:`dropfit.stages.read_sample_sheet`: numbers or text, missing cells NaN),
        with a ``sample_id`` column of unique ids.

    Returns
    -------
    pandas.DataFrame
        Indexed by ``sample_id``, one column per free column in the sheet's order: numbers (float, NaN
        where empty) where every given cell is a number, else text (missing where empty). A column named
        as a summary column gets " (sample sheet)" after its name.
    """
    from .settings import OPTIONS

    used = set(WORKFLOW_SHEET_COLUMNS) | {name for name, option in OPTIONS.items() if option.column}
    extras = pd.DataFrame(index=pd.Index(sheet["sample_id"], name="sample_id"))
    for column in sheet.columns:
        if column in used:
            continue
        text = sheet[column].astype("string").fillna("").str.strip().to_numpy(dtype=object)
        given = text != ""
        numbers = pd.to_numeric(pd.Series(text), errors="coerce").to_numpy(dtype=float)
        name = f"{column} (sample sheet)" if column in BATCH_COLUMNS else column
        if given.any() and np.isfinite(numbers[given]).all():
            extras[name] = np.where(given, numbers, np.nan)
        else:
            extras[name] = np.where(given, text, None)
    return extras


def numeric_extras(table):
    """The free sample-sheet columns of a summary table (:func:`batch_rows`) that hold numbers."""
    return [column for column in table.columns[len(BATCH_COLUMNS):]
            if pd.api.types.is_float_dtype(table[column]) and table[column].notna().any()]


def extras_png(table):
    """e of every analysed recording against each numeric free column of the sample sheet (PNG bytes).

    Parameters
    ----------
    table : pandas.DataFrame
        Summary table of :func:`batch_rows` with the sheet's free columns.

    Returns
    -------
    bytes
        One panel per numeric free column: the chosen model's e at v₁ with its 95 % interval (1)
        against the column's value, one colour per ball type; without such a column a chart that says so.
    """
    columns = numeric_extras(table)
    analysed = table[(table["status"] != "failed") & table["e"].notna()]
    n_cols = min(3, max(1, len(columns)))
    n_rows = max(1, math.ceil(len(columns) / n_cols))
    fig, axes = plt.subplots(n_rows, n_cols, figsize=(4.2 * n_cols, 3.4 * n_rows), layout="constrained",
                             squeeze=False)
    for ax in axes.flat[len(columns):]:
        ax.set_axis_off()
    if not columns:
        axes[0, 0].text(0.5, 0.5, "no numeric free column in the sample sheet", ha="center", va="center")
    balls = analysed["ball_type"].astype(object).fillna("ball not named")
    for ax, column in zip(axes.flat, columns):
        for ball in sorted(balls.unique()):  # one colour per kind of ball: e of different balls differ anyway
            drops = analysed[balls == ball]
            ax.errorbar(drops[column], drops["e"], yerr=[drops["e"] - drops["e_ci95_low"],
                                                         drops["e_ci95_high"] - drops["e"]],
                        fmt="o", ms=4, capsize=3, label=ball)
        # column names are the user's text: drawn literally, never as mathtext
        ax.set_xlabel(shown(column, 40), parse_math=False)
        ax.set_ylabel("e at v₁, 95 % interval (1)")
        ax.grid(alpha=0.3)
    if columns and balls.nunique() > 1:
        axes[0, 0].legend(fontsize=8)
    fig.suptitle("e against the sample sheet's numeric columns", fontsize=11)
    return _png_bytes(fig)


def report_href(fit_path, page_path):
    """The relative link from a batch page at ``page_path`` to the report beside a recording's
    ``fit_path`` (``report.html`` in the same directory), URL-quoted."""
    target = os.path.join(os.path.dirname(os.path.abspath(fit_path)), "report.html")
    relative = os.path.relpath(target, os.path.dirname(os.path.abspath(page_path)))
    return quote(relative.replace(os.sep, "/"))


#: What a verdict cell says: an ITF verdict, or why there is none (in words as well as in colour).
_VERDICT_WORDS = {"not applicable": "not judged", None: "not judged"}
_VERDICT_LEGEND = ("ITF verdict: <span class='verdict-cell verdict-pass'>pass</span> the 95 % interval of the "
                   "254 cm rebound lies inside the window; <span class='verdict-cell verdict-fail'>fail</span> "
                   "wholly outside; <span class='verdict-cell verdict-indeterminate'>indeterminate</span> it "
                   "straddles a limit; <span class='verdict-cell verdict-not-judged'>not judged</span> no ITF "
                   "test for this ball; <span class='verdict-cell verdict-not-analysed'>not analysed</span> the "
                   "recording failed.")


def _verdict_cell(verdict):
    """A verdict in words on its colour (:data:`_VERDICT_LEGEND`)."""
    words = _VERDICT_WORDS.get(verdict, verdict) if not _missing(verdict) else "not judged"
    return f'<span class="verdict-cell verdict-{escape(str(words)).replace(" ", "-")}">{escape(str(words))}</span>'


def _breakable(text):
    """Escaped text that may wrap after each ``_``, ``-`` and ``.`` (a sample id in a narrow column)."""
    escaped = _text(text)
    for mark in "_-.":
        escaped = escaped.replace(mark, mark + "<wbr>")
    return escaped


def _linked(text, href):
    """``text`` (plain, an id) as a link to ``href`` (already quoted), or alone without one."""
    return _breakable(text) if href is None else f'<a href="{escape(href)}">{_breakable(text)}</a>'


def _pm_cell(value, se):
    """``value ± se`` in a summary table cell (:func:`_number_cell`)."""
    return _number_cell(escape(format_pm(value, se)))


def _summary_cells(row, href, extras):
    """The HTML cells of one summary row: (content, CSS class: "num", "pm", "reason" or "" [, colspan]);
    ``extras`` maps each free column to whether it holds numbers."""
    recording = (_linked(row["sample_id"], href), "")
    if row["status"] == "failed":
        return [recording, (MISSING, ""), (_verdict_cell("not analysed"), ""),
                (f"<b>failed:</b> {_text(row['error'])}", "reason", 8 + len(extras))]
    model = row["restitution_model"]
    law = f" <span class='words'>({escape(LAWS[model])})</span>" if model in LAWS else ""
    cells = [recording, (_breakable(row["ball_type"]), ""), (_verdict_cell(row["itf_verdict"]), ""),
             (_breakable(model) + law, ""), _pm_cell(row["e"], row["e_se"]),
             (_num(row["e_speed_m_s"], ".3f"), "num"), _pm_cell(row["e1"], row["e1_se"]),
             (_text(row["n_impacts"]), "num"), (_num(row["drop_height_m"], ".4f"), "num"),
             _pm_cell(row["itf_rebound_m"], row["itf_rebound_se_m"]), (_text(row["drag_model"]), "")]
    for column, numeric in extras.items():
        cells.append((_num(row[column], ".6g"), "num") if numeric else (_breakable(row[column]), ""))
    return cells


def _cell_html(cell):
    content, css_class, *span = cell
    attributes = (f' class="{css_class}"' if css_class else "") + (f' colspan="{span[0]}"' if span else "")
    return f"<td{attributes}>{content}</td>"


def batch_report_html(table, fits, links=None, extras_figure=None):
    """HTML page of a batch summary table (from :func:`batch_rows`): one row per recording linked to
    its report, the ITF verdict in colour and words, failed recordings with their reason.

    Parameters
    ----------
    table : pandas.DataFrame
        The batch summary table, with the sample sheet's free columns after :data:`BATCH_COLUMNS`.
    fits : list of dict
        The fit results of the rows (the settings shown at the top, :func:`run_html`).
    links : list of str, optional
        Each row's link to its report (:func:`report_href`); none without.
    extras_figure : bytes, optional
        The chart of e against the numeric free columns (:func:`extras_png`), shown under the table.

    Returns
    -------
    str
        The HTML page.
    """
    failed = table["status"] == "failed"
    extras = {column: pd.api.types.is_float_dtype(table[column]) for column in table.columns[len(BATCH_COLUMNS):]}
    links = links if links is not None else [None] * len(table)
    headers = ["recording (report)", "ball", "ITF verdict", "e law", "e at v₁ ± se (1)", "v₁ (m/s)", "e₁ ± se (1)",
               "impacts fitted", "drop height (m)", "ITF rebound ± se (m)", "drag"] + list(extras)
    head = "".join(f"<th>{_breakable(header)}</th>" for header in headers)
    body = []
    for href, (_, row) in zip(links, table.iterrows()):
        row_class = ' class="failed"' if row["status"] == "failed" else ""
        body.append(f"<tr{row_class}>{''.join(_cell_html(cell) for cell in _summary_cells(row, href, extras))}</tr>")
    rows = "\n".join(body)
    figure = ""
    if extras_figure is not None:
        figure = (f"<h2>e against the sample sheet's columns</h2>\n<p>Every analysed recording's e at v₁ with "
                  f"its 95 % interval against each numeric free column of the sample sheet "
                  f"({escape(', '.join(numeric_extras(table))) or 'none'}).</p>\n"
                  + _png_img(extras_figure, "e against the sample sheet's numeric columns"))
    intro = (f"<p>{len(table)} recordings: {int((~failed).sum())} analysed, {int(failed.sum())} failed. "
             f"e is the chosen law's e at the first fitted impact's speed v₁ (a constant e at every speed; with no "
             f"law, per_impact, the first impact's own e); e₁ is that impact's own e. The CSV holds the same "
             f"numbers and e's 95 % interval.</p>\n<p>{_VERDICT_LEGEND}</p>")
    return _html_page("dropfit batch summary", intro,
                      f"<table class='batch'>\n<tr>{head}</tr>\n{rows}\n</table>\n{figure}", fits, wide=True)


# --- batch QC report ----------------------------------------------------------------------------

_VERDICT_COLOURS = {"pass": "tab:green", "fail": "tab:red", "indeterminate": "tab:orange"}


def _ball_label(ball):
    """Tick label of a ball: its id, and how many of its drops failed."""
    return shown(ball.ball_id, 30) + (f"\n({ball.n_failed} failed)" if ball.n_failed else "")


def qc_chart_png(batch, recordings, balls, statistics, window):
    """Control chart of the 254 cm rebound height per drop, grouped by ball (PNG bytes).

    Parameters
    ----------
    batch : str
        Batch name (title).
    recordings : pandas.DataFrame
        Per-recording table with ``ball_id``, ``status``, ``itf_rebound_m`` and ``itf_rebound_se_m`` (m).
    balls : pandas.DataFrame
        Per-ball table of :func:`dropfit.batch.ball_rows`.
    statistics : dict
        Batch statistics of :func:`dropfit.batch.batch_statistics` (heights in m).
    window : dict
        The ITF test: ``drop_height_m``, ``rebound_min_m``, ``rebound_max_m`` (m).

    Returns
    -------
    bytes
        The PNG; without any rebound height (not tennis balls, or every drop failed) an empty chart
        that says so.
    """
    measured = balls[np.isfinite(balls["rebound_m"])]
    cm = 100.0
    rebound_min_m, rebound_max_m = window["rebound_min_m"], window["rebound_max_m"]
    fig, ax = plt.subplots(figsize=(max(6.5, 1.3 * len(measured) + 3), 5.2), layout="constrained")
    ax.axhspan(cm * rebound_min_m, cm * rebound_max_m, color="tab:green", alpha=0.08)
    for limit in (rebound_min_m, rebound_max_m):
        ax.axhline(cm * limit, color="tab:red", ls="--", lw=1.2,
                   label=f"ITF limits {cm * rebound_min_m:.0f} / {cm * rebound_max_m:.0f} cm"
                   if limit == rebound_min_m else None)
    centre = statistics["rebound_mean_m"]
    if np.isfinite(centre):
        ax.axhline(cm * centre, color="0.3", lw=1.2, label=f"batch mean of balls {cm * centre:.1f} cm")
    if np.isfinite(statistics["control_low_m"]):
        for limit in ("control_low_m", "control_high_m"):
            ax.axhline(cm * statistics[limit], color="tab:blue", ls=":", lw=1.5,
                       label="control limits: mean ± 3 sd of the ball means" if limit == "control_low_m" else None)
    for x, ball in enumerate(measured.itertuples()):
        drops = recordings[(recordings["ball_id"] == ball.ball_id) & (recordings["status"] != "failed")]
        offsets = x - 0.15 + np.linspace(-0.08, 0.08, len(drops)) if len(drops) > 1 else np.array([x - 0.15])
        ax.errorbar(offsets, cm * drops["itf_rebound_m"], yerr=cm * Z95 * drops["itf_rebound_se_m"], fmt="o",
                    ms=4, color="0.45", capsize=2, label="drops (±1.96 se)" if x == 0 else None)
        colour = _VERDICT_COLOURS.get(ball.itf_verdict, "0.3")
        ax.errorbar([x + 0.15], [cm * ball.rebound_m],
                    yerr=[[cm * (ball.rebound_m - ball.rebound_ci95_low_m)],
                          [cm * (ball.rebound_ci95_high_m - ball.rebound_m)]],
                    fmt="D", ms=7, color=colour, capsize=4, lw=2)
    for verdict, colour in _VERDICT_COLOURS.items():  # legend entries of the ball means, by verdict
        ax.errorbar([], [], yerr=[], fmt="D", ms=7, color=colour, label=f"ball mean, 95 % interval: {verdict}")
    if measured.empty:
        ax.text(0.5, 0.5, "no ball of this batch has an ITF rebound height", transform=ax.transAxes, ha="center")
    # ball ids and the batch name are the user's text: drawn literally, never as mathtext
    ax.set_xticks(range(len(measured)), [_ball_label(ball) for ball in measured.itertuples()], parse_math=False)
    ax.set_xlim(-0.6, len(measured) - 0.4)
    ax.set_xlabel("ball")
    ax.set_ylabel(f"rebound height from a {cm * window['drop_height_m']:.0f} cm drop (cm)")
    ax.set_title(f"batch {shown(batch)}: ITF rebound control chart", loc="left", parse_math=False)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize=9, frameon=False)
    return _png_bytes(fig)


def _cm_pm(value_m, se_m):
    """A height in m shown in cm as ``value ± se``."""
    return escape(format_pm(100 * value_m, 100 * se_m))


def _cm_interval(low_m, high_m, se_m):
    """A 95 % interval in m shown in cm, to the precision of its standard error."""
    return escape(format_interval([100 * low_m, 100 * high_m], 100 * se_m))




def _qc_summary(statistics, window):
    counts = ", ".join(f"{count} {verdict}" for verdict, count in statistics["verdict_counts"].items() if count)
    outside = statistics["out_of_control"]
    cm = 100.0
    if np.isfinite(statistics["control_low_m"]):
        control = (f"{cm * statistics['control_low_m']:.1f} cm to {cm * statistics['control_high_m']:.1f} cm "
                   f"(batch mean ± 3 ball-to-ball sd): "
                   + (f"{', '.join(outside)} outside" if outside else "every ball mean inside"))
    else:
        control = "no control limits: fewer than two balls have a rebound height"
    return _definitions([
        ("Balls", f"{statistics['n_balls']} ({statistics['n_balls_measured']} with a rebound height)"),
        ("Verdicts", _text(counts)),
        ("ITF window", escape(f"rebound from {cm * window['drop_height_m']:.0f} cm between "
                              f"{cm * window['rebound_min_m']:.0f} cm and {cm * window['rebound_max_m']:.0f} cm "
                              f"(pass: the ball's 95 % interval inside; fail: wholly outside; "
                              f"indeterminate: straddles a limit)")),
        ("Batch mean rebound", _quantity(statistics["rebound_mean_m"], cm, ".2f", "cm")
         + " (mean of the ball means; centre line)"),
        ("Ball-to-ball spread", _quantity(statistics["rebound_sd_between_balls_m"], cm, ".2f", "cm")
         + " (standard deviation of the ball means)"),
        ("Drop-to-drop spread", _quantity(statistics["rebound_sd_within_balls_m"], cm, ".2f", "cm")
         + f" (standard deviation pooled over the balls, {statistics['within_balls_dof']} degrees of freedom)"),
        ("Control limits", escape(control)),
    ])


def _qc_balls_table(balls):
    rows = []
    for ball in balls.itertuples():
        rows.append([
            (_text(ball.ball_id), False), (_text(ball.n_drops), True), (_text(ball.n_failed), True),
            (_cm_pm(ball.rebound_m, ball.rebound_se_m), True),
            (_cm_interval(ball.rebound_ci95_low_m, ball.rebound_ci95_high_m, ball.rebound_se_m), True),
            (_num(100 * ball.rebound_sd_between_drops_m, ".2f"), True), (_text(ball.rebound_se_from), False),
            (escape(format_pm(ball.e, ball.e_se)), True), (_num(ball.e_sd_between_drops, ".4f"), True),
            (_verdict_cell(ball.itf_verdict), False),
        ])
    return _table(["ball", "drops", "failed drops", "rebound ± se (cm)", "rebound 95 % interval (cm)",
                   "drop-to-drop sd (cm)", "se from", "e ± se (1)", "drop-to-drop sd of e (1)", "ITF verdict"], rows)


def _qc_drops_table(recordings, links):
    rows = [[(_linked(row.sample_id, href), False), (_text(row.ball_id), False), (_text(row.status), False),
             (_cm_pm(row.itf_rebound_m, row.itf_rebound_se_m), True), (escape(format_pm(row.e, row.e_se)), True),
             (_verdict_cell("not analysed" if row.status == "failed" else row.itf_verdict), False)]
            for href, row in zip(links, recordings.itertuples(index=False))]
    return _table(["recording (report)", "ball", "status", "rebound ± se (cm)", "e ± se (1)",
                   "ITF verdict of the drop"], rows)


def _qc_failed_list(failed):
    if failed.empty:
        return "<p>None: every recording was analysed.</p>"
    items = "".join(f"<li><b>{_text(row.sample_id)}</b> (ball {_text(row.ball_id)}): {_text(row.reason)}</li>\n"
                    for row in failed.itertuples(index=False))
    return f"<ul>\n{items}</ul>"


def qc_report_html(batch, recordings, balls, statistics, failed, window, png, fits, links=None):
    """The self-contained batch QC page: batch summary, control chart, per-ball and per-drop tables,
    failed recordings.

    Parameters
    ----------
    batch : str
        Batch name.
    recordings : pandas.DataFrame
        Per-recording table (:func:`batch_rows` with ``ball_id``).
    balls, statistics, failed
        Outputs of :func:`dropfit.batch.ball_rows`, :func:`dropfit.batch.batch_statistics` and
        :func:`dropfit.batch.failed_recordings`.
    window : dict
        The ITF test: ``drop_height_m``, ``rebound_min_m``, ``rebound_max_m`` (m).
    png : bytes
        The control chart, embedded as base64.
    fits : list of dict
        The fit results of the recordings (the settings shown at the top, :func:`run_html`).
    links : list of str, optional
        Each recording's link to its report (:func:`report_href`); none without.

    Returns
    -------
    str
        The HTML page.
    """
    chart = _png_img(png, f"control chart of the rebound heights of batch {batch}")
    sections = [
        ("Batch summary", _qc_summary(statistics, window)),
        ("Control chart", chart),
        ("Balls", "<p>Mean over each ball's analysed drops; the standard error is the larger of the "
                  "drop-to-drop scatter (sd/√n) and the propagated measurement errors, the 95 % interval "
                  "uses Student's t with n − 1 degrees of freedom (±1.96 se for one drop).</p>\n"
                  + _qc_balls_table(balls)),
        ("Drops", _qc_drops_table(recordings, links if links is not None else [None] * len(recordings))),
        ("Failed recordings", _qc_failed_list(failed)),
    ]
    n_failed = len(failed)
    return _html_page(f"dropfit batch QC: {batch}",
                      f"<p>{len(recordings)} recordings of {len(balls)} balls: {len(recordings) - n_failed} "
                      f"analysed, {n_failed} failed.</p>\n<p>{_VERDICT_LEGEND}</p>", _sections_html(sections), fits)
