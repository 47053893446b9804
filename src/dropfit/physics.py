"""Pure physics of a bouncing ball: vertical flight with optional quadratic drag, and restitution laws.

All functions take and return SI units: time in s, height in m (up), speed in m/s, the drag
parameter ``k`` in 1/m (acceleration from drag = k v², i.e. k = ρ C_d A / 2m), and ``g`` in m/s².
A flight is described by its apex: time ``t_apex`` (s) and height ``y_apex`` (m). Without drag
(k = 0) every formula reduces exactly to the parabola y = y_apex − g (t − t_apex)² / 2.

With drag the closed forms follow from v̇ = −g − k v|v|, with the terminal speed v_t = √(g/k):
rising, v = v_t tan(w s) and y = y_apex + ln(cos w s)/k with s = t_apex − t and w = √(g k);
falling, v = −v_t tanh(w u) and y = y_apex − ln(cosh w u)/k with u = t − t_apex.
"""

from __future__ import annotations

import numpy as np

STANDARD_GRAVITY_M_S2 = 9.80665
#: Standard error of g where the site is not known: g varies over the Earth's surface by about ±0.3 %
#: (9.780 m/s² at the equator to 9.832 at the poles, less on mountains), taken as uniform.
UNKNOWN_SITE_GRAVITY_SE_M_S2 = 0.003 * STANDARD_GRAVITY_M_S2 / np.sqrt(3.0)
#: Standard error of :func:`normal_gravity`: local anomalies stay within about ±0.01 %.
NORMAL_GRAVITY_SE_M_S2 = 1e-3
AIR_DENSITY_KG_M3 = 1.2
#: Drag coefficient of a smooth sphere at the Reynolds numbers of a drop test (10⁴–10⁵).
SPHERE_DRAG_COEFFICIENT = 0.5


def normal_gravity(latitude_deg, altitude_m=0.0):
    """g in m/s² at a site: the WGS84 normal gravity (Somigliana) with the free-air correction.

    Parameters
    ----------
    latitude_deg : float
        Geodetic latitude in degrees.
    altitude_m : float
        Height above sea level in m.
    """
    sin2 = np.sin(np.radians(latitude_deg)) ** 2
    at_sea_level = 9.7803253359 * (1.0 + 0.00193185265241 * sin2) / np.sqrt(1.0 - 0.00669437999013 * sin2)
    return float(at_sea_level - 3.086e-6 * altitude_m)


def drag_parameter(drag_coefficient, radius_m, mass_kg, air_density_kg_m3=AIR_DENSITY_KG_M3):
    """Quadratic-drag parameter k = ρ C_d π R² / (2 m) in 1/m.

    Parameters
    ----------
    drag_coefficient : float
        C_d, dimensionless (about 0.5 for a smooth sphere, 0.55–0.6 for a tennis ball).
    radius_m : float
        Ball radius in m.
    mass_kg : float
        Ball mass in kg.
    air_density_kg_m3 : float
        Air density ρ in kg/m³.
    """
    return air_density_kg_m3 * drag_coefficient * np.pi * radius_m**2 / (2.0 * mass_kg)


#: Below this x = √(g k)·|t − t_apex|, :func:`flight_height` uses the series of log cos x and log cosh x (to x¹⁰):
#: their next terms are 2 × 10⁻¹⁶ of the first there.
SMALL_DRAG_X = 0.05


def flight_height(t, t_apex, y_apex, k=0.0, g=STANDARD_GRAVITY_M_S2):
    """Height in m of a ball in vertical flight at times ``t`` (s).

    Parameters
    ----------
    t : array_like
        Times in s.
    t_apex, y_apex : float
        Time (s) and height (m) of the apex of the flight.
    k : float
        Quadratic-drag parameter in 1/m (0 = no drag).
    g : float
        Gravitational acceleration in m/s².

    Returns
    -------
    numpy.ndarray
        Height in m. On the rising side, times before the drag solution exists (the ball would have
        had to move infinitely fast) give −inf.
    """
    dt = np.asarray(t, dtype=float) - t_apex
    if k == 0.0:
        return y_apex - 0.5 * g * dt**2
    w = np.sqrt(g * k)
    x = w * np.abs(dt)
    with np.errstate(invalid="ignore", divide="ignore"):
        rising = np.log(np.cos(np.minimum(x, np.pi / 2))) / k
    falling = -(x + np.log1p(np.exp(-2.0 * x)) - np.log(2.0)) / k  # log cosh x, without cosh's overflow
    # where the drag has bent the flight little, log cos x and log cosh x are x²/2 less rounding: their series in
    # u = x², exact to double precision for x ≤ SMALL_DRAG_X (the closed forms' error there, ~1e-16 / x², made the
    # numerical derivative by k of a flight with k near 0 a rounding noise)
    small = x <= SMALL_DRAG_X
    if np.any(small):
        # log cosh x = x²/2 − x⁴/12 + x⁶/45 − 17 x⁸/2520 + 31 x¹⁰/14175 − …; log cos x: the same with all signs −
        u = x**2
        odd = u / 12.0 + 17.0 * u**3 / 2520.0
        even = 0.5 + u**2 / 45.0 + 31.0 * u**4 / 14175.0
        squared = g * dt**2  # x² / k
        rising = np.where(small, -squared * (even + odd), rising)
        falling = np.where(small, -squared * (even - odd), falling)
    return y_apex + np.where(dt < 0, rising, falling)


def flight_velocity(t, t_apex, y_apex, k=0.0, g=STANDARD_GRAVITY_M_S2):
    """Vertical velocity in m/s (positive up) of a ball in flight at times ``t`` (s).

    Parameters are those of :func:`flight_height`; ``y_apex`` is unused but kept so that both
    functions take the same flight description.
    """
    dt = np.asarray(t, dtype=float) - t_apex
    if k == 0.0:
        return -g * dt
    w = np.sqrt(g * k)
    v_terminal = np.sqrt(g / k)
    x = w * np.abs(dt)
    return np.where(dt < 0, v_terminal * np.tan(np.minimum(x, np.pi / 2)), -v_terminal * np.tanh(x))


#: Steps of the grid on which :func:`horizontal_flight` integrates the drag (trapezoids).
HORIZONTAL_GRID_STEPS = 2000
#: Fixed-point passes of :func:`horizontal_flight` (u in |V| taken from the pass before).
HORIZONTAL_PASSES = 4


def horizontal_flight(t, t_ref, u_ref, t_apex, y_apex, k=0.0, g=STANDARD_GRAVITY_M_S2):
    """Horizontal displacement in m and velocity in m/s of a ball in flight at times ``t`` (s), with
    quadratic drag on the full velocity: du/dt = −k u |V|, |V| = √(u² + v²), v the vertical flight's
    velocity (:func:`flight_velocity` of the apex ``t_apex``, ``y_apex``, with the same k, 1/m, and g,
    m/s²).

    u = u_ref exp(−k S) with the path length S = ∫|V| dt from ``t_ref``, iterated
    :data:`HORIZONTAL_PASSES` times from |V| with u = u_ref (each pass shrinks the error by a factor
    k|V|τ, a few % for a ball in air), and x − x(t_ref) = ∫u dt; the integrals by trapezoids on
    :data:`HORIZONTAL_GRID_STEPS` steps.

    Parameters
    ----------
    t : array_like
        Times in s.
    t_ref, u_ref : float
        The reference time (s) and the horizontal velocity then (m/s); the displacement is from
        the position at ``t_ref``.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        x(t) − x(t_ref) in m and u(t) in m/s; without drag u_ref (t − t_ref) and u_ref.
    """
    from scipy.integrate import cumulative_trapezoid

    t = np.asarray(t, dtype=float)
    if k == 0.0 or u_ref == 0.0 or t.size == 0:
        return u_ref * (t - t_ref), np.full_like(t, u_ref)
    grid = np.union1d(np.linspace(min(t.min(), t_ref), max(t.max(), t_ref), HORIZONTAL_GRID_STEPS + 1), [t_ref])
    origin = int(np.searchsorted(grid, t_ref))
    vertical = flight_velocity(grid, t_apex, y_apex, k, g)
    velocity = np.full_like(grid, u_ref)
    for _ in range(HORIZONTAL_PASSES):
        path = cumulative_trapezoid(np.hypot(velocity, vertical), grid, initial=0.0)
        with np.errstate(over="ignore", invalid="ignore"):  # an absurd speed overflows: the caller checks
            velocity = u_ref * np.exp(-k * (path - path[origin]))
    displacement = cumulative_trapezoid(velocity, grid, initial=0.0)
    return np.interp(t, grid, displacement - displacement[origin]), np.interp(t, grid, velocity)


def speed_below_apex(drop_m, k=0.0, g=STANDARD_GRAVITY_M_S2, rising=False):
    """Speed in m/s of a ball ``drop_m`` (m) below the apex of its flight.

    Falling: v² = (g/k)(1 − e^{−2kΔ}); rising: v² = (g/k)(e^{2kΔ} − 1); both 2gΔ without drag.
    """
    drop_m = np.asarray(drop_m, dtype=float)
    if k == 0.0:
        return np.sqrt(2.0 * g * drop_m)
    if rising:
        return np.sqrt(g * np.expm1(2.0 * k * drop_m) / k)
    return np.sqrt(-g * np.expm1(-2.0 * k * drop_m) / k)


def time_from_apex(drop_m, k=0.0, g=STANDARD_GRAVITY_M_S2, rising=False):
    """Time in s between the apex and the moment the ball is ``drop_m`` (m) below it.

    Falling: u = asinh(√(e^{2kΔ} − 1)) / √(gk); rising: s = atan(√(e^{2kΔ} − 1)) / √(gk);
    both √(2Δ/g) without drag.
    """
    drop_m = np.asarray(drop_m, dtype=float)
    if k == 0.0:
        return np.sqrt(2.0 * drop_m / g)
    root = np.sqrt(np.expm1(2.0 * k * drop_m))
    w = np.sqrt(g * k)
    return (np.arctan(root) if rising else np.arcsinh(root)) / w


def apex_rise(speed_m_s, k=0.0, g=STANDARD_GRAVITY_M_S2):
    """Height in m that a ball launched upwards at ``speed_m_s`` (m/s) rises: ln(1 + k v²/g)/(2k)."""
    speed_m_s = np.asarray(speed_m_s, dtype=float)
    if k == 0.0:
        return speed_m_s**2 / (2.0 * g)
    return np.log1p(k * speed_m_s**2 / g) / (2.0 * k)


def restitution(speed_in_m_s, model):
    """Coefficient of restitution for an impact at ``speed_in_m_s`` (m/s, magnitude).

    Parameters
    ----------
    speed_in_m_s : float or array_like
        Impact speed in m/s.
    model : dict
        ``{"kind": "constant", "e0": e}``;
        ``{"kind": "linear", "e0": e0, "slope_s_m": a}`` for e = e0 − a v (a in s/m);
        ``{"kind": "power", "coefficient": b, "exponent": p}`` for 1 − e = b v^p
        (p = 1/5 for viscoelastic Hertz contact; b in (s/m)^p).

    Returns
    -------
    float or numpy.ndarray
        e, clipped to [0, 1].
    """
    v = np.asarray(speed_in_m_s, dtype=float)
    kind = model["kind"]
    if kind == "constant":
        e = np.full_like(v, model["e0"])
    elif kind == "linear":
        e = model["e0"] - model["slope_s_m"] * v
    elif kind == "power":
        e = 1.0 - model["coefficient"] * v ** model["exponent"]
    else:
        raise ValueError(f"unknown restitution model kind {kind!r}")
    return np.clip(e, 0.0, 1.0)


def bounce_heights(e, first_height_m, n_bounces):
    """Apex heights h_n = e^{2n} h₀ in m of bounces n = 1 … ``n_bounces`` for a constant e, no drag."""
    return first_height_m * np.asarray(e, dtype=float) ** (2 * np.arange(1, n_bounces + 1))


def total_bouncing_time(e, fall_time_s):
    """Time in s from release until the bouncing stops: t∞ = t₀ (1 + e)/(1 − e), constant e, no drag."""
    return fall_time_s * (1.0 + e) / (1.0 - e)


def touchdown_time(e, fall_time_s, impact):
    """Time in s from release to touchdown ``impact`` (1, 2, …) and its derivative with respect to e (s):
    t₀ (1 + 2 Σ_{k=1}^{n−1} eᵏ), the partial sum of t∞'s series, constant e, no drag."""
    k = np.arange(1, int(impact))
    return fall_time_s * (1.0 + 2.0 * np.sum(e ** k)), fall_time_s * 2.0 * np.sum(k * e ** (k - 1))


def time_after_first_touchdown(e, first_flight_s, impact):
    """Flight time in s from touchdown 1 to touchdown ``impact`` (2, 3, …; ``numpy.inf``: every one) and its
    derivative with respect to e (s): T₁ Σ_{k=0}^{n−2} eᵏ, each flight e times the one before (T₁ the first),
    constant e, no drag; T₁/(1 − e) summed to the end."""
    if np.isinf(impact):
        return first_flight_s / (1.0 - e), first_flight_s / (1.0 - e) ** 2
    k = np.arange(0, int(impact) - 1)
    return first_flight_s * np.sum(e ** k), first_flight_s * np.sum(k * e ** (k - 1.0))
