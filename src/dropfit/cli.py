"""Command line: ``dropfit <stage> …``, one subcommand per workflow stage, ``dropfit run`` for all of
them on one recording, and ``dropfit batch`` for the recordings of a sample sheet (the workflow's jobs).

The options (``--ball-radius-m``, ``--gravity-m-s2``, ``--drag`` …) are those of
:data:`dropfit.settings.OPTIONS`; one not given takes the default of :class:`dropfit.settings.Settings`.

A value starting with ``-`` is read as a value where its flag takes one (``--floor-m -5e-05``, which
argparse alone reads as an option); a recording whose name starts with ``-`` comes after ``--``
(``dropfit run --out DIR -- -drop.csv``). A problem with the input prints one line, ``dropfit: error: <file>: <what is wrong>; <what to try>``,
and exits with status 1; with ``--record-failure`` the stage instead writes failure records to its
outputs and exits 0 (also for a usage error, such as an option value that is not a number, when the
outputs can be read from the command line), so that a batch goes on and its summary lists the recording. The line quotes
the user's text only through :func:`dropfit.errors.shown` (short, no control characters), and an
output the failed stage had begun to write is removed: outputs are whole or absent.
"""

from __future__ import annotations

import argparse
import difflib
import os
import sys
import traceback
import warnings
from pathlib import Path

from . import __version__, stages
from .errors import InputError, OutputError, one_line, shown, shown_path
from .files import environment_message, write_failure
from .heightlog import is_number
from .settings import OPTIONS, OptionError, Settings, check_config, option_default, split_options


SAMPLE_ID_HELP = "the recording's name, kept in its outputs (the workflow's sample_id)"
#: The report's files: its inputs, as dropfit measure, analyse and fit write them, and its outputs.
REPORT_FILES = {"trajectory": "trajectory NetCDF (dropfit measure)", "flights": "flights table (CSV, dropfit analyse)",
                "impacts": "impacts table (CSV, dropfit analyse)", "analysis": "analysis summary (JSON, dropfit analyse)",
                "fit": "fit result (JSON, dropfit fit)", "html": "report to write (HTML)",
                "figure": "figure to write (PNG)"}


class _UsageError(Exception):
    """A command line argparse cannot read: the parser that says so and its message."""

    def __init__(self, parser, message):
        super().__init__(message)
        self.parser = parser


class _Parser(argparse.ArgumentParser):
    """argparse, raising :class:`_UsageError` instead of exiting, so that ``--record-failure`` can record it."""

    def error(self, message):
        raise _UsageError(self, message)


def build_parser(lenient=False):
    """The command line's parser; ``lenient``: every option value taken as text and none required, to find
    the outputs of a command line the strict parser refused."""
    parser = _Parser(prog="dropfit", description="Ball drop tests to trustworthy numbers.")
    parser.add_argument("--version", action="version", version=f"dropfit {__version__}",
                        help="print dropfit's version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND",
                                help="the stage to run (dropfit COMMAND --help for its options)")
    real_add_parser = sub.add_parser

    def add_parser(name, **kwargs):
        command = real_add_parser(name, **kwargs)
        if lenient:  # a bad value or a missing option is what the strict parser reports
            real_add_argument = command.add_argument

            def add_argument(*names, **options):
                if names[0].startswith("-") and "action" not in options:
                    options.update(required=False, type=None, choices=None)
                return real_add_argument(*names, **options)

            command.add_argument = add_argument
        return command

    sub.add_parser = add_parser

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

    run = stage("run", "one recording → every file the workflow writes for it (trajectory.nc, impacts.csv, "
                       "flights.csv, analysis.json, fit.json, report.html, report.png) in --out; prints the headline")
    run.add_argument("recording", help="height log CSV, a video (.avi, .mp4, .mov, .mkv, .m4v), the sound of the "
                                       "bounces (.wav, .flac, .ogg, .m4a, .aac, .mp3) or a CSV of impact times")
    run.add_argument("--out", required=True, help="directory to write the files into")
    run.add_argument("--sample-id", help=SAMPLE_ID_HELP)
    _add_options(run, "run")

    batch = sub.add_parser("batch", help="the recordings of a sample sheet → the files dropfit run writes for each, in "
                                         "RESULTS/<sample_id>/, in one process; a recording that fails gets failure "
                                         "records and the batch goes on (the workflow's jobs)")
    batch.add_argument("sample_ids", nargs="*", metavar="SAMPLE_ID",
                       help="the rows to do, in this order (default: every row); put them after --")
    batch.add_argument("--samples", required=True, help="the sample sheet (tab-separated, config/samples.tsv)")
    batch.add_argument("--results", default="results", help="directory of the recordings' directories "
                                                            "(default results)")
    batch.add_argument("--config", help="the workflow's config (site, analysis, itf): a YAML file such as "
                                        "config/config.yaml, or the mapping itself as JSON")

    measure = stage("measure", "height log (CSV) or video → trajectory (NetCDF, m); sound → impact times (NetCDF, s)")
    measure.add_argument("log", help="height log CSV, a video (.avi, .mp4, .mov, .mkv, .m4v), the sound of the "
                                     "bounces (.wav, .flac, .ogg, .m4a, .aac, .mp3) or a CSV of impact times")
    measure.add_argument("--out", required=True, help="trajectory NetCDF to write")
    measure.add_argument("--sample-id", help=SAMPLE_ID_HELP)
    measure.add_argument("--track", help="a video's tracked table to write (CSV: every frame's ball in px and its "
                                         "quality flag); written even when the clip is then refused")
    _add_options(measure, "measure")

    overlay = stage("overlay", "what was tracked, drawn on a video: a contact sheet (PNG) of frames at the release, "
                               "apexes, impacts and the end, and optionally every frame as an annotated H.264 clip")
    overlay.add_argument("video", help="the video (.avi, .mp4, .mov, .mkv, .m4v)")
    overlay.add_argument("--out", required=True, help="contact sheet to write (PNG)")
    overlay.add_argument("--clip", help="annotated clip to write (H.264 MP4)")
    overlay.add_argument("--results", help="the recording's results directory (track.csv, trajectory.nc, flights.csv, "
                                           "impacts.csv, analysis.json, as dropfit measure --track and analyse write "
                                           "them); without it the video is tracked and analysed with the options")
    overlay.add_argument("--tiles", type=int, help="frames on the contact sheet (default 16)")
    overlay.add_argument("--sample-id", help=SAMPLE_ID_HELP)
    _add_options(overlay, "run")

    sound_video = stage("sound-video", "a video with sound: impacts heard and seen paired (CSV), the audio/video "
                                       "offset and e from both (JSON)")
    sound_video.add_argument("video", help="a video with a sound track (.mp4, .mov, .mkv, .avi)")
    sound_video.add_argument("--out", required=True, help="paired impacts to write (CSV)")
    sound_video.add_argument("--summary", required=True, help="offset and e from both to write (JSON)")
    sound_video.add_argument("--sample-id", help=SAMPLE_ID_HELP)
    _add_options(sound_video, "run")

    analyse = stage("analyse", "trajectory → impacts and flights tables (CSV) and analysis summary (JSON)")
    analyse.add_argument("trajectory", help="trajectory NetCDF (dropfit measure)")
    analyse.add_argument("--impacts", required=True, help="impacts table to write (CSV)")
    analyse.add_argument("--flights", required=True, help="flights table to write (CSV)")
    analyse.add_argument("--summary", required=True, help="analysis summary to write (JSON)")
    _add_options(analyse, "analyse")

    fit = stage("fit", "impacts → fit result (JSON): e, theory checks, ITF verdict")
    fit.add_argument("--analysis", required=True, help="analysis summary (JSON, dropfit analyse)")
    fit.add_argument("--impacts", required=True, help="impacts table (CSV, dropfit analyse)")
    fit.add_argument("--out", required=True, help="fit result to write (JSON)")
    _add_options(fit, "fit")

    report = stage("report", "per-recording HTML report and PNG figure")
    for name, help_text in REPORT_FILES.items():
        report.add_argument(f"--{name}", required=True, help=help_text)
    report.add_argument("--contact-sheet", help="a video's contact sheet (PNG, dropfit overlay) to show; a failed "
                                                "report's page shows it too")

    summary = sub.add_parser("summary", help="batch summary table (CSV, HTML) over fit results")
    summary.add_argument("fits", nargs="+", help="fit.json files, one per recording")
    summary.add_argument("--csv", required=True, help="summary table to write (CSV, SI units in the column names)")
    summary.add_argument("--html", required=True, help="summary page to write (HTML), each recording linked to the "
                                                       "report.html beside its fit.json")
    summary.add_argument("--samples", help="the sample sheet (tab-separated, a sample_id column): its columns the "
                                           "workflow does not read (surface, temperature …) are carried into the "
                                           "summary, with e charted against each numeric one")
    summary.add_argument("--figure", help="that chart of e against the sheet's numeric columns to write (PNG)")

    qc = sub.add_parser("qc", help="batch QC report: per-ball ITF verdicts, batch statistics, control chart")
    qc.add_argument("fits", nargs="+", help="fit.json files, one per recording (drop) of the batch")
    qc.add_argument("--ball-ids", nargs="+", help="ball of each fit file, in the same order (default: one ball each)")
    qc.add_argument("--batch", required=True, help="batch name (report title)")
    qc.add_argument("--html", required=True, help="QC report to write (HTML)")
    qc.add_argument("--figure", required=True, help="control chart to write (PNG)")
    qc.add_argument("--csv", required=True, help="per-ball table to write (CSV, heights in m)")
    _add_options(qc, "qc")
    return parser


def _add_options(parser, stage):
    """The options of :data:`dropfit.settings.OPTIONS` that ``stage`` takes; not given, they are None and
    the stage uses the default of :class:`dropfit.settings.Settings` (shown in the help)."""
    for option in OPTIONS.values():
        if stage in option.stages:
            default = option_default(option.name)
            help_text = (option.help + ("" if default is None else f" (default {default})")).replace("%", "%%")
            parser.add_argument(option.flag, type=None if option.text else float, choices=option.choices,
                                help=help_text)


def _options(args):
    """(Ball, Settings) from the parsed options; a value outside its range is an InputError naming the
    stage's input and the flag."""
    values = {name: getattr(args, name, None) for name in OPTIONS}
    try:
        return split_options(values)
    except OptionError as error:
        raise InputError(f"{_input_name(args)}: {error.named(lambda name: OPTIONS[name].flag)}") from None


def _run(args):
    """Call the stage with the parsed arguments."""
    if args.command == "synth":
        stages.synth(args.scenarios, args.name, args.log, args.truth, args.seed)
        return
    if args.command == "synth-video":
        stages.synth_video(args.name, args.out_dir, args.seed)
        return
    if args.command == "batch":
        stages.run_batch(args.samples, args.results, _batch_config(args.config), args.sample_ids or None)
        return
    ball, settings = _options(args)
    if args.command == "run":
        print(stages.run(args.recording, args.out, ball, settings, args.sample_id).summary())
    elif args.command == "measure":
        stages.measure(args.log, args.out, ball, settings, args.sample_id, args.track)
    elif args.command == "overlay":
        stages.overlay(args.video, args.out, args.clip, args.results, ball, settings, args.sample_id, args.tiles)
    elif args.command == "sound-video":
        summary = stages.sound_video(args.video, args.out, args.summary, ball, settings, args.sample_id)
        e_video, e_sound = summary["e_video"], summary["e_sound"]
        print(f"{shown_path(args.video)}: sound − video {1e3 * summary['offset_s']:.2f} ± "
              f"{1e3 * summary['offset_se_s']:.2f} ms over {summary['n_paired']} impacts; e video "
              f"{e_video['value']:.4f} ± {e_video['se']:.4f}, e sound {e_sound['value']:.4f} ± {e_sound['se']:.4f}")
    elif args.command == "analyse":
        stages.analyse(args.trajectory, args.impacts, args.flights, args.summary, settings)
    elif args.command == "fit":
        stages.fit(args.analysis, args.impacts, args.out, settings, ball.type)
    elif args.command == "report":
        stages.report(args.trajectory, args.flights, args.impacts, args.analysis, args.fit, args.html, args.figure,
                      args.contact_sheet)
    elif args.command == "summary":
        stages.summary(args.fits, args.csv, args.html, args.samples, args.figure)
    elif args.command == "qc":
        stages.qc(args.fits, args.batch, args.html, args.figure, args.csv, args.ball_ids, settings)


def _batch_config(value):
    """The workflow's config of ``dropfit batch --config``: a JSON mapping or a YAML file (None: empty)."""
    import json

    import yaml

    if value is None:
        return {}
    try:
        config = json.loads(value) if value.lstrip().startswith("{") else yaml.safe_load(Path(value).read_text("utf-8"))
    except (OSError, ValueError, yaml.YAMLError) as error:
        raise InputError(f"{shown_path(value)}: --config is neither a readable YAML file nor a JSON mapping "
                         f"({type(error).__name__}: {shown(error)}); give config/config.yaml") from None
    if not isinstance(config, dict):
        raise InputError(f"{shown_path(value)}: --config holds no mapping of keys; give config/config.yaml")
    check_config(config, f"{shown_path(value)}: --config" if not value.lstrip().startswith("{") else "--config")
    return config


#: The outputs of each stage, by argument name.
_OUTPUTS = {"measure": ["out", "track"], "overlay": ["out", "clip"], "sound-video": ["out", "summary"],
            "analyse": ["impacts", "flights", "summary"], "fit": ["out"],
            "report": ["html", "figure"], "summary": ["csv", "html", "figure"], "qc": ["html", "figure", "csv"]}
#: Outputs a stage writes whole before a later step of it may fail, and keeps then: a clip refused after
#: tracking keeps its tracked table, which shows why.
_KEPT_ON_FAILURE = {"measure": ["track"]}
#: The input each stage's messages name: the recording, the trajectory, the analysis, the fit results.
_INPUTS = {"synth": "scenarios", "synth-video": "name", "run": "recording", "batch": "samples", "measure": "log",
           "overlay": "video",
           "sound-video": "video",
           "analyse": "trajectory", "fit": "analysis", "report": "trajectory", "summary": "fits", "qc": "fits"}


def _outputs(args):
    """The files the stage writes (``run``: the files of :func:`dropfit.stages.run_files` in ``--out``)."""
    if args.command == "run":
        names = stages.run_files(args.recording, Settings(kind="audio") if args.kind == "audio" else None)
        return [os.path.join(args.out, name) for name in names]
    return [getattr(args, name) for name in _OUTPUTS.get(args.command, []) if getattr(args, name) is not None]


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


def _bound_values(argv):
    """``argv`` with ``--flag -5e-05`` as ``--flag=-5e-05`` where the flag takes a value: argparse reads a
    token that starts with ``-`` as an option unless it looks like a plain negative number."""
    flags = {option.flag for option in OPTIONS.values()} | {"--seed", "--tiles"}
    bound = []
    tokens = iter(argv)
    for token in tokens:
        if token == "--":  # what follows is positional (a recording named -x.csv): leave it as it is
            bound += [token, *tokens]
            break
        if token in flags:
            value = next(tokens, None)
            if value is not None and value.startswith("-") and is_number(value):
                bound.append(f"{token}={value}")
                continue
            bound += [token] if value is None else [token, value]
            continue
        bound.append(token)
    return bound


#: Longest argparse message quoted in a failure record, characters: its list of choices ("choose from …") is
#: the advice, and a value given on the command line is rarely long.
USAGE_MESSAGE_LIMIT = 600


def _commands():
    """Subcommand name → its parser."""
    return next(action.choices for action in build_parser()._actions if isinstance(action, argparse._SubParsersAction))


def _command_parser(argv):
    """The subcommand's parser of ``argv`` (the first token that names a subcommand), or None."""
    commands = _commands()
    command = next((token for token in argv if token in commands or token == "--"), None)
    return commands.get(command)


def _did_you_mean(argv, error):
    """argparse's message with the option (or command) meant, where one is given that it does not know: ``did you
    mean --ball-radius-m?`` for ``--ball-raduis-m``."""

    message = str(error)
    parser = _command_parser(argv)
    if message.startswith("unrecognized arguments:") and parser is not None:
        flags = [flag for action in parser._actions for flag in action.option_strings if flag.startswith("--")]
        meant = []
        for token in argv:
            name = token.split("=", 1)[0]
            if name.startswith("--") and name not in flags and name != "--":
                close = difflib.get_close_matches(name, flags, n=1, cutoff=0.6)
                meant += [(shown(name), close[0])] if close else []
        if len(meant) == 1:
            return f"{message}; did you mean {meant[0][1]}?"
        return "; ".join([message, *(f"{name}: did you mean {flag}?" for name, flag in meant)])
    if message.startswith("argument COMMAND: invalid choice:"):
        given = next((token for token in argv if not token.startswith("-")), "")
        close = difflib.get_close_matches(given, list(_commands()), n=1, cutoff=0.6)
        return message + (f"; did you mean {close[0]}?" if close else "")
    return message


def _usage_failure(argv, error):
    """A command line the parser refused: argparse's message first, with the option meant where one is misspelled
    (:func:`_did_you_mean`), then where to read the options, and exit status 2; under ``--record-failure``, when
    the outputs can be read from the command line, its failure records (status 0, as for any failed recording)."""
    error = _UsageError(error.parser, _did_you_mean(argv, error))
    if "--record-failure" in argv:
        try:
            args, _ = build_parser(lenient=True).parse_known_args(argv)
            outputs = _outputs(args)
            # argparse's message is the diagnosis (with the value given, short): quoted whole up to a generous limit
            line = one_line(f"{_input_name(args)}: {shown(str(error), USAGE_MESSAGE_LIMIT)}; see dropfit {args.command} "
                            f"--help")
        except (_UsageError, InputError, AttributeError, KeyError, TypeError):
            outputs = []
        if outputs:
            print(f"dropfit: error: {line}", file=sys.stderr)
            try:
                for path in outputs:
                    write_failure(path, line, None)
            except InputError as unwritten:  # the disk, or a file in the way
                print(f"dropfit: error: {one_line(str(unwritten))}", file=sys.stderr)
                return 1
            return 0
    parser = _command_parser(argv) or error.parser
    print(f"{parser.prog}: error: {error}", file=sys.stderr)  # the line that matters first, not after the usage
    usage = parser.format_usage()
    print(usage.rstrip() if usage.count("\n") <= 3 else f"{parser.prog} --help lists every option", file=sys.stderr)
    return 2


def main(argv=None):
    """Entry point of the ``dropfit`` console script and ``python -m dropfit``."""
    argv = _bound_values([str(token) for token in (sys.argv[1:] if argv is None else argv)])
    try:
        args = build_parser().parse_args(argv)
    except _UsageError as error:
        return _usage_failure(argv, error)
    record = getattr(args, "record_failure", False)
    outputs = _outputs(args)
    before = {path: _stat(path) for path in outputs}
    keepable = {getattr(args, name) for name in _KEPT_ON_FAILURE.get(args.command, [])}
    tracked, unwritable = None, False
    try:
        with warnings.catch_warnings():
            if not sys.warnoptions:  # numerical warnings are for developers (python -W shows them)
                warnings.simplefilter("ignore")
            _run(args)
    except InputError as error:
        message = one_line(str(error))
        tracked = getattr(error, "tracked", None)  # a video refused after tracking (dropfit run)
        unwritable = isinstance(error, OutputError)
    except Exception as error:  # noqa: BLE001 — a bug, not the user's fault
        environment = environment_message(error, outputs[0] if outputs else getattr(args, _INPUTS[args.command]))
        if environment is not None:  # the user's disk or folders (an error no writer named): not a bug
            message, unwritable = one_line(environment), True
        else:
            # the traceback goes to the log (standard error); the line, the failure records and the batch
            # summary name the input and the error only
            traceback.print_exc()
            message = one_line(f"{_input_name(args)}: internal error in dropfit {args.command} "
                               f"({type(error).__name__}: {shown(error)}); please report it with this file")
    else:
        return 0
    kept = {path for path in outputs if path in keepable and _stat(path) != before[path]}
    for path in outputs:  # an output this run began to write is not whole: remove it
        if _stat(path) != before[path] and path not in kept:
            try:
                os.remove(path)
            except OSError:
                pass
    if not record or unwritable:  # an output that cannot be written: its failure record could not be either
        print(f"dropfit: error: {message}", file=sys.stderr)
        return 1
    try:
        _write_failure_records(args, outputs, kept, message, tracked)
    except InputError as error:  # the records cannot be written (the disk, a file in the way): one line says both
        message += f" (and its failure records were not written: {one_line(str(error))})"
        print(f"dropfit: error: {one_line(message)}", file=sys.stderr)
        return 1
    print(f"dropfit: error: {message}", file=sys.stderr)
    return 0


def _write_failure_records(args, outputs, kept, message, tracked):
    """Under ``--record-failure``: a failure record carrying ``message`` in every output not ``kept``."""
    figure = _failure_figure(args)
    refused_video = args.command == "run" and tracked is not None
    drawn = {os.path.join(args.out, name) for name in ("track.csv", "contact_sheet.png")} if refused_video else set()
    for path in outputs:
        if path not in kept and path not in drawn and not (refused_video and path.endswith("report.html")):
            write_failure(path, message, figure)
    if refused_video:  # its tracked table and its frames drawn, under the refusal read from the records above
        figure = stages.record_refused_video(args.recording, args.out, tracked, message)
        write_failure(os.path.join(args.out, "report.html"), message, figure)


def _failure_figure(args):
    """The PNG a failure record's page shows: a refused video's contact sheet, given to ``report``."""
    path = getattr(args, "contact_sheet", None)
    try:
        return Path(path).read_bytes() if path else None
    except OSError:  # the failure's own message says what is missing
        return None


if __name__ == "__main__":
    sys.exit(main())
