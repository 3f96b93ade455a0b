"""The quantisation bootstrap (guardid.uncertainty, ``identify --quantisation-bootstrap``):
its statistics by hand, its plumbing on replicas whose error is known from the fit's
linearity, its replicas against a capture of the simulated robot, the command's lines."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from badinput_tools import invoke
from capturetools import VARIANT

# the guard robot and its counts per radian by hand
from test_replay import COUNTS_PER_RAD, GUARD


def test_statistics_by_hand():
    from guardid.uncertainty import QuantisationBootstrap

    # one parameter, errors 1 and 3: mean 2, sample variance 2; the fits reported 0.5 each
    bs = QuantisationBootstrap(("a",), np.array([10.0]), np.array([[1.0], [3.0]]),
                               np.full((2, 1, 1), 0.5))  # fmt: skip
    assert bs.replicas == 2
    assert bs.bias == pytest.approx([2.0])
    assert bs.persistent == pytest.approx(np.array([[1.5]]))  # 2 - 0.5
    assert bs.corrected([10.0]) == pytest.approx([8.0])
    assert bs.covariance([[1.0]]) == pytest.approx(np.array([[3.5]]))  # 1 + 1.5 + 2 / 2
    # reported covariance larger than the spread: nothing persists (clipped at 0)
    quiet = QuantisationBootstrap(("a",), np.array([0.0]), np.array([[1.0], [3.0]]),
                                  np.full((2, 1, 1), 5.0))  # fmt: skip
    assert quiet.persistent == pytest.approx(np.array([[0.0]]))
    # two parameters, errors along (1, 1) only: the persistent part is that direction's
    e = np.array([[1.0, 1.0], [-1.0, -1.0], [0.0, 0.0]])  # covariance [[1, 1], [1, 1]]
    two = QuantisationBootstrap(("a", "b"), np.zeros(2), e, np.zeros((3, 2, 2)))
    assert two.persistent == pytest.approx(np.ones((2, 2)))


def test_known_bias_through_the_fit(gap_guard_captures, monkeypatch):
    """Replicas = the log with its current scaled by (1 + c_k): the momentum form is linear
    in the effort and WLS's weights scale with it, so each replica's estimate is (1 + c_k)
    theta and its error c_k theta: the bias mean(c) theta, known without the simulation
    (to 3 % of each error: the fit is linear in the effort to about 1 % here, measured)."""
    from dataclasses import replace

    import guardid.uncertainty.bootstrap as bootstrap_module
    import guardid.uncertainty.replicas as replicas_module
    from guardid.identify.pipeline import IdentifyOptions, identify
    from guardid.identify.prepare import current_on_adc_levels
    from guardid.identify.runs import load_run
    from guardid.uncertainty import BootstrapOptions, quantisation_bootstrap

    # on the ADC levels first, as the command puts it: the scaled replicas are then the
    # fitted currents scaled (scaled values are off the levels and are fitted as they are)
    run = current_on_adc_levels(load_run(gap_guard_captures[1]), GUARD, in_place=True)
    run.current_zero = None  # no zero to subtract: the fit stays linear in the effort
    options = IdentifyOptions(methods=("wls",))
    result = identify([run], GUARD, options)
    theta = result.results["wls"].theta
    scales = iter([0.02, 0.06, -0.01])

    def scaled(r, description, values, phase, supply, seed):
        simulated = [values[n] for n in result.names]
        assert simulated == pytest.approx(theta)  # simulated with the estimate
        assert np.all((0.0 <= phase) & (phase < 1.0))
        assert supply.ripple < 0.005  # the capture's supply has no ripple
        return replace(r, current=r.current * (1.0 + next(scales)))

    monkeypatch.setattr(replicas_module, "replica_run", scaled)
    monkeypatch.setattr(bootstrap_module, "replica_run", scaled, raising=False)
    bs = quantisation_bootstrap([run], GUARD, result, "wls",
                                BootstrapOptions(replicas=3, tolerance=0.0), options)  # fmt: skip
    c = np.array([0.02, 0.06, -0.01])
    assert bs.replicas == 3
    np.testing.assert_allclose(bs.errors, c[:, None] * theta[None], rtol=0.03, atol=1e-9)
    np.testing.assert_allclose(bs.bias, c.mean() * theta, rtol=0.03, atol=1e-9)
    np.testing.assert_allclose(bs.corrected(theta), theta - bs.bias, rtol=1e-12)
    np.testing.assert_allclose(bs.corrected(theta), (1 - c.mean()) * theta, rtol=1e-3)


def test_replica_reproduces_a_noise_free_capture(noise_free_replay):
    """Simulated with the robot YAML's values from the capture's own start (on the count
    grid: phase 0), a replica's counts stay within one count of the capture's (read with
    numpy), its angles are its counts over the counts per radian, its current follows the
    capture's; another phase changes the counts."""
    from dataclasses import replace

    from guardid.identify.runs import load_run
    from guardid.identify.validation import reference_set
    from guardid.uncertainty import replica_run

    log = noise_free_replay["yaml"]
    run = load_run(log)
    true = reference_set(noise_free_replay["true"], GUARD).values
    zero = {"pan": {"mean_a": 0.02, "std_a": 0.008, "rows": 100}}
    rep = replica_run(replace(run, current_zero=zero), GUARD, true, [0.0, 0.0])
    assert rep.current_zero is None  # the simulated sensor reads no offset: not the log's
    lines = [x for x in log.read_text().splitlines() if not x.startswith("#")]
    data = np.array([[float(v) for v in x.split(",")] for x in lines[1:]])
    cols = dict(zip(lines[0].split(","), data.T, strict=True))
    counts = np.stack([cols["counts_pan"], cols["counts_tilt"]], axis=1)
    current = np.stack([cols["i_pan_A"], cols["i_tilt_A"]], axis=1)
    assert np.max(np.abs(rep.counts - counts)) <= 1
    np.testing.assert_allclose(rep.q, rep.counts / COUNTS_PER_RAD, rtol=1e-12)
    assert np.sqrt(np.mean((rep.current - current) ** 2)) < 0.05 * np.sqrt(np.mean(current**2))
    np.testing.assert_array_equal(rep.ticks, cols["tick"])
    other = replica_run(run, GUARD, true, [0.7, 0.4])
    assert np.any(other.counts != rep.counts)


@pytest.mark.parametrize("rows", [(), ("--spaced-rows",)], ids=["every-tick", "spaced"])
def test_identify_bootstrap_corrects_the_verdicts_method(gap_guard_captures, tmp_path, rows):
    log = gap_guard_captures[2]
    plain, boot = tmp_path / "plain.yaml", tmp_path / "boot.yaml"
    assert invoke("identify", log, "--method", "wls", *rows, "-o", plain).exit_code == 0
    res = invoke("identify", log, "--method", "wls", *rows, "--quantisation-bootstrap", "2",
                 "-o", boot)  # fmt: skip
    assert res.exit_code == 0, res.stderr
    assert "less the encoder quantisation's bias" in res.stdout
    p, b = (yaml.safe_load(f.read_text())["methods"]["wls"] for f in (plain, boot))
    entry = b["quantisation_bootstrap"]
    assert entry["replicas"] == 2
    np.testing.assert_allclose(b["values"], np.subtract(p["values"], entry["bias_removed"]),
                               rtol=1e-9, atol=1e-12)  # fmt: skip
    assert np.all(np.array(b["std"]) >= np.array(p["std"]))
    assert np.any(np.array(b["std"]) > np.array(p["std"]))
    # the repeating part's variance is the same; its share of the wider total smaller
    shares = [np.array(x["repeating_residual"]["variance_share"]) for x in (p, b)]
    if rows:  # at every tick the noise neighbours share outweighs it (shares below 1 %)
        assert np.any(shares[0] > 0.01)
    wider = np.square(np.divide(p["std"], b["std"]))
    np.testing.assert_allclose(shares[1], shares[0] * wider, atol=2e-4)  # 4 decimals each


def test_identify_bootstrap_cannot_run_one_line(gap_guard_captures, tmp_path):
    log = gap_guard_captures[3]
    text = open(GUARD.source, encoding="utf-8").read()
    robot = tmp_path / "guard.yaml"
    robot.write_text("\n".join(x for x in text.splitlines() if not x.strip().startswith("pid:")))
    foreign = ("--robot", "guard", "--columns",
               "time=time_s,q1=q_pan_rad,q2=q_tilt_rad,i1=i_pan_A,i2=i_tilt_A")  # fmt: skip
    for extra, why in ((foreign, "no setpoints"), (("--robot", robot), "no pid")):
        _bootstrap_cannot_run(log, tmp_path / f"p{len(extra)}.yaml", why, *extra, k="3")


def _bootstrap_cannot_run(log, out, why, *extra, k="2"):
    """identify --quantisation-bootstrap ``k`` on ``log`` (with ``extra`` options), written
    to ``out``: exit 0, one warning line saying ``why``, no traceback, the estimate written
    without the bootstrap."""
    res = invoke("identify", log, "--method", "wls", "--quantisation-bootstrap", k, "-o", out,
                 *extra)  # fmt: skip
    assert res.exit_code == 0, res.stderr
    lines = [x for x in res.stderr.splitlines() if "quantisation-bootstrap" in x]
    assert len(lines) == 1 and "cannot run" in lines[0] and why in lines[0], res.stderr
    assert "Traceback" not in res.stderr
    assert "quantisation_bootstrap" not in yaml.safe_load(out.read_text())["methods"]["wls"]


def test_supply_measured_from_the_log(tmp_path, noise_free_replay):
    """The supply's level and ripple that ``sim://guard?supply=F&ripple=R`` drew (by hand
    from its documented stream: random.Random('supply-SEED'), level 1 + uniform(-F, F))
    are found in the log; a capture on the nominal supply has level 1 and no ripple."""
    import random

    from guardid.identify.runs import load_run
    from guardid.uncertainty.supply import measured_supply

    log = tmp_path / "ripple.csv"
    res = invoke("capture", "--port", "sim://guard?seed=3&supply=0.05&ripple=0.02",
                 "--trajectory", noise_free_replay["traj"], "--duration", 8, "--quiet", "-o",
                 log)  # fmt: skip
    assert res.exit_code == 0, res.output
    level = 1.0 + random.Random("supply-3").uniform(-0.05, 0.05)
    found = measured_supply(load_run(log), GUARD)
    assert found.level == pytest.approx(level, abs=0.003)
    assert found.ripple == pytest.approx(0.02, rel=0.15)
    nominal = measured_supply(load_run(noise_free_replay["yaml"]), GUARD)
    assert nominal.level == pytest.approx(1.0, abs=0.003) and nominal.ripple < 0.003


def test_replica_starts_as_the_log_in_identify(far_start_capture):
    """What identify keeps of a log for the bootstrap (``_lean``) starts the replica's PID
    as the firmware had it: the replica, simulated with the robot's own parameters, follows
    the logged angles (within 0.25 deg on each joint; 0.08 deg measured). Without the first
    rows' counts the replica starts on a wrong integral and is several degrees off in its
    first seconds (8.5 deg here; simulated with a poorly conditioned fit's estimate, its
    tilt fell onto the -15 deg stop and the bootstrap could not run)."""
    from guardid.closedloop.rows import start_of
    from guardid.commands.identify import _lean
    from guardid.identify.prepare import current_on_adc_levels
    from guardid.identify.runs import load_run
    from guardid.robot import load_robot
    from guardid.uncertainty.replicas import replica_run, simulated_values

    robot = load_robot(str(VARIANT))
    run = current_on_adc_levels(load_run(far_start_capture), robot)
    first_gap = np.degrees(np.abs(run.setpoint[0] - run.q[0]))
    assert first_gap.max() > 3.0  # the case: the first setpoint far from the start
    lean = _lean(run, robot, ("wls",), bootstrap=True)
    assert start_of(lean, robot)[3] is not None  # the first rows' counts and voltages
    truth = simulated_values(robot, (), ())  # the YAML's base parameters
    rep = replica_run(lean, robot, truth, [0.5, 0.5])
    off = np.degrees(np.abs(rep.q - run.q)).max(axis=0)
    assert np.all(off < 0.25), off


def test_identify_bootstrap_runs_on_a_log_starting_far_from_its_setpoint(
    far_start_capture, tmp_path
):
    """The command on that log: it runs, and the bias it removes is finite and within a
    few of the log's own std (the encoder's part of the error, not a diverged replica's)."""
    plain, out = tmp_path / "plain.yaml", tmp_path / "p.yaml"
    args = ("--robot", VARIANT, "--method", "wls")
    assert invoke("identify", far_start_capture, *args, "-o", plain).exit_code == 0
    res = invoke("identify", far_start_capture, *args, "--quantisation-bootstrap", "2", "-o", out)
    assert res.exit_code == 0, res.stderr
    assert "cannot run" not in res.stderr
    entry = yaml.safe_load(out.read_text())["methods"]["wls"]["quantisation_bootstrap"]
    assert entry["replicas"] == 2
    std = np.array(yaml.safe_load(plain.read_text())["methods"]["wls"]["std"])
    bias = np.array(entry["bias_removed"])
    assert np.all(np.isfinite(bias)) and np.all(np.abs(bias) < 3.0 * std), bias / std


def test_identify_bootstrap_a_replica_fit_not_finite_one_line(
    far_start_capture, tmp_path, monkeypatch
):
    """A replica whose fit is not finite (a closed loop that does not move as the log)."""
    import guardid.identify.pipeline as pipeline

    real = pipeline.identify

    def one_nan(runs, description, options=None):
        result = real(runs, description, options)
        if str(runs[0].path).endswith("(replica)"):
            for fit in result.results.values():
                fit.theta = np.full_like(np.asarray(fit.theta, dtype=float), np.nan)
        return result

    monkeypatch.setattr(pipeline, "identify", one_nan)
    _bootstrap_cannot_run(far_start_capture, tmp_path / "p.yaml",
                          "replica 1: its fit is not finite", "--robot", VARIANT)  # fmt: skip


def test_identify_bootstrap_no_covariance_one_line(far_start_capture, tmp_path, monkeypatch):
    """The replicas' covariance failing to decompose (a LinAlgError)."""
    from guardid.uncertainty.bootstrap import QuantisationBootstrap

    def no_eigen(self, cov):
        raise np.linalg.LinAlgError("Eigenvalues did not converge")

    monkeypatch.setattr(QuantisationBootstrap, "covariance", no_eigen)
    _bootstrap_cannot_run(far_start_capture, tmp_path / "p.yaml", "give no covariance",
                          "--robot", VARIANT)  # fmt: skip
