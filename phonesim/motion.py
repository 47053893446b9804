"""The ball's and the hand's motion: refsim's physics, and a prescribed hand around it.

The ball's flights, contacts, release and catch come from
:func:`refsim.simulate` (numerical integration of the flights with drag and
of every contact); nothing here fits or tracks anything.  Times are on the
clip clock (s): the clip starts at 0 and the ball is released at rest at
``hand.hold_s``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd

import refsim

from .config import ClipConfig

#: Step (s) of the table the blur's sub-frame positions are interpolated from (linear
#: interpolation errs by g dt^2 / 8 = 5e-8 m in flight).
TRACK_STEP_S = 2e-4


def smoothstep(x):
    """0 below 0, 1 above 1, 3x^2 - 2x^3 between (a smooth start and stop)."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


class BallMotion:
    """The simulated drop and the hand that releases (and catches) the ball.

    Parameters
    ----------
    config : ClipConfig
        The clip; its ``ball``, ``hand``, ``drop_height_m`` and ``g_m_s2`` are used.
    """

    def __init__(self, config: ClipConfig):
        ball = refsim.preset(config.ball.model)
        if config.ball.radius_m is not None:
            ball = replace(ball, radius_m=config.ball.radius_m)
        if config.ball.drag_coefficient is not None:
            ball = replace(ball, drag_coefficient=config.ball.drag_coefficient)
        self.hand = config.hand
        catch = None
        if config.hand.catch_after_impact is not None:
            catch = refsim.Catch(after_impact=config.hand.catch_after_impact, tremor_amp_m=5e-4)
        self.truth = refsim.simulate(ball, config.drop_height_m, g_m_s2=config.g_m_s2,
                                     t_release_s=config.hand.hold_s, catch=catch,
                                     t_end_s=config.hand.hold_s + (15.0 if config.duration_s is None
                                                                   else max(config.duration_s, 0.0) + 0.2))
        self.radius_m = ball.radius_m
        if config.duration_s is not None:
            self.duration_s = float(config.duration_s)
        elif catch is not None:
            self.duration_s = float(self.truth.t_catch_s) + 0.8
        elif self.truth.status == "rest":
            self.duration_s = float(self.truth.rest_time_s) + 0.6
        else:
            self.duration_s = float(self.truth.t_end_s) - 0.1
        # the table reaches past the last exposure; refsim's track ends at t_end_s unless the ball rests
        grid = np.arange(0.0, self.duration_s + 0.05, TRACK_STEP_S)
        table = self.truth.sample(grid)
        spin = table["spin_rad_s"].to_numpy()
        self._grid_s = grid
        self._grid_x_m = table["x_m"].to_numpy()
        self._grid_y_m = table["y_centre_m"].to_numpy()
        self._grid_angle_rad = np.concatenate([[0.0], np.cumsum(0.5 * (spin[1:] + spin[:-1]) * TRACK_STEP_S)])

    @property
    def release_time_s(self) -> float:
        """Release time (s)."""
        return float(self.truth.t_release_s)

    @property
    def catch_time_s(self) -> float:
        """Catch time (s), NaN without a catch."""
        return float(self.truth.t_catch_s)

    def sample(self, t_s) -> pd.DataFrame:
        """The ball at times ``t_s`` (s), exactly: refsim's columns plus ``spin_angle_rad`` (counter-clockwise)."""
        df = self.truth.sample(np.asarray(t_s, dtype=float))
        df["spin_angle_rad"] = np.interp(df["t_s"].to_numpy(), self._grid_s, self._grid_angle_rad)
        return df

    def interpolated(self, t_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Centre X, Y (m) and spin angle (rad) at times ``t_s`` (s) from the 0.2 ms table (for the blur)."""
        return (np.interp(t_s, self._grid_s, self._grid_x_m), np.interp(t_s, self._grid_s, self._grid_y_m),
                np.interp(t_s, self._grid_s, self._grid_angle_rad))

    def hand_pose(self, t_s: float) -> tuple[float, float, float]:
        """Where the hand grips at time ``t_s`` (s): (X, Y) in m of the gripped ball's centre, and the grip's opening (0 closed, 1 open)."""
        release = self.release_time_s
        x0 = float(self.truth.x(release)[0])
        y0 = float(self.truth.y_release_centre_m)
        away_x, away_y = self.hand.away_m
        if t_s <= release:
            return x0, y0, 0.0
        catch = self.catch_time_s
        if not math.isnan(catch) and t_s >= catch - self.hand.catch_approach_s:
            if t_s >= catch:
                return float(self.truth.x(t_s)[0]), float(self.truth.y_centre(t_s)[0]), 0.0
            xc, yc = float(self.truth.x(catch)[0]), float(self.truth.y_centre(catch)[0])
            k = float(smoothstep((catch - t_s) / self.hand.catch_approach_s))
            return xc + k * away_x, yc + k * away_y, k
        k = float(smoothstep((t_s - release) / self.hand.away_s))
        opening = float(smoothstep((t_s - release) / 0.1))
        return x0 + k * away_x, y0 + k * away_y, opening
