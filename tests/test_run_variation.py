"""``sim://...&start=C&supply=F&ripple=F``: seeds that differ as a real robot's repeated runs.

The grammar (bad values one line, exit 2), the start pose (within +-C counts, seeded, clipped
into the limits), the supply (the motors and the voltage sensor see the PWM level times the
run's and the tick's factor), and the point of it all: two seeds' closed-loop count
sequences differ in most rows, while one seed repeats exactly.
"""

import math
import random
import subprocess
import sys

import numpy as np
import pytest
from capturetools import gentle_trajectory

from guardid.fakeport.options import SimUrlError, parse_sim_url
from guardid.plant import Plant, SupplyVariation, make_plant, start_pose_q0
from guardid.robot import load_robot

GUARD = load_robot("guard")
# counts per joint radian, by hand: 48 counts per motor turn x gear 500 (pan), 1000 (tilt)
PER_RAD = (48 * 500 / (2 * math.pi), 48 * 1000 / (2 * math.pi))
TILT_LIMITS = (math.radians(-10.0), math.radians(35.0))


def test_the_url_options():
    opts = parse_sim_url("sim://guard?start=50&supply=0.02&ripple=0.01")
    assert (opts.start, opts.supply, opts.ripple) == (50.0, 0.02, 0.01)
    plain = parse_sim_url("sim://guard")
    assert (plain.start, plain.supply, plain.ripple) == (0.0, 0.0, 0.0)


@pytest.mark.parametrize(
    "query, option",
    [
        ("start=-1", "start"),
        ("start=nan", "start"),
        ("start=1e30", "start"),  # beyond the telemetry's 32-bit counts (was a traceback)
        ("start=x", "start"),
        ("supply=0.6", "supply"),
        ("supply=-0.01", "supply"),
        ("ripple=0.3", "ripple"),
        ("ripple=inf", "ripple"),
        ("start=5&phase=1", "start"),
    ],
)
def test_bad_values_name_the_option(query, option):
    with pytest.raises(SimUrlError, match=option) as info:
        parse_sim_url(f"sim://guard?{query}")
    assert "\n" not in str(info.value)


def test_a_bad_value_on_the_command_line_is_bad_input(tmp_path):
    traj = gentle_trajectory(tmp_path / "traj.yaml")
    out = tmp_path / "run.csv"
    res = subprocess.run(
        [sys.executable, "-m", "guardid", "capture", "--trajectory", str(traj), "--duration",
         "1", "--port", "sim://guard?supply=2", "-o", str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("guardid: error: ") and "supply" in lines[0]
    assert not out.exists()


def test_start_pose_within_the_counts_seeded_and_clipped():
    counts = []
    for seed in range(30):
        q0 = start_pose_q0(GUARD, seed, 50.0)
        c = [q * k for q, k in zip(q0, PER_RAD, strict=True)]
        assert all(-50.0 <= x <= 50.0 for x in c)
        counts.append(tuple(c))
    assert start_pose_q0(GUARD, 7, 50.0) == start_pose_q0(GUARD, 7, 50.0)
    assert len(set(counts)) == 30
    flat = np.array(counts)
    assert flat.min() < -25.0 and flat.max() > 25.0  # multi-count, both directions
    assert np.any(np.abs(flat - np.round(flat)) > 0.25)  # and off the grid
    # far beyond the tilt's travel: on its limits, the pan (unlimited) anywhere
    far = np.array([start_pose_q0(GUARD, s, 1e6)[1] for s in range(20)])
    assert set(np.round(far, 12)) <= {round(x, 12) for x in TILT_LIMITS}


def test_the_plant_starts_there():
    plant = make_plant(GUARD, parse_sim_url("sim://guard?seed=3&start=50"))
    assert list(plant.state.q) == start_pose_q0(GUARD, 3, 50.0)
    q0 = plant.state.q
    assert plant.counts() == tuple(math.floor(q * k) for q, k in zip(q0, PER_RAD, strict=True))


def _pwm_level(volts):
    """The guard's 8-bit PWM of 12 V, by hand: the nearest of 255 steps."""
    return math.floor(volts / 12.0 * 255 + 0.5) * 12.0 / 255


def test_the_motors_and_the_voltage_sensor_see_the_supply():
    u = (6.0, -3.0)
    nominal = Plant(GUARD, seed=3, noise=False)
    varied = Plant(GUARD, seed=3, noise=False, supply=SupplyVariation(0.05, 0.0))
    run = None
    for _ in range(20):
        a, b = nominal.step(u), varied.step(u)
        assert a.voltage_true == pytest.approx([_pwm_level(6.0), -_pwm_level(3.0)], abs=1e-12)
        factor = b.voltage_true[0] / a.voltage_true[0]
        assert b.voltage_true[1] / a.voltage_true[1] == pytest.approx(factor, abs=1e-12)
        assert run is None or factor == run  # one factor for the whole run
        run = factor
    assert 0.95 <= run <= 1.05 and run != 1.0
    # the motor follows: more voltage, more speed on the pan (no gravity on its axis)
    assert (b.qd[0] - a.qd[0]) * (run - 1.0) > 0.0
    # each seed its own supply
    factors = {SupplyVariation(0.05, 0.0).factors(s).__next__() for s in range(20)}
    assert len(factors) == 20 and all(0.95 <= f <= 1.05 for f in factors)


def test_the_ripple_varies_tick_to_tick_with_its_std():
    gen = SupplyVariation(0.0, 0.01).factors(4)
    f = np.array([next(gen) for _ in range(20000)])
    assert abs(f.mean() - 1.0) < 4 * 0.01 / math.sqrt(f.size)
    assert f.std() == pytest.approx(0.01, rel=0.03)
    assert abs(np.corrcoef(f[:-1], f[1:])[0, 1]) < 0.03  # white


def test_without_them_the_plant_is_unchanged():
    """supply=0, ripple=0: the same telemetry as a plant without the option (the sensor
    noise stream untouched, no factor applied)."""
    rng = random.Random(1)
    u_seq = [(rng.uniform(-12, 12), rng.uniform(-12, 12)) for _ in range(100)]
    a = Plant(GUARD, seed=5)
    b = Plant(GUARD, seed=5, supply=SupplyVariation(0.0, 0.0))
    for u in u_seq:
        assert a.step(u) == b.step(u)


def _capture(tmp_path, traj, port, name):
    out = tmp_path / name
    res = subprocess.run(
        [sys.executable, "-m", "guardid", "capture", "--trajectory", str(traj), "--duration",
         "20", "--port", port, "--quiet", "-o", str(out)],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    rows = [line.split(",") for line in out.read_text().splitlines()
            if line and line[0].isdigit()]  # fmt: skip
    return np.array([[int(r[2]), int(r[3])] for r in rows]), [r[2:10] for r in rows]


def test_seeds_differ_in_most_rows_and_a_seed_repeats(tmp_path):
    traj = gentle_trajectory(tmp_path / "traj.yaml")
    opts = "start=50&supply=0.02&ripple=0.01"
    c3, rows3 = _capture(tmp_path, traj, f"sim://guard?seed=3&{opts}", "a.csv")
    c4, _ = _capture(tmp_path, traj, f"sim://guard?seed=4&{opts}", "b.csv")
    _, again = _capture(tmp_path, traj, f"sim://guard?seed=3&{opts}", "c.csv")
    assert again == rows3  # counts, angles, voltages and currents, to the last digit
    n = min(len(c3), len(c4))
    assert n > 1300
    differ = np.any(c3[:n] != c4[:n], axis=1)
    assert differ.mean() > 0.9  # phase=1 instead: 34 % of the rows
