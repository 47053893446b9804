"""Every reader has a bound: an input over it is refused in one line naming the bound, and in little memory.

Each hostile input is made here, small on disk: a zip whose one member unpacks to far more than
:data:`dropfit.files.MAX_ARCHIVE_MEMBER_BYTES` (a phyphox export, a Tracker ``.trz``), a phyphox set of
a line longer than :data:`dropfit.importers.table.MAX_LINE_CHARACTERS`, tables and projects over
:data:`dropfit.files.MAX_TABLE_BYTES` or :data:`dropfit.files.MAX_TABLE_LINES`, sound over
:data:`dropfit.audio.decode.MAX_SOUND_SAMPLES`, and a clip of frames larger than
:data:`dropfit.video.decode.MAX_FRAME_PIXELS`. Each runs ``python -m dropfit measure`` in a subprocess that
reports its own peak memory (``VmHWM`` of ``/proc/self/status``: unlike ``ru_maxrss``, not inherited from
the test process it was forked from), so that what other tests hold does not count.
"""

from __future__ import annotations

import json
import sys
import zipfile

import numpy as np
import pandas as pd
import pytest

from dropfit.errors import InputError
from dropfit.files import MAX_ARCHIVE_MEMBER_BYTES, MAX_TABLE_BYTES, MAX_TABLE_LINES
from dropfit.importers.table import MAX_LINE_CHARACTERS
from dropfit.video import decode
from dropfit.video.decode import MAX_FRAME_PIXELS, frame_reduction
from dropfit.video.opencv import cv2
from dropfit.video.track import TrackerHints, track_video

from helpers import assert_one_line_error, measured_dropfit

#: The most memory a refused archive may take, MB: the interpreter with dropfit, numpy and PyAV loaded takes
#: 130 MB; reading the 128 MiB members below whole took 390-410 MB (and a 1.6 GB one 4.86 GB).
ARCHIVE_REFUSAL_PEAK_MB = 250
#: ... and a refused clip: FFmpeg's probe of its stream decodes a frame (an 8192 × 8192 clip: 325 MB); decoding
#: its two frames took 3.0 GB.
CLIP_REFUSAL_PEAK_MB = 500
#: The memory the workflow's profile gives a job, MB (workflow/profiles/default).
JOB_MEMORY_MB = 1000

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="peak memory from /proc (Linux)")


def _zip_with(path, members):
    """A zip at ``path`` of ``members`` {name: (bytes, repeats)}: each member its bytes that many times over."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as archive:
        for name, (chunk, repeats) in members.items():
            with archive.open(name, "w", force_zip64=True) as member:
                for _ in range(repeats):
                    member.write(chunk)
    return path


def _refused(tmp_path, path, words, peak_limit_mb=ARCHIVE_REFUSAL_PEAK_MB):
    done, peak_mb = measured_dropfit("measure", path, "--out", tmp_path / "trajectory.nc", cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    assert_one_line_error(done.stderr, path.name)
    assert "internal error" not in done.stderr
    for word in words:
        assert word in done.stderr, done.stderr
    assert peak_mb < peak_limit_mb, f"{path.name} took {peak_mb:.0f} MB"
    assert not (tmp_path / "trajectory.nc").exists()


def test_the_bounds_leave_room_for_real_inputs():
    assert 8 * 2 ** 20 <= MAX_ARCHIVE_MEMBER_BYTES <= 64 * 2 ** 20
    assert 3840 * 2160 <= MAX_FRAME_PIXELS < 7680 * 4320
    assert MAX_TABLE_LINES > 10 ** 6 and MAX_TABLE_BYTES >= 10 ** 6 * len("0.999999,0.53303\n")  # a second at 1 MHz
    from dropfit.audio.decode import MAX_SOUND_SAMPLES, MAX_SOUND_VALUES

    assert MAX_SOUND_SAMPLES >= 120 * 48_000 and MAX_SOUND_VALUES >= 2 * MAX_SOUND_SAMPLES  # minutes of stereo


def test_a_phyphox_set_that_unpacks_beyond_the_bound_is_refused(tmp_path):
    # 128 MiB of one line, 0.6 MB on disk: read whole, it took gigabytes and then an internal error
    chunk = b"1" * (4 << 20)
    path = _zip_with(tmp_path / "phyphox.zip", {"meta/device.csv": (b'"property","value"\n', 1),
                                                "Position.csv": (chunk, 32)})
    _refused(tmp_path, path, ["Position.csv", "MAX_ARCHIVE_MEMBER_BYTES", "128 MiB", "export again"])


def test_phyphox_sets_are_bounded_together(tmp_path):
    # five sets each under the bound (5 MiB each of a bound of 16), together over it
    chunk = b"2" * (1 << 20)
    sets = {f"Set {index}.csv": (chunk, MAX_ARCHIVE_MEMBER_BYTES // (4 << 20) + 1) for index in range(5)}
    path = _zip_with(tmp_path / "phyphox.zip", {"meta/device.csv": (b'"property","value"\n', 1)} | sets)
    _refused(tmp_path, path, ["Set 3.csv", "MAX_ARCHIVE_MEMBER_BYTES", "all members together"])


def test_a_tracker_project_that_unpacks_beyond_the_bound_is_refused(tmp_path):
    # a .trk of 128 MiB of spaces in a .trz of 0.6 MB
    path = _zip_with(tmp_path / "drop.trz", {"drop.trk": (b" " * (4 << 20), 32)})
    _refused(tmp_path, path, ["drop.trk", "MAX_ARCHIVE_MEMBER_BYTES", "128 MiB", "Tracker"])


def test_a_table_line_beyond_the_bound_is_refused_not_an_internal_error(tmp_path):
    # a line over the csv module's field limit (131072) in a phyphox set gave "internal error … field limit"
    line = b"1" * (200_000) + b"\n"
    path = _zip_with(tmp_path / "phyphox.zip", {"meta/device.csv": (b'"property","value"\n', 1),
                                                "Position.csv": (b'"Time (s)","Distance (m)"\n' + line
                                                                 + b"0.1,0.2\n0.2,0.3\n", 1)})
    _refused(tmp_path, path, ["200000 characters", str(MAX_LINE_CHARACTERS), "MAX_LINE_CHARACTERS"])


def test_a_table_over_the_byte_bound_is_refused_before_it_is_read(tmp_path):
    # a 1 GB .trk of spaces took 2.18 GB; the file's size refuses it now, not what reading it costs
    for name in ("log.csv", "drop.trk"):
        path = tmp_path / name
        path.write_bytes((b"time_s,y_m\n" if name.endswith(".csv") else b"<?xml version='1.0'?>\n")
                         + b" " * MAX_TABLE_BYTES)
        _refused(tmp_path, path, ["MAX_TABLE_BYTES", "32 MiB", "every second row"])


def test_a_misnamed_video_over_the_byte_bound_is_named_a_video(tmp_path):
    path = tmp_path / "clip.csv"
    with open(path, "wb") as handle:
        handle.write(b"\x00\x00\x00\x18ftypmp42")
        handle.truncate(MAX_TABLE_BYTES + 1)
    _refused(tmp_path, path, ["MP4 or MOV video", ".mp4"])


def test_a_table_of_more_lines_than_the_bound_is_refused(tmp_path):
    # 'i,1' rows: the most lines a file under the byte bound can hold, each a row that costs memory
    path = tmp_path / "log.csv"
    path.write_text("time_s,y_m\n" + "".join(f"{i},1\n" for i in range(MAX_TABLE_LINES)))
    assert path.stat().st_size < MAX_TABLE_BYTES
    _refused(tmp_path, path, [f"{MAX_TABLE_LINES + 1:,} lines", "MAX_TABLE_LINES"])


def test_a_tracker_project_of_more_xml_than_an_archive_may_hold_is_refused(tmp_path):
    path = tmp_path / "drop.trk"
    path.write_bytes(b"<?xml version='1.0'?>\n<object>" + b"<a/>" * (MAX_ARCHIVE_MEMBER_BYTES // 4) + b"</object>")
    _refused(tmp_path, path, ["of XML", "MAX_ARCHIVE_MEMBER_BYTES", "Tracker"])


def _clicks_wav(path, seconds, channels, rate_hz=8000):
    """A sound file of low-level noise, ``seconds`` long (16-bit PCM)."""
    import soundfile

    noise = np.random.default_rng(3).normal(0.0, 1e-3, (int(seconds * rate_hz), channels))
    soundfile.write(path, noise, rate_hz, subtype="PCM_16")
    return path


@pytest.mark.parametrize("channels, bound", [(1, "MAX_SOUND_SAMPLES"), (6, "MAX_SOUND_VALUES")])
def test_sound_beyond_its_bound_is_refused_before_it_is_decoded(tmp_path, channels, bound):
    from dropfit.audio.decode import MAX_SOUND_SAMPLES, MAX_SOUND_VALUES

    most = min(MAX_SOUND_SAMPLES, MAX_SOUND_VALUES // channels)
    path = _clicks_wav(tmp_path / "long.wav", most / 8000 + 1, channels)
    done, peak_mb = measured_dropfit("run", path, "--out", tmp_path / "out", cwd=tmp_path)
    assert done.returncode == 1, done.stderr
    assert_one_line_error(done.stderr, path.name)
    for word in (bound, f"{most:,} samples a channel", "ffmpeg"):
        assert word in done.stderr, done.stderr
    assert peak_mb < ARCHIVE_REFUSAL_PEAK_MB, f"took {peak_mb:.0f} MB"


def test_compressed_sound_is_counted_while_it_is_decoded(tmp_path, monkeypatch):
    # a compressed file's length is known only by decoding it: the count stops it at the bound
    import av

    from dropfit.audio import decode

    monkeypatch.setattr(decode, "MAX_SOUND_SAMPLES", 8000)
    path = tmp_path / "long.m4a"
    with av.open(str(path), "w") as output:
        stream = output.add_stream("aac", rate=8000)
        stream.layout = "mono"
        noise = (np.random.default_rng(4).normal(0, 300, 3 * 8000)).astype(np.int16)
        for start in range(0, noise.size, 1024):
            frame = av.AudioFrame.from_ndarray(noise[None, start:start + 1024], format="s16", layout="mono")
            frame.sample_rate = 8000
            for packet in stream.encode(frame):
                output.mux(packet)
        for packet in stream.encode(None):
            output.mux(packet)
    with pytest.raises(InputError, match=r"lasts more than 1 s of 1 channel.*MAX_SOUND_SAMPLES"):
        decode.read_sound(path)


def test_frames_beyond_the_pixel_bound_are_refused_before_decoding(tmp_path):
    # 2 flat frames of 8192 × 8192 (0.2 MB on disk): decoded, they took 2.98 GB before "only 2 frames"
    av = pytest.importorskip("av")
    path = tmp_path / "huge.mp4"
    container = av.open(str(path), "w")
    stream = container.add_stream("libx264", rate=30)
    stream.width = stream.height = 8192
    stream.pix_fmt = "yuv420p"
    stream.options = {"preset": "ultrafast"}
    frame = av.VideoFrame(8192, 8192, "yuv420p")
    for plane in frame.planes:
        memoryview(plane)[:] = b"\x5a" * plane.buffer_size
    for index in range(2):
        frame.pts = index
        container.mux(stream.encode(frame))
    container.mux(stream.encode())
    container.close()
    _refused(tmp_path, path, ["8192 × 8192 px", "MAX_FRAME_PIXELS", "scale"], CLIP_REFUSAL_PEAK_MB)


def _bouncing_ball_clip(path, width, height, frames, fps=30):
    """An H.264 clip of a ball (radius a 54th of the frame's height) dropped 1 m with e = 0.8 before a mottled wall,
    the frame 0.8 m high at the drop; returns the ball's centre (x, y) in px of each frame, from the closed form."""
    av = pytest.importorskip("av")
    rng = np.random.default_rng(5)
    wall = cv2.resize(cv2.GaussianBlur(rng.integers(60, 200, (height // 8, width // 8, 3), dtype=np.uint8), (0, 0), 3),
                      (width, height), interpolation=cv2.INTER_LINEAR)
    radius, g, e, px_per_m = height / 54, 9.81, 0.8, 0.8 * height
    fall = np.sqrt(2 / g)
    centres = []
    container = av.open(str(path), "w")
    stream = container.add_stream("libx264", rate=fps)
    stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
    stream.options = {"preset": "ultrafast", "crf": "12"}
    for index in range(frames):
        t = index / fps
        if t < fall:
            above = 1 - g * t * t / 2
        else:
            speed, t = e * g * fall, t - fall
            while t > 2 * speed / g:
                t, speed = t - 2 * speed / g, e * speed
            above = speed * t - g * t * t / 2
        x, y = width / 2 + 0.3, 0.9 * height - radius - above * px_per_m
        centres.append((x, y))
        image = wall.copy()
        cv2.circle(image, (round(x * 16), round(y * 16)), round(radius * 16), (40, 220, 230), -1, cv2.LINE_AA, 4)
        container.mux(stream.encode(av.VideoFrame.from_ndarray(image, format="bgr24")))
    container.mux(stream.encode())
    container.close()
    return np.array(centres)


@pytest.mark.slow
def test_a_4k_clip_is_tracked_reduced_in_the_memory_a_job_has(tmp_path):
    """A 4096 × 2160 clip is tracked in frames reduced by 2 as they are decoded (MAX_TRACKED_FRAME_PIXELS): its
    `dropfit run` stays under the workflow's 1000 MB a job (whole, it took 1.45-1.54 GB), the centres are the
    closed form's in the reduced frames' px, and the report says in which px they are."""
    path = tmp_path / "uhd.mp4"
    truth = _bouncing_ball_clip(path, 4096, 2160, 60)
    assert frame_reduction(4096, 2160) == 2
    done, peak_mb = measured_dropfit("run", path, "--out", tmp_path / "out", "--ball-type", "tennis", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert peak_mb < JOB_MEMORY_MB, f"took {peak_mb:.0f} MB"
    table = pd.read_csv(tmp_path / "out" / "track.csv", comment="#")
    ok = table["quality"] == "ok"
    assert ok.sum() >= 40
    # a reduced pixel averages coded pixels 2j and 2j + 1: its centre is at coded 2j + 0.5
    error = np.hypot(table["x_px"] - (truth[:, 0] - 0.5) / 2, table["y_px"] - (truth[:, 1] - 0.5) / 2)[ok]
    assert error.median() < 0.15 and error.max() < 1.5, error.describe()
    assert "frames tracked reduced 2 times" in (tmp_path / "out" / "report.html").read_text()


def test_hints_in_the_clip_s_own_px_reach_frames_tracked_reduced(tmp_path, monkeypatch):
    """With the bound lowered so that a 640 × 480 clip is tracked reduced by 2: the centres are the closed form's
    in the reduced frames' px, a --ball-at-px given in the clip's px is checked against the clip's 640 × 480 (not the reduced
    frames'), and the table says it is reduced."""
    monkeypatch.setattr(decode, "MAX_TRACKED_FRAME_PIXELS", 320 * 240)
    path = tmp_path / "small.mp4"
    truth = _bouncing_ball_clip(path, 640, 480, 45)
    table = track_video(path, hints=TrackerHints(ball_at_px=(3, *truth[3])))
    assert table.attrs["reduced_by"] == 2 and "reduced 2 times" in table.attrs["frames_note"]
    ok = (table["quality"] == "ok").to_numpy()
    assert ok.sum() >= 35
    error = np.hypot(table["x_px"] - (truth[:, 0] - 0.5) / 2, table["y_px"] - (truth[:, 1] - 0.5) / 2)[ok]
    assert np.median(error) < 0.15, error
    # 500 px is inside the clip's width (640) and outside the reduced frames' (320)
    track_video(path, hints=TrackerHints(ball_at_px=(3, 500.0, truth[3, 1])))
    with pytest.raises(InputError, match="outside the 640x480 px frame"):
        track_video(path, hints=TrackerHints(ball_at_px=(3, 700.0, truth[3, 1])))


@pytest.mark.slow
def test_a_long_clip_of_a_large_ball_is_tracked_in_the_memory_a_job_has(tmp_path):
    """3000 frames of 640 × 480 (30 s at 100 frames/s) of a ball 120 px across: the crops about it kept for
    further passes grew with the frames (2.40 GB); now they stop at their budget and the clip is decoded again.
    The ball is drawn here (OpenCV's anti-aliased disc, no code of the tracker's) from 0.2 m at 1800 px/m, e = 0.85."""
    g, e, drop_m, scale, radius, fps = 9.80665, 0.85, 0.2, 1800.0, 60, 100.0
    impacts, speeds = [np.sqrt(2 * drop_m / g)], [e * np.sqrt(2 * g * drop_m)]
    while speeds[-1] > 0.05:
        impacts.append(impacts[-1] + 2 * speeds[-1] / g)
        speeds.append(speeds[-1] * e)
    path = tmp_path / "long.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (640, 480))
    rng = np.random.default_rng(5)
    for index in range(3000):
        t = index / fps
        flight = int(np.searchsorted(impacts, t))
        tau = t - impacts[flight - 1] if 0 < flight < len(impacts) else 0.0
        height = drop_m - 0.5 * g * t * t if flight == 0 else (
            speeds[flight - 1] * tau - 0.5 * g * tau * tau if flight < len(impacts) else 0.0)
        image = (40 + rng.integers(0, 5, (480, 640, 3))).astype(np.uint8)
        cv2.circle(image, (320, int(round(480 - 20 - radius - max(height, 0.0) * scale))), radius, (60, 200, 230),
                   -1, lineType=cv2.LINE_AA)
        writer.write(image)
    writer.release()
    done, peak_mb = measured_dropfit("run", path, "--out", tmp_path / "out", "--ball-radius-m", "0.0333",
                                     cwd=tmp_path, timeout_s=600)
    assert done.returncode == 0, done.stderr
    assert peak_mb < JOB_MEMORY_MB, f"took {peak_mb:.0f} MB"
    fit = json.loads((tmp_path / "out" / "fit.json").read_text(encoding="utf-8"))
    assert abs(fit["restitution"]["e"]["value"] - e) < 0.005
