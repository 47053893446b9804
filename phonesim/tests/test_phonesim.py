"""phonesim: written files, timing, and the truth against what is drawn."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import replace
from fractions import Fraction

import av
import cv2
import numpy as np
import pandas as pd
import pytest

import phonesim
from phonesim.camera import PlaneView, displayed_from_stored
from phonesim.config import FrameTiming
from phonesim.encode import ClipWriter
from phonesim.render import iter_frames
from phonesim.scene import render_static_scene
from phonesim.timing import FrameSchedule


def static_scene(config):
    width, height = config.frame_size_px
    view = PlaneView.build(config.camera, width, height, config.downscale, config.drop_height_m / 2)
    return view, render_static_scene(config, view, np.random.default_rng(0))


def decode(path):
    """Displayed RGB frames, presentation times (s) and rotations read back with PyAV."""
    frames, times, rotations = [], [], []
    with av.open(str(path)) as container:
        for frame in container.decode(video=0):
            rotations.append(frame.rotation % 360)
            times.append(float(frame.time))
            frames.append(displayed_from_stored(frame.to_ndarray(format="rgb24"), frame.rotation % 360))
    return frames, np.array(times), rotations


def yellow_centroid(picture, truth_row, window_r=3.0):
    """Centroid of the yellow ball by a colour mask (red minus blue) in a window around the truth."""
    r = truth_row["radius_px"]
    x0, y0 = int(truth_row["x_px"] - window_r * r), int(truth_row["y_px"] - window_r * r)
    patch = picture[max(y0, 0):y0 + int(2 * window_r * r), max(x0, 0):x0 + int(2 * window_r * r)].astype(float)
    chroma = patch[:, :, 0] - patch[:, :, 2]
    mask = chroma > 0.5 * chroma.max()
    ys, xs = np.nonzero(mask)
    return xs.mean() + max(x0, 0), ys.mean() + max(y0, 0)


@pytest.fixture(scope="module")
def pingpong_clip(tmp_path_factory):
    config = replace(phonesim.PRESETS["white_pingpong_mov"].scaled(0.2), duration_s=2.2)
    path = tmp_path_factory.mktemp("clips") / "pingpong.mov"
    return config, path, phonesim.render_clip(config, path, seed=1)


def test_mov_decodes_with_rotation_timestamps_and_repeats(pingpong_clip):
    config, path, truth = pingpong_clip
    frames, times, rotations = decode(path)
    table = truth.frames
    assert len(frames) == len(table) == int(round(2.2 * 30)) * 2 + 2
    assert set(rotations) == {270}
    width, height = config.frame_size_px
    assert frames[0].shape == (height, width, 3)
    np.testing.assert_allclose(times, table["time_s"], atol=1e-6)
    assert table["is_duplicate"].tolist() == [False, True] * (len(table) // 2)
    # every other frame repeats the capture before it: same capture time, the same picture encoded again
    # (H.264 does not keep a repeat bit-exact: it differs by the quantisation only)
    for k in np.flatnonzero(table["is_duplicate"]):
        assert table["capture_time_s"][k] == table["capture_time_s"][k - 1]
        assert np.abs(frames[k].astype(int) - frames[k - 1]).mean() < 0.5
    capture = cv2.VideoCapture(str(path))
    ok, bgr = capture.read()
    assert ok and bgr.shape == (height, width, 3)  # OpenCV turns it upright too
    summary = json.loads(path.with_suffix(".truth.json").read_text())
    assert summary["clip"]["rotation_deg"] == 270
    assert Fraction(summary["clip"]["container_fps"]) == 60
    assert len(pd.read_csv(path.with_suffix(".frames.csv"))) == len(table)


def test_impacts_e_is_v_out_over_v_in(pingpong_clip):
    _, path, truth = pingpong_clip
    impacts = json.loads(path.with_suffix(".truth.json").read_text())["physics"]["impacts"]
    assert len(impacts) >= 3
    for impact in impacts:
        assert impact["e"] == pytest.approx(impact["v_out_m_s"] / impact["v_in_m_s"], rel=1e-12)
    released = truth.frames[truth.frames["capture_time_s"] < 1.5]
    assert (released["phase"] == "held").all() and released["hand_visible"].all()


def test_clean_ball_centroid_matches_truth_and_decoded_orientation(tmp_path):
    config = replace(phonesim.PRESETS["yellow_flicker_portrait"].clean().scaled(0.6), duration_s=2.0, crf=4)
    checked = 0
    pictures = {}
    for row, picture in iter_frames(config, seed=0):
        flying = row["phase"] == "flight" and row["bottom_height_m"] > 0.2 and row["occluded_fraction"] == 0
        if flying and not row["hand_visible"]:
            x, y = yellow_centroid(picture, row)
            assert abs(x - row["x_px"]) < 0.2 and abs(y - row["y_px"]) < 0.2
            checked += 1
            pictures[row["frame"]] = row
    assert checked >= 3
    path = tmp_path / "portrait.mp4"
    truth = phonesim.render_clip(config, path, seed=0)
    frames, _, rotations = decode(path)
    assert set(rotations) == {270}
    frame_index = max(pictures)
    x, y = yellow_centroid(frames[frame_index], truth.frames.iloc[frame_index])
    assert abs(x - truth.frames["x_px"][frame_index]) < 0.5 and abs(y - truth.frames["y_px"][frame_index]) < 0.5


def test_avi_constant_rate_29_97(tmp_path):
    config = replace(phonesim.PRESETS["green_board_avi"].scaled(0.15), duration_s=1.0)
    truth = phonesim.render_clip(config, tmp_path / "board.avi", seed=2)
    frames, times, rotations = decode(tmp_path / "board.avi")
    assert len(frames) == len(truth.frames) == 30
    assert set(rotations) == {0}
    np.testing.assert_allclose(np.diff(times), 1001 / 30000, rtol=1e-9)


def test_schedule_jitter_drops_and_repeats():
    timing = FrameTiming(capture_fps=Fraction(240), pts_jitter_s=3e-4, drop_probability=0.05, frames_per_capture=2)
    schedule = FrameSchedule.build(timing, 2.0, constant_rate=False, rng=np.random.default_rng(3))
    assert np.all(np.diff(schedule.pts) > 0)
    captures = schedule.capture_index[~schedule.is_duplicate]
    assert np.any(np.diff(captures) > 1)  # some captures were dropped
    jitter = schedule.capture_time_s[~schedule.is_duplicate] - captures / 240
    assert 1e-4 < jitter.std() < 5e-4
    assert schedule.container_fps == 480


def test_ruler_ticks_sit_on_whole_rows_at_the_scale():
    config = phonesim.PRESETS["yellow_flicker_portrait"].clean()
    view, scene = static_scene(config)
    ruler = config.rulers[0]
    info = scene.objects["rulers"][0]
    zero_x, zero_y = info["zero_px"]
    assert info["direction_px_per_m"] == pytest.approx([0.0, -view.scale_px_per_m], abs=1e-3)
    column = scene.image[:, int(round(zero_x)) + 1].sum(axis=1)
    dark_rows = set(np.flatnonzero(column < 150).tolist())
    expected = {int(round(zero_y - view.scale_px_per_m * mm * 1e-3))
                for mm in range(0, int(ruler.length_m * 1000) + 1, 5)}
    assert dark_rows == expected
    cm_rows = np.array(sorted(r for r in expected))[::2]
    assert set(np.diff(cm_rows).tolist()) == {4, 5}


def test_aruco_markers_are_found_where_the_truth_says():
    config = phonesim.PRESETS["tennis_aruco_tilted"].clean().scaled(0.5)
    view, scene = static_scene(config)
    image = np.clip(scene.image + 0.5, 0, 255).astype(np.uint8)
    grey = cv2.cvtColor(image, cv2.COLOR_RGB2GRAY)
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_4X4_50), parameters)
    corners, ids, _ = detector.detectMarkers(grey)
    assert ids is not None and sorted(ids.ravel().tolist()) == [0, 1, 2, 3]
    truth = {m["id"]: np.array(m["corners_px"]) for m in scene.objects["markers"]}
    detected, planar = [], []
    for marker_id, found in zip(ids.ravel(), corners):
        found = found.reshape(4, 2)
        assert np.abs(found - truth[marker_id]).max() < 0.5  # the detector's sub-pixel refinement errs ~0.3 px
        marker = next(m for m in config.markers if m.marker_id == marker_id)
        side_px = np.linalg.norm(np.diff(np.vstack([found, found[:1]]), axis=0), axis=1).mean()
        assert side_px == pytest.approx(marker.side_m * view.local_scale_px_per_m(*marker.centre_m), rel=0.02)
        detected.append(found)
        planar.append(phonesim.scene.marker_corners_m(marker))
    # the markers reveal the tilt: their homography is the truth's
    homography, _ = cv2.findHomography(np.vstack(planar), np.vstack(detected))
    probe = np.array([[0.0, 0.0], [0.0, 0.8], [0.3, 0.4]])
    got = cv2.perspectiveTransform(probe[None], homography)[0]
    want = np.column_stack(view.to_px(probe[:, 0], probe[:, 1]))
    assert np.abs(got - want).max() < 1.0


def test_rendered_repeats_are_pixel_identical():
    config = replace(phonesim.PRESETS["white_pingpong_mov"].scaled(0.1), duration_s=0.4)
    previous = None
    for row, picture in iter_frames(config, seed=0):
        if row["is_duplicate"]:
            assert np.array_equal(picture, previous)
        previous = picture.copy()


@pytest.mark.parametrize("name", sorted(phonesim.PRESETS))
def test_every_preset_renders(name):
    config = replace(phonesim.PRESETS[name].scaled(0.1), duration_s=0.3)
    rows = [row for row, _ in iter_frames(config, seed=0)]
    assert rows and all(np.isfinite(row["x_px"]) for row in rows)


_ENCODE_SCRIPT = """
import sys
from dataclasses import replace
import phonesim
config = replace(phonesim.PRESETS["red_blur_portrait"].scaled(0.25), duration_s=1.5)
phonesim.render_clip(config, sys.argv[1], seed=0)
"""


def test_an_h264_encode_does_not_depend_on_leftover_memory(tmp_path):
    # glibc fills fresh allocations with MALLOC_PERTURB_'s byte: an encoder that reads memory it never
    # wrote writes different files in the two runs (x264's macroblock tree did, 1 CI run in ~5)
    written = []
    for fill in ("85", "170"):
        path = tmp_path / f"clip_{fill}.mp4"
        env = dict(os.environ, MALLOC_PERTURB_=fill)
        subprocess.run([sys.executable, "-c", _ENCODE_SCRIPT, str(path)], env=env, check=True)
        written.append(path.read_bytes())
    assert written[0] == written[1]


def test_an_hevc_10_bit_mov_is_stored_as_a_phone_stores_it(tmp_path):
    """A phone's HDR video: HEVC Main 10 (10 bits a sample), tagged hvc1, in a MOV with its display rotation; the
    frames decode to the picture drawn (the clean clip's ball: its colour centroid within 0.5 px of the truth), and
    encoding the same seed twice writes the same file (one frame thread, no cu-tree)."""
    config = replace(phonesim.PRESETS["yellow_flicker_portrait_120"].clean().scaled(0.3), duration_s=2.0, crf=4,
                     codec="libx265", bit_depth=10)
    written = []
    for name in ("a.mov", "b.mov"):
        truth = phonesim.render_clip(config, tmp_path / name, seed=2)
        written.append((tmp_path / name).read_bytes())
    assert written[0] == written[1]
    with av.open(str(tmp_path / "a.mov")) as container:
        stream = container.streams.video[0]
        assert (stream.codec_context.name, stream.codec_context.codec_tag) == ("hevc", "hvc1")
        assert stream.codec_context.pix_fmt == "yuv420p10le"
    frames, _, rotations = decode(tmp_path / "a.mov")
    assert set(rotations) == {config.rotation_deg % 360}
    rows = truth.frames
    clear = rows["in_frame"] & ~rows["hand_visible"] & (rows["occluded_fraction"] == 0)
    visible = rows[(rows["phase"] == "flight") & clear]
    row = visible.iloc[len(visible) // 2]
    x, y = yellow_centroid(frames[int(row["frame"])], row)
    assert np.hypot(x - row["x_px"], y - row["y_px"]) < 0.5


def test_ten_bits_are_refused_without_hevc(tmp_path):
    with pytest.raises(ValueError, match="10 bits need libx265"):
        ClipWriter(tmp_path / "clip.mp4", 64, 64, 0, Fraction(30), Fraction(1, 30), codec="libx264", bit_depth=10)


def test_sound_track_clicks_at_the_contacts(tmp_path):
    """A clip with a PCM sound track: the audio stream decodes to the clip's length, each click's onset is
    the touchdown plus the offset and the travel to the microphone, the sound is loud just after each onset
    and quiet just before it; a missed impact has no click; a silent track holds noise only."""
    import av
    from dataclasses import replace as replaced

    from phonesim import PRESETS, SoundTrack, render_clip

    base = PRESETS["yellow_green_tape"]
    config = replaced(base.scaled(0.1), duration_s=2.0, drop_height_m=0.4, hand=replaced(base.hand, hold_s=0.3))
    for track in (SoundTrack(offset_s=0.05, codec="pcm_s16le", missed_impacts=(2,)),
                  SoundTrack(codec="pcm_s16le", silent=True)):
        path = tmp_path / "clip.mov"
        truth = render_clip(config, path, seed=1, sound=track)
        with av.open(str(path)) as container:
            stream = container.streams.audio[0]
            samples = np.concatenate([frame.to_ndarray().reshape(-1) for frame in container.decode(stream)])
        samples = samples / 32768.0
        assert samples.size == pytest.approx(2.0 * track.rate_hz, abs=track.rate_hz * 0.01)
        if track.silent:
            assert truth.sound.empty and np.max(np.abs(samples)) < 0.1
            continue
        assert 2 not in set(truth.sound["impact"])
        expected = truth.sound["t_touchdown_s"] + 0.05 + track.options.mic_distance_m / 343.0
        assert np.allclose(truth.sound["onset_s"], expected)
        touchdowns = dict(zip(truth.impacts["impact"], truth.impacts["t_touchdown_s"]))
        assert np.allclose(truth.sound["t_touchdown_s"], [touchdowns[n] for n in truth.sound["impact"]])
        for onset in truth.sound["onset_s"]:
            at = int(onset * track.rate_hz)
            before = np.abs(samples[at - 400:at - 10]).max()
            after = np.abs(samples[at:at + 400]).max()
            assert after > 5 * before
