"""``validate --simulate`` (guardid.replay) and the twin (guardid.twin): replays and twins
held against captures of the simulated robot, read back with plain numpy."""

from __future__ import annotations

import math

import numpy as np
import pytest
from badinput_tools import ERROR_PREFIX, invoke

from guardid.robot import load_robot

GUARD = load_robot("guard")
# encoder counts per joint radian, by hand from guard.yaml: 48 counts per motor turn (a
# 12-slot disc decoded x4) times the gear (500, 1000)
COUNTS_PER_RAD = np.array([48 * 500, 48 * 1000]) / (2 * math.pi)


def log_columns(path) -> dict[str, np.ndarray]:
    """A guardid log's data columns by name (comment lines skipped), with numpy only."""
    lines = [x for x in open(path, encoding="utf-8").read().splitlines() if not x.startswith("#")]
    names = lines[0].split(",")
    data = np.array([[float(v) for v in x.split(",")] for x in lines[1:]])
    return {n: data[:, k] for k, n in enumerate(names)}


def counts_of(path) -> np.ndarray:
    cols = log_columns(path)
    return np.stack([cols["counts_pan"], cols["counts_tilt"]], axis=1)


def test_true_parameters_replay_a_noise_free_capture_within_one_count(noise_free_replay):
    from guardid.identify.runs import load_run
    from guardid.identify.validation import reference_set
    from guardid.replay import replay

    log = noise_free_replay["yaml"]
    run = load_run(log)
    true = reference_set(noise_free_replay["true"], GUARD)
    q_sim = replay(run, GUARD, true.values)
    err = q_sim * COUNTS_PER_RAD - counts_of(log)  # simulated minus logged, in counts
    assert np.max(np.abs(err)) <= 1.0 + 1e-9
    off = reference_set(noise_free_replay["off"], GUARD)
    err_off = replay(run, GUARD, off.values) * COUNTS_PER_RAD - counts_of(log)
    assert np.sqrt(np.mean(err_off**2)) > 10 * max(np.sqrt(np.mean(err**2)), 0.1)


def test_validate_simulate_prints_every_set_and_the_yaml(noise_free_replay, tmp_path):
    log, true, off = noise_free_replay["yaml"], noise_free_replay["true"], noise_free_replay["off"]
    report = tmp_path / "r.html"
    res = invoke("validate", log, "--params", true, "--params", off, "--simulate",
                 "--report", report)  # fmt: skip
    assert res.exit_code == 0, res.stderr
    lines = res.stdout.splitlines()
    start = next(k for k, x in enumerate(lines) if x.startswith("simulation error"))
    rows = {x.split()[0]: x.split() for x in lines[start + 3 : start + 6]}
    assert set(rows) == {"robot", "true", "off"}
    # per joint: rms / max [deg], rms / max [counts]; the YAML's and truth's max <= 1 count
    for key in ("robot", "true"):
        cells = rows[key][-12:]
        pan_max_counts, tilt_max_counts = float(cells[5]), float(cells[11])
        assert pan_max_counts <= 1 and tilt_max_counts <= 1
        assert float(cells[2]) <= 360 / (48 * 500) + 1e-9  # pan max deg: one count
    assert float(rows["off"][-1]) > 10
    page = report.read_text()
    assert "id='simulation'" in page and page.count("<svg") >= 2


def test_validate_simulate_foreign_log_one_line(noise_free_replay):
    log, true = noise_free_replay["yaml"], noise_free_replay["true"]
    res = invoke("validate", log, "--params", true, "--simulate", "--robot", "guard", "--columns",
                 "time=time_s,q1=q_pan_rad,q2=q_tilt_rad,i1=i_pan_A,i2=i_tilt_A")  # fmt: skip
    assert res.exit_code == 2
    assert res.stderr.startswith(ERROR_PREFIX) and "no setpoints" in res.stderr
    assert res.stderr.count("\n") == 1 and res.stdout == ""


def test_validate_simulate_robot_without_pid_one_line(noise_free_replay, tmp_path):
    text = open(GUARD.source, encoding="utf-8").read()
    robot = tmp_path / "guard.yaml"
    robot.write_text("\n".join(x for x in text.splitlines() if not x.strip().startswith("pid:")))
    log, true = noise_free_replay["yaml"], noise_free_replay["true"]
    res = invoke("validate", log, "--params", true, "--simulate", "--robot", robot)
    assert res.exit_code == 2
    assert res.stderr.startswith(ERROR_PREFIX) and "no pid" in res.stderr
    assert res.stderr.count("\n") == 1 and res.stdout == ""


def test_twin_of_true_parameters_captures_as_the_yaml(noise_free_replay):
    yaml_counts = counts_of(noise_free_replay["yaml"])
    true_counts = counts_of(noise_free_replay["twin_true"])
    off_counts = counts_of(noise_free_replay["twin_off"])
    assert yaml_counts.shape == true_counts.shape == off_counts.shape
    assert np.max(np.abs(true_counts - yaml_counts)) <= 1
    assert np.max(np.abs(off_counts - yaml_counts)) > 10


def test_simulate_params_runs_the_twin(noise_free_replay, tmp_path):
    outs = {}
    for key in ("yaml", "true", "off"):
        outs[key] = tmp_path / f"{key}.csv"
        args = [] if key == "yaml" else ["--params", noise_free_replay[key]]
        res = invoke("simulate", "--duration", 1, "--no-noise", *args, "-o", outs[key])
        assert res.exit_code == 0, res.stderr
    q = {k: np.stack([log_columns(p)["q_true_1"], log_columns(p)["q_true_2"]], axis=1)
         for k, p in outs.items()}  # fmt: skip
    assert np.max(np.abs(q["true"] - q["yaml"])) < 1e-6  # rad
    assert np.max(np.abs(q["off"] - q["yaml"])) > 1e-3


@pytest.mark.parametrize(
    ("query", "needle"),
    [("method=wls", "method: only with params"),
     ("params=p.yaml&payload_time=1&payload_mass=1", "payload_time: not with params")],
)  # fmt: skip
def test_sim_url_twin_options_refused(query, needle):
    from guardid.fakeport.options import SimUrlError, parse_sim_url

    with pytest.raises(SimUrlError, match=needle):
        parse_sim_url(f"sim://guard?{query}")


def test_twin_refuses_an_unphysical_set(noise_free_replay, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("guardid-reference: 1\nvalues: {ZZ1R: -0.5}\n")
    out = tmp_path / "x.csv"
    res = invoke("capture", "--port", f"sim://guard?params={bad}", "--trajectory",
                 noise_free_replay["traj"], "--duration", 1, "--quiet", "-o", out)  # fmt: skip
    assert res.exit_code == 2
    assert res.stderr.startswith(ERROR_PREFIX) and "not a robot to simulate" in res.stderr
    assert not out.exists()
