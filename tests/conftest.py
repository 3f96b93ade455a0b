"""Session fixtures shared by several test modules (keep them few, specific and cheap)."""

from __future__ import annotations

import pytest
from badinput_tools import invoke, one_blas_thread

GAP_SEEDS = (1, 2, 3)
GAP_CAPTURE_S = 60


@pytest.fixture(scope="session")
def gap_guard_captures(tmp_path_factory) -> dict:
    """{seed: path} of a 60 s lock-step capture of ``sim://guard?seed=N`` (seeds 1-3) on the
    unoptimised default excitation, made once per session (about 2 s of CPU each); tests
    copy or edit them, never write beside them."""
    d = tmp_path_factory.mktemp("gap_guard_captures")
    traj = d / "traj.yaml"
    with one_blas_thread():
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
    with one_blas_thread():
        for seed, log in gap_guard_captures.items():
            out[seed] = d / f"p{seed}.yaml"
            res = invoke("identify", log, "--method", "wls", "-o", out[seed])
            assert res.exit_code == 0, res.stderr
    return out


@pytest.fixture(scope="session")
def seed001_table1_report():
    """``guardid reproduce seed001-table1`` at its defaults (15 noise seeds), run once per
    session (about 25 s of CPU): shared by test_reproduce and test_mlp_reproduce."""
    from guardid.reproduce import seed001_table1

    return seed001_table1.run(0)


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
    with one_blas_thread():
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
