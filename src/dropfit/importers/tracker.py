"""Tracker (Open Source Physics): projects (``.trk`` XML, ``.trz`` zip) and exported data tables.

A ``.trk`` file is the XML of Tracker's ``XMLControl``: ``<object class="…">`` elements holding
``<property name=… type=…>``. dropfit reads from it

- each point mass (class ``…PointMass``): its ``name`` and its ``framedata`` array, whose item
  ``[n]`` holds the image position ``x``, ``y`` (px, y down) marked in video frame n;
- the coordinate system (``…ImageCoordSystem``): per key frame the image position of the world
  origin (``xorigin``, ``yorigin``, px), the angle of the world x axis counter-clockwise from the
  image x axis (``angle``, degrees) and the scale (``xscale``, ``yscale``, px per world unit); a frame
  without an entry keeps the last key frame's values. The world y axis is 90° counter-clockwise from its x
  axis: up at angle 0, down near ±180° (a common set-up: y down from the release). The height is along the
  flights' up (:func:`upright`), whichever way the user turned the axes;
- the clip's timing: the video clip's ``startframe`` and ``starttime`` (ms) and the clip control's
  ``delta_t`` (ms per frame): frame n is at ``starttime + (n − startframe) · delta_t``;
- the panel's ``length_unit`` (the world unit, m by default).

A ``.trz`` project is a zip holding the ``.trk`` (and the video). Tracker's exported data tables are
text: a first line naming the track, then ``t x y`` (tab separated), in s and the world unit (m
unless the header names another).
"""

from __future__ import annotations

import dataclasses
import io
import math
import xml.etree.ElementTree as ElementTree
import zipfile
from dataclasses import dataclass

import numpy as np

from ..errors import InputError, shown, shown_path
from ..files import MAX_ARCHIVE_MEMBER_BYTES, ZIP_ERRORS, read_archive_member
from .base import LENGTH_UNITS_M, ImportedTrack, pick_track
from .table import Table, describe, parse_column, read_table, split, track_from_table


@dataclass
class PointMass:
    """One point mass of a Tracker project: its name and its marks (video frame, image px, y down)."""

    name: str
    frames: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray


@dataclass
class TrackerProject:
    """What dropfit reads from a Tracker project.

    Attributes
    ----------
    point_masses : list of PointMass
    coords : dict
        Frame number → (x origin px, y origin px, angle rad, x scale px/unit, y scale px/unit), key frames.
    start_frame : int
        The clip's first video frame.
    start_time_s : float
        The time of the clip's first frame, s.
    frame_interval_s : float or None
        Time between video frames, s (``delta_t``).
    length_unit : str
        The world unit of the coordinate system.
    """

    point_masses: list
    coords: dict
    start_frame: int
    start_time_s: float
    frame_interval_s: float | None
    length_unit: str

    def frame_coords(self, frames):
        """The coordinate system of each frame: arrays (x origin, y origin, angle rad, x scale, y scale)."""
        keys = sorted(self.coords)
        if not keys:
            return tuple(np.full(len(frames), value) for value in (0.0, 0.0, 0.0, 1.0, 1.0))
        rows = [self.coords[keys[max(0, int(np.searchsorted(keys, frame, side="right")) - 1)]] for frame in frames]
        return tuple(np.array(column, float) for column in zip(*rows))

    def world(self, point_mass):
        """(x, y) of a point mass in the world unit, y up: Tracker's image-to-world transform of each frame."""
        x0, y0, angle, x_scale, y_scale = self.frame_coords(point_mass.frames)
        u = (point_mass.x_px - x0) / x_scale
        v = -(point_mass.y_px - y0) / y_scale
        return np.cos(angle) * u + np.sin(angle) * v, -np.sin(angle) * u + np.cos(angle) * v

    def times_s(self, frames):
        """Times in s of video frames."""
        return self.start_time_s + (np.asarray(frames, float) - self.start_frame) * self.frame_interval_s


def _properties(node):
    return {prop.get("name"): prop for prop in node.findall("property")}


def _number(prop, default=None):
    if prop is None or prop.text is None:
        return default
    try:
        return float(prop.text)
    except ValueError:
        return default


def _object(prop):
    return prop.find("object") if prop is not None else None


def _array_items(prop):
    """(index, object) of an XMLControl array property's items ``[n]``."""
    items = []
    for item in prop.findall("property") if prop is not None else []:
        name = item.get("name", "")
        if name.startswith("[") and name.endswith("]") and name[1:-1].isdigit() and _object(item) is not None:
            items.append((int(name[1:-1]), _object(item)))
    return items


def parse_project(path, xml_bytes):
    """A :class:`TrackerProject` from the bytes of a ``.trk`` file; InputError if it is not one."""
    name = shown_path(path)
    try:
        root = ElementTree.fromstring(xml_bytes)
    except (ElementTree.ParseError, LookupError) as error:  # (LookupError: an encoding Python does not know)
        raise InputError(f"{name}: is not a readable Tracker project (XML error: {shown(error)}); save it again in "
                         f"Tracker") from None
    if not root.get("class", "").endswith("TrackerPanel"):
        raise InputError(f"{name}: is XML but not a Tracker project (no TrackerPanel); give a .trk or .trz file")
    masses = []
    for node in root.iter("object"):
        if not node.get("class", "").endswith(".PointMass"):
            continue
        props = _properties(node)
        marks = [(frame, _number(_properties(data).get("x")), _number(_properties(data).get("y")))
                 for frame, data in _array_items(props.get("framedata"))]
        marks = [mark for mark in marks if mark[1] is not None and mark[2] is not None]
        label = props["name"].text if "name" in props and props["name"].text else f"point mass {len(masses) + 1}"
        frames, x, y = (np.array(column, float) for column in zip(*marks)) if marks else (np.array([]),) * 3
        masses.append(PointMass(label, frames, x, y))
    coords = {}
    system = next((n for n in root.iter("object") if n.get("class", "").endswith(".ImageCoordSystem")), None)
    if system is not None:
        for frame, data in _array_items(_properties(system).get("framedata")):
            values = _properties(data)
            coords[frame] = (_number(values.get("xorigin"), 0.0), _number(values.get("yorigin"), 0.0),
                             math.radians(_number(values.get("angle"), 0.0)), _number(values.get("xscale"), 1.0),
                             _number(values.get("yscale"), 1.0))
    clip = next((n for n in root.iter("object") if n.get("class", "").endswith(".VideoClip")), None)
    clip_props = _properties(clip) if clip is not None else {}
    control = next((n for n in root.iter("object") if n.get("class", "").endswith("ClipControl")), None)
    delta_t_ms = _number(_properties(control).get("delta_t")) if control is not None else None
    start_time_ms = _number(clip_props.get("starttime"), 0.0)
    root_props = _properties(root)
    unit = root_props["length_unit"].text.strip() if root_props.get("length_unit") is not None \
        and root_props["length_unit"].text else "m"
    return TrackerProject(masses, coords, int(_number(clip_props.get("startframe"), 0.0)),
                          (start_time_ms if math.isfinite(start_time_ms) else 0.0) / 1000.0,
                          delta_t_ms / 1000.0 if delta_t_ms and delta_t_ms > 0 else None, unit)


_TOO_LARGE_ADVICE = "save a project of fewer frames in Tracker, or export the track as a table (CSV)"


def project_bytes(path, raw):
    """The ``.trk`` XML of a ``.trk`` file or of a ``.trz`` project (the first ``.trk`` in the zip), no more than
    :data:`dropfit.files.MAX_ARCHIVE_MEMBER_BYTES` either way (16 MiB of XML tags took 460 MB to parse)."""
    if not raw.startswith(b"PK"):
        if len(raw) > MAX_ARCHIVE_MEMBER_BYTES:
            raise InputError(f"{shown_path(path)}: holds {len(raw) / 1024 ** 2:.0f} MiB of XML, more than the "
                             f"{MAX_ARCHIVE_MEMBER_BYTES // 1024 ** 2} MiB dropfit reads from a Tracker project "
                             f"(MAX_ARCHIVE_MEMBER_BYTES); {_TOO_LARGE_ADVICE}")
        return raw
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as archive:
            names = [n for n in archive.namelist() if n.lower().endswith(".trk")]
            if not names:
                raise InputError(f"{shown_path(path)}: is a zip archive without a Tracker project (.trk) in it; give "
                                 f"the .trz saved by Tracker, or export the data as CSV")
            return read_archive_member(path, archive, names[0], _TOO_LARGE_ADVICE)
    except ZIP_ERRORS:
        raise InputError(f"{shown_path(path)}: is a damaged zip archive (a .trz?); save the project again") from None


def read_tracker_project(path):
    """The :class:`TrackerProject` of a ``.trk`` or ``.trz`` file."""
    from ..files import read_table_bytes

    return parse_project(path, project_bytes(path, read_table_bytes(path, "Tracker project (.trk, .trz)")))


def read_project(path, raw, options):
    """A Tracker project → :class:`ImportedTrack` of the chosen point mass, in the world unit, y up.

    Without a calibration (scale 1 px per unit, the default) the positions stay in image px.
    """
    name = shown_path(path)
    project = parse_project(path, project_bytes(path, raw))
    masses = {index + 1: mass for index, mass in enumerate(project.point_masses) if mass.frames.size}
    if not masses:
        raise InputError(f"{name}: the Tracker project has no point mass with marked positions; mark the ball with a "
                         f"point mass in Tracker")
    number = pick_track(path, {k: (m.frames, m.x_px, m.y_px) for k, m in masses.items()}, options.track_id,
                        "point mass")
    mass = masses[number]
    if project.frame_interval_s is None and not options.fps:
        raise InputError(f"{name}: the Tracker project gives no frame timing (delta_t); give the frame rate with "
                         f"--fps")
    timing = _timing_words(project.frame_interval_s, options.fps)
    if options.fps:
        project.frame_interval_s = 1.0 / options.fps
    time = project.times_s(mass.frames)
    _, _, angle, x_scale, y_scale = project.frame_coords(mass.frames)
    calibrated = not (np.all(x_scale == 1.0) and np.all(y_scale == 1.0))
    unit = project.length_unit if project.length_unit in LENGTH_UNITS_M else None
    if calibrated and unit is None:
        raise InputError(f"{name}: the Tracker project's length unit '{shown(project.length_unit)}' is not one dropfit "
                         f"reads (m, cm, mm, in, ft); set it to m in Tracker")
    if calibrated:
        x, y, up_deg, vertical = upright(time, *project.world(mass))
        calibration = {"px_per_unit": float(np.median(y_scale)), "angle_deg": float(np.degrees(np.median(angle))),
                       "origin_px": f"{project.frame_coords(mass.frames[:1])[0][0]:.3f},"
                                    f"{project.frame_coords(mass.frames[:1])[1][0]:.3f}",
                       "up_deg": up_deg}
        what = f"Tracker's calibration ({np.median(y_scale):.6g} px/{unit}, axes at {np.degrees(np.median(angle)):.4g}°" \
               f"{vertical})"
    else:
        x, y, unit, calibration, what = mass.x_px, mass.y_px, "px", {}, "image px (no calibration in the project)"
    mapping = describe(path, [f"point mass '{mass.name}' ({mass.frames.size} marks)", what,
                              timing])
    track = ImportedTrack(time, y, unit, "tracker", mapping, x, 1.0 / project.frame_interval_s,
                          {f"tracker_{key}": value for key, value in calibration.items()})
    return track


#: A world axis within this many degrees of the flights' up (:func:`dropfit.analysis.up_direction`), or within
#: three of its standard errors, is the vertical: the user's axes, exactly; farther, the flights' own up is (axes
#: turned by hand to −179.6° are 0.4° off: 0.3 % on the late heights of a ball drifting 5 cm/s).
AXIS_SNAP_DEG = 0.1


def upright(time_s, x, y):
    """World positions (``x``, ``y`` in the world unit, in Tracker's axes) turned so that height points up.

    Tracker's world y axis is wherever the user turned it: up (angle 0), down (about ±180°, y down with
    the origin at the release, a common set-up), sideways (±90°), or along a tilted camera's vertical. The
    flights fall along g, so the up of their curvature (:func:`dropfit.analysis.up_direction`) names the
    vertical: the world axis nearest to it when within :data:`AXIS_SNAP_DEG` (or three standard errors),
    else that direction itself. x is the horizontal, turned with it (a rotation: no mirror).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, float, str)
        Horizontal and height in the world unit, the up direction in degrees counter-clockwise from the world
        x axis, and words for the mapping ("" for the world y axis as it is).
    """
    from ..analysis import up_direction

    found, found_se = up_direction(time_s, x, y)
    axes = np.radians([90.0, -90.0, 0.0, 180.0])  # +y, −y, +x, −x as up
    off = np.abs(np.angle(np.exp(1j * (axes - found))))
    nearest = int(np.argmin(off))
    if off[nearest] <= max(np.radians(AXIS_SNAP_DEG), 3 * found_se):
        up = float(axes[nearest])
        words = ["", "; its y axis points down: heights are −y", "; its x axis points up: heights are x",
                 "; its x axis points down: heights are −x"][nearest]
    else:
        up = found
        words = (f"; the flights fall {np.degrees(abs(np.angle(np.exp(1j * (found - np.pi / 2))))):.1f}° from its y "
                 f"axis: heights along their vertical ({np.degrees(found):.1f}° from its x axis)")
    cos, sin = np.cos(up), np.sin(up)
    if up in axes:  # exactly an axis: no term of the other (a mark without x keeps its height)
        cos, sin = round(cos), round(sin)

    def turned(a, first, b, second):
        return sum(weight * values for weight, values in ((a, first), (b, second)) if weight != 0)

    return turned(sin, x, -cos, y), turned(cos, x, sin, y), float(np.degrees(up)), words


def _timing_words(delta_t_s, fps):
    """How the frame step was taken: the project's ``delta_t``, or ``fps`` given (the camera's rate wins).

    A step stated to the whole ms that is no whole frame rate (66 ms is 15.15 fps) was rounded or cut:
    Tracker stores the step of a whole rate exactly (66.667 ms for 15 fps). A step 1 % short reads g, and a
    scale from gravity, 2 % high, so the words name the whole rate the step most likely stands for.
    """
    if fps:
        stated = f"; the project says {delta_t_s * 1000:.6g} ms" if delta_t_s else ""
        return f"frames {1000 / fps:.6g} ms apart (--fps {fps:g}{stated})"
    step_ms = delta_t_s * 1000
    words = f"frames {step_ms:.6g} ms apart (Tracker's delta_t)"
    rate = _whole_rate_cut_to(step_ms)
    if rate is not None:
        words += (f"; a step given to the whole ms, {1000 / step_ms:.4g} fps: if the camera ran at {rate} fps "
                  f"({1000 / rate:.5g} ms), give --fps {rate}")
    return words


def _whole_rate_cut_to(step_ms):
    """The whole frame rate (fps) whose step rounds or truncates to ``step_ms``, a whole number of ms that no
    whole rate has exactly; a multiple of 5 fps first (cameras' rates), else the nearest. None otherwise, and
    for steps under 10 ms, where many rates share a whole ms."""
    if abs(step_ms - round(step_ms)) > 1e-9 or step_ms < 10:
        return None
    step = round(step_ms)
    if abs(1000 / step - round(1000 / step)) < 1e-9:
        return None
    rates = [rate for rate in range(math.floor(1000 / (step + 1)), math.ceil(1000 / (step - 1)) + 1)
             if rate > 0 and step in (math.floor(1000 / rate), round(1000 / rate))]
    if not rates:
        return None
    return min(rates, key=lambda rate: (rate % 5 != 0, abs(1000 / rate - step_ms)))


def read_data_table(table, options, which=""):
    """Tracker's exported data (a track name line, then ``t x y``): time in s and lengths in m unless named;
    ``which`` says how the track was chosen among several. Its x and y are in the project's axes, turned as
    the user turned them: the height is along the flights' up (:func:`upright`; with y alone, y or −y),
    unless ``--columns`` names the columns."""
    track = track_from_table(table, "tracker", options, default_time_unit="s", default_length_unit="m")
    if track.unit != "px" and not options.columns:
        if track.x is not None:
            x, y, _, words = upright(track.time_s, track.x, track.y)
        else:
            from ..analysis import vertical_sign

            down = vertical_sign(track.time_s, track.y) < 0
            x, y, words = None, -track.y if down else track.y, "; its y axis points down: heights are −y" if down \
                else ""
        track = dataclasses.replace(track, x=x, y=y, mapping=track.mapping + words.replace("its", "Tracker's", 1))
    if table.preamble:
        track.mapping += f" (track '{shown(table.preamble[-1].strip(), 30)}'{which})"
    return track


def track_groups(lines):
    """The tracks of Tracker's data table of several tracks, or None for another table.

    Such a table names each track once over its columns (``mass A<tab><tab><tab>mass B<tab><tab>``), then
    gives ``t x y`` (or the columns chosen in Tracker) under each name, ``t`` first.

    Returns
    -------
    (str, list of (str, int, int)) or None
        The separator and each track's name, first and past-last column.
    """
    if len(lines) < 3:
        return None
    for separator in ("\t", ",", ";"):
        names, header = split(lines[0], separator), split(lines[1], separator)
        starts = [i for i, field in enumerate(header) if parse_column(field).name == "t"]
        named = [i for i, name in enumerate(names) if name.strip().strip('"').strip()]
        if len(starts) >= 2 and starts[0] == 0 and named == starts:
            ends = starts[1:] + [len(header)]
            return separator, [(names[i].strip().strip('"').strip(), i, end) for i, end in zip(starts, ends)]
    return None


def read_tracks_table(path, lines, options):
    """Tracker's data table of several tracks (:func:`track_groups`) → :class:`ImportedTrack` of one:
    ``options.track_id`` (counted from 1, left to right) or the one that moves like a dropped ball."""
    _, groups = track_groups(lines)
    table = read_table(path, lines[1:])
    tracks = {}
    for number, (name, start, end) in enumerate(groups, 1):
        rows = [row[start:end] for row in table.rows if len(row) > start and row[start].strip()]  # its own times
        if rows:
            tracks[number] = Table(table.path, table.header[start:end], rows, table.separator, table.decimal_comma,
                                   [name], table.units_row[start:end] if table.units_row else None)
    if not tracks:
        raise InputError(f"{shown_path(path)}: no track of the Tracker table has a time; export the data again")
    read, refused = {}, {}
    for number, group in tracks.items():
        try:
            read[number] = read_data_table(group, options)
        except InputError as error:  # a track of no position (a protractor's t θ) beside the ball's
            refused[number] = error
    if options.track_id in refused or not read:
        raise refused.get(options.track_id, next(iter(refused.values())))
    number = pick_track(path, {k: (t.time_s, t.x, t.y) for k, t in read.items()}, options.track_id, "track")
    which = ", given" if options.track_id is not None else f", the most ball-like of {len(read)}"
    return read_data_table(tracks[number], options, which)
