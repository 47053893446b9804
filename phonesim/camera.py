"""The camera: drop plane (m) to displayed pixels, and the display rotation.

Pixel coordinates: x (column) to the right, y (row) down, the centre of the
top-left pixel at (0, 0), so pixel centres sit at integer coordinates.  The
plane's coordinates are X right and Y up in m, origin on the floor at the
drop line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config import CameraSetup


def rotation_matrix(pitch_deg: float, yaw_deg: float, roll_deg: float) -> np.ndarray:
    """Camera rotation R = Rz(roll) Ry(yaw) Rx(pitch), angles in degrees, camera axes x right, y down, z forward."""
    p, y, r = (math.radians(a) for a in (pitch_deg, yaw_deg, roll_deg))
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    ry = np.array([[math.cos(y), 0, math.sin(y)], [0, 1, 0], [-math.sin(y), 0, math.cos(y)]])
    rz = np.array([[math.cos(r), -math.sin(r), 0], [math.sin(r), math.cos(r), 0], [0, 0, 1]])
    return rz @ ry @ rx


def apply_homography(h: np.ndarray, x, y) -> tuple[np.ndarray, np.ndarray]:
    """Map points (x, y) through the 3x3 homography ``h``; returns the mapped (x, y) arrays."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    w = h[2, 0] * x + h[2, 1] * y + h[2, 2]
    return (h[0, 0] * x + h[0, 1] * y + h[0, 2]) / w, (h[1, 0] * x + h[1, 1] * y + h[1, 2]) / w


@dataclass(frozen=True)
class PlaneView:
    """The pinhole view of the drop plane.

    Attributes
    ----------
    plane_to_px : ndarray
        3x3 homography from plane (X, Y in m) to displayed pixels (x, y).
    image_rotation : ndarray
        3x3 homography from the untilted image to the tilted one (pure
        camera rotation, re-centred); the static room is drawn untilted and
        warped by it.
    scale_px_per_m : float
        Nominal scale before the tilt (px per m).
    """

    plane_to_px: np.ndarray
    image_rotation: np.ndarray
    scale_px_per_m: float

    @classmethod
    def build(cls, camera: CameraSetup, width_px: int, height_px: int, downscale: float,
              centre_height_m: float) -> "PlaneView":
        """The view for a displayed frame of ``width_px`` x ``height_px``.

        ``centre_height_m`` is the plane height (m) on the drop line that
        stays at its untilted pixel when the camera is rotated.
        """
        s = camera.scale_px_per_m * downscale
        u0 = camera.drop_column_frac * (width_px - 1)
        v0 = camera.floor_row_frac * (height_px - 1)
        untilted = np.array([[s, 0.0, u0], [0.0, -s, v0], [0.0, 0.0, 1.0]])
        rotation = np.eye(3)
        if camera.tilted:
            f = 0.5 * width_px / math.tan(math.radians(camera.horizontal_fov_deg) / 2)
            k = np.array([[f, 0, (width_px - 1) / 2], [0, f, (height_px - 1) / 2], [0, 0, 1.0]])
            rotation = k @ rotation_matrix(camera.pitch_deg, camera.yaw_deg, camera.roll_deg) @ np.linalg.inv(k)
            ax, ay = u0, v0 - s * centre_height_m
            bx, by = apply_homography(rotation, ax, ay)
            rotation = np.array([[1, 0, ax - bx], [0, 1, ay - by], [0, 0, 1.0]]) @ rotation
            rotation /= rotation[2, 2]
        return cls(rotation @ untilted, rotation, s)

    def to_px(self, x_m, y_m) -> tuple[np.ndarray, np.ndarray]:
        """Displayed pixel (x, y) of plane points (X, Y in m)."""
        return apply_homography(self.plane_to_px, x_m, y_m)

    def local_scale_px_per_m(self, x_m, y_m) -> np.ndarray:
        """Local isotropic scale sqrt|det J| (px per m) of the plane-to-pixel map at (X, Y)."""
        h = self.plane_to_px
        x_m = np.asarray(x_m, dtype=float)
        y_m = np.asarray(y_m, dtype=float)
        w = h[2, 0] * x_m + h[2, 1] * y_m + h[2, 2]
        # det of the Jacobian of a homography is det(H) / w^3
        return np.sqrt(np.abs(np.linalg.det(h)) / np.abs(w) ** 3)

    def direction_px_per_m(self, x_m: float, y_m: float, dx: float, dy: float) -> tuple[float, float]:
        """Pixel displacement per m moved along the plane direction (dx, dy) from (X, Y)."""
        eps = 1e-4
        x0, y0 = self.to_px(x_m, y_m)
        x1, y1 = self.to_px(x_m + eps * dx, y_m + eps * dy)
        return float((x1 - x0) / eps), float((y1 - y0) / eps)


def stored_from_displayed(frame: np.ndarray, rotation_deg: int) -> np.ndarray:
    """The frame as stored in the file when it is displayed rotated by ``rotation_deg`` (counter-clockwise).

    Rotating the stored frame counter-clockwise by ``rotation_deg`` (what
    players do with the display matrix) gives ``frame`` back.
    """
    return np.ascontiguousarray(np.rot90(frame, -(rotation_deg // 90)))


def displayed_from_stored(frame: np.ndarray, rotation_deg: int) -> np.ndarray:
    """The displayed frame for a stored (decoded) frame and its rotation (counter-clockwise degrees)."""
    return np.ascontiguousarray(np.rot90(frame, (rotation_deg // 90) % 4))
