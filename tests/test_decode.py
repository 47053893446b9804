"""Decoding phone-like files with PyAV: rotation, times, frame counts, one open and one pass per clip,
progress; clips encoded here with PyAV (libx264, MJPEG)."""

import io
import subprocess
import sys
from fractions import Fraction

import av
import numpy as np
import pytest

from dropfit.errors import InputError
from dropfit.video import decode
from dropfit.video.contrast import CHANNELS
from dropfit.video.decode import Progress, VideoFile
from dropfit.video.detect import QUALITY_DUPLICATE, QUALITY_OK
from dropfit.video.track import MAX_BACKGROUND_REFINEMENTS, track_video

from helpers import CALL_TIMEOUT_S, ball_frames, encode_clip, without_progress

SHAPE = (96, 160)  # px, coded height and width
#: Tracked centre error allowed on the small lossy H.264 clips, px.
CENTRE_TOLERANCE_PX = 0.5
TIME_TOLERANCE_S = 1e-9


def marked_frames(count=40):
    """Frames whose content tells the orientation: a white block in the coded top-left corner."""
    frames = []
    for k in range(count):
        image = np.full((*SHAPE, 3), 60, np.uint8)
        image[:20, :30] = 255
        image[:, :, 1] = 4 * k
        frames.append(image)
    return frames


def block_centre(image):
    """Row and column of the white block's centre, px."""
    return np.argwhere(image[:, :, 0] > 160).mean(axis=0)


@pytest.mark.parametrize("suffix, rotation, shape, centre", [
    (".mp4", 0, (96, 160), (9.5, 14.5)),
    (".mp4", 90, (160, 96), (144.5, 9.5)),  # counter-clockwise: the top-left corner goes to the bottom-left
    (".mov", 270, (160, 96), (14.5, 85.5)),  # a phone held upright: clockwise, to the top-right
    (".mov", 180, (96, 160), (85.5, 144.5)),
])
def test_frames_are_shown_as_the_display_matrix_turns_them(tmp_path, suffix, rotation, shape, centre):
    path = encode_clip(tmp_path / f"clip{suffix}", marked_frames(), rotation_deg=rotation if rotation else None,
                       gop=10)
    with VideoFile(path) as video:
        info = video.info
        frames = list(video.frames())
    assert (info.height, info.width, info.rotation_deg, info.codec) == (*shape, rotation, "h264")
    assert (info.frame_count, info.container_fps) == (40, Fraction(30))
    assert info.duration_s == pytest.approx(40 / 30)
    assert len(frames) == 40 and frames[0][2].shape == (*shape, 3)
    assert np.allclose(block_centre(frames[0][2]), centre, atol=0.6)


def test_times_come_from_the_time_stamps(tmp_path):
    """29.97 fps, jittered stamps and a dropped frame: each frame at its stamp, the gap kept."""
    path = encode_clip(tmp_path / "ntsc.mp4", marked_frames(), fps=Fraction(30000, 1001))
    with VideoFile(path) as video:
        assert video.info.container_fps == Fraction(30000, 1001)
        times = [t for _, t, _ in video.frames()]
    assert np.allclose(times, np.arange(40) * 1001 / 30000, atol=1e-4)

    rng = np.random.default_rng(1)
    stamps = np.round((np.arange(40) + rng.uniform(-0.2, 0.2, 40)) * 3000).astype(int)
    stamps = np.delete(stamps, 17)  # a dropped frame
    path = encode_clip(tmp_path / "jitter.mp4", marked_frames(39), fps=30, pts=stamps,
                       time_base=Fraction(1, 90000))
    table = track_video(encode_clip(tmp_path / "ball.mp4", ball_frames(39)[0], fps=30, pts=stamps,
                                    time_base=Fraction(1, 90000)))
    with VideoFile(path) as video:
        times = np.array([t for _, t, _ in video.frames()])
    assert np.allclose(times, (stamps - stamps[0]) / 90000, atol=TIME_TOLERANCE_S)
    assert np.allclose(table["time_s"], times, atol=TIME_TOLERANCE_S)
    assert table.attrs["time_source"] == "container time stamps"
    assert np.diff(times)[16] == pytest.approx(2 * np.median(np.diff(times)), rel=0.3)


def test_repeated_frames_of_a_60_fps_container_are_duplicates(tmp_path):
    """A true 30 Hz capture in a 60 fps container, every frame twice: the repeats are flagged."""
    frames, centres = ball_frames(30)
    doubled = [frame for frame in frames for _ in range(2)]
    table = track_video(encode_clip(tmp_path / "doubled.mp4", doubled, fps=60))
    assert len(table) == 60
    assert np.allclose(table["time_s"], np.arange(60) / 60, atol=1e-6)
    quality = table["quality"].to_numpy()
    # the first repeat comes before the ball was seen to move, so it counts as a true frame
    assert (quality[3::2] == QUALITY_DUPLICATE).all() and (quality[0::2] == QUALITY_OK).all()
    error = np.hypot(table["x_px"].to_numpy()[0::2] - centres[:, 0], table["y_px"].to_numpy()[0::2] - centres[:, 1])
    assert error.max() < CENTRE_TOLERANCE_PX


@pytest.mark.parametrize("name, codec, gop, rotation", [("clip.avi", "mjpeg", None, None),
                                                        ("clip.mp4", "libx264", 8, 270),
                                                        ("long_gop.mp4", "libx264", 250, None)])
def test_a_clip_is_opened_once_and_decoded_once(tmp_path, monkeypatch, name, codec, gop, rotation):
    """One av.open and one decoding pass (plus the background samples) per track_video."""
    frames, centres = ball_frames(60, step_px=(2.0, 0.0), gravity_px=0.035)
    path = encode_clip(tmp_path / name, frames, codec=codec, gop=gop, rotation_deg=rotation)
    opened, converted = [], []
    real_open, real_image = av.open, VideoFile.image
    monkeypatch.setattr(av, "open", lambda *args, **kwargs: opened.append(args[0]) or real_open(*args, **kwargs))
    monkeypatch.setattr(VideoFile, "image", lambda self, frame: converted.append(frame.pts) or real_image(self, frame))
    table = track_video(path)
    assert len(opened) == 1
    assert len(converted) <= 60 + 11
    assert table.attrs["rotation_deg"] == (rotation or 0)
    assert table.attrs["codec"] == ("mjpeg" if codec == "mjpeg" else "h264")
    if rotation is None:
        error = np.hypot(table["x_px"] - centres[:, 0], table["y_px"] - centres[:, 1])
        assert error.max() < CENTRE_TOLERANCE_PX


def colour_noise_frames(count=6, seed=3):
    """Frames of colour noise: each pixel's conversion differs from its neighbours'."""
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (*SHAPE, 3), dtype=np.uint8) for _ in range(count)]


def plainly_converted(path, rotation_deg):
    """Every frame of ``path`` converted whole by PyAV and turned ``rotation_deg`` counter-clockwise."""
    with av.open(str(path)) as container:
        return [np.rot90(frame.to_ndarray(format="bgr24"), k=rotation_deg // 90) for frame in container.decode(video=0)]


#: Reads a tracker makes of a frame (a sparse grid, windows), and others numpy allows; last, one that converts
#: the whole frame (a negative step).
READS = [np.s_[::16], np.s_[::16, ::16], np.s_[5], np.s_[:, 7], np.s_[-1], np.s_[3:9, 11:12], np.s_[-5:, -3:],
         np.s_[10:4], np.s_[31:70:3, 1:2], np.s_[7:40, 13:90, 1], np.s_[1:2, 3:4, ::-1], np.s_[5, 7],
         np.s_[-1, 3, 2], np.s_[::16, 3:50], np.s_[::16, ::16, 1], np.s_[:, :], np.s_[::-1, :5]]


@pytest.mark.parametrize("name, codec, rotation", [("clip.avi", "mjpeg", 0), ("clip.mp4", "libx264", 270),
                                                   ("clip.mov", "libx264", 90), ("turned.mp4", "libx264", 180)])
def test_frames_converted_where_they_are_read_give_the_pixels_of_the_whole_frame(tmp_path, name, codec, rotation):
    """Each read of a frame converted lazily (windows at odd places, sparse rows and grids, single rows and
    columns, a channel) is bit for bit that part of the frame PyAV converts whole, turned as shown."""
    path = encode_clip(tmp_path / name, colour_noise_frames(), codec=codec, rotation_deg=rotation or None)
    whole = plainly_converted(path, rotation)
    rng = np.random.default_rng(4)
    with VideoFile(path) as video, video.frames(lazy=True) as frames:
        for index, _, frame in frames:
            assert isinstance(frame, decode.LazyFrame) and frame.shape == whole[index].shape
            height, width = frame.shape[:2]
            windows = [np.s_[y:y + h, x:x + w] for y, x, h, w in zip(
                rng.integers(0, height, 60), rng.integers(0, width, 60), rng.integers(1, 60, 60), rng.integers(1, 60, 60))]
            for key in READS + windows:  # each read alone
                frame.release()
                assert np.array_equal(frame[key], whole[index][key]), key
            frame.release()
            for key in READS:  # in a row, as a tracker reads (a frame converted whole serves the later ones)
                assert np.array_equal(frame[key], whole[index][key]), key
            assert np.array_equal(np.asarray(frame), whole[index])


def test_frames_of_other_pixel_formats_are_converted_whole(tmp_path):
    """A 4:4:4 clip (no 2 × 2 chroma blocks) is handed out in whole frames, and tracked."""
    path = encode_clip(tmp_path / "full_chroma.mp4", colour_noise_frames(), pix_fmt="yuv444p")
    with VideoFile(path) as video, video.frames(lazy=True) as frames:
        images = [image for _, _, image in frames]
    assert all(isinstance(image, np.ndarray) for image in images)
    assert all(np.array_equal(image, expected) for image, expected in zip(images, plainly_converted(path, 0)))
    frames, centres = ball_frames(40)
    table = track_video(encode_clip(tmp_path / "ball444.mp4", frames, pix_fmt="yuv444p"))
    assert np.hypot(table["x_px"] - centres[:, 0], table["y_px"] - centres[:, 1]).max() < CENTRE_TOLERANCE_PX


OPEN_GOP = "open-gop=1:bframes=3:b-adapt=0:keyint=4:min-keyint=4:scenecut=0"


@pytest.mark.parametrize("name, irregular, x264_params", [("keys.mp4", False, None), ("keys.mp4", True, None),
                                                          ("keys.mov", True, OPEN_GOP), ("keys.mkv", False, None)],
                         ids=["regular", "irregular-timing", "open-gop", "matroska"])
def test_background_samples_are_the_frames_a_plain_decoding_gives(tmp_path, monkeypatch, name, irregular, x264_params):
    """Key frames reached by seeking, each decoded alone by a decoder of its own (never by the clip's, which
    decodes several frames for each after a seek), are the very frames, at the same times, that decoding the
    file in order gives, turned as the phone shows them. With irregular timing the index's key frame times
    miss the frames' own, and some samples are frames decoded after a later one (B-frames), which the decoder
    hands out only when drained; an open group of pictures starts with frames that refer to the group
    before (failed before: the clip's decoder took over); Matroska keeps its index at the file's end (failed
    before: 0 samples, the clip refused as corrupt)."""
    frames, _ = ball_frames(60, step_px=(2.0, 0.0), gravity_px=0.035)
    timing = {}
    if irregular:
        stamps = np.cumsum(np.random.default_rng(5).integers(2400, 3600, 60))
        timing = {"pts": stamps - stamps[0], "time_base": Fraction(1, 90000)}
    path = encode_clip(tmp_path / name, frames, gop=None if x264_params else 4, rotation_deg=270,
                       x264_params=x264_params, **timing)
    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        plain = {frame.pts * stream.time_base: np.rot90(frame.to_ndarray(format="bgr24"), k=-1)
                 for frame in container.decode(stream)}
    start = min(plain)
    with VideoFile(path) as video:
        monkeypatch.setattr(VideoFile, "_decoded", lambda self: pytest.fail("a sample decoded by the clip's decoder"))
        samples = video.samples(11)
    assert len(samples) == 11 and len({time_s for time_s, _ in samples}) == 11
    for time_s, image in samples:
        expected = plain[min(plain, key=lambda t: abs(float(t - start) - time_s))]
        assert np.array_equal(image, expected), time_s


def test_an_avi_whose_index_is_cut_off_gives_samples_over_the_whole_clip(tmp_path):
    """An AVI whose index (written last) was cut off: the demuxer knows one frame of it. The samples are
    frames spread over the clip (before: that one frame, a background with the ball in it), and the ball
    is tracked."""
    frames, centres = ball_frames(60, step_px=(2.0, 0.0), gravity_px=0.035)
    whole = encode_clip(tmp_path / "whole.avi", frames, codec="mjpeg").read_bytes()
    path = tmp_path / "cut.avi"
    path.write_bytes(whole[:whole.rfind(b"idx1")])
    with av.open(str(path)) as container:
        plain = [frame.to_ndarray(format="bgr24") for frame in container.decode(video=0)]
    with VideoFile(path) as video:
        samples = video.samples(11)
    assert len(samples) >= 11 and max(time_s for time_s, _ in samples) >= 1.5
    for time_s, image in samples:
        assert np.array_equal(image, plain[round(time_s * 30)]), time_s
    table = track_video(path)
    assert np.hypot(table["x_px"] - centres[:, 0], table["y_px"] - centres[:, 1]).max() < CENTRE_TOLERANCE_PX


def test_ball_in_the_background_is_tracked_again_from_memory(tmp_path, monkeypatch):
    """A ball in view and nearly still all clip long is in the first background; the further passes
    use frames kept whole, never the file; past the memory budget, crops about the ball serve the
    first contrast channel's passes, and another channel, tried when the first one measures too few
    frames cleanly, reads the file again."""
    frames, centres = ball_frames(45, step_px=(0.8, 0.0), gravity_px=0.0, start=(60.3, 40.2))
    path = encode_clip(tmp_path / "still.avi", frames, codec="mjpeg")
    opened = []
    real_open = av.open
    monkeypatch.setattr(av, "open", lambda *args, **kwargs: opened.append(args[0]) or real_open(*args, **kwargs))
    whole = track_video(path)
    assert len(opened) == 1
    cropped = track_video(path, frame_memory_bytes=2 * frames[0].nbytes)  # two frames whole, 45 crops
    # a channel after the first decodes the file for each of its passes (the background cleaned up to
    # MAX_BACKGROUND_REFINEMENTS times)
    assert len(opened) - 1 <= 1 + (len(CHANNELS) - 1) * (1 + MAX_BACKGROUND_REFINEMENTS)
    assert cropped.attrs["contrast"] == whole.attrs["contrast"]
    assert (whole["quality"] == cropped["quality"]).all()
    assert np.allclose(whole["x_px"], cropped["x_px"], atol=0.05, equal_nan=True)
    # crops over the budget too (a long clip of a large ball) are let go: every pass decodes the file again
    opened.clear()
    decoded = track_video(path, frame_memory_bytes=0)
    assert len(opened) >= 2
    assert (whole["quality"] == decoded["quality"]).all()
    assert np.allclose(whole["x_px"], decoded["x_px"], atol=0.05, equal_nan=True)
    ok = whole["quality"] == QUALITY_OK
    error = np.hypot(whole["x_px"] - centres[:, 0], whole["y_px"] - centres[:, 1])
    assert ok.any() and error[ok].max() < CENTRE_TOLERANCE_PX


def test_truncated_mp4_is_refused_in_one_line(tmp_path):
    path = encode_clip(tmp_path / "clip.mp4", marked_frames())
    data = path.read_bytes()
    path.write_bytes(data[: len(data) * 7 // 10])
    with pytest.raises(InputError, match="clip.mp4: cannot be opened as a video"):
        track_video(path)


def test_library_messages_stay_off_the_terminal(tmp_path):
    """No OpenCV backend warning (VIDEOIO) nor FFmpeg message on standard error while an .mp4 is tracked."""
    path = encode_clip(tmp_path / "clip.mp4", ball_frames(40)[0])
    (tmp_path / "damaged.avi").write_bytes(encode_clip(tmp_path / "m.avi", ball_frames(40)[0], codec="mjpeg")
                                           .read_bytes()[:30000])
    script = ("import sys; from dropfit.video.track import track_video; from dropfit.errors import InputError\n"
              "print(len(track_video(sys.argv[1])))\n"
              "try:\n    track_video(sys.argv[2])\nexcept InputError:\n    pass\n")
    result = subprocess.run([sys.executable, "-c", script, str(path), str(tmp_path / "damaged.avi")],
                            capture_output=True, text=True, timeout=CALL_TIMEOUT_S)
    # standard error is not a terminal here: each clip writes its one progress line, and nothing else
    assert (result.returncode, result.stdout.strip()) == (0, "40")
    assert result.stderr.startswith("clip.mp4: 40 frames in ") and without_progress(result.stderr) == [], result.stderr


class FakeTerminal(io.StringIO):
    def isatty(self):
        return True


def test_progress_updates_one_line_on_a_terminal_and_writes_one_line_to_a_log():
    now = [0.0]
    terminal = FakeTerminal()
    progress = Progress("clip.mp4", 1000, terminal, clock=lambda: now[0])
    for done in range(1, 1001):
        now[0] = done / 200.0  # 200 frames/s for 5 s
        progress.update(done)
    progress.finish(1000)
    text = terminal.getvalue()
    updates = text.split("\r")[1:-1]
    assert 10 <= len(updates) <= 5 / decode.PROGRESS_INTERVAL_S + 1 and "\n" not in "".join(updates)
    assert "500/1000 frames, 200 frames/s, 2 s left" in text or "501/1000 frames, 200 frames/s, 2 s left" in text
    assert text.endswith("clip.mp4: 1000 frames in 5.0 s (200 frames/s)\x1b[K\n")

    log = io.StringIO()
    progress = Progress("clip.mp4", 1000, log, clock=lambda: now[0])
    for done in range(1, 1001):
        progress.update(done)
    now[0] += 2.0
    progress.finish(1000)
    assert log.getvalue() == "clip.mp4: 1000 frames in 2.0 s (500 frames/s)\n"

    short = FakeTerminal()
    Progress("short.mp4", 40, short).finish(40)
    assert short.getvalue() == ""  # a short clip is quiet on a terminal
    short_log = io.StringIO()
    progress = Progress("short.mp4", 40, short_log, clock=lambda: now[0])
    now[0] += 0.5
    progress.finish(40)
    assert short_log.getvalue() == "short.mp4: 40 frames in 0.5 s (80 frames/s)\n"  # and has its line in a log
