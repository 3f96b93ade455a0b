"""``sim://...&phase=1``: the start pose at a seeded point within one encoder count."""

import math

import pytest

from guardid.fakeport.options import SimUrlError, parse_sim_url
from guardid.plant import make_plant
from guardid.plant.plant import encoder_phase_q0
from guardid.robot import load_robot

GUARD = load_robot("guard")
# counts per joint radian, by hand: 48 counts per motor turn x gear 500 (pan), 1000 (tilt)
PER_RAD = (48 * 500 / (2 * math.pi), 48 * 1000 / (2 * math.pi))


def test_the_url_option():
    assert parse_sim_url("sim://guard?phase=1").phase is True
    assert parse_sim_url("sim://guard").phase is False
    with pytest.raises(SimUrlError, match="phase"):
        parse_sim_url("sim://guard?phase=yes")


def test_start_within_the_first_count_and_seeded():
    fractions = []
    for seed in range(20):
        q0 = encoder_phase_q0(GUARD, seed)
        f = [q * k for q, k in zip(q0, PER_RAD, strict=True)]
        assert all(0.0 <= x < 1.0 for x in f)
        fractions.append(tuple(f))
    assert encoder_phase_q0(GUARD, 7) == encoder_phase_q0(GUARD, 7)
    assert len(set(fractions)) == 20  # every seed elsewhere on the grid
    assert min(x for f in fractions for x in f) < 0.2 < 0.8 < max(x for f in fractions for x in f)


def test_the_fake_port_plant_starts_there():
    options = parse_sim_url("sim://guard?seed=5&phase=1")
    plant = make_plant(GUARD, options)
    assert list(plant.state.q) == pytest.approx(encoder_phase_q0(GUARD, 5), abs=0)
    assert plant.counts() == (0, 0)  # still inside the first count
    on_grid = make_plant(GUARD, parse_sim_url("sim://guard?seed=5"))
    assert list(on_grid.state.q) == [0.0, 0.0]
