"""Calibrate a contact law's stiffness and damping to a target e and contact time.

Used offline to choose the presets' parameters (the numbers are then written
into :data:`refsim.ball.PRESETS`); also handy for tests that want a ball
with given properties.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy.optimize import least_squares

from .ball import G_DEFAULT, Ball, impact_response
from .contact import make_law

__all__ = ["calibrate_contact", "e_and_contact_time_table"]


def calibrate_contact(ball: Ball, kind: str, *, e_target: float, v_e_m_s: float, contact_time_s: float,
                      v_t_m_s: float, g_m_s2: float = G_DEFAULT, x0=None) -> Ball:
    """Find stiffness and damping so that e(v_e) = e_target and T(v_t) = contact_time_s.

    Parameters
    ----------
    ball : Ball
        Ball whose mass, radius, drag... are kept.
    kind : {"hertz_damped", "hunt_crossley", "linear"}
        Contact law to calibrate.
    e_target : float
        Restitution (dimensionless) wanted at impact speed ``v_e_m_s`` (m/s).
    contact_time_s : float
        Contact time (delta = 0 to delta = 0, s) wanted at impact speed
        ``v_t_m_s`` (m/s).
    g_m_s2 : float
        Gravity during the contact (m/s^2).
    x0 : (float, float) or None
        Starting (stiffness, damping).

    Returns
    -------
    Ball
        A copy of ``ball`` with the calibrated law.
    """
    m = ball.mass_kg
    if x0 is None:
        # undamped Hertz / linear estimates for the stiffness
        if kind == "linear":
            k0 = m * (math.pi / contact_time_s) ** 2
            d0 = 2.0 * m * (math.pi / contact_time_s) * 0.05
        else:
            k0 = m * (3.2181 / contact_time_s) ** 2.5 * v_t_m_s ** -0.5
            d0 = 0.05 * k0 if kind == "hertz_damped" else (1.0 - e_target) / v_e_m_s
            if kind == "hertz_damped":
                # 1 - e ~ 1.15 C m^-2/5 K^-3/5 v^1/5 (Kuwabara-Kono scaling, rough prefactor)
                d0 = (1.0 - e_target) / 1.15 * m**0.4 * k0**0.6 * v_e_m_s ** -0.2
        x0 = (k0, d0)

    def trial(p):
        return replace(ball, contact=make_law(kind, math.exp(p[0]), math.exp(p[1])))

    def resid(p):
        b = trial(p)
        re = impact_response(b, v_e_m_s, g_m_s2=g_m_s2, rtol=1e-9, atol=1e-12)
        rt = re if v_t_m_s == v_e_m_s else impact_response(b, v_t_m_s, g_m_s2=g_m_s2, rtol=1e-9, atol=1e-12)
        e = re["e"] if np.isfinite(re["e"]) else 0.0
        T = rt["contact_time_s"] if np.isfinite(rt["contact_time_s"]) else 10 * contact_time_s
        return [e - e_target, math.log(T / contact_time_s)]

    sol = least_squares(resid, np.log(x0), x_scale=1.0, diff_step=1e-6, xtol=1e-12, ftol=1e-12)
    return trial(sol.x)


def e_and_contact_time_table(ball: Ball, speeds_m_s=(0.5, 1.0, 2.0, 4.0, 7.0), g_m_s2: float = G_DEFAULT):
    """e, contact times, peak force and max penetration at several impact speeds.

    Returns
    -------
    pandas.DataFrame
        Columns ``v_in_m_s``, ``e``, ``contact_time_ms``,
        ``contact_time_force_ms``, ``peak_force_N``, ``max_penetration_mm``.
    """
    import pandas as pd

    rows = []
    for v in speeds_m_s:
        r = impact_response(ball, v, g_m_s2=g_m_s2)
        rows.append({"v_in_m_s": v, "e": r["e"], "contact_time_ms": 1e3 * r["contact_time_s"],
                     "contact_time_force_ms": 1e3 * r["contact_time_force_s"], "peak_force_N": r["peak_force_N"],
                     "max_penetration_mm": 1e3 * r["max_penetration_m"]})
    return pd.DataFrame(rows)
