"""Synthetic drop-test videos with per-frame ground truth, rendered from :class:`dropfit.synth.DropTruth`.

A ball of known radius and colour (plain, or with a tennis-ball seam that turns slowly) falls along a
vertical drop line in front of a background with a ruler (ticks every 1 cm, longer every 5 and 10 cm)
and a floor. The ruler stands in the ball's plane, so its ticks calibrate the scale at the ball.
A :class:`Camera` films it with a given resolution, frame rate and exposure time; motion blur is the
average of sub-frames spread over the exposure, then a slow lighting drift, Gaussian sensor noise and
the codec's compression (Motion-JPEG) are applied. Optionally the camera is tilted a little (the
image is the homography of a rotated pinhole camera), the ball flattens against the floor during a
finite contact, and a hand holds the ball before release and moves away after it.

Coordinates
-----------
World: ``x_m`` horizontal (m, right of the drop line) and ``height_m`` (m, up from the floor), in the
ball's plane. Image: ``x_px`` (column) and ``y_px`` (row, down) in pixels; pixel ``(i, j)`` covers
``[j − ½, j + ½] × [i − ½, i + ½]``, so integer coordinates are pixel centres. The untilted ("flat")
image is ``x = drop_column_px + x_m·px_per_m``, ``y = image_row_of_floor_px − height_m·px_per_m``;
with a tilt the flat image is mapped through :meth:`Camera.homography`.

Frame ``k`` is exposed over ``[t_k − E/2, t_k + E/2]`` with ``t_k = start_s + k/fps`` (mid-exposure)
and ``E`` the exposure time. Its ground truth is the ball centre at ``t_k``; the exposure-averaged,
coverage-weighted centroid of the drawn ball (what an intensity centroid measures) is stored too.

Everything is seeded (a :class:`numpy.random.Generator` from ``seed``) and frames are streamed to
the video writer one at a time, so memory does not grow with the clip length.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path

from .video.opencv import cv2
import numpy as np
import pandas as pd

from .contact import LinearContact
from .numerics import normal_quantile
from .synth import ground_truth_record, simulate_drop

#: Sub-samples per pixel side used for the ball's edge pixels (16 × 16 = 256 samples per pixel).
SUPERSAMPLE = 16
#: Codecs tried in order: (fourcc, file suffix, use OpenCV's own MJPEG writer with a quality setting).
_CODECS = (("MJPG", ".avi", True), ("MJPG", ".avi", False), ("mp4v", ".mp4", False))
#: Gaussian quantiles addressed by a uniform 16-bit integer: fast seeded sensor noise (tails to 4.3 σ).
_NOISE_TABLE = normal_quantile((np.arange(65536) + 0.5) / 65536).astype(np.float32)


@dataclass(frozen=True)
class Camera:
    """A camera filming the drop, with its optics, exposure and sensor defects.

    Parameters
    ----------
    width_px, height_px : int
        Image size in px.
    fps : float
        Capture rate in frames per second (1/s); the video plays back at this rate.
    exposure_s : float, optional
        Exposure (shutter) time in s, at most 1/fps; 0 means no motion blur. Default: half the frame
        interval, 1/(2 fps).
    px_per_m : float
        Image scale in px per m in the ball's plane (before any tilt).
    image_row_of_floor_px : float
        Image row (px, down, sub-pixel allowed) of the floor line, where the ball's bottom touches
        the floor.
    drop_column_px : float, optional
        Image column (px) of the drop line, i.e. of the ball centre. Default: the image centre column.
    noise_sigma : float
        Standard deviation of the Gaussian sensor noise in grey levels (0–255 scale), independent per
        pixel, channel and frame.
    lighting_drift : float
        Relative amplitude (dimensionless, e.g. 0.03 = ±3 %) of a slow sinusoidal brightness change.
    lighting_period_s : float
        Period of the lighting drift in s.
    quality : int
        JPEG quality (0–100) of the Motion-JPEG codec.
    tilt_deg : float
        Small rotation of the camera about its horizontal axis in degrees (0 = the image plane is
        parallel to the ball's plane); keystones the image through a homography.
    focal_px : float, optional
        Focal length in px of the pinhole model used for the tilt. Default: ``width_px``.
    blur_step_px : float
        Largest displacement of the ball in px between two sub-frames of the motion blur.
    max_subframes : int
        Upper limit on the number of sub-frames averaged over an exposure.
    """

    width_px: int = 1280
    height_px: int = 720
    fps: float = 240.0
    exposure_s: float | None = None
    px_per_m: float = 250.0
    image_row_of_floor_px: float = 690.0
    drop_column_px: float | None = None
    noise_sigma: float = 2.0
    lighting_drift: float = 0.0
    lighting_period_s: float = 2.0
    quality: int = 90
    tilt_deg: float = 0.0
    focal_px: float | None = None
    blur_step_px: float = 0.25
    max_subframes: int = 64

    def __post_init__(self):
        if self.exposure_s is not None and not 0.0 <= self.exposure_s <= 1.0 / self.fps * (1 + 1e-9):
            raise ValueError(f"exposure_s = {self.exposure_s} s must lie in [0, 1/fps = {1 / self.fps} s]")
        if self.width_px < 1 or self.height_px < 1 or self.fps <= 0 or self.px_per_m <= 0:
            raise ValueError("width_px, height_px, fps and px_per_m must be positive")

    @property
    def exposure(self):
        """Exposure time in s (the default resolved)."""
        return 0.5 / self.fps if self.exposure_s is None else float(self.exposure_s)

    @property
    def drop_column(self):
        """Image column in px of the drop line (the default resolved)."""
        return (self.width_px - 1) / 2.0 if self.drop_column_px is None else float(self.drop_column_px)

    def homography(self):
        """3 × 3 homography mapping flat (untilted) image px to image px: K R K⁻¹.

        R is a rotation by ``tilt_deg`` about the camera's horizontal axis; K has focal length
        ``focal_px`` and its principal point at the image centre. The identity when ``tilt_deg`` = 0.
        """
        if self.tilt_deg == 0.0:
            return np.eye(3)
        f = float(self.focal_px or self.width_px)
        cx, cy = (self.width_px - 1) / 2.0, (self.height_px - 1) / 2.0
        k = np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])
        c, s = math.cos(math.radians(self.tilt_deg)), math.sin(math.radians(self.tilt_deg))
        rotation = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        return k @ rotation @ np.linalg.inv(k)

    def flat_to_image(self, x_px, y_px):
        """Map flat (untilted) image coordinates in px to image coordinates in px (arrays broadcast)."""
        x_px, y_px = np.broadcast_arrays(np.asarray(x_px, dtype=float), np.asarray(y_px, dtype=float))
        if self.tilt_deg == 0.0:
            return x_px.copy(), y_px.copy()
        h = self.homography()
        w = h[2, 0] * x_px + h[2, 1] * y_px + h[2, 2]
        return ((h[0, 0] * x_px + h[0, 1] * y_px + h[0, 2]) / w,
                (h[1, 0] * x_px + h[1, 1] * y_px + h[1, 2]) / w)

    def world_to_flat(self, x_m, height_m):
        """Flat image coordinates in px of the world point ``x_m`` (m, right) and ``height_m`` (m, up)."""
        return (self.drop_column + np.asarray(x_m, dtype=float) * self.px_per_m,
                self.image_row_of_floor_px - np.asarray(height_m, dtype=float) * self.px_per_m)

    def world_to_image(self, x_m, height_m):
        """Image coordinates in px (column, row down) of the world point ``x_m``, ``height_m`` (m)."""
        return self.flat_to_image(*self.world_to_flat(x_m, height_m))


@dataclass(frozen=True)
class Scene:
    """What is in front of the camera: background, ruler, floor, ball and (optionally) a hand.

    Parameters
    ----------
    ball_radius_m : float, optional
        Ball radius in m as drawn. Default: the radius of the :class:`~dropfit.synth.DropTruth`.
    ball_colour_bgr : tuple of float
        Ball colour, blue-green-red grey levels (0–255). The default is tennis-ball optic yellow.
    seam : bool
        Draw a tennis-ball seam (the closed curve of a tennis ball, projected) that turns with the ball.
    seam_colour_bgr : tuple of float
        Seam colour (0–255, BGR).
    seam_width_m : float
        Seam width in m.
    spin_rad_s : float
        Rotation rate of the ball's texture in rad/s (about a fixed, slightly oblique axis).
    flatten : bool
        During a contact (centre height below the radius) draw the ball as an ellipse pressed against
        the floor: vertical semi-axis R − δ/2 for a penetration δ (m), bottom on the floor line, top where
        the top of the rigid ball would be, horizontal semi-axis R·√(R/(R − δ/2)) (volume kept).
    background_grey : float
        Mean background grey level (0–255).
    background_texture : float
        Amplitude in grey levels of a smooth random texture on the background (0 = uniform).
    texture_seed : int
        Seed of the background texture (the scene is fixed; frame noise uses ``render_video``'s seed).
    ruler_column_px : float, optional
        Flat-image column in px of the ruler's left edge. Default: a fifth of the image width.
    ruler_width_px : float
        Ruler width in px. 1 cm ticks span 40 % of it, 5 cm ticks 70 %, 10 cm ticks all of it.
    ruler_top_m : float
        Height in m of the ruler's top above the floor (it stands on the floor).
    tick_width_px : float
        Thickness of a tick mark in px; the tick at height h is centred on the row
        ``image_row_of_floor_px − h·px_per_m``. With a whole number of px the darkness-weighted
        centroid of a tick's rows is exactly that row (any other width biases it by up to ~0.1 px).
    ruler_grey, tick_grey, floor_grey : float
        Grey levels (0–255) of the ruler face, its ticks and the floor band.
    hand : bool
        Draw a hand (with forearm) that pinches the ball's top before release and then moves away.
    hand_colour_bgr : tuple of float
        Hand colour (0–255, BGR).
    hand_width_m : float
        Hand width in m.
    hand_speed_m_s : float
        Speed in m/s at which the hand moves away (up and to the right) after release.
    """

    ball_radius_m: float | None = None
    ball_colour_bgr: tuple = (40.0, 225.0, 205.0)
    seam: bool = False
    seam_colour_bgr: tuple = (235.0, 240.0, 240.0)
    seam_width_m: float = 0.003
    spin_rad_s: float = 3.0
    flatten: bool = True
    background_grey: float = 110.0
    background_texture: float = 0.0
    texture_seed: int = 0
    ruler_column_px: float | None = None
    ruler_width_px: float = 24.0
    ruler_top_m: float = 3.0
    tick_width_px: float = 1.0
    ruler_grey: float = 235.0
    tick_grey: float = 25.0
    floor_grey: float = 60.0
    hand: bool = False
    hand_colour_bgr: tuple = (120.0, 150.0, 205.0)
    hand_width_m: float = 0.09
    hand_speed_m_s: float = 1.5


# --------------------------------------------------------------------------------------------------
# Pure geometry and rasterisation
# --------------------------------------------------------------------------------------------------


def _overlap(lo, hi, centres):
    """Length (px) of [lo, hi] inside each pixel [c − ½, c + ½] for pixel centres ``centres`` (px)."""
    return np.clip(np.minimum(hi, centres + 0.5) - np.maximum(lo, centres - 0.5), 0.0, 1.0)


def ellipse_coverage(cx_px, cy_px, a_px, b_px, x0, y0, width, height, supersample=SUPERSAMPLE):
    """Fraction of each pixel covered by an axis-aligned ellipse (anti-aliased by supersampling).

    Parameters
    ----------
    cx_px, cy_px : float
        Ellipse centre in px (column, row down).
    a_px, b_px : float
        Horizontal and vertical semi-axes in px.
    x0, y0 : int
        Column and row in px of the patch's top-left pixel.
    width, height : int
        Patch size in px.
    supersample : int
        Sub-samples per pixel side for the pixels the edge passes through (interior and exterior
        pixels are exact).

    Returns
    -------
    numpy.ndarray
        ``(height, width)`` float64 coverage in [0, 1].
    """
    dy = (y0 + np.arange(height, dtype=float) - cy_px)[:, None]
    dx = (x0 + np.arange(width, dtype=float) - cx_px)[None, :]
    r = np.sqrt((dx / a_px) ** 2 + (dy / b_px) ** 2)  # 1 on the edge; Lipschitz constant 1/min(a, b) per px
    margin = 0.7072 / min(a_px, b_px)  # half a pixel diagonal
    coverage = (r < 1.0 - margin).astype(float)
    edge_rows, edge_cols = np.nonzero(np.abs(r - 1.0) <= margin)
    if edge_rows.size:
        offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
        sx = (dx[0, edge_cols][:, None, None] + offsets[None, None, :]) / a_px
        sy = (dy[edge_rows, 0][:, None, None] + offsets[None, :, None]) / b_px
        coverage[edge_rows, edge_cols] = (sx * sx + sy * sy <= 1.0).mean(axis=(1, 2))
    return coverage


def ball_shape(height_m, radius_m, flatten=True):
    """Drawn ball shape at centre height ``height_m`` (m) for a ball of radius ``radius_m`` (m).

    Parameters
    ----------
    height_m : float or array_like
        Centre height in m above the floor (below ``radius_m`` during a contact).
    radius_m : float
        Ball radius in m.
    flatten : bool
        Flatten the ball against the floor during contact; otherwise draw a rigid disc at the centre.

    Returns
    -------
    (centre_m, a_m, b_m)
        Height of the drawn ellipse's centre (m), horizontal and vertical semi-axes (m). In contact
        with penetration δ = R − h: b = R − δ/2, centre = b (bottom on the floor), a = R √(R/b).
    """
    h = np.asarray(height_m, dtype=float)
    if not flatten:
        return h, np.full_like(h, radius_m), np.full_like(h, radius_m)
    delta = np.clip(radius_m - h, 0.0, radius_m)
    b = radius_m - 0.5 * delta
    centre = np.where(delta > 0, b, h)
    return centre, radius_m * np.sqrt(radius_m / b), b


def seam_curve(angle_rad, n=240, lobe=0.3):
    """Points of a tennis-ball seam on the unit sphere, turned by ``angle_rad`` (rad).

    The classic closed curve (a cos t + b cos 3t, a sin t − b sin 3t, 2√(ab) sin 2t) with a + b = 1
    lies on the unit sphere; it is turned about a fixed oblique axis.

    Parameters
    ----------
    angle_rad : float
        Rotation angle in rad.
    n : int
        Number of points.
    lobe : float
        b, the size of the seam's lobes (dimensionless, 0 < b < 1).

    Returns
    -------
    numpy.ndarray
        ``(n, 3)`` unit vectors (x right, y up, z towards the camera).
    """
    t = np.linspace(0.0, 2.0 * np.pi, n, endpoint=False)
    a, b = 1.0 - lobe, lobe
    p = np.stack([a * np.cos(t) + b * np.cos(3 * t), a * np.sin(t) - b * np.sin(3 * t),
                  2.0 * np.sqrt(a * b) * np.sin(2 * t)], axis=1)
    axis = np.array([0.35, 0.9, 0.25]) / np.linalg.norm([0.35, 0.9, 0.25])
    kx = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rotation = np.eye(3) + math.sin(angle_rad) * kx + (1 - math.cos(angle_rad)) * kx @ kx
    return p @ rotation.T


def render_background(camera, scene):
    """The static scene (background, floor band, ruler with ticks) in flat image coordinates.

    Parameters
    ----------
    camera : Camera
        Image size (px), scale (px/m) and floor row (px).
    scene : Scene
        Grey levels, texture and ruler geometry.

    Returns
    -------
    numpy.ndarray
        ``(height_px, width_px, 3)`` float32 BGR grey levels (0–255), before tilt, lighting and noise.
    """
    h, w = camera.height_px, camera.width_px
    rows = np.arange(h, dtype=float)
    cols = np.arange(w, dtype=float)
    grey = np.full((h, w), float(scene.background_grey))
    if scene.background_texture:
        rng = np.random.default_rng(scene.texture_seed)
        coarse = rng.standard_normal((max(2, h // 24), max(2, w // 24))).astype(np.float32)
        smooth = cv2.resize(coarse, (w, h), interpolation=cv2.INTER_CUBIC)
        grey += scene.background_texture * smooth / max(float(smooth.std()), 1e-6)
    floor = _overlap(camera.image_row_of_floor_px, np.inf, rows)[:, None]
    grey = grey * (1 - floor) + scene.floor_grey * floor
    # ruler: a light strip standing on the floor
    left = camera.width_px / 5.0 if scene.ruler_column_px is None else float(scene.ruler_column_px)
    right = left + scene.ruler_width_px
    top = camera.image_row_of_floor_px - scene.ruler_top_m * camera.px_per_m
    ruler = _overlap(top, camera.image_row_of_floor_px, rows)[:, None] * _overlap(left, right, cols)[None, :]
    grey = grey * (1 - ruler) + scene.ruler_grey * ruler
    # ticks every 1 cm: 40 % of the width; every 5 cm: 70 %; every 10 cm: the full width
    half = 0.5 * scene.tick_width_px
    for cm in range(1, int(math.floor(scene.ruler_top_m * 100 + 1e-9)) + 1):
        row = camera.image_row_of_floor_px - cm * 0.01 * camera.px_per_m
        if row + half < -0.5 or row - half > h - 0.5:
            continue
        length = 1.0 if cm % 10 == 0 else 0.7 if cm % 5 == 0 else 0.4
        r0, r1 = max(int(math.floor(row - half - 0.5)), 0), min(int(math.ceil(row + half + 0.5)) + 1, h)
        c0, c1 = max(int(math.floor(left)) - 1, 0), min(int(math.ceil(right)) + 2, w)
        tick = (_overlap(row - half, row + half, rows[r0:r1])[:, None]
                * _overlap(left, left + length * scene.ruler_width_px, cols[c0:c1])[None, :])
        grey[r0:r1, c0:c1] = grey[r0:r1, c0:c1] * (1 - tick) + scene.tick_grey * tick
    return np.repeat(grey.astype(np.float32)[:, :, None], 3, axis=2)


def _subframe_times(truth, camera, t_mid):
    """Sub-frame times (s) spreading the exposure around ``t_mid`` (s), enough for ``blur_step_px``."""
    exposure = camera.exposure
    if exposure <= 0:
        return np.array([t_mid])
    probe = t_mid + exposure * (np.linspace(0.0, 1.0, 17) - 0.5)
    path_px = np.abs(np.diff(truth.height(probe))).sum() * camera.px_per_m
    k = int(min(max(math.ceil(path_px / camera.blur_step_px), 1), camera.max_subframes))
    return t_mid + exposure * ((np.arange(k) + 0.5) / k - 0.5)


def _seam_mask(cx, cy, a, b, angle, width_px, x0, y0, w, h):
    """Anti-aliased seam weight (0–1) on a patch; the seam's visible half projected orthographically."""
    p = seam_curve(angle)
    mask = np.zeros((h, w), np.uint8)
    shift = 4
    scale = 1 << shift
    pts = np.stack([(cx - x0 + p[:, 0] * a) * scale, (cy - y0 - p[:, 1] * b) * scale], axis=1)
    visible = p[:, 2] > 0
    # split the closed curve into runs of visible points
    order = np.roll(np.arange(len(p)), -int(np.argmin(visible)) if not visible.all() else 0)
    runs, run = [], []
    for i in order:
        if visible[i]:
            run.append(pts[i])
        elif run:
            runs.append(run)
            run = []
    if run:
        runs.append(run)
    polylines = [np.round(np.array(r)).astype(np.int32) for r in runs if len(r) > 1]
    if polylines:
        cv2.polylines(mask, polylines, visible.all(), 255, max(1, int(round(width_px))), cv2.LINE_AA, shift)
    return mask.astype(np.float32) / 255.0


def _ball_patch(truth, camera, scene, times):
    """Exposure-averaged ball layer over its bounding box in flat coordinates.

    Returns ``(x0, y0, alpha, premultiplied_colour, centroid_x, centroid_y)``: the patch origin
    (px), mean coverage (h, w), mean coverage × colour (h, w, 3) and the coverage-weighted mean
    centre of the drawn shape (flat px).
    """
    radius = scene.ball_radius_m or truth.radius_m
    heights = truth.height(times)
    centre_m, a_m, b_m = ball_shape(heights, radius, scene.flatten)
    cx = np.full(times.shape, camera.drop_column)
    _, cy = camera.world_to_flat(0.0, centre_m)
    a, b = a_m * camera.px_per_m, b_m * camera.px_per_m
    x0 = int(math.floor((cx - a).min())) - 1
    x1 = int(math.ceil((cx + a).max())) + 2
    y0 = int(math.floor((cy - b).min())) - 1
    y1 = int(math.ceil((cy + b).max())) + 2
    w, h = x1 - x0, y1 - y0
    alpha = np.zeros((h, w))
    colour = np.zeros((h, w, 3)) if scene.seam else None
    base = np.asarray(scene.ball_colour_bgr, dtype=float)
    seam_colour = np.asarray(scene.seam_colour_bgr, dtype=float)
    areas = a * b
    for j, t in enumerate(times):
        cov = ellipse_coverage(cx[j], cy[j], a[j], b[j], x0, y0, w, h)
        alpha += cov
        if scene.seam:
            m = _seam_mask(cx[j], cy[j], a[j], b[j], scene.spin_rad_s * t,
                           scene.seam_width_m * camera.px_per_m, x0, y0, w, h)[:, :, None]
            colour += cov[:, :, None] * (base * (1 - m) + seam_colour * m)
    alpha /= len(times)
    premult = colour / len(times) if scene.seam else alpha[:, :, None] * base
    weights = areas / areas.sum()
    return x0, y0, alpha, premult, float(weights @ cx), float(weights @ cy)


def _hand_patch(truth, camera, scene, t):
    """Hand (and forearm) layer at time ``t`` (s): ``(x0, y0, alpha, premultiplied_colour)`` or None."""
    radius = scene.ball_radius_m or truth.radius_m
    hold_m = truth.drop_height_m + radius
    away = max(t - truth.release_time_s, 0.0) * scene.hand_speed_m_s
    left_m = -0.5 * scene.hand_width_m + 0.8 * away
    bottom_m = hold_m + 0.55 * radius + 0.6 * away
    x_lo, y_hi = camera.world_to_flat(left_m, bottom_m)
    x_hi = x_lo + scene.hand_width_m * camera.px_per_m
    x0, x1 = max(int(math.floor(x_lo)) - 1, -camera.width_px), int(math.ceil(x_hi)) + 2
    y0, y1 = -1, int(math.ceil(y_hi)) + 2
    if y1 <= y0 or x1 <= x0:
        return None
    rows = np.arange(y0, y1, dtype=float)
    cols = np.arange(x0, x1, dtype=float)
    alpha = _overlap(-np.inf, y_hi, rows)[:, None] * _overlap(x_lo, x_hi, cols)[None, :]
    return x0, y0, alpha, alpha[:, :, None] * np.asarray(scene.hand_colour_bgr, dtype=float)


def _composite(buf, background, gain, layer, camera, homography):
    """Blend a layer ``(x0, y0, alpha, premult)`` given in flat px into the frame buffer (in place).

    ``buf`` already holds gain × background (+ noise); the layer adds gain × (premult − alpha ×
    background) over its footprint. With a tilt the layer is warped into the image first.
    """
    x0, y0, alpha, premult = layer
    h, w = alpha.shape
    if camera.tilt_deg != 0.0:
        corners_x = np.array([x0 - 1, x0 + w, x0 - 1, x0 + w], dtype=float)
        corners_y = np.array([y0 - 1, y0 - 1, y0 + h, y0 + h], dtype=float)
        ix, iy = camera.flat_to_image(corners_x, corners_y)
        dx0, dy0 = int(math.floor(ix.min())) - 1, int(math.floor(iy.min())) - 1
        dw, dh = int(math.ceil(ix.max())) + 2 - dx0, int(math.ceil(iy.max())) + 2 - dy0
        shift_src = np.array([[1, 0, x0], [0, 1, y0], [0, 0, 1]], dtype=float)
        shift_dst = np.array([[1, 0, -dx0], [0, 1, -dy0], [0, 0, 1]], dtype=float)
        m = shift_dst @ homography @ shift_src
        layer4 = np.dstack([alpha, premult]).astype(np.float32)
        warped = cv2.warpPerspective(layer4, m, (dw, dh), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        x0, y0, alpha, premult = dx0, dy0, warped[:, :, 0], warped[:, :, 1:]
        h, w = alpha.shape
    r0, r1 = max(y0, 0), min(y0 + h, buf.shape[0])
    c0, c1 = max(x0, 0), min(x0 + w, buf.shape[1])
    if r1 <= r0 or c1 <= c0:
        return
    a = alpha[r0 - y0:r1 - y0, c0 - x0:c1 - x0, None]
    p = premult[r0 - y0:r1 - y0, c0 - x0:c1 - x0]
    buf[r0:r1, c0:c1] += (gain * (p - a * background[r0:r1, c0:c1])).astype(np.float32)


def lighting_gain(camera, time_s):
    """Relative brightness (dimensionless, 1 = nominal) of the lighting at ``time_s`` (s)."""
    return 1.0 + camera.lighting_drift * np.sin(2.0 * np.pi * np.asarray(time_s, dtype=float)
                                                / camera.lighting_period_s)


class FrameRenderer:
    """Renders frames of one clip; keeps only the static background between frames.

    Parameters
    ----------
    truth : dropfit.synth.DropTruth
        The motion (centre height in m against time in s).
    camera : Camera
        The camera.
    scene : Scene
        The scene.
    seed : int or numpy.random.Generator, optional
        Seed of the sensor noise.
    start_s : float
        Mid-exposure time in s of frame 0 (on the clock of ``truth``).
    """

    def __init__(self, truth, camera, scene, seed=None, start_s=0.0):
        self.truth, self.camera, self.scene, self.start_s = truth, camera, scene, float(start_s)
        self.rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
        self.homography = camera.homography()
        flat = render_background(camera, scene)
        if camera.tilt_deg != 0.0:
            flat = cv2.warpPerspective(flat, self.homography, (camera.width_px, camera.height_px),
                                       flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        self.background = flat
        self.noise_table = _NOISE_TABLE * np.float32(camera.noise_sigma) + np.float32(0.5)

    def frame_time(self, index):
        """Mid-exposure time in s of frame ``index``."""
        return self.start_s + index / self.camera.fps

    def render(self, index):
        """Frame ``index`` as uint8 BGR ``(height_px, width_px, 3)`` and its ground-truth row (dict)."""
        camera, scene, truth = self.camera, self.scene, self.truth
        t_mid = self.frame_time(index)
        gain = float(lighting_gain(camera, t_mid))
        times = _subframe_times(truth, camera, t_mid)
        if camera.noise_sigma > 0:
            u = self.rng.integers(0, 65536, size=self.background.shape, dtype=np.uint16)
            buf = self.noise_table[u]
            cv2.scaleAdd(self.background, gain, buf, dst=buf)
        else:
            buf = self.background * np.float32(gain) + np.float32(0.5)
        x0, y0, alpha, premult, mean_cx, mean_cy = _ball_patch(truth, camera, scene, times)
        _composite(buf, self.background, gain, (x0, y0, alpha, premult), camera, self.homography)
        hand_overlap = False
        if scene.hand:
            hand = _hand_patch(truth, camera, scene, t_mid)
            if hand is not None:
                _composite(buf, self.background, gain, hand, camera, self.homography)
                hx0, hy0, ha, _ = hand
                hh, hw = ha.shape
                hand_overlap = (hx0 < x0 + alpha.shape[1] and x0 < hx0 + hw
                                and hy0 < y0 + alpha.shape[0] and y0 < hy0 + hh)
        np.clip(buf, 0.0, 255.5, out=buf)
        frame = buf.astype(np.uint8)
        return frame, self._truth_row(index, t_mid, gain, mean_cx, mean_cy, hand_overlap)

    def _truth_row(self, index, t_mid, gain, mean_cx, mean_cy, hand_overlap):
        camera, scene = self.camera, self.scene
        radius = scene.ball_radius_m or self.truth.radius_m
        height = float(self.truth.height(t_mid))
        centre_m, a_m, b_m = (float(v) for v in ball_shape(height, radius, scene.flatten))
        x, y = camera.world_to_image(0.0, height)
        cx, cy = camera.flat_to_image(mean_cx, mean_cy)
        fx, fy = camera.world_to_flat(0.0, centre_m)
        ex = fx + np.array([-1, 1, -1, 1]) * a_m * camera.px_per_m
        ey = fy + np.array([-1, -1, 1, 1]) * b_m * camera.px_per_m
        ix, iy = camera.flat_to_image(ex, ey)
        _, bottom = camera.flat_to_image(fx, fy + b_m * camera.px_per_m)
        visible = bool(ix.min() >= -0.5 and ix.max() <= camera.width_px - 0.5
                       and iy.min() >= -0.5 and iy.max() <= camera.height_px - 0.5)
        return {
            "frame": index, "time_s": t_mid, "height_m": height,
            "x_px": float(x), "y_px": float(y), "radius_px": radius * camera.px_per_m,
            "in_contact": bool(height < radius), "penetration_m": max(radius - height, 0.0),
            "visible": visible, "centroid_x_px": float(cx), "centroid_y_px": float(cy),
            "bottom_y_px": float(bottom), "lighting_gain": gain, "hand_overlap": bool(hand_overlap),
        }


def render_frame(truth, camera, scene, index, seed=None, start_s=0.0):
    """One frame (uint8 BGR) and its ground-truth row; see :class:`FrameRenderer`.

    Parameters
    ----------
    truth : dropfit.synth.DropTruth
        The motion.
    camera : Camera
        The camera.
    scene : Scene
        The scene.
    index : int
        Frame number; its mid-exposure time is ``start_s + index / fps`` (s).
    seed : int, optional
        Seed of the sensor noise.
    start_s : float
        Mid-exposure time in s of frame 0.
    """
    return FrameRenderer(truth, camera, scene, seed, start_s).render(index)


# --------------------------------------------------------------------------------------------------
# Video files
# --------------------------------------------------------------------------------------------------


def _open_writer(path, fps, size, quality):
    """Open a video writer on a temporary name next to ``path``; returns (writer, tmp, final, codec)."""
    path = Path(path)
    for fourcc, suffix, own_mjpeg in _CODECS:
        final = path if path.suffix.lower() == suffix else path.with_suffix(suffix)
        tmp = final.with_name(f".{final.stem}.tmp{os.getpid()}{suffix}")
        if own_mjpeg:
            writer = cv2.VideoWriter(str(tmp), cv2.CAP_OPENCV_MJPEG, cv2.VideoWriter_fourcc(*fourcc), fps, size,
                                     [cv2.VIDEOWRITER_PROP_QUALITY, int(quality)])
        else:
            writer = cv2.VideoWriter(str(tmp), cv2.VideoWriter_fourcc(*fourcc), fps, size)
        if writer.isOpened():
            return writer, tmp, final, fourcc
        writer.release()
        tmp.unlink(missing_ok=True)
    raise RuntimeError(f"no video codec available to write {path} (tried MJPG .avi and mp4v .mp4)")


def render_video(truth, camera, scene, duration_s, seed, path=None, start_s=0.0):
    """Render a clip and (optionally) write it as a video file, with per-frame ground truth.

    Parameters
    ----------
    truth : dropfit.synth.DropTruth
        The motion: ball centre height in m against time in s (flight, contact, rest).
    camera : Camera
        Resolution (px), frame rate (1/s), exposure (s), scale (px/m), noise, lighting, codec, tilt.
    scene : Scene
        Background, ruler, floor, ball look and hand.
    duration_s : float
        Clip length in s; ``round(duration_s · fps)`` frames.
    seed : int
        Seed of the sensor noise (a :class:`numpy.random.Generator`).
    path : str or pathlib.Path, optional
        Output video. Written with Motion-JPEG into an AVI (``.avi``; ``mp4v`` into ``.mp4`` if this
        OpenCV build cannot write MJPG), through a temporary file in the same directory that is
        renamed into place once complete.
    start_s : float
        Mid-exposure time in s (on the clock of ``truth``) of frame 0.

    Returns
    -------
    pandas.DataFrame
        One row per frame: ``frame``, ``time_s`` (mid-exposure, s), ``height_m`` (centre height, m),
        ``x_px``, ``y_px`` (true centre at mid-exposure, image px, y down), ``radius_px``,
        ``in_contact``, ``penetration_m`` (m), ``visible`` (the drawn ball lies wholly inside the
        image), ``centroid_x_px``, ``centroid_y_px`` (exposure-averaged, coverage-weighted centroid of
        the drawn ball, px), ``bottom_y_px`` (row of the drawn ball's bottom at mid-exposure, px),
        ``lighting_gain`` and ``hand_overlap``. ``attrs`` holds ``video_path`` and ``codec``.
    """
    renderer = FrameRenderer(truth, camera, scene, seed, start_s)
    n_frames = int(round(duration_s * camera.fps))
    writer = tmp = final = codec = None
    if path is not None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        writer, tmp, final, codec = _open_writer(path, camera.fps, (camera.width_px, camera.height_px),
                                                 camera.quality)
    rows = []
    try:
        for k in range(n_frames):
            frame, row = renderer.render(k)
            rows.append(row)
            if writer is not None:
                writer.write(frame)
        if writer is not None:
            writer.release()
            writer = None
            os.replace(tmp, final)
    finally:
        if writer is not None:
            writer.release()
        if tmp is not None and tmp.exists():
            tmp.unlink()
    table = pd.DataFrame(rows)
    table.attrs.update(video_path=None if final is None else str(final), codec=codec)
    return table


def video_metadata(truth, camera, scene, seed, start_s=0.0):
    """JSON-ready description of a clip: camera, scene, seed and the drop's ground truth (SI units)."""
    record = ground_truth_record(truth, 0.0)
    x_floor, y_floor = camera.flat_to_image(camera.drop_column, camera.image_row_of_floor_px)
    return {
        "units": {"length": "m", "image": "px", "time": "s", "grey": "0-255"},
        "seed": seed,
        "start_s": start_s,
        "camera": {**asdict(camera), "exposure_s": camera.exposure, "drop_column_px": camera.drop_column,
                   "floor_row_in_image_px": float(y_floor), "homography": camera.homography().tolist()},
        "scene": {**asdict(scene), "ball_radius_m": scene.ball_radius_m or truth.radius_m},
        "drop": record,
    }


def write_ground_truth(frames, csv_path, json_path=None, metadata=None):
    """Write the per-frame ground truth as CSV and (optionally) the clip's metadata as JSON.

    Parameters
    ----------
    frames : pandas.DataFrame
        The table returned by :func:`render_video`.
    csv_path : str or pathlib.Path
        Output CSV (one row per frame).
    json_path : str or pathlib.Path, optional
        Output JSON with ``metadata`` (e.g. from :func:`video_metadata`) plus the video's path and codec.
    metadata : dict, optional
        Clip description.
    """
    frames.to_csv(csv_path, index=False)
    if json_path is not None:
        record = dict(metadata or {})
        record.update(video=frames.attrs.get("video_path"), codec=frames.attrs.get("codec"),
                      n_frames=int(len(frames)))
        Path(json_path).write_text(json.dumps(record, indent=2, default=_json_default) + "\n")


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (tuple, np.ndarray)):
        return list(value)
    raise TypeError(f"not JSON serialisable: {type(value)}")


# --------------------------------------------------------------------------------------------------
# The default data set
# --------------------------------------------------------------------------------------------------

#: Tennis ball through the seed's spring–damper contact (k = 30 kN/m, c = 8.2 N·s/m), 254 cm drop.
_TENNIS = dict(drop_height_m=2.54, radius_m=0.0335, mass_kg=0.057, drag_coefficient=0.55,
               release_time_s=0.3, contact_model=LinearContact(30000.0, 8.2))


def default_clips():
    """The default synthetic videos: name → dict of ``truth`` kwargs, ``camera``, ``scene``, times.

    * ``phone_240fps_tennis_254cm`` — a phone's 240 fps slow motion (1280 × 720, 1/480 s exposure,
      noise, lighting drift, 0.5° tilt, MJPEG quality 80) of a seamed tennis ball held by a hand and
      dropped from 254 cm, with its first two bounces (3 s).
    * ``contact_2000fps_closeup`` — a 2000 fps high-speed close-up (640 × 480, 3000 px/m, 1/10 000 s
      exposure) of the first contact of the same drop, 30 ms around touchdown.
    """
    truth = simulate_drop(**_TENNIS)
    touchdown = float(truth.impacts["t_s"].iloc[0])
    return {
        "phone_240fps_tennis_254cm": dict(
            truth=_TENNIS, start_s=0.0, duration_s=3.0,
            camera=Camera(1280, 720, 240.0, 1 / 480, px_per_m=250.0, image_row_of_floor_px=690.0,
                          noise_sigma=3.0, lighting_drift=0.03, lighting_period_s=2.5, quality=80,
                          tilt_deg=0.5),
            scene=Scene(seam=True, hand=True, background_texture=6.0, ruler_top_m=2.75)),
        "contact_2000fps_closeup": dict(
            truth=_TENNIS, start_s=round(touchdown - 0.012, 6), duration_s=0.03,
            camera=Camera(640, 480, 2000.0, 1e-4, px_per_m=3000.0, image_row_of_floor_px=450.0,
                          noise_sigma=2.0, quality=90),
            scene=Scene(seam=True, background_texture=4.0, ruler_column_px=60.0, ruler_width_px=40.0,
                        tick_width_px=2.0, ruler_top_m=0.16)),
    }


def make_default_videos(out_dir, seed=0, names=None):
    """Render the clips of :func:`default_clips` into ``out_dir``.

    Writes ``<name>.avi`` (or ``.mp4``), ``<name>.frames.csv`` (per-frame truth) and
    ``<name>.truth.json`` (camera, scene, seed and drop truth) per clip.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        Output directory.
    seed : int
        Seed of the sensor noise (clip i uses ``seed + i``).
    names : list of str, optional
        Clips to render (default: all).

    Returns
    -------
    list of pathlib.Path
        The video files written.
    """
    out_dir = Path(out_dir)
    written = []
    for i, (name, clip) in enumerate(default_clips().items()):
        if names is not None and name not in names:
            continue
        truth = simulate_drop(**clip["truth"])
        frames = render_video(truth, clip["camera"], clip["scene"], clip["duration_s"], seed + i,
                              out_dir / f"{name}.avi", start_s=clip["start_s"])
        meta = video_metadata(truth, clip["camera"], clip["scene"], seed + i, clip["start_s"])
        meta["name"] = name
        write_ground_truth(frames, out_dir / f"{name}.frames.csv", out_dir / f"{name}.truth.json", meta)
        written.append(Path(frames.attrs["video_path"]))
    return written


__all__ = ["Camera", "Scene", "FrameRenderer", "ball_shape", "default_clips", "ellipse_coverage",
           "lighting_gain", "make_default_videos", "render_background", "render_frame", "render_video",
           "seam_curve", "video_metadata", "write_ground_truth"]
