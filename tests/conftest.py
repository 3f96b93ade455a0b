"""Session fixtures shared by several test modules (keep them few, specific and cheap)."""

from __future__ import annotations

import fcntl
import os
import pickle
from pathlib import Path

import pytest
from badinput_tools import invoke, one_blas_thread
from capturetools import VARIANT


def made_once(tmp_path_factory, name: str, make) -> Path:
    """A directory ``make(directory)`` fills once per test run, shared by the xdist workers
    (a lock file: the first worker to ask makes it, the others wait and reuse it). Only for
    deterministic content that no test writes to."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the workers' common base
    d = root / f"once-{name}"
    with open(root / f"once-{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (d / ".complete").exists():
            d.mkdir(exist_ok=True)
            make(d)
            (d / ".complete").touch()
    return d


@pytest.fixture(scope="session")
def excitation(tmp_path_factory):
    """``excitation(*args)``: the path of ``guardid excite ARGS -o traj.yaml`` (deterministic:
    the optimisation is seeded), made once per test run whichever module asks first. Read
    only: copy it before editing."""

    def get(*args) -> Path:
        name = "excite" + "".join(str(a).replace("-", "_") for a in args)

        def make(d):
            res = invoke("excite", *args, "-o", d / "traj.yaml")
            assert res.exit_code == 0, res.output

        return made_once(tmp_path_factory, name, make) / "traj.yaml"

    return get


GAP_SEEDS = (1, 2, 3)
GAP_CAPTURE_S = 60


@pytest.fixture(scope="session")
def gap_guard_captures(tmp_path_factory) -> dict:
    """{seed: path} of a 60 s lock-step capture of ``sim://guard?seed=N`` (seeds 1-3) on the
    unoptimised default excitation, made once per session (about 2 s of CPU each); tests
    copy or edit them, never write beside them."""
    d = tmp_path_factory.mktemp("gap_guard_captures")
    traj = d / "traj.yaml"
    res = invoke("excite", "--no-optimise", "-o", traj)
    assert res.exit_code == 0, res.output
    out = {}
    for seed in GAP_SEEDS:
        log = d / f"run{seed}.csv"
        res = invoke("capture", "--port", f"sim://guard?seed={seed}", "--trajectory", traj,
                     "--duration", GAP_CAPTURE_S, "--quiet", "-o", log)  # fmt: skip
        assert res.exit_code == 0, res.output
        out[seed] = log
    return out


@pytest.fixture(scope="session")
def gap_guard_wls_params(gap_guard_captures, tmp_path_factory) -> dict:
    """{seed: path} of ``identify --method wls -o`` on each intact capture of
    :func:`gap_guard_captures` (the reference the damaged copies are held against)."""
    d = tmp_path_factory.mktemp("gap_guard_wls")
    out = {}
    for seed, log in gap_guard_captures.items():
        out[seed] = d / f"p{seed}.yaml"
        res = invoke("identify", log, "--method", "wls", "-o", out[seed])
        assert res.exit_code == 0, res.stderr
    return out


@pytest.fixture(scope="session", autouse=True)
def _one_blas_thread_in_every_test_process():
    """BLAS on one thread in each test process for the whole run, as every guardid command
    sets for itself (:func:`guardid.cli._one_blas_thread`, before numpy loads). In a test
    process numpy has loaded with OpenBLAS's default before any command runs in it
    (CliRunner) or any library call, and the two xdist workers already fill the 2-core
    runner, where a second BLAS thread only spins (test_identify_conditioning,
    test_identify_guard and test_every_tick: 59 s of CPU with two threads, 40 s with one,
    2026-11-27; seed001-table1's reproduction about 11 s on one, 20 s on two). scipy.linalg
    first: scipy has an OpenBLAS of its own, which the limit reaches only when loaded."""
    import scipy.linalg  # noqa: F401  (its own OpenBLAS loaded, so that the limit covers it)

    with one_blas_thread():
        yield


@pytest.fixture(scope="session")
def reproduced(tmp_path_factory):
    """``reproduced(name, run)``: the Report of ``run()``, a deterministic reproduction,
    made once per test run (under the session's one BLAS thread) whichever
    xdist worker asks first, and unpickled in each worker that asks."""

    def get(name: str, run):
        def make(d):
            (d / "report.pickle").write_bytes(pickle.dumps(run()))

        d = made_once(tmp_path_factory, name, make)
        return pickle.loads((d / "report.pickle").read_bytes())

    return get


@pytest.fixture(scope="session")
def seed001_table1_report(reproduced):
    """``guardid reproduce seed001-table1`` at its defaults (15 noise seeds), run once per
    test run (about 11 s of CPU): shared by test_reproduce and test_mlp_reproduce."""
    from guardid.reproduce import seed001_table1

    return reproduced("seed001_table1", lambda: seed001_table1.run(0))


REPLAY_CAPTURE_S = 8


@pytest.fixture(scope="session")
def noise_free_replay(tmp_path_factory) -> dict:
    """Paths for the replay and twin tests, made once per session (about 1 s of CPU): 8 s
    lock-step captures on the unoptimised default excitation of ``sim://guard?noise=0``
    ('yaml'), of its twin from the robot YAML's own base parameters ('twin_true', with
    'true': that reference values file) and of a twin 30 % heavier and stickier
    ('twin_off', 'off': its reference file, every base parameter x 1.3)."""
    import yaml

    from guardid.dynamics import build_model
    from guardid.robot import load_robot

    d = tmp_path_factory.mktemp("noise_free_replay")
    model = build_model(load_robot("guard"))
    values = (float(x) for x in model.base.values(model.params))
    true = dict(zip(model.base.names, values, strict=True))
    out = {"traj": d / "traj.yaml", "true": d / "true.yaml", "off": d / "off.yaml"}
    for key, scale in (("true", 1.0), ("off", 1.3)):
        values = {k: v * scale for k, v in true.items()}
        out[key].write_text(yaml.safe_dump({"guardid-reference": 1, "label": key,
                                            "values": values}))  # fmt: skip
    res = invoke("excite", "--no-optimise", "-o", out["traj"])
    assert res.exit_code == 0, res.output
    for key, extra in (("yaml", ""), ("twin_true", f"&params={out['true']}"),
                       ("twin_off", f"&params={out['off']}")):  # fmt: skip
        out[key] = d / f"{key}.csv"
        port = f"sim://guard?noise=0{extra}"
        res = invoke("capture", "--port", port, "--trajectory", out["traj"], "--duration",
                     REPLAY_CAPTURE_S, "--quiet", "-o", out[key])  # fmt: skip
        assert res.exit_code == 0, res.output
    return out


def _variant_schroeder(d: Path, seed: int, duration_s: float) -> None:
    """``d / "log.csv"``: ``duration_s`` of the Schroeder excitation on the variant robot
    (capturetools.VARIANT) through ``sim://VARIANT?seed=SEED&start=50&supply=0.02&ripple=0.01``."""
    traj = d / "traj.yaml"
    made = invoke("excite", "--robot", VARIANT, "--kind", "schroeder", "-o", traj)
    assert made.exit_code == 0, made.stderr
    port = f"sim://{VARIANT}?seed={seed}&start=50&supply=0.02&ripple=0.01"
    res = invoke("capture", "--trajectory", traj, "--robot", VARIANT, "--port", port,
                 "--duration", f"{duration_s:g}", "--quiet", "-o", d / "log.csv")  # fmt: skip
    assert res.exit_code == 0, res.stderr


@pytest.fixture(scope="session")
def far_start_capture(tmp_path_factory) -> Path:
    """30 s of the Schroeder excitation on the variant robot (capturetools.VARIANT), its
    first setpoint 4 and 10 deg from the rest pose the capture starts at, so the PID starts
    saturated: the log (read only)."""
    make = lambda d: _variant_schroeder(d, 12000, 30.0)  # noqa: E731
    return made_once(tmp_path_factory, "far_start", make) / "log.csv"


@pytest.fixture(scope="session")
def variant_schroeder_300s(tmp_path_factory) -> Path:
    """300 s of the Schroeder excitation on the variant robot, seed 12001: the log (read
    only)."""
    make = lambda d: _variant_schroeder(d, 12001, 300.0)  # noqa: E731
    return made_once(tmp_path_factory, "variant_schroeder_300s", make) / "log.csv"
