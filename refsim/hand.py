"""Prescribed hand motions: the phase before the release and a catch at the end.

The hand is not simulated physically: its path is a prescribed, smooth
function of time.  What *is* physical is the hand-off: at the release the
ball leaves with the hand's position **and velocity** (the free flight
starts from the hand's state), and at a catch the hand takes over the ball's
position and velocity and then moves it anyhow.

Times are relative: ``tau = t - t_release`` (s, <= 0) for a
:class:`HandPhase`, ``tau = t - t_catch`` (s, >= 0) for a :class:`Catch`.
Displacements are in m relative to the release (catch) point, vertical
positive up; velocities in m/s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["HandPhase", "Catch"]

_KINDS = ("hold", "lift", "lower", "shake")


def _tremor_components(rng: np.random.Generator, amp_m: float, freq_hz: float):
    """Three sinusoids around ``freq_hz`` with random phases; amplitudes sum to ~amp_m."""
    freqs = freq_hz * np.array([1.0, 1.37, 0.71]) * rng.uniform(0.95, 1.05, 3)
    amps = amp_m * np.array([0.6, 0.3, 0.25])
    phases = rng.uniform(0.0, 2.0 * np.pi, 3)
    return freqs, amps, phases


def _sin_sum(tau, freqs, amps, phases):
    """Sum of a_i (sin(2 pi f_i tau + p_i) - sin p_i) and its derivative (m, m/s)."""
    tau = np.asarray(tau, dtype=float)
    y = np.zeros_like(tau)
    v = np.zeros_like(tau)
    for f, a, p in zip(freqs, amps, phases):
        w = 2.0 * np.pi * f
        y += a * (np.sin(w * tau + p) - np.sin(p))
        v += a * w * np.cos(w * tau + p)
    return y, v


@dataclass(frozen=True)
class HandPhase:
    """The ball held by a hand for ``duration_s`` before the release.

    Parameters
    ----------
    kind : {"hold", "lift", "lower", "shake"}
        ``hold``: the hand is still apart from the tremor.  ``lift`` /
        ``lower``: the hand moves up / down at ``speed_m_s`` (smooth cosine
        ramp of ``ramp_s`` from rest at the phase start); with
        ``moving_at_release`` the ball is released while the hand moves (its
        initial vertical velocity is then +-speed_m_s plus the tremor's), else
        the hand ramps down to rest during the last ``ramp_s`` before the
        release.  ``shake``: the hand oscillates with amplitude
        ``shake_amp_m`` at ``shake_freq_hz`` (release at a random phase, so
        generally while moving).
    duration_s : float
        Length of the hand phase in s (0.3-3 s is typical).
    speed_m_s : float
        Lift / lower speed in m/s (0.05-0.5 m/s typical).
    ramp_s : float
        Duration of the speed ramps in s.
    moving_at_release : bool
        For lift / lower: release while the hand still moves.
    tremor_amp_m : float
        Tremor amplitude in m (a few tenths of a mm to a few mm).
    tremor_freq_hz : float
        Main tremor frequency in Hz (5-10 Hz).
    shake_amp_m, shake_freq_hz : float
        Shake amplitude (m) and frequency (Hz), for ``kind="shake"``.
    seed : int
        Seed of the tremor's (and shake's) random phases.

    Notes
    -----
    The displacement is zero at the release by construction, so the track is
    continuous in position there; the velocity at the release,
    :meth:`release_velocity`, is the free flight's initial vertical velocity.
    Before the phase start (``tau < -duration_s``) the hand is frozen at its
    start position.
    """

    kind: str = "hold"
    duration_s: float = 1.0
    speed_m_s: float = 0.2
    ramp_s: float = 0.15
    moving_at_release: bool = True
    tremor_amp_m: float = 5e-4
    tremor_freq_hz: float = 8.0
    shake_amp_m: float = 0.01
    shake_freq_hz: float = 3.0
    seed: int = 0
    _tremor: tuple = field(init=False, repr=False, compare=False)
    _shake_phase: float = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.kind not in _KINDS:
            raise ValueError(f"kind must be one of {_KINDS}, got {self.kind!r}")
        if self.duration_s <= 0:
            raise ValueError("duration_s must be > 0")
        rng = np.random.default_rng(self.seed)
        object.__setattr__(self, "_tremor", _tremor_components(rng, self.tremor_amp_m, self.tremor_freq_hz))
        object.__setattr__(self, "_shake_phase", float(rng.uniform(0.0, 2.0 * np.pi)))

    # -- base motion (without tremor) -------------------------------------------------
    def _base(self, tau):
        tau = np.asarray(tau, dtype=float)
        if self.kind == "hold":
            return np.zeros_like(tau), np.zeros_like(tau)
        if self.kind == "shake":
            w = 2.0 * np.pi * self.shake_freq_hz
            p = self._shake_phase
            a = self.shake_amp_m
            return a * (np.sin(w * tau + p) - np.sin(p)), a * w * np.cos(w * tau + p)
        s = self.speed_m_s * (1.0 if self.kind == "lift" else -1.0)
        D = self.duration_s
        r = min(self.ramp_s, 0.5 * D)
        # velocity profile w(x), x = tau + D in [0, D]; its integral P(x)
        x = np.clip(tau + D, 0.0, D)

        def P(x):
            x = np.asarray(x, dtype=float)
            up = np.where(x < r, 0.5 * (x - r / math.pi * np.sin(math.pi * x / r)), 0.5 * r + (x - r))
            if not self.moving_at_release:
                x2 = np.clip(x - (D - r), 0.0, r)  # time into the down-ramp
                # replace the constant speed by 0.5 (1 + cos(pi x2 / r)) during the down-ramp
                up = up - x2 + 0.5 * (x2 + r / math.pi * np.sin(math.pi * x2 / r))
            return up

        def W(x):
            x = np.asarray(x, dtype=float)
            w = np.where(x < r, 0.5 * (1.0 - np.cos(math.pi * x / r)), 1.0)
            if not self.moving_at_release:
                x2 = np.clip(x - (D - r), 0.0, r)
                w = np.where(x > D - r, 0.5 * (1.0 + np.cos(math.pi * x2 / r)), w)
            return w

        y = s * (P(x) - P(D))
        v = s * W(x) * ((tau >= -D) & (tau <= 0.0))
        return y, v

    def relative(self, tau):
        """Hand displacement and velocity relative to the release point.

        Parameters
        ----------
        tau : array_like
            Time relative to the release in s (<= 0).

        Returns
        -------
        dy_m, vy_m_s : ndarray
            Vertical displacement (m, up) and velocity (m/s).
        """
        tau = np.minimum(np.asarray(tau, dtype=float), 0.0)
        frozen = tau < -self.duration_s
        tau_c = np.maximum(tau, -self.duration_s)
        yb, vb = self._base(tau_c)
        yt, vt = _sin_sum(tau_c, *self._tremor)
        v = np.where(frozen, 0.0, vb + vt)
        return yb + yt, v

    def release_velocity(self) -> float:
        """Vertical velocity of the hand (and ball) at the release, in m/s."""
        return float(self.relative(np.array([0.0]))[1][0])


@dataclass(frozen=True)
class Catch:
    """A hand catching the ball; the track then follows the hand.

    Parameters
    ----------
    after_impact : int or None
        Catch at the apex of the flight after this impact (1-based).
    t_s : float or None
        Or catch at this time (s, simulation clock).  Exactly one of the two.
    decel_time_s : float
        Time constant in s with which the hand stops the ball's motion.
    hold_s : float
        The hand holds roughly still for this long (s) before lifting.
    lift_speed_m_s : float
        Then lifts the ball at this speed (m/s, up positive).
    tremor_amp_m, tremor_freq_hz : float
        Hand tremor amplitude (m) and main frequency (Hz).
    seed : int
        Seed of the tremor phases.

    Notes
    -----
    y(tau) = y_c + v_c T (1 - exp(-tau/T)) + s ramp(tau - hold) + tremor(tau),
    continuous in position and velocity at the catch (tau = 0).
    """

    after_impact: int | None = None
    t_s: float | None = None
    decel_time_s: float = 0.04
    hold_s: float = 0.4
    lift_speed_m_s: float = 0.3
    tremor_amp_m: float = 1e-3
    tremor_freq_hz: float = 7.0
    seed: int = 0
    _tremor: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if (self.after_impact is None) == (self.t_s is None):
            raise ValueError("give exactly one of after_impact or t_s")
        rng = np.random.default_rng(self.seed)
        object.__setattr__(self, "_tremor", _tremor_components(rng, self.tremor_amp_m, self.tremor_freq_hz))

    def relative(self, tau, v_c: float, u_c: float):
        """Displacement and velocity of the caught ball relative to the catch point.

        Parameters
        ----------
        tau : array_like
            Time since the catch in s (>= 0).
        v_c, u_c : float
            Vertical and horizontal velocity of the ball at the catch (m/s).

        Returns
        -------
        dx_m, dy_m, u_m_s, v_m_s : ndarray
        """
        tau = np.maximum(np.asarray(tau, dtype=float), 0.0)
        T = self.decel_time_s
        ex = np.exp(-tau / T)
        ramp = 0.15
        x = np.clip(tau - self.hold_s, 0.0, None)
        lift = self.lift_speed_m_s * np.where(x < ramp, 0.5 * (x - ramp / math.pi * np.sin(math.pi * x / ramp)), 0.5 * ramp + (x - ramp))
        vlift = self.lift_speed_m_s * np.where(x < ramp, 0.5 * (1.0 - np.cos(math.pi * x / ramp)), 1.0)
        # the tremor fades in so that the velocity stays continuous at tau = 0
        yt, vt = _sin_sum(tau, *self._tremor)
        fade = 1.0 - np.exp(-tau / 0.05)
        dfade = np.exp(-tau / 0.05) / 0.05
        dy = v_c * T * (1.0 - ex) + lift + fade * yt
        v = v_c * ex + vlift + fade * vt + dfade * yt
        dx = u_c * T * (1.0 - ex)
        u = u_c * ex
        return dx, dy, u, v
