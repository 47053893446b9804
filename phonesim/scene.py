"""The static scene, drawn once per clip: room, floor, and the scale objects in the drop plane.

The room (wall, board, clutter, floor) is drawn in the untilted image and
warped by the camera's rotation homography.  Objects in the drop plane
(rulers, tapes, markers, checkerboards) are painted afterwards straight
through the plane-to-pixel homography, each pixel averaging 4 x 4 samples of
the object's printed texture, so their truth (corner and tick positions) is
exactly the homography's image of their plane coordinates.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from .camera import PlaneView, apply_homography
from .config import Checkerboard, ClipConfig, Marker, Ruler, SceneStyle

#: Sub-pixel samples per axis when painting a planar object.
PLANAR_SUPERSAMPLING = 4


@dataclass(frozen=True)
class PlanarTexture:
    """A printed object lying in the drop plane.

    Attributes
    ----------
    image : ndarray
        RGB texture (rows, cols, 3); texture pixel (i, j) covers
        [j, j+1) x [i, i+1) in texture units.
    origin_m : tuple
        Plane point (X, Y in m) of the texture's corner (0, 0).
    along, across : tuple
        Plane unit vectors of the texture's columns and rows.
    px_per_m : float
        Texture pixels per m.
    """

    image: np.ndarray
    origin_m: tuple[float, float]
    along: tuple[float, float]
    across: tuple[float, float]
    px_per_m: float


def paint_planar(canvas: np.ndarray, view: PlaneView, texture: PlanarTexture) -> None:
    """Paint ``texture`` into the float RGB ``canvas`` in place, supersampled 4 x 4 per pixel."""
    rows, cols = texture.image.shape[:2]
    length, width = cols / texture.px_per_m, rows / texture.px_per_m
    ox, oy = texture.origin_m
    (ax, ay), (cx, cy) = texture.along, texture.across
    corner_x = np.array([ox, ox + length * ax, ox + length * ax + width * cx, ox + width * cx])
    corner_y = np.array([oy, oy + length * ay, oy + length * ay + width * cy, oy + width * cy])
    px, py = view.to_px(corner_x, corner_y)
    height_px, width_px = canvas.shape[:2]
    x0, x1 = max(int(math.floor(px.min())) - 1, 0), min(int(math.ceil(px.max())) + 2, width_px)
    y0, y1 = max(int(math.floor(py.min())) - 1, 0), min(int(math.ceil(py.max())) + 2, height_px)
    if x0 >= x1 or y0 >= y1:
        return
    ss = PLANAR_SUPERSAMPLING
    offsets = (np.arange(ss) + 0.5) / ss - 0.5
    gy, gx = np.meshgrid(np.arange(y0, y1), np.arange(x0, x1), indexing="ij")
    shape = gx.shape + (ss, ss)
    sx = np.broadcast_to(gx[..., None, None] + offsets[None, None, None, :], shape).ravel()
    sy = np.broadcast_to(gy[..., None, None] + offsets[None, None, :, None], shape).ravel()
    plane_x, plane_y = apply_homography(np.linalg.inv(view.plane_to_px), sx, sy)
    dx, dy = plane_x - ox, plane_y - oy
    col = (dx * ax + dy * ay) * texture.px_per_m
    row = (dx * cx + dy * cy) * texture.px_per_m
    inside = (col >= 0) & (col < cols) & (row >= 0) & (row < rows)
    region = canvas[y0:y1, x0:x1]
    samples = np.repeat(region.reshape(-1, 3), ss * ss, axis=0)
    samples[inside] = texture.image[row[inside].astype(int), col[inside].astype(int)]
    region[...] = samples.reshape(y1 - y0, x1 - x0, ss * ss, 3).mean(axis=2)


# ---------------------------------------------------------------------------------------
# Scale objects
# ---------------------------------------------------------------------------------------
def ruler_axes(ruler: Ruler) -> tuple[tuple[float, float], tuple[float, float]]:
    """Plane unit vectors (along the scale, across into the body).

    Upright: the scale runs up and the body lies right of the tick edge.
    Lying: the scale runs right and the body lies below the tick edge (so the
    print is not mirrored).
    """
    return ((0.0, 1.0), (1.0, 0.0)) if ruler.upright else ((1.0, 0.0), (0.0, -1.0))


def tick_length_frac(mm: int, tape: bool) -> float:
    """Length of the tick at ``mm`` as a fraction of the ruler's width."""
    if mm % 10 == 0:
        return 0.5 if not tape else 0.4
    if mm % 5 == 0:
        return 0.33
    return 0.22


def _put_centred_text(image, text, centre_xy, height_px, colour, thickness):
    scale = height_px / 22.0
    (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thickness)
    origin = (int(round(centre_xy[0] - w / 2)), int(round(centre_xy[1] + h / 2)))
    cv2.putText(image, text, origin, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, thickness, cv2.LINE_AA)


def ruler_texture(ruler: Ruler, with_ticks: bool) -> PlanarTexture:
    """The printed ruler or tape (ticks, numbers) as a planar texture at 8 px per mm."""
    tex_px_per_m = 8000.0
    cols = int(round(ruler.length_m * tex_px_per_m))
    rows = int(round(ruler.width_m * tex_px_per_m))
    tape = ruler.kind == "tape"
    image = np.empty((rows, cols, 3), np.uint8)
    image[:] = ruler.colour_rgb
    ink = tuple(float(c) for c in ruler.ink_rgb)
    n_mm = int(math.floor(ruler.length_m * 1000 + 1e-9))
    line_px = max(1, int(round(0.3e-3 * tex_px_per_m)))
    for mm in range(n_mm + 1):
        x = int(round(mm * 1e-3 * tex_px_per_m))
        if with_ticks:
            length = int(round(tick_length_frac(mm, tape) * rows))
            cv2.line(image, (x, 0), (x, length), ink, line_px)
        if mm % 10 == 0 and 0 < mm < n_mm:
            big = tape and mm % 100 == 0
            colour = (200.0, 30.0, 30.0) if big else ink
            height = (0.32 if big else 0.22) * rows
            _put_centred_text(image, str(mm // 10), (x, 0.72 * rows), height, colour, max(1, int(rows * 0.03)))
    cv2.rectangle(image, (0, 0), (cols - 1, rows - 1), tuple(0.7 * float(c) for c in ruler.colour_rgb), line_px)
    along, across = ruler_axes(ruler)
    return PlanarTexture(image.astype(np.float32), ruler.zero_m, along, across, tex_px_per_m)


def paint_ticks_on_rows(canvas: np.ndarray, view: PlaneView, ruler: Ruler) -> None:
    """Paint an upright ruler's ticks as whole pixel rows (each at the rounded row of its plane height)."""
    scale = view.scale_px_per_m
    x_edge, _ = view.to_px(ruler.zero_m[0], ruler.zero_m[1])
    for mm in range(int(math.floor(ruler.length_m * 1000 + 1e-9)) + 1):
        step_mm = 10 if mm % 10 == 0 else (5 if mm % 5 == 0 else 1)
        # ticks closer than 2 px merge into a grey band; leave those to the body
        if step_mm < 10 and step_mm * 1e-3 * scale < 2.0:
            continue
        _, y = view.to_px(ruler.zero_m[0], ruler.zero_m[1] + mm * 1e-3)
        row = int(round(float(y)))
        length_px = tick_length_frac(mm, ruler.kind == "tape") * ruler.width_m * scale
        c0 = int(round(float(x_edge)))
        c1 = int(round(float(x_edge) + length_px))
        if 0 <= row < canvas.shape[0]:
            canvas[row, max(c0, 0):max(c1, 0) + 1] = ruler.ink_rgb


def paper(centre_m: tuple[float, float], width_m: float, height_m: float) -> PlanarTexture:
    """A white sheet of paper (plain texture) centred at ``centre_m``."""
    px_per_m = 1000.0
    image = np.full((int(round(height_m * px_per_m)), int(round(width_m * px_per_m)), 3), 245.0, np.float32)
    return PlanarTexture(image, (centre_m[0] - width_m / 2, centre_m[1] + height_m / 2), (1.0, 0.0), (0.0, -1.0),
                         px_per_m)


def marker_texture(marker: Marker) -> PlanarTexture:
    """The marker's black-and-white bits (one texture pixel per bit, black border included)."""
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, marker.dictionary))
    bits = dictionary.markerSize + 2
    image = cv2.aruco.generateImageMarker(dictionary, marker.marker_id, bits, borderBits=1)
    rgb = np.repeat(image[:, :, None].astype(np.float32), 3, axis=2) * (230.0 / 255.0) + 15.0
    half = marker.side_m / 2
    return PlanarTexture(rgb, (marker.centre_m[0] - half, marker.centre_m[1] + half), (1.0, 0.0), (0.0, -1.0),
                         bits / marker.side_m)


def marker_corners_m(marker: Marker) -> np.ndarray:
    """Plane corners (4, 2) in m in ArUco's order: top-left, top-right, bottom-right, bottom-left."""
    cx, cy = marker.centre_m
    h = marker.side_m / 2
    return np.array([[cx - h, cy + h], [cx + h, cy + h], [cx + h, cy - h], [cx - h, cy - h]])


def checkerboard_texture(board: Checkerboard) -> PlanarTexture:
    """The checkerboard's squares, one texture pixel per square, the top-left square black."""
    cols, rows = board.squares
    pattern = (np.add.outer(np.arange(rows), np.arange(cols)) % 2).astype(np.float32)
    rgb = np.repeat(pattern[:, :, None], 3, axis=2) * 230.0 + 15.0
    return PlanarTexture(rgb, (board.centre_m[0] - cols * board.square_m / 2,
                               board.centre_m[1] + rows * board.square_m / 2),
                         (1.0, 0.0), (0.0, -1.0), 1.0 / board.square_m)


def checkerboard_inner_corners_m(board: Checkerboard) -> np.ndarray:
    """Plane positions (n, 2) in m of the inner corners, row by row from the top-left."""
    cols, rows = board.squares
    x0 = board.centre_m[0] - cols * board.square_m / 2
    y0 = board.centre_m[1] + rows * board.square_m / 2
    j, i = np.meshgrid(np.arange(1, cols), np.arange(1, rows))
    return np.column_stack([x0 + j.ravel() * board.square_m, y0 - i.ravel() * board.square_m])


# ---------------------------------------------------------------------------------------
# The room
# ---------------------------------------------------------------------------------------
def _smooth_noise(rng: np.random.Generator, shape: tuple[int, int], cell_px: float) -> np.ndarray:
    """Zero-mean, unit-sd noise varying over about ``cell_px`` pixels."""
    small = rng.standard_normal((max(2, int(shape[0] / cell_px) + 2), max(2, int(shape[1] / cell_px) + 2)))
    big = cv2.resize(small.astype(np.float32), (shape[1], shape[0]), interpolation=cv2.INTER_CUBIC)
    return (big - big.mean()) / (big.std() + 1e-9)


def _draw_wall(canvas, style: SceneStyle, wall_base_row: int, rng):
    height, width = canvas.shape[:2]
    rows = np.arange(height, dtype=np.float32)[:, None]
    light = 1.06 - 0.12 * rows / max(wall_base_row, 1)
    texture = 1.0 + style.wall_texture * _smooth_noise(rng, (height, width), 60.0) \
        + 0.3 * style.wall_texture * _smooth_noise(rng, (height, width), 4.0)
    canvas[:] = np.asarray(style.wall_rgb, np.float32) * (light * texture)[:, :, None]


def _draw_board(canvas, centre_x: float, floor_row: float, scale: float):
    x0, x1 = int(centre_x - 0.7 * scale), int(centre_x + 0.7 * scale)
    y0, y1 = int(floor_row - 2.1 * scale), int(floor_row - 0.3 * scale)
    frame_px = max(2, int(0.02 * scale))
    cv2.rectangle(canvas, (x0 - frame_px, y0 - frame_px), (x1 + frame_px, y1 + frame_px), (150, 152, 158), -1,
                  cv2.LINE_AA)
    ys = np.clip(np.arange(y0, y1), 0, canvas.shape[0] - 1)
    xs = np.clip(np.arange(x0, x1), 0, canvas.shape[1] - 1)
    gloss = 0.97 + 0.03 * np.linspace(1.0, -1.0, xs.size)[None, :] + 0.02 * np.linspace(1, 0, ys.size)[:, None]
    canvas[np.ix_(ys, xs)] = np.array([246, 246, 243], np.float32) * gloss[:, :, None]


def _draw_clutter(canvas, count: int, drop_x: float, wall_base_row: int, scale: float, rng):
    height, width = canvas.shape[:2]
    keep_clear = 0.25 * scale
    for _ in range(count):
        kind = rng.choice(["poster", "furniture", "edge"], p=[0.45, 0.35, 0.2])
        side = rng.choice([-1, 1])
        x = drop_x + side * (keep_clear + rng.uniform(0.0, 0.5) * width)
        if kind == "edge":
            shade = rng.uniform(0.6, 1.1)
            thickness = max(2, int(0.04 * scale))
            cv2.line(canvas, (int(x), 0), (int(x), wall_base_row), tuple(float(c) for c in 180 * shade * np.ones(3)),
                     thickness, cv2.LINE_AA)
            cv2.line(canvas, (int(x) + thickness, 0), (int(x) + thickness, wall_base_row), (90, 85, 80), 1,
                     cv2.LINE_AA)
        elif kind == "poster":
            w, h = rng.uniform(0.3, 0.7) * scale, rng.uniform(0.4, 0.9) * scale
            y = rng.uniform(0.05, 0.6) * wall_base_row
            colour = rng.uniform(40, 230, 3)
            cv2.rectangle(canvas, (int(x - w / 2), int(y)), (int(x + w / 2), int(y + h)), colour.tolist(), -1,
                          cv2.LINE_AA)
            for _ in range(rng.integers(2, 6)):
                bx, by = x + rng.uniform(-0.4, 0.3) * w, y + rng.uniform(0.05, 0.85) * h
                cv2.rectangle(canvas, (int(bx), int(by)), (int(bx + rng.uniform(0.1, 0.4) * w),
                                                           int(by + rng.uniform(0.03, 0.12) * h)),
                              rng.uniform(0, 255, 3).tolist(), -1, cv2.LINE_AA)
        else:
            w, h = rng.uniform(0.3, 0.8) * scale, rng.uniform(0.3, 0.9) * scale
            colour = (rng.uniform(60, 120), rng.uniform(40, 80), rng.uniform(25, 50))
            cv2.rectangle(canvas, (int(x - w / 2), int(wall_base_row - h)), (int(x + w / 2), int(wall_base_row + 0.05 * scale)),
                          colour, -1, cv2.LINE_AA)
            cv2.ellipse(canvas, (int(x), int(wall_base_row - h)), (int(w / 2), max(1, int(0.05 * scale))), 0, 0, 360,
                        tuple(1.2 * c for c in colour), -1, cv2.LINE_AA)


def _draw_floor(canvas, style: SceneStyle, wall_base_row: int, floor_row: float, focal_px: float, scale: float, rng):
    height, width = canvas.shape[:2]
    if wall_base_row >= height:
        return
    horizon = min((height - 1) / 2, wall_base_row - 0.02 * height)
    # depth (m) of each floor row and lateral position (m) of each pixel, the drop plane at focal/scale m
    distance = focal_px / scale
    rows = np.arange(wall_base_row, height, dtype=np.float32)
    depth = distance * (floor_row - horizon) / (rows - horizon)
    lateral = (np.arange(width, dtype=np.float32)[None, :] - (width - 1) / 2) * depth[:, None] / focal_px
    base = np.asarray(style.floor_rgb, np.float32)
    if style.floor == "plain":
        shade = 1.0 + 0.03 * _smooth_noise(rng, (rows.size, width), 20.0)
    else:
        plank_m = 0.14 if style.floor == "wood" else 0.9
        plank = np.floor(depth / plank_m).astype(int)
        tone = 1.0 + 0.08 * rng.standard_normal(plank.max() - plank.min() + 1)[plank - plank.min()]
        phase = rng.uniform(0, 2 * np.pi, plank.max() - plank.min() + 1)[plank - plank.min()]
        grain = np.sin(2 * np.pi * (depth[:, None] * 60.0 + 0.6 * np.sin(lateral * 3.0 + phase[:, None]))) \
            * np.sin(lateral * 0.7 + phase[:, None])
        seam = np.abs(depth / plank_m - np.round(depth / plank_m)) * plank_m * focal_px / depth < 0.8
        shade = tone[:, None] * (1.0 + 0.07 * grain) * np.where(seam[:, None], 0.7, 1.0)
    canvas[wall_base_row:] = base * shade[:, :, None]
    skirting = max(2, int(0.05 * scale))
    canvas[max(wall_base_row - skirting, 0):wall_base_row] = np.asarray(style.wall_rgb, np.float32) * 1.04


@dataclass
class StaticScene:
    """The rendered static frame and where its scale objects are.

    Attributes
    ----------
    image : ndarray
        Displayed RGB frame (float32, 0-255) without ball, shadow or hand.
    floor_mask : ndarray of bool
        Pixels showing the floor (the floor shadow falls only there).
    objects : dict
        Truth of the scale objects (see :func:`render_static_scene`).
    """

    image: np.ndarray
    floor_mask: np.ndarray
    objects: dict


def render_static_scene(config: ClipConfig, view: PlaneView, rng: np.random.Generator) -> StaticScene:
    """Draw the room and the scale objects once.

    ``objects`` holds, in displayed pixels: ``markers`` (id, dictionary,
    side_m, ``corners_px`` in ArUco order), ``checkerboards`` (square_m,
    ``inner_corners_px``), ``rulers`` (kind, ``zero_px``,
    ``direction_px_per_m``: pixel step per m along the scale at the zero).
    """
    width, height = config.frame_size_px
    style = config.scene
    scale = view.scale_px_per_m
    drop_x = config.camera.drop_column_frac * (width - 1)
    floor_row = config.camera.floor_row_frac * (height - 1)
    wall_base_row = int(round(floor_row - style.wall_base_above_floor_frac * height))
    focal = 0.5 * width / math.tan(math.radians(config.camera.horizontal_fov_deg) / 2)
    canvas = np.empty((height, width, 3), np.float32)
    _draw_wall(canvas, style, wall_base_row, rng)
    if style.board:
        _draw_board(canvas, drop_x, floor_row, scale)
    _draw_clutter(canvas, style.clutter, drop_x, wall_base_row, scale, rng)
    _draw_floor(canvas, style, wall_base_row, floor_row, focal, scale, rng)
    floor_mask = np.zeros((height, width), np.uint8)
    floor_mask[wall_base_row:] = 1
    if config.camera.tilted:
        canvas = cv2.warpPerspective(canvas, view.image_rotation, (width, height), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_REFLECT)
        floor_mask = cv2.warpPerspective(floor_mask, view.image_rotation, (width, height), flags=cv2.INTER_NEAREST,
                                         borderMode=cv2.BORDER_REPLICATE)
    objects: dict = {"markers": [], "checkerboards": [], "rulers": []}
    for marker in config.markers:
        paint_planar(canvas, view, paper(marker.centre_m, 1.4 * marker.side_m, 1.4 * marker.side_m))
        paint_planar(canvas, view, marker_texture(marker))
        corners = marker_corners_m(marker)
        cx, cy = view.to_px(corners[:, 0], corners[:, 1])
        objects["markers"].append({"id": marker.marker_id, "dictionary": marker.dictionary, "side_m": marker.side_m,
                                   "corners_px": np.column_stack([cx, cy]).tolist()})
    for board in config.checkerboards:
        cols, rows = board.squares
        paint_planar(canvas, view, paper(board.centre_m, (cols + 1) * board.square_m, (rows + 1) * board.square_m))
        paint_planar(canvas, view, checkerboard_texture(board))
        inner = checkerboard_inner_corners_m(board)
        cx, cy = view.to_px(inner[:, 0], inner[:, 1])
        objects["checkerboards"].append({"squares": list(board.squares), "square_m": board.square_m,
                                         "inner_corners_px": np.column_stack([cx, cy]).tolist()})
    for ruler in config.rulers:
        on_rows = ruler.ticks_on_rows and ruler.upright and not config.camera.tilted
        paint_planar(canvas, view, ruler_texture(ruler, with_ticks=not on_rows))
        if on_rows:
            paint_ticks_on_rows(canvas, view, ruler)
        along, _ = ruler_axes(ruler)
        zx, zy = view.to_px(*ruler.zero_m)
        objects["rulers"].append({"kind": ruler.kind, "length_m": ruler.length_m, "zero_m": list(ruler.zero_m),
                                  "zero_px": [float(zx), float(zy)], "ticks_on_rows": on_rows,
                                  "direction_px_per_m": list(view.direction_px_per_m(*ruler.zero_m, *along))})
    return StaticScene(canvas, floor_mask.astype(bool), objects)
