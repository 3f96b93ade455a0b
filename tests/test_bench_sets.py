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
