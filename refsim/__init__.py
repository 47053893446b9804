"""refsim: an independent reference simulator of ball drop tests.

Integrates the ball's flights *and* contacts numerically (solve_ivp with
events), records the result the way real sensors / trackers would, and gives
the ground truth per impact.  See ``refsim/README.md``.
"""

from .ball import G_DEFAULT, PRESETS, Ball, Truth, impact_response, preset, simulate
from .contact import HertzDamped, HuntCrossley, LinearSpringDamper, make_law
from .hand import Catch, HandPhase

__all__ = [
    "G_DEFAULT", "PRESETS", "Ball", "Truth", "impact_response", "preset", "simulate",
    "HertzDamped", "HuntCrossley", "LinearSpringDamper", "make_law", "Catch", "HandPhase",
]
