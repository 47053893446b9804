"""Named, seeded, ready-made recordings.

Each function returns ``(log, truth)``: the log DataFrame exactly as
:func:`refsim.record.record` makes it (what a user's CSV would contain) and
the :class:`refsim.ball.Truth` on the **same time base** as the log's time
column (``truth.recording`` holds the per-sample :class:`RecordInfo`:
true instants, noise-free values, jump / lost / kept masks).

Gravity is 9.81 m/s^2 in all of them (``truth.g_m_s2``).
"""

from __future__ import annotations

from .ball import Ball, simulate
from .contact import LinearSpringDamper
from .hand import Catch, HandPhase
from .record import Jumps, record

__all__ = ["tennis_100hz", "steel_500hz", "marble_paper_200fps_px", "tennis_bottom_2khz",
           "table_tennis_caught_60fps_px",
           "seed_example3_oblique", "SMOOTH_TENNIS_BALL", "SCENARIOS"]


def _finish(truth, log_info, offset):
    log, info = log_info
    truth = truth.shifted(offset) if offset else truth
    truth.recording = info
    return log, truth


def tennis_100hz(seed: int = 0):
    """Tennis ball dropped from 1.00 m (bottom) at rest, centre logged at 100 Hz in m.

    1 mm Gaussian noise, quadratic drag, recording from 0.25 s before the
    release to 1.5 s after the rest (~22 impacts, rest at ~4.0 s).
    """
    truth = simulate("tennis", 1.0, t_end_s=12.0)
    res = record(truth, 100.0, point="centre", unit="m", noise_sd=1e-3,
                 duration_s=truth.rest_time_s + 1.5 - (truth.t_release_s - 0.25), rng=seed, return_info=True)
    return _finish(truth, res, 0.0)


def steel_500hz(seed: int = 0):
    """Steel ball bearing dropped from 0.30 m, centre logged at 500 Hz in mm.

    0.2 mm noise with lag-1 correlation 0.3, 0.1 mm resolution; simulated
    and recorded for 2.5 s (still bouncing at the end: no rest).
    """
    truth = simulate("steel", 0.30, t_end_s=2.5)
    res = record(truth, 500.0, t_start_s=-0.2, duration_s=2.7, point="centre", unit="mm", noise_sd=0.2,
                 noise_lag1=0.3, resolution=0.1, rng=seed, return_info=True)
    return _finish(truth, res, 0.0)


def marble_paper_200fps_px(seed: int = 0):
    """Glass marble on a stack of paper, tracked at 200 fps in image rows (px, down).

    Drop from 0.20 m; a 1.2 s hand phase (lifting at 0.12 m/s with 0.5 mm
    tremor, released while still moving up), 2500 px/m, floor at row 1050,
    0.3 px noise, 4 tracker jumps of 1-6 frames by 50-200 px, 1 % lost
    frames (empty cells) and 0.2 % dropped frames, timing jitter 2 %;
    rest threshold 0.1 mm (0.25 px) to keep the micro-hops' count bounded;
    recorded to 1 s after the rest.
    """
    hand = HandPhase("lift", duration_s=1.2, speed_m_s=0.12, tremor_amp_m=5e-4, tremor_freq_hz=7.0,
                     seed=seed + 101)
    truth = simulate("marble_paper", 0.20, hand=hand, t_end_s=8.0, h_rest_m=1e-4)
    res = record(truth, 200.0, point="centre", unit="px", px_per_m=2500.0, floor_row_px=1050.0, noise_sd=0.3,
                 jitter_frac=0.02, lost_frac=0.01, lost_run=(1, 3), drop_frac=0.002,
                 jumps=Jumps(n=4, length=(1, 6)), rng=seed, return_info=True)
    return _finish(truth, res, 0.0)


def tennis_bottom_2khz(seed: int = 0):
    """Tennis ball dropped from 2.54 m (ITF), its bottom logged at 2 kHz in mm.

    Unix-epoch time base (offset 1.7e9 s), 5 % timing jitter, 0.1 mm noise,
    sensor zero 2 mm below the floor (floor reads 2.0 mm), recorded from
    0.1 s before the release to 1 s after the rest.
    """
    offset = 1.7e9
    truth = simulate("tennis", 2.54, t_end_s=14.0)
    res = record(truth, 2000.0, t_start_s=-0.1, duration_s=truth.rest_time_s + 1.1, point="bottom", unit="mm",
                 floor_offset_m=0.002, noise_sd=0.1, jitter_frac=0.05, time_offset_s=offset, rng=seed,
                 return_info=True)
    return _finish(truth, res, offset)


def table_tennis_caught_60fps_px(seed: int = 0):
    """Table-tennis ball from 0.305 m (ITTF), top tracked at 60 fps (px), caught after impact 4.

    A 0.8 s hold with 1 mm tremor before the release; the hand catches the
    ball at the apex after the 4th impact and lifts it; 1200 px/m, floor row
    900, whole-pixel rounding, 0.4 px noise, 2 tracker jumps.
    """
    hand = HandPhase("hold", duration_s=0.8, tremor_amp_m=1e-3, tremor_freq_hz=9.0, seed=seed + 7)
    truth = simulate("table_tennis", 0.305, hand=hand, catch=Catch(after_impact=4, seed=seed + 11), t_end_s=10.0)
    res = record(truth, 60.0, point="top", unit="px", px_per_m=1200.0, floor_row_px=900.0, noise_sd=0.4,
                 resolution=1.0, jumps=Jumps(n=2), rng=seed, return_info=True)
    return _finish(truth, res, 0.0)


#: The tennis ball of the seed's Example 3 on a smooth floor: no friction, no drag, and a stiff linear
#: contact of 0.1 ms calibrated to e = 0.745 at 4.2 m/s with
#: ``calibrate_contact(ball, "linear", e_target=0.745, v_e_m_s=4.2, contact_time_s=1e-4, v_t_m_s=4.2)``
#: (e = 0.74500 at 4.2 m/s, 0.74494 at 1.3 m/s: gravity acts during the contact), close to the
#: seed's instantaneous bounce.
SMOOTH_TENNIS_BALL = Ball("tennis_smooth_floor", 0.057, 0.0335, LinearSpringDamper(k=5.6778370e7, c=358.15592),
                          drag_coefficient=0.0, friction_coefficient=0.0)


def seed_example3_oblique(seed: int = 0):
    """The seed's Example 3: a tennis ball rolls off a 0.9 m table at 3 m/s and bounces across a
    smooth floor (e = 0.745: peaks 0.5, 0.277, 0.154, 0.085, 0.047 m; t_inf = 2.93 s; u t_inf = 8.79 m).

    The ball's bottom leaves the table's edge (x = 0, 0.9 m above the floor) at t = 0 with u = 3 m/s and
    no vertical speed; g = 9.81 m/s^2; at rest once it cannot rise 0.1 mm. Its centre is logged in x and y at 200 Hz in m from t = 0 to
    0.5 s after the rest, 1 mm noise on each.
    """
    truth = simulate(SMOOTH_TENNIS_BALL, 0.9, u0_m_s=3.0, t_end_s=6.0, h_rest_m=1e-4)
    res = record(truth, 200.0, t_start_s=0.0, duration_s=truth.rest_time_s + 0.5, point="centre", unit="m",
                 noise_sd=1e-3, rng=seed, return_info=True, horizontal=True)
    return _finish(truth, res, 0.0)


SCENARIOS = {
    "tennis_100hz": tennis_100hz,
    "steel_500hz": steel_500hz,
    "marble_paper_200fps_px": marble_paper_200fps_px,
    "tennis_bottom_2khz": tennis_bottom_2khz,
    "table_tennis_caught_60fps_px": table_tennis_caught_60fps_px,
    "seed_example3_oblique": seed_example3_oblique,
}
