"""The presets land in the documented ranges of e and contact time."""

import pytest

import refsim
from refsim import impact_response

G = 9.81


def resp(name, v):
    return impact_response(refsim.preset(name), v, g_m_s2=G)


def test_tennis():
    r7 = resp("tennis", 7.06)
    assert r7["e"] == pytest.approx(0.75, abs=0.01)
    assert 4e-3 <= r7["contact_time_s"] <= 5e-3
    r05 = resp("tennis", 0.5)
    assert 0.8 <= r05["e"] <= 0.87 and r05["e"] > r7["e"]


def test_steel():
    r = resp("steel", 3.0)
    assert r["e"] == pytest.approx(0.9, abs=0.01)
    assert 0.1e-3 <= r["contact_time_s"] <= 0.3e-3
    assert refsim.preset("steel").drag_k_1_m < 3e-3


def test_table_tennis():
    r = resp("table_tennis", 2.45)
    assert r["e"] == pytest.approx(0.89, abs=0.01)
    assert 0.8e-3 <= r["contact_time_s"] <= 1.2e-3
    assert refsim.preset("table_tennis").drag_k_1_m > 0.1


def test_marble_on_paper():
    lo, hi = resp("marble_paper", 1.4), resp("marble_paper", 3.0)
    assert 0.65 <= lo["e"] <= 0.75 and 0.45 <= hi["e"] <= 0.6
    for r in (lo, hi):
        assert 0.5e-3 <= r["contact_time_s"] <= 2e-3


def test_rubber():
    r = resp("rubber", 4.0)
    assert 0.8 <= r["e"] <= 0.9 and 0.5e-3 <= r["contact_time_s"] <= 2e-3


def test_unknown_preset():
    with pytest.raises(KeyError):
        refsim.preset("bowling")
