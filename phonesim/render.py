"""Render a clip: the static scene once, then per capture only the ball's, shadows' and hand's region.

Time: the clip clock starts at the first nominal capture (0 s); the ball is
released at rest at ``config.hand.hold_s``.  A capture's time is the middle
of its exposure; the truth's ball centre is the ball's position then.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from fractions import Fraction
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np
import pandas as pd

from .camera import PlaneView
from .config import ClipConfig
from .encode import ClipWriter, constant_rate_container
from .motion import BallMotion
from .scene import render_static_scene
from .sprites import Capsule, ball_colour, disc_coverage, hand_coverage_and_colour, soft_ellipse
from .timing import FrameSchedule

#: Number of pre-drawn noise fields the sensor noise is cut from (a random one and offset per frame).
NOISE_FIELDS = 3
NOISE_MARGIN_PX = 16
#: The forearm reaches this far (m) from the palm: beyond the frame's edge.
ARM_LENGTH_M = 2.5
ARM_PIECES = 16
#: The blur averages about one sub-frame sample per this many px of the ball's motion during the exposure.
BLUR_STEP_PX = 1.0

CONVENTIONS = (
    "Pixels: x (column) right, y (row) down, in the DISPLAYED orientation (after the display rotation); "
    "pixel centres at integer coordinates, the top-left pixel's centre at (0, 0). Drop plane: X right, Y up "
    "(m), origin on the floor at the drop line. plane_to_px maps (X, Y, 1) to (x w, y w, w). Times in s on "
    "the clip clock (first nominal capture at 0); capture_time_s is the middle of the exposure. Heights: "
    "centre_height_m is the ball centre above the floor, bottom_height_m its lowest point (0 in contact). "
    "rotation_deg is counter-clockwise (PyAV's VideoFrame.rotation, mod 360)."
)


@dataclass
class Truth:
    """Ground truth of a rendered clip.

    Attributes
    ----------
    summary : dict
        Clip, timing, physics, camera and scale objects (what the JSON holds;
        see ``CONVENTIONS`` and the README).
    frames : pandas.DataFrame
        One row per written (displayed) frame: ``frame``, ``time_s``
        (presentation), ``pts`` (ticks), ``capture_index``,
        ``capture_time_s``, ``is_duplicate``, ``x_px``, ``y_px``,
        ``radius_px`` (ball centre and radius, displayed px), ``x_m``,
        ``centre_height_m``, ``bottom_height_m``, ``phase`` (refsim's:
        held, flight, contact, contact_free, caught, rest, ...),
        ``in_frame``, ``hand_visible``, ``occluded_fraction`` (of the ball's
        area under the hand), ``brightness_gain`` (flicker x exposure
        drift), ``blur_samples``.
    impacts : pandas.DataFrame
        refsim's impacts (``t_touchdown_s``, ``t_liftoff_s``, ``v_in_m_s``,
        ``v_out_m_s``, ``e`` = v_out/v_in, ``h_before_m``, ``h_after_m``, ...).
    sound : pandas.DataFrame or None
        With a sound track, one row per click (``impact``, 0 for a click that is not one;
        ``t_touchdown_s``; ``onset_s`` on the clip clock).
    """

    summary: dict
    frames: pd.DataFrame
    impacts: pd.DataFrame
    sound: pd.DataFrame | None = None

    def write(self, json_path: str | Path, csv_path: str | Path) -> None:
        """Write the summary (with the impacts) as JSON and the frames as CSV."""
        Path(json_path).write_text(json.dumps(self.summary, indent=1, default=_json_default))
        self.frames.to_csv(csv_path, index=False)


def _json_default(value):
    if isinstance(value, Fraction):
        return str(value)
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value)}")


def truth_paths(clip_path: str | Path) -> tuple[Path, Path]:
    """The truth files beside a clip: ``<stem>.truth.json`` and ``<stem>.frames.csv``."""
    clip_path = Path(clip_path)
    return clip_path.with_suffix(".truth.json"), clip_path.with_suffix(".frames.csv")


class ClipRenderer:
    """Draws the frames of one clip.

    Parameters
    ----------
    config : ClipConfig
        The clip.
    seed : int
        Seeds every random choice (room, jitter, drops, noise).
    constant_rate : bool
        Frames at consecutive ticks (AVI) instead of capture timestamps.
    """

    def __init__(self, config: ClipConfig, seed: int = 0, constant_rate: bool = False):
        self.config = config
        self.rng = np.random.default_rng(seed)
        self.motion = BallMotion(config)
        self.width_px, self.height_px = config.frame_size_px
        mid_height = config.drop_height_m / 2 + self.motion.radius_m
        self.view = PlaneView.build(config.camera, self.width_px, self.height_px, config.downscale, mid_height)
        self.schedule = FrameSchedule.build(config.timing, self.motion.duration_s, constant_rate, self.rng)
        scene = render_static_scene(config, self.view, self.rng)
        self.objects = scene.objects
        self.floor_mask = scene.floor_mask
        self.vignette = self._vignette()
        self.static = np.clip(scene.image * self.vignette[:, :, None] + 0.5, 0, 255).astype(np.uint8)
        self.noise = self._noise_fields()
        self.captures = self.motion.sample(np.unique(self.schedule.capture_time_s))

    # -- set-up ---------------------------------------------------------------------------
    def _vignette(self) -> np.ndarray:
        ys = (np.arange(self.height_px, dtype=np.float32) - (self.height_px - 1) / 2) / (self.height_px / 2)
        xs = (np.arange(self.width_px, dtype=np.float32) - (self.width_px - 1) / 2) / (self.width_px / 2)
        r2 = (xs[None, :] ** 2 + ys[:, None] ** 2) / 2.0
        return 1.0 - self.config.sensor.vignetting * r2

    def _noise_fields(self) -> np.ndarray | None:
        sd = self.config.sensor.noise_sd_dn
        if sd <= 0:
            return None
        shape = (NOISE_FIELDS, self.height_px + NOISE_MARGIN_PX, self.width_px + NOISE_MARGIN_PX, 3)
        noise = self.rng.standard_normal(shape, dtype=np.float32) * sd + 128.0
        return np.clip(noise + 0.5, 0, 255).astype(np.uint8)

    def brightness_gain(self, t_s: float) -> float:
        """Relative brightness of the capture at ``t_s`` (s): mains flicker averaged over the exposure, times the exposure drift."""
        sensor = self.config.sensor
        gain = 1.0
        if sensor.flicker > 0:
            omega = 2 * math.pi * 2 * sensor.mains_hz
            exposure = self.config.timing.exposure_s
            if exposure > 0:
                mean_cos = (math.sin(omega * (t_s + exposure / 2)) - math.sin(omega * (t_s - exposure / 2))) / (
                    omega * exposure)
            else:
                mean_cos = math.cos(omega * t_s)
            gain *= 1.0 + sensor.flicker * mean_cos
        if sensor.exposure_drift > 0:
            gain *= 1.0 + sensor.exposure_drift * math.sin(2 * math.pi * t_s / sensor.exposure_drift_period_s + 0.7)
        return gain

    # -- per capture -----------------------------------------------------------------------
    def _ball_px(self, x_m, y_m):
        cx, cy = self.view.to_px(x_m, y_m)
        return cx, cy, self.motion.radius_m * self.view.local_scale_px_per_m(x_m, y_m)

    def _blur_times(self, t_s: float) -> np.ndarray:
        exposure = self.config.timing.exposure_s
        if exposure <= 0:
            return np.array([t_s])
        x, y, _ = self.motion.interpolated(np.array([t_s - exposure / 2, t_s, t_s + exposure / 2]))
        px, py, _ = self._ball_px(x, y)
        travel = np.hypot(np.diff(px), np.diff(py)).sum()
        n = int(np.clip(math.ceil(travel / BLUR_STEP_PX) + 1, 1, self.config.timing.max_blur_samples))
        return t_s + exposure * ((np.arange(n) + 0.5) / n - 0.5)

    def _draw_ball(self, frame: np.ndarray, t_s: float) -> int:
        """Composite the ball and its shadows, averaged over the exposure, into ``frame``; returns the sample count."""
        scene = self.config.scene
        times = self._blur_times(t_s)
        x_m, y_m, angle = self.motion.interpolated(times)
        cx, cy, radius = self._ball_px(x_m, y_m)
        _, floor_y = self.view.to_px(x_m, np.zeros_like(x_m))
        height_m = np.maximum(y_m - self.motion.radius_m, 0.0)
        wall_dx, wall_dy = scene.wall_shadow_offset_r
        wall_soft = scene.wall_shadow_softness_r * radius
        floor_strength = scene.floor_shadow * np.exp(-height_m / scene.floor_shadow_fade_m)
        floor_semi_x = radius * (1.0 + height_m / 0.5)
        floor_semi_y = 0.3 * radius * (1.0 + height_m / 0.5)
        floor_soft = radius * (0.15 + height_m / scene.floor_shadow_fade_m * 0.3)
        reach = radius + 2.0
        if scene.wall_shadow > 0:
            reach = np.maximum(reach, radius * (1.0 + max(abs(wall_dx), abs(wall_dy))) + 4 * wall_soft)
        x0, x1 = (cx - reach).min(), (cx + reach).max()
        y0, y1 = (cy - reach).min(), (cy + reach).max()
        floor_on = floor_strength > 0.01
        if floor_on.any():
            x0 = min(x0, (cx - floor_semi_x - 4 * floor_soft)[floor_on].min())
            x1 = max(x1, (cx + floor_semi_x + 4 * floor_soft)[floor_on].max())
            y1 = max(y1, (floor_y + floor_semi_y + 4 * floor_soft)[floor_on].max())
        x0, y0 = max(int(math.floor(x0)), 0), max(int(math.floor(y0)), 0)
        x1, y1 = min(int(math.ceil(x1)) + 1, self.width_px), min(int(math.ceil(y1)) + 1, self.height_px)
        if x0 >= x1 or y0 >= y1:
            return len(times)
        cols = np.arange(x0, x1, dtype=np.float32)
        rows = np.arange(y0, y1, dtype=np.float32)
        background = self.static[y0:y1, x0:x1].astype(np.float32)
        vignette = self.vignette[y0:y1, x0:x1, None]
        on_floor = self.floor_mask[y0:y1, x0:x1]
        # the soft shadows hardly change within an exposure: averaged over at most 4 of the samples
        shadow = np.zeros(background.shape[:2], np.float32)
        shadow_samples = np.unique(np.linspace(0, len(times) - 1, min(len(times), 4)).round().astype(int))
        for k in shadow_samples:
            sample = np.zeros_like(shadow)
            if scene.wall_shadow > 0:
                wall = soft_ellipse(cols, rows, cx[k] + wall_dx * radius[k], cy[k] + wall_dy * radius[k],
                                    radius[k], radius[k], wall_soft[k])
                sample = np.where(on_floor, 0.0, scene.wall_shadow * wall)
            if floor_on[k]:
                ellipse = soft_ellipse(cols, rows, cx[k], floor_y[k] + 0.1 * radius[k], floor_semi_x[k],
                                       floor_semi_y[k], floor_soft[k])
                sample = np.where(on_floor, np.maximum(sample, floor_strength[k] * ellipse), sample)
            shadow += sample / len(shadow_samples)
        layer = background * (1.0 - shadow)[:, :, None]
        # the mean over samples of layer + coverage (colour - layer): only the balls' boxes differ from layer
        total = layer * len(times)
        for k in range(len(times)):
            bx0 = max(int(math.floor(cx[k] - radius[k])) - 1 - x0, 0)
            bx1 = max(min(int(math.ceil(cx[k] + radius[k])) + 2 - x0, x1 - x0), bx0)
            by0 = max(int(math.floor(cy[k] - radius[k])) - 1 - y0, 0)
            by1 = max(min(int(math.ceil(cy[k] + radius[k])) + 2 - y0, y1 - y0), by0)
            box_cols, box_rows = cols[bx0:bx1], rows[by0:by1]
            coverage = disc_coverage(box_cols, box_rows, cx[k], cy[k], radius[k])[:, :, None]
            colour = ball_colour(box_cols, box_rows, cx[k], cy[k], radius[k], self.config.ball, angle[k])
            box = layer[by0:by1, bx0:bx1]
            total[by0:by1, bx0:bx1] += coverage * (colour * vignette[by0:by1, bx0:bx1] - box)
        frame[y0:y1, x0:x1] = np.clip(total / len(times) + 0.5, 0, 255).astype(np.uint8)
        return len(times)

    def hand_capsules(self, t_s: float) -> list[Capsule]:
        """The hand (palm, thumb, three fingers, forearm to beyond the frame) at ``t_s`` (s), in displayed px."""
        grip_x, grip_y, opening = self.motion.hand_pose(t_s)
        r = self.motion.radius_m
        scale = float(self.view.local_scale_px_per_m(grip_x, grip_y))
        palm_y = grip_y + r + 0.03
        angle = math.radians(self.config.hand.arm_angle_deg)
        arm_end = (grip_x + ARM_LENGTH_M * math.cos(angle), palm_y + ARM_LENGTH_M * math.sin(angle))
        limbs = [((grip_x - 0.03, palm_y), (grip_x + 0.03, palm_y), 0.032),
                 ((grip_x - 0.035, palm_y - 0.01), (grip_x - r - 0.006 - 0.03 * opening, grip_y + 0.1 * r), 0.011),
                 ]
        # the forearm as a chain of short capsules: each is evaluated in its own small box
        for k in range(ARM_PIECES):
            a, b = k / ARM_PIECES, (k + 1) / ARM_PIECES
            limbs.append(((grip_x + a * (arm_end[0] - grip_x), palm_y + a * (arm_end[1] - palm_y)),
                          (grip_x + b * (arm_end[0] - grip_x), palm_y + b * (arm_end[1] - palm_y)), 0.034))
        for i in range(3):
            limbs.append(((grip_x + 0.01 + 0.012 * i, palm_y - 0.01),
                          (grip_x + r + 0.004 + 0.03 * opening, grip_y + (0.4 - 0.35 * i) * r), 0.0085))
        capsules = []
        for (ax, ay), (bx, by), radius_m in limbs:
            (pax, pbx), (pay, pby) = self.view.to_px(np.array([ax, bx]), np.array([ay, by]))
            capsules.append(Capsule(float(pax), float(pay), float(pbx), float(pby), radius_m * scale))
        return capsules

    def _draw_hand(self, frame: np.ndarray, t_s: float, ball_px: tuple[float, float, float]) -> tuple[bool, float]:
        """Composite the hand into ``frame``; returns whether it shows and the ball's occluded fraction."""
        capsules = self.hand_capsules(t_s)
        boxes = np.array([c.bounds() for c in capsules])
        x0, y0 = max(int(boxes[:, 0].min()), 0), max(int(boxes[:, 1].min()), 0)
        x1 = min(int(math.ceil(boxes[:, 2].max())) + 1, self.width_px)
        y1 = min(int(math.ceil(boxes[:, 3].max())) + 1, self.height_px)
        if x0 >= x1 or y0 >= y1:
            return False, 0.0
        cols = np.arange(x0, x1, dtype=np.float32)
        rows = np.arange(y0, y1, dtype=np.float32)
        coverage, colour = hand_coverage_and_colour(capsules, cols, rows, self.config.hand.skin_rgb)
        if not coverage.any():
            return False, 0.0
        region = frame[y0:y1, x0:x1].astype(np.float32)
        colour *= self.vignette[y0:y1, x0:x1, None]
        frame[y0:y1, x0:x1] = np.clip(region + coverage[:, :, None] * (colour - region) + 0.5, 0, 255).astype(np.uint8)
        ball = disc_coverage(cols, rows, *ball_px)
        ball_area = math.pi * ball_px[2] ** 2
        return True, float((ball * coverage).sum() / ball_area)

    def _sensor(self, frame: np.ndarray, gain: float) -> np.ndarray:
        if self.noise is None:
            return frame if gain == 1.0 else cv2.convertScaleAbs(frame, alpha=gain)
        field = self.noise[self.rng.integers(NOISE_FIELDS)]
        dy, dx = self.rng.integers(0, NOISE_MARGIN_PX, 2)
        noise = field[dy:dy + self.height_px, dx:dx + self.width_px]
        return cv2.addWeighted(frame, gain, noise, 1.0, -128.0)

    def frames(self) -> Iterator[tuple[dict, np.ndarray]]:
        """Yield (truth row, displayed uint8 RGB frame) for every written frame; repeats yield the same array."""
        schedule = self.schedule
        captures = self.captures.set_index(self.captures["t_s"].to_numpy())
        hand_visible_until = self.motion.release_time_s + self.config.hand.away_s
        catch_time = self.motion.catch_time_s
        picture = None
        row: dict = {}
        canvas = np.empty_like(self.static)
        for frame_index in range(schedule.pts.size):
            t_s = float(schedule.capture_time_s[frame_index])
            if not schedule.is_duplicate[frame_index] or picture is None:
                state = captures.loc[t_s]
                cx, cy, radius = (float(v) for v in self._ball_px(state["x_m"], state["y_centre_m"]))
                np.copyto(canvas, self.static)
                samples = self._draw_ball(canvas, t_s)
                hand_shown, occluded = False, 0.0
                hand_due = (self.config.hand.visible_at_release and t_s <= hand_visible_until) or (
                    not math.isnan(catch_time) and t_s >= catch_time - self.config.hand.catch_approach_s)
                if self.config.hand.visible and hand_due:
                    hand_shown, occluded = self._draw_hand(canvas, t_s, (cx, cy, radius))
                gain = self.brightness_gain(t_s)
                picture = self._sensor(canvas, gain)
                row = {"capture_index": int(schedule.capture_index[frame_index]), "capture_time_s": t_s,
                       "x_px": cx, "y_px": cy, "radius_px": radius, "x_m": float(state["x_m"]),
                       "centre_height_m": float(state["y_centre_m"]), "bottom_height_m": float(state["y_bottom_m"]),
                       "phase": state["phase"],
                       "in_frame": bool(0 <= cx <= self.width_px - 1 and 0 <= cy <= self.height_px - 1),
                       "hand_visible": hand_shown, "occluded_fraction": occluded, "brightness_gain": gain,
                       "blur_samples": samples}
            yield {"frame": frame_index, "time_s": float(schedule.time_s[frame_index]),
                   "pts": int(schedule.pts[frame_index]), "is_duplicate": bool(schedule.is_duplicate[frame_index]),
                   **row}, picture

    def summary(self, frame_count: int) -> dict:
        """The JSON truth (without the per-frame table)."""
        config, motion, view, schedule = self.config, self.motion, self.view, self.schedule
        truth = motion.truth
        floor_x, floor_y = view.to_px(0.0, 0.0)
        release_y = truth.y_release_centre_m
        flights = truth.flights
        apexes = flights[flights["apex_is_turning_point"].astype(bool)]
        impacts = truth.impacts[["impact", "t_touchdown_s", "t_liftoff_s", "v_in_m_s", "v_out_m_s", "e",
                                 "h_before_m", "h_after_m"]]
        return {
            "conventions": CONVENTIONS,
            "clip": {"width_px": self.width_px, "height_px": self.height_px, "rotation_deg": config.rotation_deg % 360,
                     "frame_count": frame_count, "capture_fps": schedule.capture_fps,
                     "capture_fps_hz": float(schedule.capture_fps), "container_fps": schedule.container_fps,
                     "container_fps_hz": float(schedule.container_fps), "time_base_s": schedule.time_base,
                     "frames_per_capture": config.timing.frames_per_capture, "duration_s": motion.duration_s,
                     "exposure_s": config.timing.exposure_s},
            "physics": {"g_m_s2": config.g_m_s2, "ball_model": config.ball.model, "radius_m": motion.radius_m,
                        "mass_kg": truth.mass_kg, "drag_k_1_m": truth.drag_k_1_m,
                        "drop_height_m": config.drop_height_m, "release_time_s": motion.release_time_s,
                        "release_centre_height_m": release_y, "catch_time_s": motion.catch_time_s,
                        "rest_time_s": float(truth.rest_time_s),
                        "impacts": impacts.to_dict(orient="records"),
                        "apexes": [{"t_apex_s": float(r.t_apex_s), "bottom_height_m": float(r.h_apex_m),
                                    "centre_height_m": float(r.y_apex_centre_m)} for r in apexes.itertuples()]},
            "camera": {"plane_to_px": view.plane_to_px.tolist(), "tilted": config.camera.tilted,
                       "pitch_deg": config.camera.pitch_deg, "yaw_deg": config.camera.yaw_deg,
                       "roll_deg": config.camera.roll_deg, "nominal_scale_px_per_m": view.scale_px_per_m,
                       "scale_px_per_m_at_floor": float(view.local_scale_px_per_m(0.0, 0.0)),
                       "scale_px_per_m_at_release": float(view.local_scale_px_per_m(0.0, release_y)),
                       "vertical_px_per_m_at_drop_line": list(view.direction_px_per_m(0.0, 0.0, 0.0, 1.0)),
                       "floor_px_at_drop_line": [float(floor_x), float(floor_y)],
                       "floor_row_px": float(floor_y)},
            "objects": self.objects,
            "config": asdict(config),
        }


def iter_frames(config: ClipConfig, seed: int = 0) -> Iterator[tuple[dict, np.ndarray]]:
    """Render without encoding: yield (truth row, displayed uint8 RGB frame) per written frame."""
    yield from ClipRenderer(config, seed).frames()


def render_clip(config: ClipConfig, path: str | Path, seed: int = 0, sound=None) -> Truth:
    """Render ``config`` into the video ``path`` and write the truth beside it.

    Frames are streamed to the encoder one by one (memory does not grow with
    the clip's length).  The container follows the suffix (.mp4/.mov/.mkv:
    timestamps per frame and a display matrix; .avi: constant rate, no
    rotation).  Writes ``<stem>.truth.json`` and ``<stem>.frames.csv`` too.
    With ``sound`` (:class:`phonesim.sound.SoundTrack`) a sound track is muxed in: a click at each
    contact (:mod:`phonesim.sound`), its clicks' truth in the JSON's ``sound`` and in ``Truth.sound``.

    Returns
    -------
    Truth
    """
    renderer = ClipRenderer(config, seed, constant_rate=constant_rate_container(path))
    rows = []
    width, height = config.frame_size_px
    clicks = track = None
    if sound is not None:
        from .sound import render_track

        samples, clicks = render_track(renderer.motion.truth.impacts, renderer.motion.duration_s, sound, seed,
                                       config.timing.slow_motion)
        track = (sound, samples)
    with ClipWriter(path, width, height, config.rotation_deg, renderer.schedule.container_fps,
                    renderer.schedule.time_base, config.codec, config.crf, config.encoder_preset,
                    config.bit_depth, track) as writer:
        for row, picture in renderer.frames():
            writer.write(picture, row["pts"])
            rows.append(row)
    frames = pd.DataFrame(rows)
    truth = Truth(renderer.summary(len(frames)), frames, renderer.motion.truth.impacts.copy(), clicks)
    if clicks is not None:
        truth.summary["sound"] = {"offset_s": sound.offset_s, "codec": sound.codec, "rate_hz": sound.rate_hz,
                                  "missed_impacts": list(sound.missed_impacts), "silent": sound.silent,
                                  "clicks": clicks.to_dict(orient="records")}
    truth.summary["clip"]["path"] = Path(path).name
    truth.write(*truth_paths(path))
    return truth
