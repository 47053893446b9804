"""What dropfit assumes about a kind of ball where the recording cannot tell: its drag coefficient,
its contact time and the longest contact it can have. Pure data and lookups, no I/O.

Drag coefficients at the Reynolds numbers of a drop test (10³–10⁵): a smooth sphere 0.47, a tennis
ball's felt 0.5–0.6 (Mehta & Pallis 2001: 0.55 for new balls), a table-tennis ball 0.45–0.5; an
unknown kind 0.5 with a quarter of it as its standard error.

The contact time of a ball on a rigid floor falls slowly with the impact speed; for Hertz contact as
τ ∝ v^(−1/5). It is described here at 1 m/s: τ(v) = τ₁ (v / 1 m/s)^(−CONTACT_TIME_EXPONENT). The
typical values come from the contact laws of an independent simulator calibrated to published
behaviour (``refsim/README.md``: a tennis ball 4.5 ms at 7 m/s, a steel ball 0.13 ms, a rubber ball
about 1 ms, a table-tennis ball 1.0 ms, a glass marble on paper about 1 ms) and the seed's Example 4
(a tennis ball, 4.36 ms from 254 cm); the standard errors are wide on purpose: the floor is not known.
"""

from __future__ import annotations

from dataclasses import dataclass

from .errors import InputError, shown

#: Exponent β of τ ∝ v^(−β) of an unknown kind, the prior of its fit: between a linear spring–damper
#: (0) and Hertz contact (0.2), with a standard error that spans both.
CONTACT_TIME_EXPONENT = 0.1
CONTACT_TIME_EXPONENT_SE = 0.07


@dataclass(frozen=True)
class Regulation:
    """The size and mass a game's rules allow its ball: ranges, taken as uniform within them.

    Attributes
    ----------
    diameter_m, mass_kg : (float, float)
        Smallest and largest diameter (m) and mass (kg) allowed.
    rule : str
        Where the ranges are written.
    """

    diameter_m: tuple
    mass_kg: tuple
    rule: str

    @property
    def radius_m(self):
        """Middle of the allowed radii (m)."""
        return sum(self.diameter_m) / 4

    @property
    def mass_middle_kg(self):
        """Middle of the allowed masses (kg)."""
        return sum(self.mass_kg) / 2

    def area_per_mass_relative_se(self, radius_given=False, mass_given=False):
        """Relative standard error of r²/m (what drag depends on) from what is taken from the allowed ranges
        (each uniform: half-range/√3; r² twice r's); a quantity given adds none."""
        radius = (self.diameter_m[1] - self.diameter_m[0]) / (self.diameter_m[1] + self.diameter_m[0]) / 3 ** 0.5
        mass = (self.mass_kg[1] - self.mass_kg[0]) / (self.mass_kg[1] + self.mass_kg[0]) / 3 ** 0.5
        return ((0.0 if radius_given else 2 * radius) ** 2 + (0.0 if mass_given else mass) ** 2) ** 0.5


#: ITF Rules of Tennis, Appendix I: 6.54-6.86 cm across, 56.0-59.4 g.
TENNIS_REGULATION = Regulation((0.0654, 0.0686), (0.0560, 0.0594), "ITF Rules of Tennis, Appendix I")
#: ITTF Handbook 2.3 (40 mm, 2.7 g) and its ball specification's tolerances, 39.5-40.5 mm and 2.67-2.77 g.
TABLE_TENNIS_REGULATION = Regulation((0.0395, 0.0405), (0.00267, 0.00277), "ITTF Handbook 2.3, ball specification")


@dataclass(frozen=True)
class BallKind:
    """A kind of ball, with contact times at an impact speed of 1 m/s (s).

    Attributes
    ----------
    name : str
        As written in ``ball_type``.
    contact_time_s, contact_time_se_s : float
        Typical contact time at 1 m/s on a rigid floor and its standard error (a prior for recordings
        whose floor is not known).
    max_contact_time_s : float
        The longest contact time at 1 m/s a ball of this kind can have on any floor a drop test uses;
        a longer measured one is an artefact (heights of the ball's bottom taken for its centre, a
        floor set too low).
    drag_coefficient, drag_coefficient_se : float
        C_d of quadratic air drag and its standard error (dimensionless).
    contact_time_exponent, contact_time_exponent_se : float
        β of τ ∝ v^(−β) and its standard error: 0.2 for the Hertz contact of solid elastic balls, near
        0 for a shell that deforms like a spring (a table-tennis ball), between for a felt-covered
        pressurised tennis ball.
    regulation : Regulation or None
        The size and mass its rules prescribe (tennis, table tennis), used for its drag where the
        recording's ball is not measured.
    """

    name: str
    contact_time_s: float
    contact_time_se_s: float
    max_contact_time_s: float
    drag_coefficient: float = 0.5
    drag_coefficient_se: float = 0.125
    contact_time_exponent: float = CONTACT_TIME_EXPONENT
    contact_time_exponent_se: float = CONTACT_TIME_EXPONENT_SE
    regulation: Regulation | None = None


def contact_time_at(at_1_m_s, speed_m_s, exponent=CONTACT_TIME_EXPONENT):
    """A contact time given at 1 m/s (s), at the impact speed ``speed_m_s`` (m/s): τ₁ v^(−β)."""
    return at_1_m_s * (speed_m_s / 1.0) ** (-exponent)


BALL_KINDS = {kind.name: kind for kind in (
    BallKind("tennis", 6.5e-3, 2.0e-3, 12e-3, 0.55, 0.06, 0.15, 0.05, TENNIS_REGULATION),
    BallKind("steel", 0.2e-3, 0.2e-3, 2e-3, 0.47, 0.05, 0.2, 0.03),
    BallKind("rubber", 1.3e-3, 0.8e-3, 6e-3, 0.47, 0.05, 0.15, 0.05),
    BallKind("table_tennis", 1.0e-3, 0.5e-3, 3e-3, 0.47, 0.05, 0.05, 0.05, TABLE_TENNIS_REGULATION),
    BallKind("marble", 1.0e-3, 1.0e-3, 5e-3, 0.47, 0.05, 0.15, 0.05),
    BallKind("other", 2.5e-3, 2.5e-3, 20e-3),
)}


def ball_kind(name):
    """The :class:`BallKind` of ``name`` (any case; None or empty → ``other``).

    Raises
    ------
    InputError
        For a name that is not a known kind.
    """
    key = "other" if name is None or str(name).strip() == "" else str(name).strip().lower()
    if key not in BALL_KINDS:
        raise InputError(f"ball type {shown(name)!r} is not one dropfit knows; give one of "
                         f"{', '.join(BALL_KINDS)}")
    return BALL_KINDS[key]
