"""A sound recording or a table of impact times as dropfit's pipeline carries it: measured into a
dataset of impact times (what ``trajectory.nc`` holds for sound) and analysed into flights and impacts
with the ball's drag and contact time and the site's g.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ..balls import ball_kind
from ..errors import InputError, shown_path
from .decode import is_audio, read_sound
from .flights import analyse_impact_times
from .onsets import detect_impacts, timing_jitter
from .tables import DEFAULT_TABLE_SE_S, is_impact_table, is_table_file, read_impact_table


def is_sound_recording(path):
    """True if ``path`` is a sound file or a table of impact times."""
    return is_audio(path) or is_impact_table(path)


def is_sound_dataset(trajectory):
    """True if a measured dataset holds impact times (from sound or a table), not heights."""
    return "impact_time_s" in trajectory


def sound_trajectory(path, attrs, release_time_s=None, sound=None, columns=None):
    """A sound file (or a video's sound track), or a table of impact times → the dataset of impact times.

    Parameters
    ----------
    path : str or pathlib.Path
        The recording.
    attrs : dict
        Attributes to keep (ball, g, provenance).
    release_time_s : float, optional
        When the ball was let go at rest, s on the recording's clock.
    sound : dropfit.audio.decode.Sound, optional
        The decoded sound, when decoded already (a video's track).
    columns : str, optional
        A table's column of impact times, ``"time=COL[ms]"`` (:func:`dropfit.audio.tables.read_impact_table`).

    Returns
    -------
    xarray.Dataset
        Dimension ``impact``: ``impact_time_s``, ``impact_time_se_s``; from sound also ``impact_peak``
        (full scale 1), ``impact_snr``, ``impact_clipped``, and dimension ``time`` (s) with the
        ``envelope`` (full scale 1) and dimension ``candidate`` with every click found
        (``candidate_time_s``, ``candidate_selected``). Attributes: ``source``, ``recording_kind``
        (``audio`` or ``impact_times``), the sample rate (Hz), the timing jitter (s), ``release_time_s``.
    """
    name = shown_path(path)
    attrs = {key: value for key, value in dict(attrs, source=str(path)).items() if value is not None}  # NetCDF has no None
    if release_time_s is not None:
        attrs["release_time_s"] = float(release_time_s)
    if sound is None and is_table_file(path):
        times, se, kind = read_impact_table(path, columns)
        if times.size < 3:
            raise InputError(f"{name}: {times.size} impact time{'s' if times.size != 1 else ''}; at least three are "
                             f"needed for two flights")
        missing = ~np.isfinite(se)
        if missing.any():
            jitter = timing_jitter(times, np.zeros(times.size))
            se[missing] = jitter if times.size >= 7 and jitter > 0 else DEFAULT_TABLE_SE_S
            attrs["timing_se_note"] = ("standard errors not given: the intervals' scatter about a smooth law"
                                       if times.size >= 7 and jitter > 0 else
                                       f"standard errors not given: {1e3 * DEFAULT_TABLE_SE_S:g} ms assumed "
                                       f"(the loudest sample lags a click's onset by a varying fraction of a ms to a few)")
        attrs.update(recording_kind="impact_times", table_kind=kind)
        return xr.Dataset({"impact_time_s": ("impact", times), "impact_time_se_s": ("impact", se)},
                          coords={"impact": np.arange(1, times.size + 1)}, attrs=attrs)
    sound = sound or read_sound(path)
    onsets = detect_impacts(sound.samples, sound.rate_hz, sound.start_s, source=name)
    if release_time_s is not None and release_time_s >= onsets.table["time_s"].iloc[0]:
        raise InputError(f"{name}: release_time_s {release_time_s:g} s is not before the first impact heard "
                         f"({onsets.table['time_s'].iloc[0]:.4f} s); give the time the ball was let go")
    table = onsets.table
    if sound.channel_note:
        attrs["channel_note"] = sound.channel_note
    attrs.update(recording_kind="audio", sample_rate_hz=sound.rate_hz, channels=int(sound.samples.shape[1]),
                 codec=sound.codec, duration_s=sound.duration_s, timing_jitter_s=onsets.jitter_s,
                 noise_floor=onsets.noise_floor, n_candidates=len(onsets.candidates))
    return xr.Dataset(
        {"impact_time_s": ("impact", table["time_s"].to_numpy()),
         "impact_time_se_s": ("impact", table["time_se_s"].to_numpy()),
         "impact_peak": ("impact", table["peak"].to_numpy()),
         "impact_snr": ("impact", table["snr"].to_numpy()),
         "impact_clipped": ("impact", table["clipped"].to_numpy().astype(np.int8)),
         "envelope": ("time", onsets.envelope),
         "candidate_time_s": ("candidate", onsets.candidates["time_s"].to_numpy()),
         "candidate_selected": ("candidate", onsets.candidates["selected"].to_numpy().astype(np.int8))},
        coords={"impact": table["impact"].to_numpy(), "time": onsets.envelope_time_s},
        attrs=attrs)


def analyse_sound(trajectory, gravity, drag_mode, nominal_drag):
    """The analysis (:func:`dropfit.audio.flights.analyse_impact_times`) of a dataset of impact times.

    Parameters
    ----------
    trajectory : xarray.Dataset
        As :func:`sound_trajectory` makes it.
    gravity : dropfit.settings.SiteGravity
        g at the site (value and standard error, m/s²).
    drag_mode : {"auto", "off", "on"}
        ``off``: no drag; otherwise the ball's nominal drag (impact times cannot fit it).
    nominal_drag : (float, float)
        k of a smooth ball of this kind, size and mass (1/m) and its relative standard error.
    """
    attrs = trajectory.attrs
    kind = ball_kind(attrs.get("ball_type"))
    k, k_relative_se = (0.0, 0.0) if drag_mode == "off" else nominal_drag
    release = attrs.get("release_time_s")
    analysis = analyse_impact_times(
        trajectory["impact_time_s"].values, trajectory["impact_time_se_s"].values, gravity.value_m_s2,
        gravity.se_m_s2, k, k_relative_se, (kind.contact_time_s, kind.contact_time_se_s),
        (kind.contact_time_exponent, kind.contact_time_exponent_se),
        None if release is None or (isinstance(release, float) and np.isnan(release)) else float(release),
        source=shown_path(attrs.get("source", "recording")))
    if drag_mode == "on":
        analysis.summary["notes"].append("drag on: impact times cannot fit k; it is held at the ball's nominal k")
    for key in ("timing_se_note", "channel_note"):
        if key in attrs:
            analysis.summary["notes"].append(attrs[key])
    if k == 0.0 and drag_mode != "off":
        analysis.summary["notes"].append("no drag: give the ball's radius and mass for its drag (e is biased "
                                         "low by the drag otherwise, by several % for a table-tennis ball)")
    return analysis
