"""Contact force laws between a ball and a rigid floor.

Every law gives the normal force on the ball, in N, as a function of the
penetration ``delta`` (m, > 0 when the undeformed ball would overlap the
floor; ``delta = R + floor - y_centre``) and its rate ``delta_dot`` (m/s,
> 0 while the ball moves down).  The force is clipped at zero by the
integrator (a floor cannot pull); the methods here return the *unclipped*
expression.

Laws
----
``HertzDamped``  (Kuwabara-Kono, viscoelastic Hertz)
    F = K delta^(3/2) + C delta^(1/2) delta_dot,  K in N/m^1.5, C in N s/m^1.5.
``HuntCrossley``
    F = K delta^n (1 + 3/2 alpha delta_dot),  K in N/m^n, alpha in s/m.
``LinearSpringDamper``
    F = k delta + c delta_dot,  k in N/m, c in N s/m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ContactLaw", "HertzDamped", "HuntCrossley", "LinearSpringDamper", "make_law"]


class ContactLaw:
    """Base class of the normal contact laws (see the module docstring)."""

    kind: str = "base"

    def force(self, delta, delta_dot):  # pragma: no cover - abstract
        """Unclipped normal force in N (works on floats and numpy arrays)."""
        raise NotImplementedError

    def scalar_force(self):  # pragma: no cover - abstract
        """A fast ``f(delta_m, delta_dot_m_s) -> N`` for Python floats (unclipped)."""
        raise NotImplementedError

    def sign_expr(self):  # pragma: no cover - abstract
        """A function whose sign equals the sign of the force for ``delta > 0``.

        Used as a smooth event function to find the instant the force becomes
        zero (lift-off by force) without the ``delta**(1/2)`` factor.
        """
        raise NotImplementedError

    def elastic_energy(self, delta):  # pragma: no cover - abstract
        """Energy stored by the conservative part at penetration ``delta`` (m), in J."""
        raise NotImplementedError

    def static_penetration(self, weight_n: float) -> float:  # pragma: no cover
        """Penetration in m at which the elastic force equals ``weight_n`` (N)."""
        raise NotImplementedError

    def tangent_stiffness(self, delta: float) -> float:  # pragma: no cover
        """dF/d(delta) of the elastic part at ``delta`` (m), in N/m."""
        raise NotImplementedError

    def undamped(self) -> "ContactLaw":  # pragma: no cover
        """The same law with its damping set to zero."""
        raise NotImplementedError


@dataclass(frozen=True)
class HertzDamped(ContactLaw):
    """Kuwabara-Kono viscoelastic Hertz law F = K d^1.5 + C d^0.5 d_dot.

    Parameters
    ----------
    K : float
        Hertz stiffness in N/m^1.5 (for a sphere on a half-space
        K = 4/3 E* sqrt(R)).
    C : float
        Damping in N s/m^1.5.  With C > 0 the restitution e falls with the
        impact speed v as 1 - e ~ v^(1/5).
    """

    K: float
    C: float = 0.0
    kind: str = "hertz_damped"

    def force(self, delta, delta_dot):
        d = np.maximum(delta, 0.0)
        return np.sqrt(d) * (self.K * d + self.C * delta_dot)

    def scalar_force(self):
        K, C, sqrt = self.K, self.C, math.sqrt

        def f(d, dd):
            return sqrt(d) * (K * d + C * dd)

        return f

    def sign_expr(self):
        K, C = self.K, self.C

        def h(d, dd):
            return K * d + C * dd

        return h

    def elastic_energy(self, delta):
        d = np.maximum(delta, 0.0)
        return 0.4 * self.K * d**2.5

    def static_penetration(self, weight_n):
        return (weight_n / self.K) ** (2.0 / 3.0)

    def tangent_stiffness(self, delta):
        return 1.5 * self.K * math.sqrt(max(delta, 0.0))

    def undamped(self):
        return HertzDamped(self.K, 0.0)


@dataclass(frozen=True)
class HuntCrossley(ContactLaw):
    """Hunt-Crossley law F = K d^n (1 + 3/2 alpha d_dot).

    Parameters
    ----------
    K : float
        Stiffness in N/m^n.
    alpha : float
        Damping in s/m; for small alpha v, e ~ 1 - alpha v.
    n : float
        Exponent (1.5 for Hertz).
    """

    K: float
    alpha: float = 0.0
    n: float = 1.5
    kind: str = "hunt_crossley"

    def force(self, delta, delta_dot):
        d = np.maximum(delta, 0.0)
        return self.K * d**self.n * (1.0 + 1.5 * self.alpha * delta_dot)

    def scalar_force(self):
        K, a, n = self.K, 1.5 * self.alpha, self.n
        if n == 1.5:
            sqrt = math.sqrt

            def f(d, dd):
                return K * d * sqrt(d) * (1.0 + a * dd)

        else:

            def f(d, dd):
                return K * d**n * (1.0 + a * dd)

        return f

    def sign_expr(self):
        a = 1.5 * self.alpha

        def h(d, dd):
            return 1.0 + a * dd

        return h

    def elastic_energy(self, delta):
        d = np.maximum(delta, 0.0)
        return self.K * d ** (self.n + 1.0) / (self.n + 1.0)

    def static_penetration(self, weight_n):
        return (weight_n / self.K) ** (1.0 / self.n)

    def tangent_stiffness(self, delta):
        return self.n * self.K * max(delta, 0.0) ** (self.n - 1.0)

    def undamped(self):
        return HuntCrossley(self.K, 0.0, self.n)


@dataclass(frozen=True)
class LinearSpringDamper(ContactLaw):
    """Linear spring-damper F = k d + c d_dot (clipped at >= 0 by the integrator).

    Parameters
    ----------
    k : float
        Spring stiffness in N/m.
    c : float
        Damping in N s/m.  The force jumps to c v_in at touchdown.
    """

    k: float
    c: float = 0.0
    kind: str = "linear"

    def force(self, delta, delta_dot):
        d = np.maximum(delta, 0.0)
        return self.k * d + self.c * delta_dot

    def scalar_force(self):
        k, c = self.k, self.c

        def f(d, dd):
            return k * d + c * dd

        return f

    def sign_expr(self):
        return self.scalar_force()

    def elastic_energy(self, delta):
        d = np.maximum(delta, 0.0)
        return 0.5 * self.k * d**2

    def static_penetration(self, weight_n):
        return weight_n / self.k

    def tangent_stiffness(self, delta):
        return self.k

    def undamped(self):
        return LinearSpringDamper(self.k, 0.0)


def make_law(kind: str, stiffness: float, damping: float = 0.0) -> ContactLaw:
    """Build a law by name.

    Parameters
    ----------
    kind : {"hertz_damped", "hunt_crossley", "linear"}
        Law name.
    stiffness : float
        K in N/m^1.5 (Hertz-type laws) or k in N/m (linear).
    damping : float
        C in N s/m^1.5 (hertz_damped), alpha in s/m (hunt_crossley) or c in
        N s/m (linear).
    """
    if kind == "hertz_damped":
        return HertzDamped(stiffness, damping)
    if kind == "hunt_crossley":
        return HuntCrossley(stiffness, damping)
    if kind == "linear":
        return LinearSpringDamper(stiffness, damping)
    raise ValueError(f"unknown contact law {kind!r}")
