"""docs/API.md's examples run (in one subprocess, in order, in a folder holding a capture
and its params.yaml and two DFKI runs), and the API's figures hold against independent
truth: the simulated robot's YAML values, the log's file read back with numpy, and
quantities worked out here from the result's own fields."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from badinput_tools import invoke
from realdata import DFKI

import guardid
from guardid.errors import ConfigError, GuardidError, UntrustedResult

API_MD = Path(__file__).resolve().parents[1] / "docs" / "API.md"


def blocks() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", API_MD.read_text(), flags=re.M | re.S)


@pytest.fixture(scope="module")
def folder(gap_guard_captures, tmp_path_factory):
    """A folder with the main job's files: run.csv (a 60 s capture of sim://guard, seed 1)
    and params.yaml (LS and WLS), and DFKI runs 00 and 01."""
    d = tmp_path_factory.mktemp("api_doc")
    shutil.copy(gap_guard_captures[1], d / "run.csv")
    res = invoke("identify", d / "run.csv", "--method", "ls,wls", "-o", d / "params.yaml")
    assert res.exit_code == 0, res.output
    for k in (0, 1):
        shutil.copy(DFKI / f"trajectory_0{k}.csv", d)
    return d


def test_the_examples_of_docs_api_run(folder):
    code = "\n\n".join(blocks())
    assert len(blocks()) >= 6 and "identify_logs" in code and "to_pandas" in code
    env_code = "from threadpoolctl import threadpool_limits\nthreadpool_limits(1)\n" + code
    done = subprocess.run([sys.executable, "-c", env_code], cwd=folder, capture_output=True,
                          text=True, timeout=300)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    out = done.stdout
    assert "\nwls\n" in out  # r.reference_method
    assert "params.yaml:WLS" in out and "stacked relative rms error on run.csv" in out
    assert "['pan', 'tilt']" in out


@pytest.fixture(scope="module")
def result(folder):
    return guardid.identify_logs(folder / "run.csv", methods=("ls", "wls"))


def test_identify_logs_finds_the_simulated_robot_within_3_std(result):
    """sim://guard runs the shipped guard.yaml: its base parameters are the truth."""
    values, std, nominal = result.values("wls"), result.std("wls"), result.nominal
    assert result.reference_method == "wls" and set(values) == set(result.names)
    z = [abs(values[n] - nominal[n]) / std[n] for n in result.names]
    assert max(z) < 4 and np.median(z) < 2, dict(zip(result.names, z, strict=True))
    assert result.std("wls") != result.std("ls")


def test_the_conditioning_and_table_describe_the_rows(result):
    c = result.conditioning
    assert c["equation"] == "momentum" and c["cutoff_hz"] == pytest.approx(2.0)
    assert 2000 < c["rows"] <= 4000 and 10 < c["cond"] < 1e4  # a row at most every tick of 4000
    assert f"rows {c['rows']}," in result.table and "WLS" in result.table
    for name in result.names:
        assert re.search(rf"^{name}\s", result.table, flags=re.M)


def test_to_pandas_holds_the_values_and_std(result):
    pd = pytest.importorskip("pandas")  # the test extra installs it: never skipped in CI
    df = result.to_pandas()
    assert isinstance(df, pd.DataFrame) and list(df.index) == list(result.names)
    assert list(df.columns) == ["nominal", "ls", "ls_std", "wls", "wls_std"]
    np.testing.assert_array_equal(df["wls_std"].to_numpy(), list(result.std("wls").values()))


def test_to_pandas_without_pandas_names_the_extra(result, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)
    with pytest.raises(ImportError, match=r"pip install 'guardid\[pandas\]'"):
        result.to_pandas()


def test_read_log_columns_are_the_file_read_with_numpy(folder):
    log = guardid.read_log(folder / "run.csv")
    raw = np.genfromtxt(folder / "run.csv", delimiter=",", names=True, comments="#")
    np.testing.assert_allclose(log.columns["q_tilt_rad"], raw["q_tilt_rad"], rtol=0, atol=5e-10)
    assert log.footer["rows"] == len(raw)


def test_simulate_keeps_the_quantised_angle_within_a_count_of_the_truth():
    sim = guardid.simulate("guard", duration_s=1.0, seed=2)
    desc = guardid.load_robot("guard")
    counts_per_rad = [j.encoder.counts_per_rev * j.drive.gear_ratio / (2 * np.pi)
                      for j in desc.joints]  # fmt: skip
    assert np.diff(sim["t_s"]).min() == pytest.approx(desc.sample_period)
    err = np.abs(sim["q_sensed"] - sim["q_true"]) * counts_per_rad
    assert err.max() <= 1.0 + 1e-9
    np.testing.assert_allclose(sim["q_sensed"], sim["counts"] / counts_per_rad, atol=1e-12)


def test_bad_input_is_the_commands_one_line(folder):
    with pytest.raises(GuardidError, match=r"unknown nope \(known: ls, wls"):
        guardid.identify_logs(folder / "run.csv", methods="ls,nope")
    with pytest.raises(ConfigError, match="foreign log names no robot"):
        guardid.identify_logs(folder / "trajectory_00.csv", columns="time=time,q1=pos_meas1")
    with pytest.raises(ConfigError, match="duration_s"):
        guardid.simulate(duration_s=0)


def test_an_untrusted_fit_raises_unless_forced(folder, monkeypatch):
    import guardid.identify.pipeline as pipeline

    real = pipeline.identify

    def untrusted(*args, **kwargs):
        out = real(*args, **kwargs)
        out.untrusted.append("rank-deficient regressor (made so here)")
        return out

    monkeypatch.setattr(pipeline, "identify", untrusted)
    with pytest.raises(UntrustedResult, match="made so here"):
        guardid.identify_logs(folder / "run.csv", methods="ls")
    forced = guardid.identify_logs(folder / "run.csv", methods="ls", force=True)
    assert forced.identification.untrusted == ["rank-deficient regressor (made so here)"]
