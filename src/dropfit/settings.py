"""Every option of a recording's measurement, analysis and fit, with its unit and default, in one place.

:class:`Ball` says what was dropped; :class:`Settings` how the recording was made and how to
analyse and judge it. Both are checked once, when made: a value outside its range raises
:class:`OptionError`, one line naming the option. The defaults live only in these two classes.

:data:`OPTIONS` describes each option once (its unit, range, the stages that use it, where the
workflow's ``config/config.yaml`` and sample sheet hold it). The command line builds its flags from
it (``--ball-radius-m`` for ``ball_radius_m``), and the workflow maps its config and sample-sheet
row onto the same names (:func:`workflow_values`, :func:`stage_arguments`): an option the user
leaves out is not passed, so the stage takes the default from here.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import numbers
from dataclasses import dataclass

from .balls import BALL_KINDS, ball_kind
from .errors import InputError, shown
from .importers import FORMATS, ImportOptions
from .physics import (NORMAL_GRAVITY_SE_M_S2, STANDARD_GRAVITY_M_S2, UNKNOWN_SITE_GRAVITY_SE_M_S2,
                      normal_gravity)
from .restitution import ITF_DROP_HEIGHT_M, ITF_REBOUND_MAX_M, ITF_REBOUND_MIN_M

#: The options that together say where the recording was made: a sample-sheet row that gives any of
#: them replaces all three of the config's.
SITE_OPTIONS = ("gravity_m_s2", "latitude_deg", "altitude_m")


class OptionError(InputError):
    """An option value outside its range: one line naming the option.

    ``str(error)`` names options as keyword arguments (``ball_radius_m``); :meth:`named` names them
    as the caller does (the command line: ``--ball-radius-m``).
    """

    def __init__(self, template, *options):
        self.template, self.options = template, options
        super().__init__(template.format(*options))

    def named(self, name_of):
        """The message with every option named by ``name_of(option)``."""
        return self.template.format(*(name_of(option) for option in self.options))


@dataclass(frozen=True)
class Option:
    """One option: its name (keyword argument, sample-sheet column, ``--flag``), unit and range.

    Attributes
    ----------
    name : str
        Keyword argument of :class:`Ball` (without the ``ball_`` prefix) or :class:`Settings`.
    help : str
        What it is, with its unit (the command line's help).
    stages : tuple of str
        The command-line stages that take it (``run`` takes those of measure, analyse and fit).
    what : str
        What to give instead of a value outside the range (for the message).
    low, high : float
        The range of a number; ``low_allowed`` says whether ``low`` itself is allowed.
    choices : tuple of str, optional
        The allowed values of a text option.
    parse : callable, optional
        Reads a text option's value (text or a sequence) into what the option holds; raises
        ValueError (or TypeError) for a value it cannot read.
    config : tuple of str, optional
        Its key path in the workflow's ``config/config.yaml``.
    column : bool
        Whether the workflow's sample sheet may give it per recording (a column of the same name).
    text : bool
        A text option (else a number).
    slips : tuple of (str, float)
        Units a value outside the range was likely written in, each with its size in the option's unit
        (``("cm", 0.01)`` for a length in m): the message names those that bring the value inside.
    """

    name: str
    help: str
    stages: tuple
    what: str = ""
    low: float = -math.inf
    high: float = math.inf
    low_allowed: bool = True
    choices: tuple | None = None
    parse: object = None
    config: tuple | None = None
    column: bool = False
    text: bool = False
    slips: tuple = ()

    @property
    def flag(self):
        """The command-line flag, ``--`` and the name with ``-`` for ``_``."""
        return "--" + self.name.replace("_", "-")

    def check(self, value):
        """``value`` as the option holds it (a float, or the text), or :class:`OptionError`. None stays None."""
        if value is None:
            return None
        if self.text:
            if self.choices and value not in self.choices:
                raise OptionError(f"{{0}} is '{shown(value)}'; give one of {', '.join(self.choices)}", self.name)
            if self.parse is not None:
                try:
                    return self.parse(value)
                except (ValueError, TypeError):
                    raise OptionError(f"{{0}} is '{shown(str(value))}'; give {self.what}", self.name) from None
            return value
        if isinstance(value, bool) or not isinstance(value, numbers.Real):
            raise OptionError(f"{{0}} is '{shown(value)}', not a number; give {self.what}", self.name)
        value = float(value)
        if self.name == "scale_m_per_px":
            inside = math.isfinite(value) and value != 0
        else:
            inside = math.isfinite(value) and (value >= self.low if self.low_allowed else value > self.low) \
                and value <= self.high
        if not inside:
            raise OptionError(f"{{0}} is {value:g}{self._slip_hint(value)}; give {self.what}", self.name)
        return value

    def _slip_hint(self, value):
        """``: likely in cm (0.0335 m) or mm …`` for the units of :attr:`slips` that bring ``value`` inside the
        range, else nothing."""
        unit = self.name.rsplit("_", 1)[-1]
        likely = [f"{name} ({value * size:g} {unit})" for name, size in self.slips
                  if self.low < value * size <= self.high]
        return f" {unit}, implausible: likely given in {' or '.join(likely)}" if likely else ""


#: Ball colours by name, BGR grey levels (as a camera in daylight sees them, roughly).
BALL_COLOURS = {"white": (240.0, 240.0, 240.0), "black": (30.0, 30.0, 30.0), "yellow": (30.0, 220.0, 230.0),
                "tennis": (40.0, 225.0, 205.0), "green": (60.0, 170.0, 60.0), "red": (40.0, 40.0, 200.0),
                "orange": (30.0, 130.0, 240.0), "blue": (200.0, 100.0, 30.0), "pink": (180.0, 120.0, 240.0)}


def _numbers(value, count):
    """``count`` finite numbers from text ("1,2,3", "1 2 3", "(1, 2, 3)") or a sequence; ValueError otherwise."""
    parts = value.strip().strip("()[]").replace(",", " ").split() if isinstance(value, str) else list(value)
    if len(parts) != count:
        raise ValueError(f"{len(parts)} numbers, not {count}")
    numbers = [float(part) for part in parts]
    if not all(math.isfinite(number) for number in numbers):
        raise ValueError("not finite")
    return numbers


def parse_roi_px(value):
    """A region of interest ``x0, y0, x1, y1`` (px; columns x0 ≤ x < x1, rows y0 ≤ y < y1) as a tuple of int."""
    x0, y0, x1, y1 = (int(round(number)) for number in _numbers(value, 4))
    if not (0 <= x0 < x1 and 0 <= y0 < y1):
        raise ValueError("empty region")
    return x0, y0, x1, y1


def parse_ball_at_px(value):
    """The ball's position in one frame, ``frame, x, y`` (frame index from 0; centre in px) as (int, float, float)."""
    frame, x, y = _numbers(value, 3)
    if frame < 0 or frame != int(frame) or x < 0 or y < 0:
        raise ValueError("not a frame index and a position")
    return int(frame), x, y


def parse_ball_colour(value):
    """A colour as BGR grey levels: a name of :data:`BALL_COLOURS`, ``#rrggbb`` (hex, red first), or ``b, g, r``."""
    if isinstance(value, str) and value.strip().lower() in BALL_COLOURS:
        return BALL_COLOURS[value.strip().lower()]
    if isinstance(value, str) and value.strip().startswith("#"):
        digits = value.strip()[1:]
        if len(digits) != 6:
            raise ValueError("not #rrggbb")
        red, green, blue = (float(int(digits[i:i + 2], 16)) for i in (0, 2, 4))
        return blue, green, red
    colour = tuple(_numbers(value, 3))
    if not all(0.0 <= level <= 255.0 for level in colour):
        raise ValueError("outside 0-255")
    return colour


_MEASURE, _ANALYSE, _SITE = ("measure", "run"), ("analyse", "run"), ("measure", "analyse", "run")
_FIT, _ITF = ("fit", "run"), ("fit", "qc", "run")

#: Every option, in the order of the command line's help. The upper bounds catch a value in the
#: wrong unit (a radius of 33.5 given in mm).
OPTIONS = {option.name: option for option in (
    Option("ball_radius_m", "ball radius in m", _MEASURE, "the ball's radius in m (a tennis ball: 0.0335)",
           0.0, 1.0, False, column=True, slips=(("cm", 0.01), ("mm", 0.001))),
    Option("ball_mass_kg", "ball mass in kg", _MEASURE, "the ball's mass in kg (a tennis ball: 0.057)",
           0.0, 20.0, False, column=True, slips=(("g", 0.001),)),
    Option("ball_type", f"kind of ball: {', '.join(BALL_KINDS)} (tennis gets the ITF verdict)",
           _MEASURE + ("fit",), text=True, column=True),
    Option("scale_m_per_px", "m per px for logs in px (negative if the axis points down) or videos; "
           "default: calibrated (videos: points > marker or board > ruler > gravity > ball diameter; px logs: gravity)", _MEASURE,
           "metres per pixel (negative for image rows), not 0", column=True),
    Option("ball_colour", "video: the ball's colour, a name (" + ", ".join(BALL_COLOURS) + "), #rrggbb or b,g,r "
           "(0-255): shadows and a hand are told from it", _MEASURE,
           "a colour name (" + ", ".join(BALL_COLOURS) + "), #rrggbb or three levels b,g,r from 0 to 255",
           parse=parse_ball_colour, text=True, column=True),
    Option("ball_radius_px", "video: the ball's radius in px (default: learnt from the clean frames)", _MEASURE,
           "the ball's radius in px", 0.0, 2000.0, False, column=True),
    Option("roi_px", "video: region of interest x0,y0,x1,y1 in px: the ball is looked for only there", _MEASURE,
           "four pixel coordinates x0,y0,x1,y1 with x0 < x1 and y0 < y1", parse=parse_roi_px, text=True, column=True),
    Option("ball_at_px", "video: the ball's centre in one frame, frame,x,y (frame index from 0, px): tracking "
           "starts there", _MEASURE, "a frame index and the ball's centre in px, frame,x,y", parse=parse_ball_at_px,
           text=True, column=True),
    Option("ruler_tick_m", "video: spacing in m of the finest ticks of a ruler in the ball's plane (scale from it)",
           _MEASURE, "the ruler's finest tick spacing in m (e.g. 0.01)", 0.0, 1.0, False, column=True),
    Option("scale_points_px", "video: two image points a known distance apart, as 'x1,y1,x2,y2' in px of the "
           "frame as displayed (with --scale-distance-m)", _MEASURE, text=True, column=True),
    Option("scale_distance_m", "video: the distance in m between the two --scale-points-px", _MEASURE,
           "the two points' distance in m", 0.0, 100.0, False, column=True),
    Option("marker_size_m", "video: side in m of a printed ArUco marker in the ball's plane (scale and the camera's "
           "tilt from it)", _MEASURE, "the marker's printed side in m (e.g. 0.08)", 0.0, 10.0, False, column=True),
    Option("board_square_m", "video: side in m of a square of a checkerboard in the ball's plane (with "
           "--board-inner-corners)", _MEASURE, "the board's square side in m (e.g. 0.025)", 0.0, 1.0, False,
           column=True),
    Option("board_inner_corners", "video: the checkerboard's inner corners per row and column, as '9x6' (a board "
           "of 10 × 7 squares)", _MEASURE, text=True, column=True),
    Option("floor_m", "height of the floor in the log's frame, in m (makes contact times measurable)", _MEASURE,
           "the floor's height in m in the log's frame", column=True),
    Option("height_reference", "the point of the ball a height log gives: its centre (default), bottom or top",
           _MEASURE, choices=("centre", "bottom", "top"), text=True, column=True),
    Option("format", f"the recording's format (default: found from its content): {', '.join(FORMATS)}", _MEASURE,
           choices=tuple(FORMATS), text=True, column=True),
    Option("fps", "frame rate in frames/s of a table that counts frames (MTrack2, TrackMate without times), or the "
           "camera's rate in place of a Tracker project's frame step",
           _MEASURE, "the frame rate in frames/s", 0.0, math.inf, False, column=True),
    Option("track_id", "which track (MTrack2 track number, TrackMate TRACK_ID, Tracker point mass) or run (Logger Pro, "
           "Capstone) to read; default: the one that moves like a dropped ball", _MEASURE,
           "a track or run number (a whole number)", 0.0, 1e9, True, column=True),
    Option("columns", "a table's columns, where their names do not tell: 'time=COL[s],y=COL[cm][,x=COL[cm]]' "
           "(frame=COL for a frame count, distance=COL for a distance down from a sensor)", _MEASURE, text=True,
           column=True),
    Option("sensor_height_m", "height in m of a motion detector looking down: height = this − distance (default: the "
           "direction from the bounces, zero where the ball comes to rest)", _MEASURE,
           "the sensor's height above the floor in m", 0.0, 100.0, False, column=True),
    Option("capture_fps", "capture rate in frames/s of a slow-motion video whose file states another rate",
           _MEASURE, "the capture rate in frames/s", 0.0, math.inf, False, column=True),
    Option("kind", "what the recording is: height_log, video or audio (default: told by the file's suffix and "
           "header); audio for a video measures its sound track", _MEASURE,
           choices=("height_log", "video", "audio"), text=True, column=True),
    Option("release_time_s", "audio: time in s on the recording's clock at which the ball was released at rest "
           "(gives the drop height, the first impact's e and the total bouncing time)", _MEASURE,
           "the release time in s from the start of the recording", 0.0, column=True),
    Option("gravity_m_s2", "gravity at the site in m/s² (wins over --latitude-deg); default: not known, "
           "standard gravity with the ±0.3 % spread over the Earth", _SITE, "gravity in m/s² (9.80665 on Earth)",
           0.0, 100.0, False, config=("gravity_m_s2",), column=True),
    Option("latitude_deg", "geodetic latitude of the site in degrees: g from the WGS84 normal gravity",
           _SITE, "the site's latitude in degrees (−90 to 90)", -90.0, 90.0, True, config=("latitude_deg",),
           column=True),
    Option("altitude_m", "height of the site above sea level in m (with --latitude-deg; default 0)", _SITE,
           "the site's height above sea level in m", -1000.0, 10000.0, True, config=("altitude_m",), column=True),
    Option("drag", "quadratic air drag k: fitted when BIC prefers it (auto; a video's never alone), never or "
           "always; when not fitted, held at a smooth sphere's k if the ball's radius and mass are known", _ANALYSE,
           choices=("auto", "off", "on"), config=("analysis", "drag"), text=True),
    Option("itf_drop_height_m", "ITF drop height in m (bottom of the ball above the floor)", _ITF,
           "the ITF drop height in m (2.54)", 0.0, math.inf, False, config=("itf", "drop_height_m")),
    Option("itf_rebound_min_m", "lowest ITF rebound height in m", _ITF,
           "the ITF window's lower rebound height in m (1.35)", 0.0, math.inf, False, config=("itf", "rebound_min_m")),
    Option("itf_rebound_max_m", "highest ITF rebound height in m", _ITF,
           "the ITF window's upper rebound height in m (1.47)", 0.0, math.inf, False, config=("itf", "rebound_max_m")),
    Option("itf_drop_height_tolerance_m", "how far in m the drop height may be from the ITF drop height for the "
           "measured rebound to be used (else it is predicted)", _FIT, "the drop-height tolerance in m (0.02)",
           0.0, math.inf, True, config=("itf", "drop_height_tolerance_m")),
)}

#: Options of :class:`Ball`: option name → field name.
BALL_FIELDS = {"ball_radius_m": "radius_m", "ball_mass_kg": "mass_kg", "ball_type": "type", "ball_colour": "colour"}


@dataclass(frozen=True)
class Ball:
    """The ball that was dropped. Every field may be unknown (None).

    Attributes
    ----------
    radius_m : float, optional
        Radius in m (option ``ball_radius_m``). With the floor it gives the contact height, with the
        mass the drag of a smooth sphere; a video's scale can come from it.
    mass_kg : float, optional
        Mass in kg (option ``ball_mass_kg``), for the nominal drag and the contact's k and c.
    type : str, optional
        Kind of ball (option ``ball_type``): one of :data:`dropfit.balls.BALL_KINDS`, any case,
        stored in lower case. ``tennis`` gets the ITF verdict.
    colour : (float, float, float), optional
        The ball's colour in a video, BGR grey levels (option ``ball_colour``: a name, ``#rrggbb``
        or ``b,g,r``): tells the tracker whether its shadow and a hand can be told from it by colour.
    """

    radius_m: float | None = None
    mass_kg: float | None = None
    type: str | None = None
    colour: tuple | None = None

    def __post_init__(self):
        for option, name in BALL_FIELDS.items():
            object.__setattr__(self, name, OPTIONS[option].check(getattr(self, name)))
        if self.type is not None:
            if not isinstance(self.type, str) or self.type.strip().lower() not in BALL_KINDS:
                raise OptionError(f"{{0}} is '{shown(self.type)}', not a kind dropfit knows; give one of "
                                  f"{', '.join(BALL_KINDS)}", "ball_type")
            object.__setattr__(self, "type", ball_kind(self.type).name)

    def options(self):
        """The known fields as options (``ball_radius_m`` …)."""
        return {option: getattr(self, name) for option, name in BALL_FIELDS.items() if getattr(self, name) is not None}


@dataclass(frozen=True)
class SiteGravity:
    """The g an analysis uses, with its standard error and where it comes from.

    Attributes
    ----------
    value_m_s2, se_m_s2 : float
        g and its standard error in m/s².
    source : str
        ``given``, ``normal gravity`` (WGS84 with the free-air correction, from the latitude and
        altitude) or ``unknown site`` (standard gravity with the ±0.3 % spread of g over the Earth).
    note : str
        One sentence for the report.
    """

    value_m_s2: float
    se_m_s2: float
    source: str
    note: str

    def record(self):
        """JSON-ready ``{"value", "se", "unit", "source", "note"}``."""
        return {"value": self.value_m_s2, "se": self.se_m_s2, "unit": "m/s2", "source": self.source,
                "note": self.note}


@dataclass(frozen=True)
class Settings:
    """How a recording was made and how dropfit measures, analyses and judges it.

    Every field is an option of the same name (:data:`OPTIONS`): a keyword argument of
    :func:`dropfit.analyse_recording`, a ``--flag`` of the command line, a key of the workflow's
    config or a column of its sample sheet. The values are checked when the object is made
    (:class:`OptionError`); :meth:`replace` makes a changed copy, checked again.

    Attributes
    ----------
    scale_m_per_px : float, optional
        Length scale in m/px of a px log (negative when the pixel axis points down, as image rows
        do) or of a video. Default None: calibrated (a video: points > target > ruler > gravity >
        diameter; a px log: gravity).
    ruler_tick_m : float, optional
        Video: spacing in m of the finest ticks of a ruler in the ball's plane, for the scale from
        the ruler. Default None: no ruler.
    scale_points_px : str, optional
        Video: two points of the displayed frame a known distance apart, ``"x1,y1,x2,y2"`` in px
        (each taken as clicked to ±1 px), with ``scale_distance_m``. Default None.
    scale_distance_m : float, optional
        Video: the distance in m between the ``scale_points_px``. Default None.
    marker_size_m : float, optional
        Video: printed side in m of an ArUco marker in the ball's plane: its scale, and the map from
        the image to that plane (a camera not square to it is corrected). Default None.
    board_square_m : float, optional
        Video: side in m of a checkerboard's squares in the ball's plane (with
        ``board_inner_corners``): as a marker, more precisely. Default None.
    board_inner_corners : str, optional
        Video: the checkerboard's inner corners, ``"9x6"`` (per row x per column). Default None.
    floor_m : float, optional
        Height of the floor in m in the recording's frame (after unit conversion). With the ball's
        radius it gives the contact height, and contact times become measurable. Default None:
        not known (a video's floor is then found in the image; a log's contact height is modelled).
    height_reference : {"centre", "bottom", "top"}
        The point of the ball a height log gives (an ultrasonic sensor sees the bottom; a tracker may
        follow the top); the trajectory is of the centre, one radius from either. Default ``"centre"``.
    format : str, optional
        The recording's format (:data:`dropfit.importers.FORMATS`). Default None: found from the content.
    fps : float, optional
        Frame rate in frames/s of a table that counts frames (MTrack2, TrackMate), or the camera's rate in
        place of a Tracker project's frame step. Default None.
    track_id : float, optional
        The track (MTrack2, TrackMate, Tracker) or run (Logger Pro, Capstone) to read, a whole number.
        Default None: the one that moves like a dropped ball (a single run).
    columns : str, optional
        A table's column mapping, ``"time=COL[s],y=COL[cm][,x=COL[cm]]"``. Default None: guessed from
        the names.
    sensor_height_m : float, optional
        Height in m of a motion detector looking down (height = this − distance). Default None.
    capture_fps : float, optional
        Capture rate in frames/s of a slow-motion video whose file states another rate. Default
        None: the file's rate, checked against gravity where a scale allows.
    ball_radius_px : float, optional
        Video: the ball's radius in px. Default None: learnt from the frames where it is measured
        cleanly.
    roi_px : (int, int, int, int), optional
        Video: region of interest x0, y0, x1, y1 in px (columns x0 ≤ x < x1, rows y0 ≤ y < y1):
        the ball is looked for only there. Default None: the whole frame.
    ball_at_px : (int, float, float), optional
        Video: the ball's centre (x, y in px) in one frame (index from 0): tracking starts there.
        Default None: the ball is searched for.
    kind : {"height_log", "video", "audio"}, optional
        What the recording is; ``audio`` for a video measures its sound track (the sample sheet's
        ``kind``). Default None: told by the file's suffix and header.
    release_time_s : float, optional
        Audio: when the ball was let go at rest, in s on the recording's clock (taken as exact). Default
        None: the fall is not heard, so the drop height and the first impact's e are not measured.
    gravity_m_s2 : float, optional
        g at the site in m/s², taken as exact. It wins over ``latitude_deg``. Default None: see
        :meth:`site_gravity`.
    latitude_deg : float, optional
        Geodetic latitude of the site in degrees (−90 … 90): g is then the WGS84 normal gravity
        (:func:`dropfit.physics.normal_gravity`). Default None.
    altitude_m : float, optional
        Height of the site above sea level in m, with ``latitude_deg`` (free-air correction).
        Default None: 0 m.
    drag : {"auto", "off", "on"}
        Quadratic air drag k (1/m): fitted when the BIC prefers it, never, or always. When not
        fitted it is held at that of a smooth sphere of the ball's radius and mass (0 when either is
        unknown). Default ``"auto"``; with it a video's flights' k is not used alone where the nominal one
        is known: widened by what a centre error growing with speed makes of it, it is combined with the
        nominal k and held there, and what that error does to every quantity is carried as a systematic error.
    itf_drop_height_m : float
        ITF drop height in m (bottom of the ball above the floor). Default 2.54 (ITF Rules of
        Tennis, Appendix I).
    itf_rebound_min_m, itf_rebound_max_m : float
        The ITF rebound window in m. Default 1.35 and 1.47.
    itf_drop_height_tolerance_m : float
        How far in m the measured drop height may be from ``itf_drop_height_m`` for the measured
        rebound, scaled to that height, to be judged; farther, the rebound is predicted from e and
        the drag. Default 0.02.
    """

    scale_m_per_px: float | None = None
    ruler_tick_m: float | None = None
    scale_points_px: str | None = None
    scale_distance_m: float | None = None
    marker_size_m: float | None = None
    board_square_m: float | None = None
    board_inner_corners: str | None = None
    floor_m: float | None = None
    height_reference: str = "centre"
    format: str | None = None
    fps: float | None = None
    track_id: float | None = None
    columns: str | None = None
    sensor_height_m: float | None = None
    capture_fps: float | None = None
    ball_radius_px: float | None = None
    roi_px: tuple | None = None
    ball_at_px: tuple | None = None
    kind: str | None = None
    release_time_s: float | None = None
    gravity_m_s2: float | None = None
    latitude_deg: float | None = None
    altitude_m: float | None = None
    drag: str = "auto"
    itf_drop_height_m: float = ITF_DROP_HEIGHT_M
    itf_rebound_min_m: float = ITF_REBOUND_MIN_M
    itf_rebound_max_m: float = ITF_REBOUND_MAX_M
    itf_drop_height_tolerance_m: float = 0.02

    def __post_init__(self):
        for item in dataclasses.fields(self):
            value = OPTIONS[item.name].check(getattr(self, item.name))
            if value is None and item.default is not None:
                raise OptionError(f"{{0}} must be given (default {item.default})", item.name)
            object.__setattr__(self, item.name, value)
        if not self.itf_rebound_min_m < self.itf_rebound_max_m:
            raise OptionError(f"the ITF rebound window is empty ({{0}} {self.itf_rebound_min_m:g} is not below {{1}} "
                              f"{self.itf_rebound_max_m:g}); give the lower limit first",
                              "itf_rebound_min_m", "itf_rebound_max_m")
        if (self.scale_points_px is None) != (self.scale_distance_m is None):
            raise OptionError("{0} and {1} go together: give the two points and their distance",
                              "scale_points_px", "scale_distance_m")
        if self.scale_points_px is not None:
            self.scale_points()
        if (self.board_square_m is None) != (self.board_inner_corners is None):
            raise OptionError("{0} and {1} go together: give the square's side and the inner corners",
                              "board_square_m", "board_inner_corners")
        if self.board_inner_corners is not None:
            self.board_corners()
        if self.track_id is not None and self.track_id != int(self.track_id):
            raise OptionError(f"{{0}} is {self.track_id:g}; give a whole number", "track_id")
        if self.altitude_m is not None and self.latitude_deg is None and self.gravity_m_s2 is None:
            raise OptionError("{0} is given without {1}; give the site's latitude too (g depends on both)",
                              "altitude_m", "latitude_deg")

    def scale_points(self):
        """The ``scale_points_px`` as ((x1, y1), (x2, y2)) in px, or None; :class:`OptionError` if malformed."""
        if self.scale_points_px is None:
            return None
        try:
            values = [float(part) for part in str(self.scale_points_px).replace(";", ",").split(",")]
        except ValueError:
            values = []
        if len(values) != 4 or not all(math.isfinite(v) for v in values):
            raise OptionError(f"{{0}} is '{shown(self.scale_points_px)}'; give four numbers 'x1,y1,x2,y2' in px",
                              "scale_points_px")
        return (values[0], values[1]), (values[2], values[3])

    def board_corners(self):
        """The ``board_inner_corners`` as (per row, per column), or None; :class:`OptionError` if malformed."""
        if self.board_inner_corners is None:
            return None
        parts = str(self.board_inner_corners).lower().replace("×", "x").split("x")
        if len(parts) != 2 or not all(part.strip().isdigit() and int(part) >= 2 for part in parts):
            raise OptionError(f"{{0}} is '{shown(self.board_inner_corners)}'; give the inner corners as '9x6'",
                              "board_inner_corners")
        return int(parts[0]), int(parts[1])

    def import_options(self):
        """The options of :mod:`dropfit.importers` (format, frame rate, track, columns, sensor height)."""
        return ImportOptions(self.format, self.fps, None if self.track_id is None else int(self.track_id),
                             self.columns, self.sensor_height_m)

    def replace(self, **changes):
        """A copy with ``changes`` (option name → value), checked; TypeError for an unknown option."""
        unknown = sorted(set(changes) - {item.name for item in dataclasses.fields(self)})
        if unknown:
            raise TypeError(f"unknown setting{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; the settings are "
                            f"{', '.join(item.name for item in dataclasses.fields(self))}")
        return dataclasses.replace(self, **changes)

    def to_dict(self):
        """Every setting, name → value (JSON-ready)."""
        return dataclasses.asdict(self)

    def site_gravity(self):
        """The g to use, with its standard error (:class:`SiteGravity`).

        A given ``gravity_m_s2`` is exact (se 0). Else, with ``latitude_deg`` (and ``altitude_m``),
        the WGS84 normal gravity with the free-air correction, se
        :data:`dropfit.physics.NORMAL_GRAVITY_SE_M_S2` (local anomalies). Else the site is unknown:
        standard gravity, se :data:`dropfit.physics.UNKNOWN_SITE_GRAVITY_SE_M_S2` (g spans ±0.3 %
        over the Earth's surface).
        """
        if self.gravity_m_s2 is not None:
            return SiteGravity(self.gravity_m_s2, 0.0, "given", f"g = {self.gravity_m_s2:g} m/s² as given, taken as exact")
        if self.latitude_deg is not None:
            altitude = self.altitude_m or 0.0
            value = normal_gravity(self.latitude_deg, altitude)
            return SiteGravity(value, NORMAL_GRAVITY_SE_M_S2, "normal gravity",
                               f"g = {value:.5f} m/s² ± {NORMAL_GRAVITY_SE_M_S2:g}: WGS84 normal gravity at latitude "
                               f"{self.latitude_deg:g}°, {altitude:g} m above sea level (free-air correction)")
        return SiteGravity(STANDARD_GRAVITY_M_S2, UNKNOWN_SITE_GRAVITY_SE_M_S2, "unknown site",
                           f"g = {STANDARD_GRAVITY_M_S2} m/s² (standard gravity) ± {UNKNOWN_SITE_GRAVITY_SE_M_S2:.3f}: "
                           f"the site is not known (give gravity_m_s2, or latitude_deg and altitude_m)")


def split_options(values):
    """(:class:`Ball`, :class:`Settings`) from option name → value (None or absent: the default).

    Raises
    ------
    OptionError
        For the first value outside its range (the ball's first).
    TypeError
        For a name that is no option.
    """
    values = {name: value for name, value in values.items() if value is not None}
    unknown = sorted(set(values) - set(OPTIONS))
    if unknown:
        raise TypeError(f"unknown option{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; the options are "
                        f"{', '.join(OPTIONS)}")
    ball = Ball(**{BALL_FIELDS[name]: value for name, value in values.items() if name in BALL_FIELDS})
    return ball, Settings(**{name: value for name, value in values.items() if name not in BALL_FIELDS})


def _given(value):
    """True unless ``value`` is missing: None, NaN or blank text (an empty sample-sheet cell)."""
    if value is None:
        return False
    if isinstance(value, float) and math.isnan(value):
        return False
    return str(value).strip() != ""


def _plain(value):
    """A Python value from a YAML or pandas one (numpy scalars to float or str)."""
    if hasattr(value, "item") and not isinstance(value, (str, bytes)):
        value = value.item()
    return value


def workflow_values(config, row=None):
    """The options the workflow gives one recording: option name → value, missing ones left out.

    Parameters
    ----------
    config : dict
        The workflow's config (``config/config.yaml``): ``gravity_m_s2``, ``latitude_deg``,
        ``altitude_m``, ``analysis.drag``, ``itf.*`` (see :data:`OPTIONS`, ``config``).
    row : mapping, optional
        The recording's sample-sheet row (a pandas Series or dict); its columns named as options
        win over the config. A row that gives any of :data:`SITE_OPTIONS` replaces all three of the
        config's (a site is given whole).
    """
    values = {}
    for option in OPTIONS.values():
        if option.config:
            value = config
            for key in option.config:
                value = value.get(key) if isinstance(value, dict) else None
            if _given(value):
                values[option.name] = _plain(value)
    if row is not None:
        columns = {option.name: _plain(row.get(option.name)) for option in OPTIONS.values()
                   if option.column and _given(row.get(option.name))}
        if any(name in columns for name in SITE_OPTIONS):
            for name in SITE_OPTIONS:
                values.pop(name, None)
        values.update(columns)
    return {name: values[name] for name in OPTIONS if name in values}


#: Keys of the workflow's config that configure the workflow itself (workflow/schemas/config.schema.yaml), not a
#: recording's analysis: ``dropfit batch --config`` accepts and ignores them.
WORKFLOW_ONLY_KEYS = ("samples", "scenarios", "parallel_jobs", "chunk_size", "fail_on_failed_recordings")


def check_config(config, source="--config"):
    """InputError for a workflow config that cannot apply: a key no option has (with the key meant, where one is
    close), a section such as ``analysis`` that is not a mapping. Values are checked where they are used (each
    option's range and choices, per recording)."""
    paths = [option.config for option in OPTIONS.values() if option.config]
    sections = {path[0] for path in paths if len(path) > 1}

    def refuse(key, known, where):
        close = difflib.get_close_matches(key, known, n=1)
        meant = f"did you mean {close[0]}? " if close else ""
        raise InputError(f"{source}: '{where}{shown(key, 30)}' is not a key dropfit reads; {meant}the keys are "
                         f"{', '.join(sorted(known))} (workflow/schemas/config.schema.yaml)")

    top = {path[0] for path in paths} | set(WORKFLOW_ONLY_KEYS)
    for key, value in config.items():
        if key not in top:
            refuse(str(key), top, "")
        if key in sections:
            if not isinstance(value, dict):
                raise InputError(f"{source}: {key} is '{shown(value, 30)}', not a mapping of its options; give e.g. "
                                 f"{key}: {{{', '.join(path[1] + ': …' for path in paths if path[0] == key)}}}")
            inner = {path[1] for path in paths if path[0] == key}
            for name in value:
                if name not in inner:
                    refuse(str(name), inner, f"{key}.")


def settings_from_config(config, row=None):
    """(:class:`Ball`, :class:`Settings`) of one recording of the workflow (see :func:`workflow_values`),
    checked: what a notebook uses to analyse a recording as the workflow does."""
    return split_options(workflow_values(config, row))


def stage_arguments(stage, config, row=None):
    """The ``--flag=value`` arguments (strings, unquoted) of one workflow stage of one recording: the
    options of :func:`workflow_values` that ``dropfit <stage>`` takes.

    Each value is bound to its flag by ``=``: a value starting with ``-`` (``-5e-05``, a column
    spec) would otherwise be read as an option. A recording path is not an option: the workflow
    passes it after ``--``.
    """
    return [f"{OPTIONS[name].flag}={repr(value) if isinstance(value, float) else value}"
            for name, value in workflow_values(config, row).items() if stage in OPTIONS[name].stages]


def option_default(name):
    """The default of option ``name`` (None: not given)."""
    owner = Ball if name in BALL_FIELDS else Settings
    key = BALL_FIELDS.get(name, name)
    return next(item.default for item in dataclasses.fields(owner) if item.name == key)


__all__ = ["BALL_COLOURS", "BALL_FIELDS", "OPTIONS", "SITE_OPTIONS", "Ball", "Option", "OptionError", "Settings",
           "SiteGravity", "option_default", "settings_from_config", "split_options", "stage_arguments",
           "parse_ball_at_px", "parse_ball_colour", "parse_roi_px", "workflow_values"]

