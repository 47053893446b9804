"""The moving things, drawn per frame in a small region: the shaded ball, its shadows, the hand.

Every function works on a region of interest given by its pixel-centre
coordinates ``cols`` (1-D, x) and ``rows`` (1-D, y) in displayed pixels
(integer at pixel centres, y down) and returns arrays of shape
(len(rows), len(cols)[, 3]).  Coverage is anti-aliased with a one-pixel
ramp across the outline, clip(0.5 - signed distance in px, 0, 1), which is
symmetric about the outline, so the coverage-weighted centre of a disc is its
centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import BallStyle

#: Unit vector towards the light in camera axes (x right, y up, z towards the camera): above, in front, a bit left.
LIGHT_DIRECTION = np.array([-0.25, 0.75, 0.6]) / np.linalg.norm([-0.25, 0.75, 0.6])


def _seam_points(n: int = 160) -> np.ndarray:
    """Unit vectors (n, 3) along a tennis ball's seam (the classic a cos t + b cos 3t curve)."""
    t = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
    a, b = 0.7, 0.3
    p = np.column_stack([a * np.cos(t) + b * np.cos(3 * t), a * np.sin(t) - b * np.sin(3 * t),
                         2 * math.sqrt(a * b) * np.sin(2 * t)])
    return p / np.linalg.norm(p, axis=1, keepdims=True)


SEAM_POINTS = _seam_points()


def disc_coverage(cols, rows, centre_x: float, centre_y: float, radius_px: float) -> np.ndarray:
    """Anti-aliased coverage (0-1) of a disc of ``radius_px`` centred at (centre_x, centre_y)."""
    dx = cols[None, :] - centre_x
    dy = rows[:, None] - centre_y
    return np.clip(radius_px - np.sqrt(dx * dx + dy * dy) + 0.5, 0.0, 1.0)


def ball_colour(cols, rows, centre_x: float, centre_y: float, radius_px: float, style: BallStyle,
                spin_angle_rad: float) -> np.ndarray:
    """Colour (rows, cols, 3) of the lit sphere's surface seen at each pixel (valid where covered)."""
    nx = (cols[None, :] - centre_x) / radius_px
    ny = (centre_y - rows[:, None]) / radius_px
    rho2 = nx * nx + ny * ny
    # pixels on the anti-aliased rim take the rim's normal
    norm = np.sqrt(np.maximum(rho2, 1.0))
    nx, ny = nx / norm, ny / norm
    nz = np.sqrt(np.clip(1.0 - nx * nx - ny * ny, 0.0, 1.0))
    lx, ly, lz = LIGHT_DIRECTION
    diffuse = np.clip(nx * lx + ny * ly + nz * lz, 0.0, 1.0)
    shade = style.ambient + (1.0 - style.ambient) * diffuse
    colour = np.asarray(style.colour_rgb, np.float32) * shade[:, :, None]
    if style.specular > 0:
        half = LIGHT_DIRECTION + np.array([0.0, 0.0, 1.0])
        half /= np.linalg.norm(half)
        highlight = np.clip(nx * half[0] + ny * half[1] + nz * half[2], 0.0, 1.0) ** 40
        colour += (255.0 * style.specular * highlight)[:, :, None]
    if style.seam:
        c, s = math.cos(spin_angle_rad), math.sin(spin_angle_rad)
        tilt = math.radians(35.0)
        # the seam turns with the spin about the camera axis, tilted so that it looks 3-D
        seam = SEAM_POINTS @ np.array([[1, 0, 0], [0, math.cos(tilt), -math.sin(tilt)],
                                       [0, math.sin(tilt), math.cos(tilt)]]).T
        seam = seam @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]).T
        seam = seam[seam[:, 2] > -0.1]
        if len(seam):
            normals = np.stack([nx, ny, nz], axis=-1).reshape(-1, 3).astype(np.float32)
            # nearest seam point by the largest dot product; chord distance from it
            closest = (normals @ seam.T.astype(np.float32)).max(axis=1)
            distance = np.sqrt(np.clip(2.0 - 2.0 * closest, 0.0, None)).reshape(nx.shape)
            width = 0.05
            band = np.clip((width - distance) * radius_px + 0.5, 0.0, 1.0)
            colour += (band * (0.85 * 255.0 * shade - colour[:, :, 1]).clip(0, None))[:, :, None]
    return np.clip(colour, 0.0, 255.0)


def soft_ellipse(cols, rows, centre_x: float, centre_y: float, semi_x: float, semi_y: float,
                 softness_px: float) -> np.ndarray:
    """A soft-edged ellipse (0-1): a logistic ramp of width ``softness_px`` across its outline."""
    dx = (cols[None, :] - centre_x) / semi_x
    dy = (rows[:, None] - centre_y) / semi_y
    distance_px = (np.sqrt(dx * dx + dy * dy) - 1.0) * min(semi_x, semi_y)
    return 0.5 * (1.0 - np.tanh(distance_px / (2.0 * max(softness_px, 0.3))))


@dataclass(frozen=True)
class Capsule:
    """A segment (a to b, displayed px) thickened by ``radius_px``."""

    ax: float
    ay: float
    bx: float
    by: float
    radius_px: float

    def signed_distance(self, cols, rows) -> np.ndarray:
        """Signed distance (px, negative inside) of each pixel to the capsule's outline."""
        px = cols[None, :] - self.ax
        py = rows[:, None] - self.ay
        ex, ey = self.bx - self.ax, self.by - self.ay
        h = np.clip((px * ex + py * ey) / max(ex * ex + ey * ey, 1e-12), 0.0, 1.0)
        return np.sqrt((px - h * ex) ** 2 + (py - h * ey) ** 2) - self.radius_px

    def bounds(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) bounding box in px."""
        r = self.radius_px + 1.0
        return min(self.ax, self.bx) - r, min(self.ay, self.by) - r, max(self.ax, self.bx) + r, max(self.ay, self.by) + r


def hand_coverage_and_colour(capsules: list[Capsule], cols, rows, skin_rgb) -> tuple[np.ndarray, np.ndarray]:
    """Coverage (0-1) and colour of a hand built from capsules; each limb is brighter along its middle."""
    distance = np.full((rows.size, cols.size), np.inf, np.float32)
    depth = np.zeros((rows.size, cols.size), np.float32)
    for capsule in capsules:
        bx0, by0, bx1, by1 = capsule.bounds()
        c0, c1 = np.searchsorted(cols, [bx0, bx1])
        r0, r1 = np.searchsorted(rows, [by0, by1])
        if c0 >= c1 or r0 >= r1:
            continue
        d = capsule.signed_distance(cols[c0:c1], rows[r0:r1])
        np.minimum(distance[r0:r1, c0:c1], d, out=distance[r0:r1, c0:c1])
        np.maximum(depth[r0:r1, c0:c1], np.clip(-d / max(capsule.radius_px, 1.0), 0.0, 1.0), out=depth[r0:r1, c0:c1])
    coverage = np.clip(0.5 - distance, 0.0, 1.0)
    shade = 0.72 + 0.28 * np.sqrt(depth)
    return coverage, np.asarray(skin_rgb, np.float32) * shade[:, :, None]
