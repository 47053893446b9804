"""Synthetic drop tests with known ground truth, run forwards from the models of :mod:`dropfit.physics`.

A ball is held still, released, and bounces on a rigid floor. Flights are the closed-form vertical
flights with optional quadratic drag; impacts are instantaneous with e from a restitution law of the
impact speed. The bounce sequence is computed event by event (no time stepping), so the ground truth
is exact to rounding. A sensor then samples the centre height at a fixed rate with Gaussian noise, a
zero offset, dropouts and a length unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from .contact import HuntCrossleyContact, LinearContact, simulate_contact
from .errors import InputError
from .physics import (STANDARD_GRAVITY_M_S2, apex_rise, drag_parameter, flight_height, restitution,
                      speed_below_apex, time_from_apex, total_bouncing_time)

#: Bouncing stops (the ball rests) once a rebound would rise less than this, in m.
REST_RISE_M = 1e-4
_UNIT_IN_M = {"m": 1.0, "cm": 0.01, "mm": 0.001}


@dataclass
class DropTruth:
    """The exact motion of a synthetic drop.

    Attributes
    ----------
    flights : pandas.DataFrame
        ``t_apex_s``, ``y_apex_m`` (centre height above the floor) and ``t_start_s`` of each flight.
    impacts : pandas.DataFrame
        ``t_s`` (touchdown), ``t_liftoff_s``, ``v_in_m_s``, ``v_out_m_s``, ``e``, ``rebound_height_m``
        (rise of the centre after the impact, m) of each impact.
    drag_k_per_m : float
        Quadratic-drag parameter in 1/m.
    radius_m, release_time_s, drop_height_m, rest_time_s, gravity_m_s2 : float
        Ball radius (m), release time (s), drop height of the ball's bottom (m), time at which the
        ball comes to rest (s) and gravity (m/s²).
    contacts : list of (float, dropfit.contact.ContactResult)
        Touchdown time (s) and contact history of each impact, if a contact model was used.
    """

    flights: pd.DataFrame
    impacts: pd.DataFrame
    drag_k_per_m: float
    radius_m: float
    release_time_s: float
    drop_height_m: float
    rest_time_s: float
    gravity_m_s2: float
    contacts: list = None

    def height(self, time_s):
        """Centre height in m above the floor at ``time_s`` (s): held, flying, pressed in, or at rest."""
        t = np.asarray(time_s, dtype=float)
        i = np.clip(np.searchsorted(self.flights["t_start_s"].to_numpy(), t, side="right") - 1, 0, None)
        t_apex = self.flights["t_apex_s"].to_numpy()[i]
        y_apex = self.flights["y_apex_m"].to_numpy()[i]
        y = flight_height(t, t_apex, y_apex, self.drag_k_per_m, self.gravity_m_s2)
        y = np.where(t < self.release_time_s, y_apex, np.maximum(y, self.radius_m))
        for touchdown, contact in self.contacts or []:
            inside = (t >= touchdown) & (t <= touchdown + contact.time_s[-1])
            y[inside] = self.radius_m - np.interp(t[inside] - touchdown, contact.time_s, contact.penetration_m)
        return np.where(t >= self.rest_time_s, self.radius_m, y)


def simulate_drop(drop_height_m, radius_m, restitution_model=None, mass_kg=None, drag_coefficient=0.0,
                  gravity_m_s2=STANDARD_GRAVITY_M_S2, release_time_s=0.3, max_time_s=np.inf, contact_model=None):
    """Bounce sequence of a ball dropped from rest onto a rigid floor.

    Parameters
    ----------
    drop_height_m : float
        Height of the ball's bottom above the floor at release, in m (the ITF drop is 2.54 m).
    radius_m : float
        Ball radius in m.
    restitution_model : dict, optional
        e as a function of impact speed, see :func:`dropfit.physics.restitution`; for
        instantaneous impacts (no ``contact_model``).
    mass_kg : float, optional
        Ball mass in kg; needed with drag or a contact model.
    drag_coefficient : float
        C_d of quadratic air drag (0 = none).
    gravity_m_s2 : float
        Gravitational acceleration in m/s².
    release_time_s : float
        Time in s at which the ball leaves the hand.
    max_time_s : float
        Stop following the bounces after this time in s.
    contact_model : dropfit.contact.LinearContact or dropfit.contact.HuntCrossleyContact, optional
        Resolve every impact through this contact model: the ball presses into the floor for the
        contact time and e follows from the model (``restitution_model`` is then not used).

    Returns
    -------
    DropTruth
    """
    k = drag_parameter(drag_coefficient, radius_m, mass_kg) if drag_coefficient else 0.0
    g = gravity_m_s2
    flights = [(0.0, release_time_s, radius_m + drop_height_m)]
    impacts, contacts = [], []
    t_apex, y_apex = release_time_s, radius_m + drop_height_m
    while True:
        fall = y_apex - radius_m
        t_impact = t_apex + float(time_from_apex(fall, k, g))
        v_in = float(speed_below_apex(fall, k, g))
        if contact_model is None:
            e, contact_time = float(restitution(v_in, restitution_model)), 0.0
        else:
            contact = simulate_contact(contact_model, mass_kg, v_in, g, n_points=2000)
            e, contact_time = contact.e, contact.contact_time_s
            contacts.append((t_impact, contact))
        v_out = e * v_in
        rise = float(apex_rise(v_out, k, g))
        t_liftoff = t_impact + contact_time
        impacts.append((t_impact, t_liftoff, v_in, v_out, e, rise))
        if rise < REST_RISE_M or t_impact > max_time_s:
            break
        t_apex = t_liftoff + float(time_from_apex(rise, k, g, rising=True))
        y_apex = radius_m + rise
        flights.append((t_liftoff, t_apex, y_apex))
    return DropTruth(
        flights=pd.DataFrame(flights, columns=["t_start_s", "t_apex_s", "y_apex_m"]),
        impacts=pd.DataFrame(impacts, columns=["t_s", "t_liftoff_s", "v_in_m_s", "v_out_m_s", "e", "rebound_height_m"]),
        drag_k_per_m=k,
        radius_m=radius_m,
        release_time_s=release_time_s,
        drop_height_m=drop_height_m,
        rest_time_s=impacts[-1][1],
        gravity_m_s2=g,
        contacts=contacts,
    )


def sample_height_log(truth, rng, sample_rate_hz=100.0, duration_s=None, noise_m=0.001, offset_m=0.0,
                      dropout_fraction=0.0, unit="m", px_per_m=None, image_row_of_floor_px=None):
    """Sample a height sensor watching ``truth``.

    Parameters
    ----------
    truth : DropTruth
        The motion.
    rng : numpy.random.Generator
        Source of the noise and dropouts (seed it).
    sample_rate_hz : float
        Samples per second.
    duration_s : float, optional
        Length of the log in s (default: rest time + 1 s).
    noise_m : float
        Standard deviation of the Gaussian noise of a height sample in m.
    offset_m : float
        Sensor zero offset in m added to every height (the floor is not at the sensor's zero).
    dropout_fraction : float
        Fraction of samples lost (written as empty values).
    unit : {"m", "cm", "mm", "px"}
        Length unit of the log. ``px`` gives image rows (down) with ``px_per_m`` and
        ``image_row_of_floor_px``.

    Returns
    -------
    pandas.DataFrame
        Two columns: ``time_s`` and ``y_<unit>``.
    """
    if duration_s is None:
        duration_s = truth.rest_time_s + 1.0
    time = np.arange(int(round(duration_s * sample_rate_hz)) + 1) / sample_rate_hz
    y = truth.height(time) + offset_m + rng.normal(0.0, noise_m, time.size)
    y[rng.random(time.size) < dropout_fraction] = np.nan
    if unit == "px":
        values = image_row_of_floor_px - y * px_per_m
    else:
        values = y / _UNIT_IN_M[unit]
    return pd.DataFrame({"time_s": time, f"y_{unit}": values})


def ground_truth_record(truth, offset_m):
    """Ground truth as a JSON-ready dict: every impact's time, speeds, e and rebound height (SI)."""
    impacts = truth.impacts
    fall_time = impacts["t_s"].iloc[0] - truth.release_time_s
    return {
        "units": {"time": "s", "height": "m", "speed": "m/s", "drag_k": "1/m"},
        "radius_m": truth.radius_m,
        "gravity_m_s2": truth.gravity_m_s2,
        "drag_k_per_m": truth.drag_k_per_m,
        "release_time_s": truth.release_time_s,
        "drop_height_m": truth.drop_height_m,
        "contact_height_in_log_frame_m": truth.radius_m + offset_m,
        "sensor_offset_m": offset_m,
        "rest_time_s": truth.rest_time_s,
        "fall_time_s": fall_time,
        "total_bouncing_time_constant_e_s": float(total_bouncing_time(impacts["e"].iloc[0], fall_time)),
        "impacts": [
            {
                "impact": i + 1,
                "t_s": row.t_s,
                "t_liftoff_s": row.t_liftoff_s,
                "contact_time_s": row.t_liftoff_s - row.t_s,
                "v_in_m_s": row.v_in_m_s,
                "v_out_m_s": row.v_out_m_s,
                "e": row.e,
                "rebound_height_m": row.rebound_height_m,
            }
            for i, row in enumerate(impacts.itertuples())
        ],
    }


def _contact_model(spec):
    """Contact model from a scenario's ``contact`` entry (None for instantaneous impacts)."""
    if spec is None:
        return None
    if spec["model"] == "linear":
        return LinearContact(spec["stiffness_n_m"], spec["damping_n_s_m"])
    return HuntCrossleyContact(spec["stiffness"], spec.get("exponent", 1.5), spec["damping_s_m"])


def scenario_recordings(scenarios):
    """Every synthetic recording the scenarios stand for, by name.

    A scenario stands for one recording of its own name, or, with ``drops: n``, for n drops of the
    same ball named ``<name>_drop1`` … ``<name>_drop<n>``, drop k seeded with ``seed + k − 1``.

    Parameters
    ----------
    scenarios : dict
        Scenario name → scenario (the ``scenarios`` mapping of ``data/synthetic/scenarios.yaml``).

    Returns
    -------
    dict
        Recording name → (scenario dict, seed).
    """
    recordings = {}
    for name, scenario in scenarios.items():
        seed = scenario.get("seed", 0)
        drops = scenario.get("drops")
        names = [name] if drops is None else [f"{name}_drop{k}" for k in range(1, drops + 1)]
        for offset, recording in enumerate(names):
            if recording in recordings:
                raise InputError(f"synthetic recording {recording!r} is named twice in the scenarios")
            recordings[recording] = (scenario, seed + offset)
    return recordings


def _drop_restitution(model, rng):
    """The restitution law of one drop: e0 drawn once per drop where ``e0_sd_between_drops`` is given."""
    if not model or not model.get("e0_sd_between_drops"):
        return model
    return {**model, "e0": float(rng.normal(model["e0"], model["e0_sd_between_drops"]))}


def synthesize(scenario, seed):
    """Run one scenario (a dict as in ``data/synthetic/scenarios.yaml``).

    Returns
    -------
    (pandas.DataFrame, dict)
        The height log and its ground truth.
    """
    ball = scenario["ball"]
    rng = np.random.default_rng(seed)
    truth = simulate_drop(
        drop_height_m=scenario["drop_height_m"],
        radius_m=ball["radius_m"],
        mass_kg=ball["mass_kg"],
        restitution_model=_drop_restitution(scenario.get("restitution"), rng),
        contact_model=_contact_model(scenario.get("contact")),
        drag_coefficient=scenario.get("drag_coefficient", 0.0),
        gravity_m_s2=scenario.get("gravity_m_s2", STANDARD_GRAVITY_M_S2),
        release_time_s=scenario.get("release_time_s", 0.3),
        max_time_s=scenario.get("duration_s", np.inf),
    )
    sensor = scenario["sensor"]
    log = sample_height_log(
        truth,
        rng,
        sample_rate_hz=sensor["sample_rate_hz"],
        duration_s=scenario.get("duration_s"),
        noise_m=sensor.get("noise_m", 0.0),
        offset_m=sensor.get("offset_m", 0.0),
        dropout_fraction=sensor.get("dropout_fraction", 0.0),
        unit=sensor.get("unit", "m"),
        px_per_m=sensor.get("px_per_m"),
        image_row_of_floor_px=sensor.get("image_row_of_floor_px"),
    )
    record = ground_truth_record(truth, sensor.get("offset_m", 0.0))
    record["scenario"] = scenario
    record["seed"] = seed
    return log, record
