"""The four estimators of e against closed-form truth, and where the simple ones break down."""

import numpy as np
import pytest
from conftest import sensor_log

from dropfit.errors import InputError
from dropfit.estimators import drag_fit, flight_time_ratio, parabola_fit, peak_heights
from dropfit.physics import STANDARD_GRAVITY_M_S2 as G

OFFSET_M = 0.2
#: The impacts of the ITF-like drop checked here: a 100 Hz log samples each flight at least 20 times.
CHECKED_IMPACTS = 8
#: A known-g parabola through noise-free samples of a parabola is exact up to rounding.
ROUNDING_E = 1e-8
#: analyse_bounces stops its iterations at xtol = ftol = 1e-12; its e is exact to this on noise-free data.
JOINT_FIT_E = 1e-6


def noise_free_log(truth, sample_rate_hz):
    log = sensor_log(truth, seed=0, sample_rate_hz=sample_rate_hz, noise_m=0.0, offset_m=OFFSET_M,
                     dropout_fraction=0.0)
    return log["time_s"].to_numpy(), log["y_m"].to_numpy()


def true_rises(truth):
    """Rise h_n of the centre above the contact height in flight n = 0, 1, … (m)."""
    return np.concatenate([[truth.drop_height_m], truth.impacts["rebound_height_m"].to_numpy()])


def apex_misses(truth, time_s):
    """How far below each true apex the sample nearest it lies without noise: g (t_sample − t_apex)² / 2 (m)."""
    t_apex = truth.flights["t_apex_s"].to_numpy()
    nearest = time_s[np.argmin(np.abs(time_s[None, :] - t_apex[:, None]), axis=1)]
    return 0.5 * G * (nearest - t_apex) ** 2


def check_impact_order(estimate, truth, sample_interval_s):
    """The n-th reported impact is the n-th true one (so rows can be compared by position)."""
    n = min(CHECKED_IMPACTS, len(estimate))
    lag = np.abs(estimate["t_impact_s"].to_numpy()[:n] - truth.impacts["t_s"].to_numpy()[:n])
    assert np.all(lag <= 1.5 * sample_interval_s)
    return n


@pytest.mark.parametrize("estimator", [parabola_fit, drag_fit])
def test_fits_are_exact_without_drag_or_noise(vacuum_truth, estimator):
    t, y = noise_free_log(vacuum_truth, 100.0)
    estimate = estimator(t, y)
    assert len(estimate) >= CHECKED_IMPACTS
    true_e = vacuum_truth.impacts["e"].to_numpy()
    tolerance = ROUNDING_E if estimator is parabola_fit else JOINT_FIT_E
    np.testing.assert_allclose(estimate["e"].to_numpy()[:CHECKED_IMPACTS], true_e[:CHECKED_IMPACTS], atol=tolerance)
    np.testing.assert_allclose(estimate["t_impact_s"].to_numpy()[:CHECKED_IMPACTS],
                               vacuum_truth.impacts["t_s"].to_numpy()[:CHECKED_IMPACTS], atol=1e3 * tolerance)
    assert np.all(estimate["e_se"].to_numpy()[:CHECKED_IMPACTS] < 10 * tolerance)


@pytest.mark.parametrize("sample_rate_hz", [100.0, 30.0])
def test_peak_heights_miss_each_apex_by_the_sampled_amount(vacuum_truth, sample_rate_hz):
    """Without noise the highest sample of a flight is the one nearest its apex, g (t − t_apex)²/2 below it.

    That miss is at most g (Δt/2)²/2 (0.12 mm at 100 Hz, 1.4 mm at 30 Hz) and makes e_n come out
    exactly √((h_n − miss_n) / (h_{n−1} − miss_{n−1})): a bias of up to 2e-3 at 30 Hz, where the
    parabola fit on the same samples is exact.
    """
    t, y = noise_free_log(vacuum_truth, sample_rate_hz)
    estimate = peak_heights(t, y, contact_height_m=vacuum_truth.radius_m + OFFSET_M)
    n = check_impact_order(estimate, vacuum_truth, 1.0 / sample_rate_hz)
    miss = apex_misses(vacuum_truth, t)[: n + 1]
    assert np.all(miss <= 0.5 * G * (0.5 / sample_rate_hz) ** 2)
    rise = true_rises(vacuum_truth)[: n + 1] - miss
    predicted = np.sqrt(rise[1:] / rise[:-1])
    np.testing.assert_allclose(estimate["e"].to_numpy()[:n], predicted, atol=ROUNDING_E)
    assert estimate["e_se"].isna().all()
    error = estimate["e"].to_numpy()[:n] - vacuum_truth.impacts["e"].to_numpy()[:n]
    if sample_rate_hz == 30.0:
        assert np.max(np.abs(error)) > 100 * ROUNDING_E  # the sampled apex really costs accuracy here
        exact = parabola_fit(t, y)["e"].to_numpy()[:n]
        np.testing.assert_allclose(exact, vacuum_truth.impacts["e"].to_numpy()[:n], atol=ROUNDING_E)


def test_flight_time_ratio_within_the_closed_form_timing_bound(vacuum_truth):
    """Lines through two samples of a parabola miss its end by g a b / 2 (a, b the samples' distances
    from it), so each impact time is off by at most 3 g Δt² / (v_in + v_out − 3 g Δt); the ratio of
    flight times is e exactly without drag, so its error is bounded by those of the three impact times."""
    sample_interval = 0.01
    t, y = noise_free_log(vacuum_truth, 1.0 / sample_interval)
    estimate = flight_time_ratio(t, y)
    n = check_impact_order(estimate, vacuum_truth, sample_interval) + 1  # one more impact ends flight n−1
    impacts = vacuum_truth.impacts.iloc[:n]
    speeds = impacts["v_in_m_s"].to_numpy() + impacts["v_out_m_s"].to_numpy()
    timing_bound = 3 * G * sample_interval**2 / (speeds - 3 * G * sample_interval)
    timing_error = estimate["t_impact_s"].to_numpy()[:n] - impacts["t_s"].to_numpy()
    assert np.all(np.abs(timing_error) <= timing_bound)

    flight_time = np.diff(impacts["t_s"].to_numpy())
    worst = np.maximum(np.maximum(timing_bound[:-2], timing_bound[1:-1]), timing_bound[2:])
    upper = (flight_time[1:] + 2 * worst) / (flight_time[:-1] - 2 * worst)
    lower = (flight_time[1:] - 2 * worst) / (flight_time[:-1] + 2 * worst)
    e = estimate["e"].to_numpy()
    assert np.isnan(e[0]), "the first impact has no flight before it to compare with"
    assert np.all((lower <= e[1: n - 1]) & (e[1: n - 1] <= upper))
    np.testing.assert_allclose(flight_time[1:] / flight_time[:-1], impacts["e"].to_numpy()[1:-1], rtol=1e-12)


def test_height_and_time_ratios_measure_less_than_e_under_drag(tennis_truth):
    """With drag the flight loses energy: √(h_n/h_{n−1}) and T_n/T_{n−1} fall below v_out/v_in.

    (For the lower bounces the deficit shrinks below the sampling errors, so only the high ones are
    checked against it.)

    Peak heights at 100 Hz without noise reproduce the true height ratio within the apex-sampling
    bound. For the first four impacts of this tennis ball (bounces above 0.3 m) that ratio lies
    0.006–0.03 below e, far outside the sampling bound; the drag fit recovers e.
    """
    t, y = noise_free_log(tennis_truth, 100.0)
    true_e = tennis_truth.impacts["e"].to_numpy()
    peaks = peak_heights(t, y, contact_height_m=tennis_truth.radius_m + OFFSET_M)
    n = check_impact_order(peaks, tennis_truth, 0.01)
    rise = true_rises(tennis_truth)[: n + 1]
    height_ratio = np.sqrt(rise[1:] / rise[:-1])
    miss_bound = 0.5 * G * 0.005**2
    sampling_bound = 0.5 * height_ratio * miss_bound * (1 / rise[1:] + 1 / rise[:-1])
    assert np.all(np.abs(peaks["e"].to_numpy()[:n] - height_ratio) <= sampling_bound)
    high = slice(0, 4)
    assert np.all(true_e[high] - height_ratio[high] > 10 * sampling_bound[high])

    time_ratio = flight_time_ratio(t, y)["e"].to_numpy()[1:4]
    assert np.all(true_e[1:4] - time_ratio > 0.005)
    np.testing.assert_allclose(drag_fit(t, y)["e"].to_numpy()[:n], true_e[:n], atol=JOINT_FIT_E)


def test_a_log_without_a_bounce_is_refused_by_every_estimator():
    t = np.arange(200) / 100.0
    y = 1.0 - 0.5 * G * np.clip(t - 0.3, 0.0, None) ** 2  # released, never lands in the log
    for estimate in (lambda: peak_heights(t, y, 0.0), lambda: flight_time_ratio(t, y), lambda: parabola_fit(t, y),
                     lambda: drag_fit(t, y)):
        with pytest.raises(InputError, match="bounce"):
            estimate()
