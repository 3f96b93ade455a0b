"""Model-based feedforward (capture --feedforward): the voltage against a one-joint case
worked by hand, the supply check before anything moves (every branch), older firmware
without the capability, and the footer's tracking error against numpy on the log."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from capturetools import IDLE, Witness, gentle_trajectory, witnessed
from click.testing import CliRunner

from guardid.cli import main
from guardid.dynamics import build_model
from guardid.errors import ConfigError
from guardid.excitation.sines import SumOfSines
from guardid.fakeport import register_device_factory
from guardid.feedforward import FeedforwardModel, check_supply, load_feedforward
from guardid.firmware import FirmwareEmulator
from guardid.plant import make_plant
from guardid.robot import load_robot

GUARD = load_robot("guard")


def _one_joint_robot(tmp_path) -> Path:
    """The guard's pan joint alone, its turret an isotropic body (0.02 kg m^2 about every
    axis through its centre of mass, which lies on the joint axis)."""
    data = yaml.safe_load(Path(GUARD.source).read_text())
    data["name"] = "pan_only"
    data["joints"] = data["joints"][:1]
    data["links"] = data["links"][:1]
    data["links"][0]["com"] = [0.0, 0.0, 0.0]
    path = tmp_path / "pan_only.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _params(tmp_path, description, methods: dict, motors=None, name="p.yaml") -> Path:
    """A params file as guardid identify writes it (the keys feedforward reads)."""
    names = list(build_model(description).base.names)
    data = {
        "guardid-params": 1,
        "robot": description.name,
        "base_parameters": [{"name": n} for n in names],
        "methods": {m: {"values": [float(x) for x in v]} for m, v in methods.items()},
    }
    if motors:
        data["motors"] = motors
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_one_joint_voltage_worked_by_hand(tmp_path):
    """pan alone at q = 0, q' = 0.5 rad/s, q'' = 2 rad/s^2 (guard.yaml's pan drive):
    inertia 0.02 + N^2 J = 0.02 + 500^2 * 2e-6 = 0.52 kg m^2; friction Fv 0.8, Fc 0.6;
    tau = 0.52 * 2 + 0.8 * 0.5 + 0.6 = 2.04 N m;
    i = tau / (N eta Kt) = 2.04 / (500 * 0.7 * 0.02) = 0.291428571 A;
    V = R i + Ke N q' = 8 * 0.291428571 + 0.02 * 500 * 0.5 = 7.331428571 V.
    (friction offset Fo1: null in the YAML, 0). A params file (WLS ZZ1R 0.6, Fv1 1.0,
    Fc1 0.5, Fo1 0.1; motor R 9 ohm, Ke 0.021 V s/rad; an LS row beside it that must not be
    used): tau = 0.6 * 2 + 1.0 * 0.5 + 0.5 + 0.1 = 2.3 N m, i = 2.3 / 7,
    V = 9 * 2.3 / 7 + 0.021 * 500 * 0.5 = 2.957142857 + 5.25 = 8.207142857 V."""
    desc = load_robot(str(_one_joint_robot(tmp_path)))
    assert list(build_model(desc).base.names) == ["ZZ1R", "Fv1", "Fc1", "Fo1"]
    state = (np.array([[0.0]]), np.array([[0.5]]), np.array([[2.0]]))
    true = FeedforwardModel.from_description(desc)
    assert true.torque(*state)[0, 0] == pytest.approx(2.04, rel=1e-12)
    assert true.voltage(*state)[0, 0] == pytest.approx(7.331428571, rel=1e-9)
    motors = [{"joint": "pan", "resistance_ohm": 9.0, "ke_v_s_per_rad": 0.021}]
    path = _params(tmp_path, desc, {"ls": [1, 1, 1, 1], "wls": [0.6, 1.0, 0.5, 0.1]}, motors)
    fitted = load_feedforward(str(path), desc)
    assert fitted.voltage(*state)[0, 0] == pytest.approx(8.207142857, rel=1e-9)
    assert "(WLS)" in fitted.label
    # at rest, backwards: Coulomb's sign flips, back-EMF too
    back = (np.array([[0.0]]), np.array([[-0.5]]), np.array([[0.0]]))
    assert true.voltage(*back)[0, 0] == pytest.approx(8 * (-0.4 - 0.6) / 7 - 5.0, rel=1e-9)


FAST_TILT = [1.0, 2.3]
"""Scales the gentle trajectory's tilt to 0.2 + 0.23 sin(2 pi 0.3 t): within every limit
(|q'| <= 0.434 of 0.45 rad/s, |q''| <= 0.82 of 2 rad/s^2, -0.03 .. 0.43 rad) but beyond
the 12 V supply: back-EMF 0.434 * 0.02 * 1000 = 8.7 V, gravity about 0.77 * 9.81 N m
/ 7 N m/A * 8 ohm = 8.6 V times cos q, friction (1.2 * 0.434 + 0.9) / 7 * 8 = 1.6 V."""


def _scaled(tmp_path, trajectory, factors, name: str) -> Path:
    path = tmp_path / name
    trajectory.scaled(factors).save(path)
    return path


def test_supply_check_names_the_joint_sign_and_time_every_branch(tmp_path):
    """A gentle trajectory passes; its tilt made faster (FAST_TILT) needs more than 12 V; a
    model with every sign reversed needs it negative; a pan motor of 100 ohm makes the pan
    the first to fail."""
    traj = SumOfSines.load(gentle_trajectory(tmp_path / "t.yaml"))
    true = FeedforwardModel.from_description(GUARD)
    assert 0.0 < check_supply(true, traj, "t.yaml") < 1.0
    big = traj.scaled(FAST_TILT)
    with pytest.raises(ConfigError, match=r"joint tilt needs \+\d\d\.\d\d V at t = .* 12 V"):
        check_supply(true, big, "big")
    flipped = FeedforwardModel(GUARD, -true.theta, true.resistance_ohm, -true.ke_v_s_per_rad, "x")
    with pytest.raises(ConfigError, match=r"joint tilt needs -\d\d\.\d\d V"):
        check_supply(flipped, big, "big")
    weak_pan = FeedforwardModel(GUARD, true.theta, np.array([100.0, 8.0]),
                                true.ke_v_s_per_rad, "x")  # fmt: skip
    with pytest.raises(ConfigError, match="joint pan needs"):
        check_supply(weak_pan, traj, "t")


def _true_params(tmp_path, name="true.yaml") -> Path:
    model = build_model(GUARD)
    return _params(tmp_path, GUARD, {"wls": model.base.values(model.params)}, name=name)


def _run(args):
    return CliRunner().invoke(main, ["capture", "--quiet", *map(str, args)])


def _one_line_exit_2(res) -> str:
    assert res.exit_code == 2, res.output
    (line,) = [x for x in res.output.splitlines() if x.strip()]
    assert line.startswith("guardid: error: ")
    return line


REFUSALS = {
    "supply": "beyond its 12 V supply",
    "robot": "robot: planar2, but the capture is on guard",
    "nan": "methods.wls.values: not all finite",
    "empty": "methods: empty",
    "motor": "motors[1].resistance_ohm: 'x' is not a positive number",
}


@pytest.mark.parametrize("case", sorted(REFUSALS))
def test_capture_refuses_before_the_port_opens(tmp_path, case):
    """Beyond the supply, a params file of another robot, with a NaN value or without any
    method: one line, exit 2, no port opened (no sim:// device made), no log."""
    traj = SumOfSines.load(gentle_trajectory(tmp_path / "t.yaml"))
    path = _scaled(tmp_path, traj, FAST_TILT if case == "supply" else [1.0, 1.0], "x.yaml")
    params = _true_params(tmp_path)
    data = yaml.safe_load(params.read_text())
    if case == "robot":
        data["robot"] = "planar2"
    elif case == "nan":
        data["methods"]["wls"]["values"][3] = float("nan")
    elif case == "empty":
        data["methods"] = {}
    elif case == "motor":
        data["motors"] = [{"joint": "pan"}, {"joint": "tilt", "resistance_ohm": "x"}]
    params.write_text(yaml.safe_dump(data))
    log = tmp_path / "run.csv"
    with witnessed() as robots:
        res = _run(["--trajectory", path, "--duration", 2, "--feedforward", params, "-o", log])
    line = _one_line_exit_2(res)
    assert f"--feedforward {params}" in line
    assert REFUSALS[case] in line
    assert robots == [] and not log.exists()


class Version1Firmware(FirmwareEmulator):
    """Firmware before the feedforward: protocol version 1, no capability bit 5, and
    SETPOINT_FF unknown (dropped, as a version-1 parser drops an unknown id)."""

    protocol_version = 1
    capabilities = tuple(c for c in FirmwareEmulator.capabilities if c != "feedforward")
    _HANDLERS = {k: v for k, v in FirmwareEmulator._HANDLERS.items() if k != "SetpointFf"}


def _old_firmware_capture(tmp_path, *extra):
    made = []

    def factory(robot, options):
        made.append(Witness(Version1Firmware(GUARD, make_plant(GUARD, options))))
        return made[-1]

    log = tmp_path / "old.csv"
    old = register_device_factory(factory)
    try:
        res = _run(["--trajectory", gentle_trajectory(tmp_path / "t.yaml"), "--duration", 1,
                    "-o", log, *extra])  # fmt: skip
    finally:
        register_device_factory(old)
    (w,) = made
    return res, w, log


def test_version_1_firmware_still_captures_without_feedforward(tmp_path):
    res, w, log = _old_firmware_capture(tmp_path)
    assert res.exit_code == 0, res.output
    names = {c[0] for c in w.commands}
    assert "SETPOINT" in names and "SETPOINT_FF" not in names
    assert (
        "protocol_version: 1" in log.read_text() and "complete: 67 rows" in res.output
    )  # 1 s / 15 ms


def test_version_1_firmware_with_feedforward_is_refused_before_anything_moves(tmp_path):
    res, w, log = _old_firmware_capture(tmp_path, "--feedforward", _true_params(tmp_path))
    line = _one_line_exit_2(res)
    assert "lacks the feedforward capability" in line and "protocol version 1" in line
    moved = [c for c in w.commands if c[0] in ("SETPOINT", "SETPOINT_FF", "SET_PID")]
    assert moved == [] and all(c[1] == IDLE for c in w.commands if c[0] == "SET_MODE")
    assert w.moving_ticks == 0 and not log.exists()


def _log_columns(path):
    lines = [ln for ln in Path(path).read_text().splitlines() if not ln.startswith("#")]
    head = lines[0].split(",")
    data = np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    return {name: data[:, k] for k, name in enumerate(head)}


def _footer(path) -> dict:
    text = "\n".join(ln[2:] for ln in Path(path).read_text().splitlines()
                     if ln.startswith("# ") or ln == "#")  # fmt: skip
    return yaml.safe_load(text[text.index("footer:") :])["footer"]


def test_footer_tracking_error_matches_numpy_and_feedforward_cuts_it(tmp_path):
    """3 s of the gentle trajectory with and without feedforward (true parameters): the
    footer's rms and max |setpoint - angle| equal numpy's on the logged columns (to the
    log's 1e-9 rad printing), and the feedforward lowers the rms on both joints several-fold.
    The trajectory starts at rest where the robot is: pan 0.3 (1 - cos(2 pi 0.2 t)), tilt
    0.1 (1 - cos(2 pi 0.3 t)) (the gentle one's speeds)."""
    traj = tmp_path / "rest.yaml"
    half_pi = math.pi / 2
    SumOfSines([[0.3], [0.1]], [[0.2], [0.3]], [[-half_pi], [-half_pi]], [0.3, 0.1]).save(traj)
    rms = {}
    for kind, extra in (("pid", []), ("ff", ["--feedforward", _true_params(tmp_path)])):
        log = tmp_path / f"{kind}.csv"
        res = _run(["--port", "sim://guard?seed=5", "--trajectory", traj, "--duration", 3,
                    "-o", log, *extra])  # fmt: skip
        assert res.exit_code == 0, res.output
        cols, footer = _log_columns(log), _footer(log)
        for joint in ("pan", "tilt"):
            err = cols[f"sp_{joint}_rad"] - cols[f"q_{joint}_rad"]
            got = footer["tracking_error"][joint]
            assert got["rms_rad"] == pytest.approx(math.sqrt(np.mean(err**2)), abs=2e-9)
            assert got["max_rad"] == pytest.approx(np.max(np.abs(err)), abs=2e-9)
        rms[kind] = np.array([footer["tracking_error"][j]["rms_rad"] for j in ("pan", "tilt")])
        assert ("# feedforward: null" in log.read_text()) == (kind == "pid")
    assert np.all(rms["ff"] * 10 < rms["pid"]), rms


def test_feedforward_with_reconnect_is_refused_before_anything(tmp_path):
    """--feedforward with --reconnect: a resumed run's slow approach has no feedforward, so
    the pair is refused in one line (exit 2) naming both options, before any port or log."""
    traj = gentle_trajectory(tmp_path / "t.yaml")
    log = tmp_path / "run.csv"
    with witnessed() as robots:
        res = _run(["--trajectory", traj, "--duration", 2, "--feedforward",
                    _true_params(tmp_path), "--reconnect", 5, "-o", log])  # fmt: skip
    line = _one_line_exit_2(res)
    assert "--feedforward" in line and "--reconnect" in line
    assert robots == [] and not log.exists()
