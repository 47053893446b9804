"""Impulse, average and peak force of a short contact, and the central impact of two bodies.

Pure functions in SI units after the textbook chapter "Impulse, momentum and impact" (the seed):
equation 7.5.1 (impulse = change of momentum), Example 1 (the kick), the closed forms of central
impact from momentum conservation and the restitution law 7.5.3, and Example 2 (a ball dropped on
a block resting on foam).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class CentralImpact:
    """Velocities after a central impact and the kinetic energy it dissipates.

    Attributes
    ----------
    v1_after_m_s, v2_after_m_s : float
        Velocities of body 1 and body 2 just after the impact in m/s, along the line of impact.
    energy_loss_j : float
        Kinetic energy lost in the impact, T − T', in J (≥ 0 for 0 ≤ e ≤ 1).
    """

    v1_after_m_s: float
    v2_after_m_s: float
    energy_loss_j: float


@dataclass(frozen=True)
class BallOnBlock:
    """Result of a ball dropped on a block at rest (seed, Example 2), y positive downwards.

    Attributes
    ----------
    ball_velocity_before_m_s : float
        Ball velocity just before impact, √(2gH), in m/s (positive: downwards).
    ball_velocity_after_m_s : float
        Ball velocity just after impact, −√(2gh), in m/s (negative: upwards).
    block_speed_m_s : float
        Block velocity just after impact in m/s, from momentum conservation.
    e : float
        Coefficient of restitution (dimensionless).
    energy_loss_fraction : float
        Share (T − T')/T of the kinetic energy lost in the impact (dimensionless, 0–1).
    """

    ball_velocity_before_m_s: float
    ball_velocity_after_m_s: float
    block_speed_m_s: float
    e: float
    energy_loss_fraction: float


def impulse(mass_kg, velocity_before_m_s, velocity_after_m_s):
    """Impulse of the resultant force that changes a body's velocity, J = m v2 − m v1 (seed 7.5.1).

    Parameters
    ----------
    mass_kg : float
        Mass of the body in kg.
    velocity_before_m_s : float or array_like
        Velocity before the contact in m/s: a scalar, or a 1-D vector (e.g. [vx, vy]), or a 2-D
        array of such vectors (one per row).
    velocity_after_m_s : float or array_like
        Velocity after the contact in m/s, same shape as ``velocity_before_m_s``.

    Returns
    -------
    numpy.ndarray
        Impulse in N·s, of the shape of the velocities.
    """
    v1 = np.asarray(velocity_before_m_s, dtype=float)
    v2 = np.asarray(velocity_after_m_s, dtype=float)
    if v1.shape != v2.shape:
        raise ValueError(f"velocities before {v1.shape} and after {v2.shape} must have the same shape")
    return float(mass_kg) * v2 - float(mass_kg) * v1


def average_force(impulse_n_s, duration_s):
    """Average force over a contact, F̄ = J / Δt.

    Parameters
    ----------
    impulse_n_s : float or array_like
        Impulse of the force in N·s (scalar or vector).
    duration_s : float
        Contact duration Δt in s, > 0.

    Returns
    -------
    numpy.ndarray
        Average force in N, of the shape of ``impulse_n_s``.
    """
    if not duration_s > 0:
        raise ValueError(f"duration_s must be positive, got {duration_s}")
    return np.asarray(impulse_n_s, dtype=float) / float(duration_s)


def half_sine_peak_force(average_force):
    """Peak of a half-sine force pulse with the given average, F_max = π/2 · F̄.

    Parameters
    ----------
    average_force : float or array_like
        Average force over the pulse in N (scalar or vector).

    Returns
    -------
    numpy.ndarray
        Peak force in N, of the shape of ``average_force``.
    """
    return np.pi / 2 * np.asarray(average_force, dtype=float)


def central_impact(m1_kg, m2_kg, v1_m_s, v2_m_s, e):
    """Velocities after a central impact and the kinetic energy lost (seed closed forms).

    From momentum conservation m1 v1 + m2 v2 = m1 v1' + m2 v2' and the restitution law
    e = (v2' − v1')/(v1 − v2)::

        v1' = (v1 (m1 − e m2) + v2 m2 (1 + e)) / (m1 + m2)
        v2' = (v1 m1 (1 + e) + v2 (m2 − e m1)) / (m1 + m2)
        T − T' = m1 m2 (1 − e²)(v1 − v2)² / (2 (m1 + m2))

    Parameters
    ----------
    m1_kg, m2_kg : float
        Masses of body 1 and body 2 in kg, > 0.
    v1_m_s, v2_m_s : float
        Velocities of body 1 and body 2 just before the impact in m/s, along the line of impact.
    e : float
        Coefficient of restitution (dimensionless), 0 ≤ e ≤ 1.

    Returns
    -------
    CentralImpact
        ``v1_after_m_s`` and ``v2_after_m_s`` in m/s, ``energy_loss_j`` in J.
    """
    m1, m2, v1, v2, e = (float(x) for x in (m1_kg, m2_kg, v1_m_s, v2_m_s, e))
    if not (m1 > 0 and m2 > 0):
        raise ValueError(f"masses must be positive, got {m1} and {m2} kg")
    if not 0.0 <= e <= 1.0:
        raise ValueError(f"e must lie in [0, 1], got {e}")
    total = m1 + m2
    v1_after = (v1 * (m1 - e * m2) + v2 * m2 * (1 + e)) / total
    v2_after = (v1 * m1 * (1 + e) + v2 * (m2 - e * m1)) / total
    loss = m1 * m2 * (1 - e**2) * (v1 - v2) ** 2 / (2 * total)
    return CentralImpact(v1_after_m_s=v1_after, v2_after_m_s=v2_after, energy_loss_j=loss)


def ball_on_block(m_ball_kg, m_block_kg, drop_height_m, rebound_height_m, g=9.81):
    """Ball dropped on a block at rest: block speed, e and share of energy lost (seed, Example 2).

    With y positive downwards the ball arrives at v1 = √(2gH) and leaves at v1' = −√(2gh); the block
    starts at rest, so v2' = m1 (v1 − v1')/m2, e = (v2' − v1')/v1 and
    (T − T')/T = 1 − (m1 v1'² + m2 v2'²)/(m1 v1²).

    Parameters
    ----------
    m_ball_kg : float
        Mass of the ball in kg, > 0.
    m_block_kg : float
        Mass of the block in kg, > 0.
    drop_height_m : float
        Drop height H of the ball above the block in m, > 0.
    rebound_height_m : float
        Rebound height h of the ball in m, ≥ 0.
    g : float, optional
        Gravitational acceleration in m/s² (default 9.81, as in the seed).

    Returns
    -------
    BallOnBlock
        Ball velocities before and after in m/s, ``block_speed_m_s`` in m/s, ``e`` and
        ``energy_loss_fraction`` (dimensionless).
    """
    m1, m2, H, h, g = (float(x) for x in (m_ball_kg, m_block_kg, drop_height_m, rebound_height_m, g))
    if not (m1 > 0 and m2 > 0):
        raise ValueError(f"masses must be positive, got {m1} and {m2} kg")
    if not (H > 0 and h >= 0 and g > 0):
        raise ValueError(f"need drop height > 0, rebound height >= 0 and g > 0, got {H}, {h}, {g}")
    v1 = np.sqrt(2 * g * H)
    v1_after = -np.sqrt(2 * g * h)
    v2_after = m1 * (v1 - v1_after) / m2
    e = (v2_after - v1_after) / v1
    loss = 1 - (m1 * v1_after**2 + m2 * v2_after**2) / (m1 * v1**2)
    return BallOnBlock(ball_velocity_before_m_s=float(v1), ball_velocity_after_m_s=float(v1_after),
                       block_speed_m_s=float(v2_after), e=float(e), energy_loss_fraction=float(loss))
