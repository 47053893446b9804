"""What every importer returns, and the time base of frame-indexed and video-derived tables.

An importer reads one family of files (:mod:`.tracker`, :mod:`.imagej`, :mod:`.sensors`,
:mod:`.table`, :mod:`.highspeed`) into an :class:`ImportedTrack`: times in s, the vertical coordinate
(and the horizontal one, when the file has it) in a named length unit or in image px, and how it was
read. :func:`dropfit.heightlog.trajectory_from_log` turns it into the trajectory.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError, shown, shown_path

#: Seconds per time unit a table may name.
TIME_UNITS_S = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6, "min": 60.0}
#: Metres per length unit a table may name (``px`` is calibrated later).
LENGTH_UNITS_M = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "um": 1e-6, "in": 0.0254, "ft": 0.3048}


@dataclass(frozen=True)
class ImportOptions:
    """What the user says about a file that its content cannot (command-line options of the same names).

    Attributes
    ----------
    format : str, optional
        The format's name (:data:`dropfit.importers.FORMATS`); default: found from the content.
    fps : float, optional
        Frame rate in frames/s of a frame-indexed table (MTrack2, TrackMate without times).
    track_id : int, optional
        Which track (MTrack2 track number, TrackMate ``TRACK_ID``) or run (Logger Pro, Capstone) to read.
    columns : str, optional
        The column mapping, ``"time=COL,y=COL[,x=COL]"`` (or ``frame=COL`` for ``time``), each name
        optionally followed by its unit in brackets: ``"time=Zeit[s],y=Höhe[cm]"``.
    sensor_height_m : float, optional
        Height in m of a motion detector looking down: the height is this minus the distance.
    """

    format: str | None = None
    fps: float | None = None
    track_id: int | None = None
    columns: str | None = None
    sensor_height_m: float | None = None


@dataclass
class ImportedTrack:
    """One ball's positions over time as read from a file.

    Attributes
    ----------
    time_s : numpy.ndarray
        Sample times in s, strictly increasing.
    y : numpy.ndarray
        The vertical coordinate in ``unit``, NaN where not measured: up for lengths; for ``px`` as the
        file gives it (image rows point down; the calibration finds the direction).
    unit : str
        ``m``, ``cm``, ``mm``, ``in``, ``ft`` or ``px``.
    source_format : str
        The format's name (:data:`dropfit.importers.FORMATS`).
    mapping : str
        One line saying what was read as what (``read data.csv as time 'Zeit (s)' [s], height …``).
    x : numpy.ndarray, optional
        The horizontal coordinate in ``unit`` (NaN where not measured), or None.
    frame_rate_hz : float, optional
        The frame rate of a video-derived table, frames/s.
    calibration : dict
        The file's own calibration, applied already (Tracker: ``px_per_m``, origin, angle), for the
        trajectory's attributes.
    notes : list of str
        What was repaired (duplicated frames removed, …), for the trajectory's attributes.
    """

    time_s: np.ndarray
    y: np.ndarray
    unit: str
    source_format: str
    mapping: str
    x: np.ndarray | None = None
    frame_rate_hz: float | None = None
    calibration: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    def attrs(self):
        """The trajectory attributes that say how the file was read."""
        attrs = {"log_unit": self.unit, "import_format": self.source_format, "import_mapping": self.mapping}
        if self.frame_rate_hz:
            attrs["import_frame_rate_hz"] = float(self.frame_rate_hz)
        if self.notes:
            attrs["import_notes"] = "; ".join(self.notes)
        attrs.update({f"import_{key}": value for key, value in self.calibration.items()})
        return attrs

    def with_x(self, trajectory):
        """``trajectory`` with this track's horizontal coordinate as ``x`` (m), scaled as its heights were."""
        if self.x is None or "x" in trajectory:
            return trajectory
        if self.unit == "px":
            metres = abs(float(trajectory.attrs["scale_m_per_px"]))
        else:
            metres = LENGTH_UNITS_M[self.unit]
        trajectory["x"] = ("time", self.x * metres, {"units": "m", "long_name": "horizontal position of the ball centre"})
        return trajectory


def checked_track(path, track):
    """``track`` after checking what every format must give: finite, increasing times and some position.

    A sample repeating the previous one exactly (time and position: a row exported twice) is dropped, a
    note saying how many; the same time with another position is refused, as no file tells which is right.
    """
    name = shown_path(path)
    time = np.asarray(track.time_s, float)
    if time.size == 0:
        raise InputError(f"{name}: no samples were read ({track.mapping}); check the file, or name the columns "
                         f"with --columns time=…,y=…")
    if not np.all(np.isfinite(time)):
        raise InputError(f"{name}: a time is missing or not finite (sample {int(np.flatnonzero(~np.isfinite(time))[0]) + 1}); "
                         f"every sample needs a time")
    if np.any(np.diff(time) < 0):
        back = int(np.flatnonzero(np.diff(time) < 0)[0])
        raise InputError(f"{name}: time goes back at sample {back + 2} ({time[back]:g} s then {time[back + 1]:g} s); "
                         f"sort the table by time")
    y = np.asarray(track.y, float)
    x = None if track.x is None else np.asarray(track.x, float)
    again = np.diff(time) == 0
    same = _equal(y[1:], y[:-1]) & (True if x is None else _equal(x[1:], x[:-1]))
    if np.any(again & ~same):
        row = int(np.flatnonzero(again & ~same)[0])
        raise InputError(f"{name}: time {time[row]:g} s is given twice with different positions (samples {row + 1} "
                         f"and {row + 2}); remove the wrong row, or give the times with more decimals")
    keep = np.concatenate([[True], ~again])
    if not keep.all():
        count = int(np.count_nonzero(~keep))
        track.notes.append(f"{count} sample{'s' if count > 1 else ''} repeating the one before (a row exported "
                           f"twice) dropped")
    fields = {"time_s": time[keep], "y": y[keep]}
    if x is not None:
        fields["x"] = x[keep]
    track = dataclasses.replace(track, **fields)
    if not np.any(np.isfinite(track.y)):
        raise InputError(f"{name}: the height column has no valid value ({track.mapping}); name the right one with "
                         f"--columns time=…,y=…")
    if np.any(np.isinf(track.y)):
        raise InputError(f"{name}: a height is infinite (sample {int(np.flatnonzero(np.isinf(track.y))[0]) + 1})")
    return track


def _equal(a, b):
    """Element-wise equality, two NaN (two dropouts) counting as equal."""
    return (a == b) | (np.isnan(a) & np.isnan(b))


def drop_repeated_positions(track):
    """``track`` with a video frame shown twice taken out: its time is not when the ball was there, so the
    repeat becomes a dropout (NaN).

    With x and y, a position repeated exactly in the next sample, where the ball moves before and after, is
    a duplicated frame, not a ball standing still for one frame. With the height alone a repeat is more
    often real (a sensor quantised to 1 mm repeats a height near an apex, where the ball turns, or on the
    floor; a noisy ball at rest repeats one at random), so it counts only where it breaks a smooth motion:
    the heights on both sides move the same way by more than the quantisation step (the smallest gap
    between two heights of the track) and five times the noise
    (:func:`dropfit.analysis.segmentation.estimate_noise`). Under constant acceleration the middle of
    three equal frame intervals moves by their outer ones' mean, so it cannot round to no motion when
    both outer ones move by two steps or more.

    Runs of three or more equal positions (a ball at rest) are kept.
    """
    if track.y.size < 3:
        return track
    y = track.y
    same = (y[1:] == y[:-1]) & np.isfinite(y[1:])
    if track.x is not None:
        same &= track.x[1:] == track.x[:-1]
    before = np.concatenate([[False], same[:-1]])
    after = np.concatenate([same[1:], [False]])
    repeat = np.flatnonzero(same & ~before & ~after) + 1
    if track.x is None and repeat.size:
        from ..analysis.segmentation import estimate_noise

        repeat = repeat[(repeat >= 2) & (repeat + 1 < y.size)]
        finite = np.unique(y[np.isfinite(y)])
        step = float(np.min(np.diff(finite))) if finite.size > 1 else 0.0  # the quantisation, or less
        # two steps or more (1.5 of them: a height written to 1 mm steps 0.9999999999998899 mm in binary)
        two_steps = 1.5 * step
        moved = max(two_steps, 5.0 * estimate_noise(y[np.isfinite(y)])) if finite.size > 3 else two_steps
        into, out_of = y[repeat - 1] - y[repeat - 2], y[repeat + 1] - y[repeat]
        repeat = repeat[(np.abs(into) > moved) & (np.abs(out_of) > moved) & (np.sign(into) == np.sign(out_of))]
    if repeat.size == 0:
        return track
    y, x = track.y.copy(), None if track.x is None else track.x.copy()
    y[repeat] = np.nan
    if x is not None:
        x[repeat] = np.nan
    track.notes.append(f"{repeat.size} repeated position{'s' if repeat.size > 1 else ''} (a duplicated video frame) "
                       f"set as dropout{'s' if repeat.size > 1 else ''}")
    return dataclasses.replace(track, y=y, x=x)


def frame_times(path, frames, fps, what):
    """Times in s of frame numbers ``frames`` at ``fps`` frames/s, counted from the first frame.

    A frame missing from the table (dropped, or the ball not found) leaves a gap of its own length: the
    times come from the frame numbers, not from the row count. The same frame twice is an error the
    caller has removed already.
    """
    if fps is None:
        raise InputError(f"{shown_path(path)}: {what} counts frames but gives no times; give the frame rate with --fps "
                         f"(frames/s), or an fps column in samples.tsv")
    frames = np.asarray(frames, float)
    if not np.all(np.isfinite(frames)) or np.any(frames != np.round(frames)):
        raise InputError(f"{shown_path(path)}: a frame number is not a whole number; check the frame column")
    return (frames - frames[0]) / float(fps)


def unique_frames(frames, *arrays):
    """``frames`` and ``arrays`` without a frame seen already (the first kept), and a note, or None."""
    frames = np.asarray(frames, float)
    _, first = np.unique(frames, return_index=True)
    if first.size == frames.size:
        return (frames, *arrays), None
    first = np.sort(first)
    count = frames.size - first.size
    note = f"{count} row{'s' if count > 1 else ''} of a frame already seen (a frame exported twice) dropped"
    return (frames[first], *(np.asarray(a)[first] for a in arrays)), note


def quoted(names, limit=6):
    """Column names as a message lists them: ``'a', 'b', 'c'``."""
    names = list(names)
    text = ", ".join(f"'{shown(name, 30)}'" for name in names[:limit])
    return text + (", …" if len(names) > limit else "")


def pick_track(path, tracks, track_id, what):
    """The id of the track to read among ``tracks`` (id → (frames, x, y)): ``track_id`` when given, else the
    one that moves like a dropped ball: among the tracks with at least half the most frames, the one with
    the largest vertical range."""
    if track_id is not None:
        if track_id not in tracks:
            raise InputError(f"{shown_path(path)}: there is no {what} {track_id}; the {what}s are "
                             f"{', '.join(str(key) for key in tracks)} (--track-id N)")
        return track_id
    counts = {key: int(np.count_nonzero(np.isfinite(np.asarray(y, float)))) for key, (_, _, y) in tracks.items()}
    longest = max(counts.values())
    ranges = {key: float(np.nanmax(y) - np.nanmin(y)) for key, (_, _, y) in tracks.items()
              if counts[key] >= 0.5 * longest and counts[key] > 0}
    return max(ranges, key=ranges.get)
