"""bench/bench_std_check.py's set names: the named sets, and a family followed by a length
in seconds (a set nobody named), resolved to the excitation, length and robot they mean."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench" / "bench_std_check.py"


@pytest.fixture(scope="module")
def std_check():
    spec = importlib.util.spec_from_file_location("bench_std_check", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    yield module
    sys.modules.pop(spec.name, None)


def test_named_sets_are_themselves(std_check):
    assert std_check.find_set("default60") == std_check.SETS["default60"]
    assert std_check.find_set("fast120") == std_check.EXTRA_SETS["fast120"]


@pytest.mark.parametrize(
    "name, excite, seconds, robot",
    [
        ("modified1200", (), 1200.0, "guard_modified.yaml"),
        ("tracking300", ("--base-freq", "0.2", "--harmonics", "3"), 300.0, "guard"),
        ("coarse2400", (), 2400.0, "guard_coarse.yaml"),
        ("variant300", (), 300.0, "guard_variant.yaml"),
        ("variantschroeder60", ("--kind", "schroeder"), 60.0, "guard_variant.yaml"),
        ("schroeder45", ("--kind", "schroeder"), 45.0, "guard"),
        ("fast90", ("--base-freq", "0.25", "--harmonics", "5"), 90.0, "guard"),
        ("reseeded60", ("--seed", "7"), 60.0, "guard"),
        ("small300", ("--margin", "0.3", "--start", "0,12.5"), 300.0, "guard"),
        ("longperiod1200", ("--base-freq", "0.05"), 1200.0, "guard"),
    ],
)
def test_a_family_at_any_length(std_check, name, excite, seconds, robot):
    s = std_check.find_set(name)
    assert s.excite == excite and s.duration_s == seconds
    assert Path(s.robot).name == robot


@pytest.mark.parametrize(
    "name",
    ["coarse", "coarse0", "default-60", "nosuch60", "60", "", "small", "reseeded0", "default060"],
)
def test_not_a_set(std_check, name):
    assert std_check.find_set(name) is None


def test_the_bench_robots_load_and_differ_from_the_guard(std_check):
    """The Monte Carlo's robots are valid descriptions, and differ from the guard in the
    headline changes their headers list (the controller rate, gears, encoders, the arm's
    COM off its plane; the coarse encoder; the modified pan gear)."""
    from guardid.robot import load_robot

    guard = load_robot("guard")
    variant = load_robot(str(std_check.VARIANT))
    assert (guard.sample_period, variant.sample_period) == (0.015, 0.010)
    gears = [j.drive.gear_ratio for j in variant.joints]
    counts = [j.encoder.counts_per_rev for j in variant.joints]
    assert gears == [300, 800] and counts == [64, 64]
    assert variant.links[1].com[2] == 0.03 and variant.links[1].inertia[0, 1] == 0.002
    coarse = load_robot(str(std_check.COARSE))
    assert [j.encoder.counts_per_rev for j in coarse.joints] == [12, 12]
    modified = load_robot(str(std_check.MODIFIED))
    assert modified.joints[0].drive.gear_ratio == 400
