"""The MLP in ``guardid reproduce seed001-table1`` and ``guardid identify --method mlp``."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from guardid.cli import main
from guardid.identify import IdentifyOptions, identify, method_names, run_from_arrays
from guardid.reproduce import seed001_table1
from guardid.robot import load_robot


@pytest.fixture(scope="module")
def table1(seed001_table1_report):
    return seed001_table1_report


def test_mlp_mean_estimate_within_2pct_of_truth(table1):
    """Default data (noisy quantised q, noisy tau, conditioned) and the exact-acceleration
    variant: the mean estimate within 2 % of the truth. The spread of the network's output
    over the states is bounded (1 % of the truth) on the exact-acceleration variant, where
    it was established; on the filtered default data it is larger (th4 about 1.2 % at seed
    0: the filtered q'' and tau carry more state-dependent error), which is not a bound."""
    s = table1.summary
    np.testing.assert_allclose(s["true"], [1.5, 0.5, 0.25, 1.5, 1.0], rtol=1e-12)
    assert np.all(s["pct_error"]["MLP"] < 2.0), s["pct_error"]["MLP"]
    exact = seed001_table1.run(0, exact_acceleration=True, seeds=3).summary
    assert np.all(exact["pct_error"]["MLP"] < 2.0), exact["pct_error"]["MLP"]
    # a trained network's output hardly varies with the state
    assert np.all(exact["mlp_spread"] < 0.01 * exact["true"]), exact["mlp_spread"]


def test_table_prints_every_method_and_the_paper_nn_column(table1):
    text = table1.text()
    header = "param  actual  paper LS  paper RLS  paper NN"
    assert header in text
    for name in ("LS", "RLS", "Hopfield", "gradient", "MLP"):
        assert name in table1.summary["pct_error"]
    lines = text.splitlines()
    for title in ("Actual minus estimate", "Relative error"):
        head = lines[lines.index(next(ln for ln in lines if ln.startswith(title))) + 1]
        assert head.split()[-5:] == ["LS", "RLS", "Hopfield", "gradient", "MLP"], head
    # the paper's NN column (actual minus estimate) and its relative errors
    np.testing.assert_allclose(
        seed001_table1.PAPER_NN, [-0.013, -0.02432, -0.0515, 0.0779, -0.0489]
    )
    nn = table1.summary["paper_pct_error"]["NN"]
    np.testing.assert_allclose(nn, [0.8667, 4.864, 20.6, 5.193, 4.89], atol=1e-3)
    assert "garbled" in text and "wall time" in text


def test_cli_prints_mlp_and_wall_time():
    res = CliRunner().invoke(main, ["reproduce", "seed001-table1", "--seeds", "1"])
    assert res.exit_code == 0, res.output
    assert "paper NN" in res.output and "MLP" in res.output
    assert "wall time:" in res.output


def test_identify_method_mlp():
    assert "mlp" in method_names()
    t, q, _, _, tau, _, _ = seed001_table1.simulate(duration=10.0)
    desc = load_robot("planar2")
    r = identify([run_from_arrays(t, q, tau, torque=True)], desc, IdentifyOptions(("ls", "mlp")))
    mlp = r.results["mlp"]
    assert mlp.std is None  # no standard deviation: its output's spread over the rows
    assert mlp.output_spread is not None and mlp.output_spread.shape == mlp.theta.shape
    np.testing.assert_allclose(mlp.theta, r.nominal, rtol=0.02)
    assert mlp.d_tau < 2 * r.results["ls"].d_tau
