"""Identified motors against the robot description: a current swapped between joints under
unchanged names cannot be checked against the counts, but the motor equation v = R i + Ke w
then gives an R and a Ke far from the description's, and identify refuses the result (exit
4; until 2026-11-29 a warning with exit 0); so does a current read at another scale, which
would scale every rigid-body estimate with it."""

from __future__ import annotations

import math

import pytest
import yaml
from badinput_tools import invoke
from logedit import scaled, swapped

from guardid.identify.electrical import MotorEstimate, motor_doubts
from guardid.robot import load_robot

GUARD = load_robot("guard")
PAN = next(j for j in GUARD.joints if j.name == "pan").drive  # R 8 ohm, Ke 0.02 V s/rad


def _motor(r_ohm, ke, r_std=0.01, ke_std=1e-5):
    return MotorEstimate("pan", r_ohm, ke, None, r_std, ke_std, 1000, 0.05)


def test_description_values_are_what_the_thresholds_are_worked_out_from():
    assert PAN.resistance == 8.0 and PAN.ke == 0.02  # guard.yaml, by hand


@pytest.mark.parametrize(
    ("r_ohm", "ke", "r_std", "ke_std", "doubt"),
    [
        (8.0, 0.02, 0.01, 1e-5, False),  # the description's own values
        (11.0, 0.022, 0.01, 1e-5, False),  # R 1.375x (a warm motor), Ke +10 % (datasheet)
        (8.0, 0.026, 0.01, 1e-5, True),  # Ke +30 %, 600 std
        (8.0, 0.014, 0.01, 1e-5, True),  # Ke -30 %
        (8.0, 0.026, 0.01, 0.002, False),  # Ke +30 % but only 3 of its std: undetermined
        (17.0, 0.02, 0.01, 1e-5, True),  # R 2.1x
        (3.9, 0.02, 0.01, 1e-5, True),  # R / 2.05
        (17.0, 0.02, 3.0, 1e-5, False),  # R 2.1x but 3 std
        (math.nan, math.nan, math.nan, math.nan, False),  # not determined: trust_problems' case
    ],
)
def test_motor_doubt_thresholds(r_ohm, ke, r_std, ke_std, doubt):
    out = motor_doubts(GUARD, [_motor(r_ohm, ke, r_std, ke_std)])
    assert (len(out) == 1) is doubt, out
    if doubt:
        assert out[0].startswith("motor pan: ") and "8 ohm" in out[0] and "0.02 V s/rad" in out[0]


def test_a_joint_without_a_drive_is_not_checked():
    m = MotorEstimate("elbow", 0.1, 1.0, None, 0.01, 1e-5, 100, 0.05)
    assert motor_doubts(GUARD, [m]) == []


def test_currents_swapped_under_their_names_are_named_by_identify(gap_guard_captures, tmp_path):
    """The intact capture: no motor warning; the same file with i_pan_A and i_tilt_A's values
    exchanged (names kept): both motors' R come out negative by many std (the voltage no
    longer pushes the current it drives), so identify refuses it (exit 4) naming both
    motors; with --force, a warning for each motor and exit 0."""
    log = gap_guard_captures[1]
    intact = invoke("identify", log, "--method", "wls")
    assert intact.exit_code == 0, intact.output
    assert "warning: motor " not in intact.stderr
    bad = tmp_path / "swapped.csv"
    bad.write_text(swapped(log.read_text(), "i_pan_A", "i_tilt_A", names_too=False))
    refused = invoke("identify", bad, "--method", "wls")
    assert refused.exit_code == 4, refused.output
    assert "motor pan: R -" in refused.stderr and "motor tilt: R -" in refused.stderr
    res = invoke("identify", bad, "--method", "wls", "--force")
    assert res.exit_code == 0, res.output
    doubts = [x for x in res.stderr.splitlines() if "cannot be trusted (--force): motor " in x
              and "identified R" in x]  # fmt: skip
    assert {x.split("motor ")[1].split(":")[0] for x in doubts} == {"pan", "tilt"}, res.stderr


def test_a_current_read_2_5_times_as_large_is_refused(gap_guard_captures, tmp_path):
    """i_pan_A times 2.5 (a current sensor of 2.5 times the description's sensitivity): the
    pan's motor equation gives R = 8 / 2.5 = 3.2 ohm with Ke unchanged, beyond R_FACTOR (2),
    so identify refuses it (exit 4, one line naming the pan's motor and the description's 8
    ohm, no file), where the intact capture passes; with --force the file is written, its pan
    inertia ZZ1R about 2.5 times the YAML's (the rigid-body estimates scale with the current).
    (A factor of 2 itself sits on the threshold: R came out 3.99 ohm.)"""
    log = gap_guard_captures[1]
    bad, out = tmp_path / "scaled.csv", tmp_path / "p.yaml"
    bad.write_text(scaled(log.read_text(), "i_pan_A", 2.5))
    refused = invoke("identify", bad, "--method", "wls", "-o", out)
    assert refused.exit_code == 4, refused.output
    (line,) = refused.stderr.splitlines()
    assert "scaled.csv" in line and "motor pan: identified R " in line and "8 ohm" in line
    r_ohm = float(line.split("motor pan: identified R ")[1].split()[0])
    assert 3.1 < r_ohm < 3.3, line  # 8 ohm / 2.5
    assert "motor tilt" not in line and not out.exists()
    assert invoke("identify", bad, "--method", "wls", "--force", "-o", out).exit_code == 0
    data = yaml.safe_load(out.read_text())
    zz1r = next(p for p in data["base_parameters"] if p["name"] == "ZZ1R")
    k = [p["name"] for p in data["base_parameters"]].index("ZZ1R")
    ratio = data["methods"]["wls"]["values"][k] / zz1r["yaml_value"]
    assert 2.3 < ratio < 2.7, ratio
