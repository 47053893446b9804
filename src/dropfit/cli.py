"""Command line: ``dropfit <stage> …``, one subcommand per workflow stage.

A problem with the input prints one line, ``dropfit: error: <file>: <what is wrong>; <what to try>``,
and exits with status 1; with ``--record-failure`` the stage instead writes failure records to its
outputs and exits 0, so that a batch goes on and its summary lists the recording. The line quotes
the user's text only through :func:`dropfit.errors.shown` (short, no control characters), and an
output the failed stage had begun to write is removed: outputs are whole or absent.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import traceback
import warnings

from . import stages
from .errors import InputError, one_line, shown, shown_path
from .files import write_failure
from .physics import STANDARD_GRAVITY_M_S2
from .restitution import ITF_DROP_HEIGHT_M, ITF_REBOUND_MAX_M, ITF_REBOUND_MIN_M


def _parser():
    parser = argparse.ArgumentParser(prog="dropfit", description="Ball drop tests to trustworthy numbers.")
    sub = parser.add_subparsers(dest="command", required=True)

    def stage(name, help_text):
        command = sub.add_parser(name, help=help_text, description=help_text)
        command.add_argument("--record-failure", action="store_true",
                             help="on a bad recording write failure records to the outputs and exit 0")
        return command

    synth = sub.add_parser("synth", help="generate a synthetic height log and its ground truth")
    synth.add_argument("--scenarios", required=True, help="scenarios YAML file")
    synth.add_argument("--name", required=True, help="scenario name")
    synth.add_argument("--log", required=True, help="output height log (CSV)")
    synth.add_argument("--truth", required=True, help="output ground truth (JSON)")
    synth.add_argument("--seed", type=int, help="override the scenario's seed")

    video = sub.add_parser("synth-video", help="render a default synthetic drop-test video and its ground truth")
    video.add_argument("--name", required=True, help="clip name (see dropfit.video_synth.default_clips)")
    video.add_argument("--out-dir", required=True, help="directory for <name>.avi, .frames.csv and .truth.json")
    video.add_argument("--seed", type=int, default=0, help="seed of the sensor noise")

    measure = stage("measure", "height log (CSV) or video → trajectory (NetCDF, m)")
    measure.add_argument("log", help="height log CSV, or a video (.avi, .mp4, .mov, .mkv, .m4v)")
    measure.add_argument("--out", required=True, help="trajectory NetCDF to write")
    measure.add_argument("--sample-id")
    measure.add_argument("--ball-radius-m", type=float, help="ball radius in m")
    measure.add_argument("--ball-mass-kg", type=float, help="ball mass in kg")
    measure.add_argument("--ball-type", help="tennis, steel, rubber, table_tennis or other")
    measure.add_argument("--scale-m-per-px", type=float,
                         help="m per px for logs in px (negative if the axis points down); default: from gravity")
    measure.add_argument("--gravity-m-s2", type=float, default=STANDARD_GRAVITY_M_S2, help="gravity in m/s²")
    measure.add_argument("--capture-fps", type=float,
                         help="capture rate in frames/s of a slow-motion video whose file states another rate")
    measure.add_argument("--ruler-tick-m", type=float,
                         help="video: spacing in m of the finest ticks of a ruler in the ball's plane (scale from it)")
    measure.add_argument("--floor-m", type=float,
                         help="height of the floor in the log's frame, in m (makes contact times measurable)")

    analyse = stage("analyse", "trajectory → impacts and flights tables (CSV) and analysis summary (JSON)")
    analyse.add_argument("trajectory")
    analyse.add_argument("--impacts", required=True)
    analyse.add_argument("--flights", required=True)
    analyse.add_argument("--summary", required=True)
    analyse.add_argument("--drag", choices=["auto", "off", "on"], default="auto",
                         help="quadratic air drag k: fitted when BIC prefers it (auto), never or always; when not "
                              "fitted, held at a smooth sphere's k if the ball's radius and mass are known")
    analyse.add_argument("--gravity-m-s2", type=float, default=STANDARD_GRAVITY_M_S2, help="gravity in m/s²")

    fit = stage("fit", "impacts → fit result (JSON): e, theory checks, ITF verdict")
    fit.add_argument("--analysis", required=True)
    fit.add_argument("--impacts", required=True)
    fit.add_argument("--out", required=True)
    fit.add_argument("--ball-type")
    _add_itf_window(fit)
    fit.add_argument("--itf-drop-height-tolerance-m", type=float, default=0.02)

    report = stage("report", "per-recording HTML report and PNG figure")
    for name in ("trajectory", "flights", "impacts", "analysis", "fit", "html", "figure"):
        report.add_argument(f"--{name}", required=True)

    summary = sub.add_parser("summary", help="batch summary table (CSV, HTML) over fit results")
    summary.add_argument("fits", nargs="+", help="fit.json files, one per recording")
    summary.add_argument("--csv", required=True)
    summary.add_argument("--html", required=True)

    qc = sub.add_parser("qc", help="batch QC report: per-ball ITF verdicts, batch statistics, control chart")
    qc.add_argument("fits", nargs="+", help="fit.json files, one per recording (drop) of the batch")
    qc.add_argument("--ball-ids", nargs="+", help="ball of each fit file, in the same order (default: one ball each)")
    qc.add_argument("--batch", required=True, help="batch name (report title)")
    qc.add_argument("--html", required=True, help="QC report to write (HTML)")
    qc.add_argument("--figure", required=True, help="control chart to write (PNG)")
    qc.add_argument("--csv", required=True, help="per-ball table to write (CSV, heights in m)")
    _add_itf_window(qc)
    return parser


def _add_itf_window(parser):
    """The ITF drop height and rebound window options (m), shared by ``fit`` and ``qc``."""
    parser.add_argument("--itf-drop-height-m", type=float, default=ITF_DROP_HEIGHT_M)
    parser.add_argument("--itf-rebound-min-m", type=float, default=ITF_REBOUND_MIN_M)
    parser.add_argument("--itf-rebound-max-m", type=float, default=ITF_REBOUND_MAX_M)


#: Option → (what it is, lowest, highest, whether the lowest is allowed): values outside are refused
#: with one line naming the stage's input. The upper bounds catch a value in the wrong unit (a radius
#: of 33.5 given in mm).
_OPTION_RANGES = {
    "ball_radius_m": ("the ball's radius in m (a tennis ball: 0.0335)", 0.0, 1.0, False),
    "ball_mass_kg": ("the ball's mass in kg (a tennis ball: 0.057)", 0.0, 20.0, False),
    "gravity_m_s2": ("gravity in m/s² (9.80665 on Earth)", 0.0, 100.0, False),
    "capture_fps": ("the capture rate in frames/s", 0.0, math.inf, False),
    "ruler_tick_m": ("the ruler's finest tick spacing in m (e.g. 0.01)", 0.0, 1.0, False),
    "scale_m_per_px": ("metres per pixel (negative for image rows), not 0", -math.inf, math.inf, True),
    "floor_m": ("the floor's height in m in the log's frame", -math.inf, math.inf, True),
    "itf_drop_height_m": ("the ITF drop height in m (2.54)", 0.0, math.inf, False),
    "itf_rebound_min_m": ("the ITF window's lower rebound height in m (1.35)", 0.0, math.inf, False),
    "itf_rebound_max_m": ("the ITF window's upper rebound height in m (1.47)", 0.0, math.inf, False),
    "itf_drop_height_tolerance_m": ("the drop-height tolerance in m (0.02)", 0.0, math.inf, True),
}


def _check_options(args):
    """InputError, naming the stage's input, for an option value that is not a finite number in its range."""
    for option, (what, low, high, low_allowed) in _OPTION_RANGES.items():
        value = getattr(args, option, None)
        if value is None:
            continue
        inside = math.isfinite(value) and (value >= low if low_allowed else value > low) and value <= high
        if option == "scale_m_per_px":
            inside = math.isfinite(value) and value != 0
        if not inside:
            flag = "--" + option.replace("_", "-")
            raise InputError(f"{_input_name(args)}: {flag} is {value:g}; give {what}")
    low, high = getattr(args, "itf_rebound_min_m", None), getattr(args, "itf_rebound_max_m", None)
    if low is not None and not low < high:
        raise InputError(f"{_input_name(args)}: the ITF rebound window is empty (--itf-rebound-min-m {low:g} is not "
                         f"below --itf-rebound-max-m {high:g}); give the lower limit first")


def _run(args):
    """Call the stage with the parsed arguments."""
    if args.command == "synth":
        stages.synth(args.scenarios, args.name, args.log, args.truth, args.seed)
    elif args.command == "synth-video":
        stages.synth_video(args.name, args.out_dir, args.seed)
    elif args.command == "measure":
        stages.measure(args.log, args.out, args.sample_id, args.ball_radius_m, args.ball_mass_kg, args.ball_type,
                       args.scale_m_per_px, args.gravity_m_s2, args.floor_m, args.capture_fps, args.ruler_tick_m)
    elif args.command == "analyse":
        stages.analyse(args.trajectory, args.impacts, args.flights, args.summary, args.drag, args.gravity_m_s2)
    elif args.command == "fit":
        stages.fit(args.analysis, args.impacts, args.out, args.ball_type, args.itf_drop_height_m,
                   args.itf_rebound_min_m, args.itf_rebound_max_m, args.itf_drop_height_tolerance_m)
    elif args.command == "report":
        stages.report(args.trajectory, args.flights, args.impacts, args.analysis, args.fit, args.html, args.figure)
    elif args.command == "summary":
        stages.summary(args.fits, args.csv, args.html)
    elif args.command == "qc":
        stages.qc(args.fits, args.batch, args.html, args.figure, args.csv, args.ball_ids, args.itf_drop_height_m,
                  args.itf_rebound_min_m, args.itf_rebound_max_m)


#: The outputs of each stage, by argument name.
_OUTPUTS = {"measure": ["out"], "analyse": ["impacts", "flights", "summary"], "fit": ["out"],
            "report": ["html", "figure"], "summary": ["csv", "html"], "qc": ["html", "figure", "csv"]}
#: The input each stage's messages name: the recording, the trajectory, the analysis, the fit results.
_INPUTS = {"synth": "scenarios", "synth-video": "name", "measure": "log", "analyse": "trajectory",
           "fit": "analysis", "report": "trajectory", "summary": "fits", "qc": "fits"}


def _input_name(args):
    """The stage's input file as messages name it (the first of several, with how many more)."""
    value = getattr(args, _INPUTS[args.command])
    if isinstance(value, list):
        more = f" (and {len(value) - 1} more)" if len(value) > 1 else ""
        return f"{shown_path(value[0])}{more}"
    return shown_path(value)


def _stat(path):
    try:
        info = os.stat(path)
    except OSError:
        return None
    return info.st_ino, info.st_mtime_ns, info.st_size


def main(argv=None):
    """Entry point of the ``dropfit`` console script and ``python -m dropfit``."""
    args = _parser().parse_args(argv)
    record = getattr(args, "record_failure", False)
    outputs = [getattr(args, name) for name in _OUTPUTS.get(args.command, [])]
    before = {path: _stat(path) for path in outputs}
    try:
        with warnings.catch_warnings():
            if not sys.warnoptions:  # numerical warnings are for developers (python -W shows them)
                warnings.simplefilter("ignore")
            _check_options(args)
            _run(args)
    except InputError as error:
        message = one_line(str(error))
    except Exception as error:  # noqa: BLE001 — a bug, not the user's fault
        # the traceback goes to the log (standard error); the line, the failure records and the batch
        # summary name the input and the error only
        traceback.print_exc()
        message = one_line(f"{_input_name(args)}: internal error in dropfit {args.command} "
                           f"({type(error).__name__}: {shown(error)}); please report it with this file")
    else:
        return 0
    for path in outputs:  # an output this run began to write is not whole: remove it
        if _stat(path) != before[path]:
            try:
                os.remove(path)
            except OSError:
                pass
    print(f"dropfit: error: {message}", file=sys.stderr)
    if not record:
        return 1
    for path in outputs:
        write_failure(path, message)
    return 0


if __name__ == "__main__":
    sys.exit(main())
