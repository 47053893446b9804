"""Named clip configurations reproducing drop-test clips users sent (full resolution).

Render one small with ``PRESETS[name].scaled(0.25)``.
"""

from __future__ import annotations

from dataclasses import replace
from fractions import Fraction

from .config import (BallStyle, CameraSetup, ClipConfig, FrameTiming, HandStyle, Marker, Ruler, SceneStyle,
                     SensorEffects)

#: The container format each preset was described with (``python -m phonesim`` follows the path given).
PRESET_SUFFIX: dict[str, str] = {}


def _yellow_flicker_portrait(capture_fps: Fraction) -> ClipConfig:
    return ClipConfig(
        width_px=720, height_px=1280, rotation_deg=270, drop_height_m=1.2,
        ball=BallStyle("tennis", colour_rgb=(232, 200, 40), ambient=0.7),
        # a grey wall a few levels below the ball's luminance (about 191) but far from it in colour
        scene=SceneStyle(wall_rgb=(186, 186, 186), wall_texture=0.015, floor="wood", wall_shadow=0.25),
        hand=HandStyle(hold_s=1.0, arm_angle_deg=80.0),
        camera=CameraSetup(scale_px_per_m=450.0, drop_column_frac=0.55, floor_row_frac=0.92),
        timing=FrameTiming(capture_fps=capture_fps, exposure_s=min(1 / 250, 0.5 / float(capture_fps)),
                           pts_jitter_s=2e-4),
        sensor=SensorEffects(noise_sd_dn=2.5, flicker=0.12, mains_hz=50.0),
        rulers=(Ruler("ruler", 0.3, 0.03, zero_m=(-0.3, 0.0), colour_rgb=(225, 200, 140), ticks_on_rows=True),),
    )


def _door(ball: BallStyle, exposure_s: float) -> ClipConfig:
    """A small phone clip, 314 x 486 at 20 fps exposed ``exposure_s``, of ``ball`` dropped from a hand before a dark
    wooden door."""
    return ClipConfig(
        width_px=314, height_px=486, drop_height_m=0.9, ball=ball,
        scene=SceneStyle(wall_rgb=(72, 52, 38), wall_texture=0.05, floor="wood", floor_rgb=(150, 110, 70),
                         wall_shadow=0.3),
        hand=HandStyle(hold_s=1.0, arm_angle_deg=70.0),
        camera=CameraSetup(scale_px_per_m=450.0, drop_column_frac=0.5, floor_row_frac=0.9),
        timing=FrameTiming(capture_fps=Fraction(20), exposure_s=exposure_s, pts_jitter_s=5e-4),
        sensor=SensorEffects(noise_sd_dn=3.0),
    )


PRESETS: dict[str, ClipConfig] = {
    "green_board_avi": ClipConfig(
        width_px=1920, height_px=1080, codec="mpeg4", drop_height_m=1.25,
        ball=BallStyle("tennis", radius_m=0.056, colour_rgb=(50, 165, 70), ambient=0.55),
        scene=SceneStyle(wall_rgb=(210, 208, 200), board=True, floor="wood", wall_shadow=0.4,
                         wall_shadow_offset_r=(0.35, 0.5), wall_shadow_softness_r=0.3),
        hand=HandStyle(hold_s=0.3, visible_at_release=False, catch_after_impact=8, arm_angle_deg=20.0,
                       away_m=(0.9, 0.2)),
        camera=CameraSetup(scale_px_per_m=800.0, floor_row_frac=0.9),
        timing=FrameTiming(capture_fps=Fraction(30000, 1001), exposure_s=1 / 120),
        sensor=SensorEffects(noise_sd_dn=2.0),
    ),
    "white_pingpong_mov": ClipConfig(
        width_px=1080, height_px=1920, rotation_deg=270, drop_height_m=0.6,
        ball=BallStyle("table_tennis", colour_rgb=(246, 246, 240), ambient=0.75, specular=0.25),
        scene=SceneStyle(wall_rgb=(206, 206, 204), floor="table", floor_rgb=(170, 125, 80), wall_shadow=0.25,
                         wall_shadow_offset_r=(0.4, 0.6), wall_shadow_softness_r=0.7),
        hand=HandStyle(hold_s=1.5, arm_angle_deg=60.0),
        camera=CameraSetup(scale_px_per_m=1500.0, drop_column_frac=0.55, floor_row_frac=0.88),
        timing=FrameTiming(capture_fps=Fraction(30), frames_per_capture=2, exposure_s=1 / 200, pts_jitter_s=3e-4),
        sensor=SensorEffects(noise_sd_dn=2.0),
        rulers=(Ruler("ruler", 0.3, 0.03, zero_m=(-0.2, 0.0), colour_rgb=(60, 170, 90)),),
    ),
    "red_blur_portrait": ClipConfig(
        width_px=1080, height_px=1920, rotation_deg=90, drop_height_m=1.0, duration_s=5.0,
        ball=BallStyle("rubber", colour_rgb=(205, 35, 40), ambient=0.5, specular=0.2),
        scene=SceneStyle(wall_rgb=(215, 212, 205), wall_shadow=0.6, wall_shadow_offset_r=(0.4, 0.45),
                         wall_shadow_softness_r=0.25, floor_shadow=0.8),
        hand=HandStyle(hold_s=1.0, arm_angle_deg=100.0),
        camera=CameraSetup(scale_px_per_m=1100.0, floor_row_frac=0.9),
        timing=FrameTiming(capture_fps=Fraction(30), exposure_s=1 / 60, pts_jitter_s=5e-4, drop_probability=0.01),
        sensor=SensorEffects(noise_sd_dn=3.0, exposure_drift=0.04),
    ),
    "tennis_aruco_tilted": ClipConfig(
        width_px=1920, height_px=1080, drop_height_m=0.8,
        ball=BallStyle("tennis", colour_rgb=(205, 222, 65), ambient=0.6, seam=True),
        scene=SceneStyle(wall_rgb=(196, 190, 180), clutter=7, floor="table", wall_shadow=0.2),
        hand=HandStyle(hold_s=1.2, arm_angle_deg=50.0),
        camera=CameraSetup(scale_px_per_m=950.0, floor_row_frac=0.85, pitch_deg=-10.0, yaw_deg=6.0, roll_deg=2.0),
        timing=FrameTiming(capture_fps=Fraction(60), exposure_s=1 / 500, pts_jitter_s=2e-4),
        sensor=SensorEffects(noise_sd_dn=2.5),
        markers=(Marker(0, 0.08, (-0.35, 0.12)), Marker(1, 0.08, (0.35, 0.12)), Marker(2, 0.08, (-0.35, 0.6)),
                 Marker(3, 0.08, (0.35, 0.6))),
    ),
    "yellow_green_tape": ClipConfig(
        width_px=1920, height_px=1080, drop_height_m=1.0,
        ball=BallStyle("tennis", colour_rgb=(235, 222, 45), ambient=0.6),
        scene=SceneStyle(wall_rgb=(95, 150, 95), floor="wood", wall_shadow=0.3),
        hand=HandStyle(hold_s=1.0, arm_angle_deg=75.0),
        camera=CameraSetup(scale_px_per_m=820.0, drop_column_frac=0.5, floor_row_frac=0.92),
        timing=FrameTiming(capture_fps=Fraction(30), exposure_s=1 / 250),
        sensor=SensorEffects(noise_sd_dn=2.0),
        rulers=(Ruler("tape", 1.1, 0.025, zero_m=(-0.25, 0.0), colour_rgb=(240, 205, 40)),),
    ),
    # a small 20 fps clip (314 x 486) of a white table-tennis ball before a dark wooden door, dropped from a hand; the
    # room is dim, and the phone exposes each frame for its whole interval: the falling ball is a streak
    "white_pingpong_door": _door(BallStyle("table_tennis", colour_rgb=(240, 240, 232), ambient=0.7, specular=0.2),
                                 exposure_s=1 / 20),
    # ... and a tennis ball before the same door, lit better
    "tennis_door": _door(BallStyle("tennis", colour_rgb=(205, 222, 65), ambient=0.6, seam=True), exposure_s=1 / 100),
    "yellow_flicker_portrait": _yellow_flicker_portrait(Fraction(30)),
    "yellow_flicker_portrait_120": _yellow_flicker_portrait(Fraction(120)),
    "yellow_flicker_portrait_240": _yellow_flicker_portrait(Fraction(240)),
}
PRESET_SUFFIX.update({name: ".mp4" for name in PRESETS})
PRESET_SUFFIX.update({"green_board_avi": ".avi", "white_pingpong_mov": ".mov"})
