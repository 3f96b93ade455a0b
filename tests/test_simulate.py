"""``guardid simulate``: CSV contents, determinism, errors."""

import math

import numpy as np
from click.testing import CliRunner

from guardid.cli import main


def _run(tmp_path, *args, name="truth.csv"):
    out = tmp_path / name
    res = CliRunner().invoke(main, ["simulate", "--duration", "3", *args, "-o", str(out)])
    return res, out


def _read(path):
    lines = path.read_text().splitlines()
    comments = [x for x in lines if x.startswith("#")]
    header = lines[len(comments)].split(",")
    data = np.array([[float(v) for v in x.split(",")] for x in lines[len(comments) + 1 :]])
    return comments, header, data


def test_simulate_writes_truth_csv(tmp_path):
    res, out = _run(tmp_path, "--robot", "guard", "--seed", "4")
    assert res.exit_code == 0, res.output
    assert len(res.output.strip().splitlines()) == 1 and "guard" in res.output
    comments, header, data = _read(out)
    assert comments[:3] == ["# robot: guard", "# seed: 4", "# sample_period_s: 0.015"]
    assert header[:2] == ["tick", "time_s"] and "i_sensed_2" in header and "setpoint_1" in header
    assert data.shape == (200, len(header))
    col = {h: data[:, k] for k, h in enumerate(header)}
    np.testing.assert_allclose(col["time_s"], col["tick"] * 0.015)
    for j, n in ((1, 500), (2, 1000)):
        count = 1.0 / (n * 48 / (2 * math.pi))
        err = col[f"q_true_{j}"] - col[f"q_sensed_{j}"]
        assert err.min() >= -1e-8 and err.max() < count + 1e-8
        assert np.abs(col[f"setpoint_{j}"] - col[f"q_true_{j}"]).max() < 0.3  # it tracks
    assert np.ptp(col["q_true_2"]) > 0.05


def test_simulate_seed_and_payload(tmp_path):
    _, a = _run(tmp_path, "--seed", "1", name="a.csv")
    _, b = _run(tmp_path, "--seed", "1", name="b.csv")
    _, c = _run(tmp_path, "--seed", "2", name="c.csv")
    assert a.read_text() == b.read_text() and a.read_text() != c.read_text()
    res, d = _run(tmp_path, "--seed", "1", "--payload-time", "1.5", "--payload-mass", "2",
                  name="d.csv")  # fmt: skip
    assert res.exit_code == 0
    _, header, da = _read(a)
    _, _, dd = _read(d)
    k = header.index("q_true_2")
    assert np.array_equal(da[:100, k], dd[:100, k]) and not np.array_equal(da[:, k], dd[:, k])


def test_simulate_errors_are_one_line(tmp_path):
    for args in (["--duration", "0"], ["--payload-time", "1"], ["--robot", "flexlink"],
                 ["--robot", "nosuchrobot"]):  # fmt: skip
        res = CliRunner().invoke(main, ["simulate", *args, "-o", str(tmp_path / "x.csv")])
        assert res.exit_code != 0
        assert res.output.startswith("guardid: error:") and len(res.output.splitlines()) == 1
        assert "Traceback" not in res.output
