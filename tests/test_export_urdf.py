# ruff: noqa: E501  (the hand-written URDF keeps one element per line)
"""URDF / MJCF export and URDF import, checked by loading the files in pinocchio.

The "identified model" is a consistent fit (guardid.physical) on rows simulated from a
perturbed robot; pinocchio loads the exported URDF and must reproduce guardid's inverse
dynamics of that model. Rigid body in pinocchio's rnea; the rotor inertia is pinocchio's
``armature`` (from the side YAML; a coupled rotor's off-diagonal terms by hand, they have no
URDF or pinocchio field), friction Fv qd + Fc sign(qd) from the URDF's ``<dynamics>`` as
pinocchio reads it, plus the offset from the side YAML.
"""

from __future__ import annotations

import functools
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
import yaml
from click.testing import CliRunner
from test_pinocchio import perturbed, states

from guardid.cli import main
from guardid.dynamics import build_model
from guardid.errors import ConfigError
from guardid.export import write_mjcf, write_urdf
from guardid.physical import description_with, fit_consistent
from guardid.physical.report import yaml_section
from guardid.robot import load_robot


@functools.cache
def identified(robot, seed=3):
    """(description of the identified robot, its params (p,)) from a consistent fit on
    simulated rows of a perturbed robot (noise 1 % of the torque)."""
    desc = load_robot(robot)
    truth = build_model(perturbed(desc, seed))
    model = build_model(desc)
    q, qd, qdd = states(desc.n_dof, 400, seed)
    from guardid.identify.pipeline import identified_names

    keep = [model.base.names.index(n) for n in identified_names(desc)]
    A = model.base_regressor(q, qd, qdd)[:, :, keep]
    tau = truth.inverse_dynamics(q, qd, qdd)
    rng = np.random.default_rng(seed)
    y = tau + 0.01 * tau.std(axis=0) * rng.standard_normal(tau.shape)
    fit = fit_consistent(A, y, desc)
    assert not fit.violations
    return description_with(desc, fit.names, fit.standard), fit


def pin_q(model, q):
    """pinocchio configuration of joint angles q (n,) (continuous joints: cos, sin)."""
    out = []
    for j, angle in zip(model.joints[1:], q, strict=True):
        out += [np.cos(angle), np.sin(angle)] if j.nq == 2 else [angle]
    return np.array(out)


def coupled_rotor_torque(desc, qdd):
    """Off-diagonal rotor terms (not representable as armature): J s N on M12 / M21."""
    out = np.zeros_like(qdd)
    r = desc.joints[-1].rotor
    if r is not None and r.coupling:
        s = r.coupling * r.gear_ratio * r.inertia
        out[:, 0] += s * qdd[:, 1] + r.inertia * qdd[:, 0]  # rotor spins at q1' + sN q2'
        out[:, 1] += s * qdd[:, 0]
    return out


@pytest.mark.parametrize("robot", ["guard", "planar2", "dfki_double_pendulum"])
def test_pinocchio_on_exported_urdf_reproduces_identified_model(robot, tmp_path):
    desc, fit = identified(robot)
    urdf, side_file = write_urdf(desc, tmp_path / "arm.urdf")
    side = yaml.safe_load(side_file.read_text())
    pm = pin.buildModelFromUrdf(str(urdf))
    data = pm.createData()
    for j, joint in enumerate(desc.joints):
        s = side["joints"][joint.name]
        if s["drive"] is not None:
            pm.armature[j] = s["drive"]["gear_ratio"] ** 2 * s["drive"]["rotor_inertia"]
        elif s.get("rotor"):
            pm.armature[j] = s["rotor"]["gear_ratio"] ** 2 * s["rotor"]["inertia"]
    offsets = np.array(
        [(s["friction"] or {}).get("offset") or 0.0 for s in side["joints"].values()]
    )
    q, qd, qdd = states(desc.n_dof, 1000, 11)
    ours = build_model(desc).inverse_dynamics(q, qd, qdd)
    theirs = np.array(
        [pin.rnea(pm, data, pin_q(pm, a), b, c) for a, b, c in zip(q, qd, qdd, strict=True)]
    )
    theirs += pm.damping * qd + pm.friction * np.sign(qd) + offsets
    theirs += coupled_rotor_torque(desc, qdd)
    rel = np.abs(ours - theirs).max(axis=0) / np.abs(ours).max(axis=0)
    assert rel.max() <= 1e-9
    assert np.allclose(fit.standard, build_model(desc).params, rtol=1e-12, atol=1e-15)


def test_urdf_round_trip_same_dynamics_and_base_values(tmp_path):
    for robot in ("guard", "dfki_double_pendulum"):
        desc, _ = identified(robot)
        write_urdf(desc, tmp_path / f"{robot}.urdf")
        back = load_robot(tmp_path / f"{robot}.urdf")
        m0, m1 = build_model(desc), build_model(back)
        q, qd, qdd = states(desc.n_dof, 200, 5)
        tau0 = m0.inverse_dynamics(q, qd, qdd)
        assert np.abs(m1.inverse_dynamics(q, qd, qdd) - tau0).max() <= 1e-9 * np.abs(tau0).max()
        # same base parameters (names may lose the R suffix: the last DH frame differs)
        strip = [n.rstrip("R") for n in m0.base.names]
        assert [n.rstrip("R") for n in m1.base.names] == strip
        b0, b1 = m0.base.values(m0.params), m1.base.values(m1.params)
        assert np.allclose(b1, b0, rtol=1e-9, atol=1e-12 * np.abs(b0).max())
        assert back.name == desc.name and back.sample_period == desc.sample_period


HAND_URDF = """<?xml version="1.0"?>
<robot name="hand">
  <link name="root"/>
  <link name="stand"><inertial><mass value="3"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
  <joint name="fix" type="fixed"><parent link="root"/><child link="stand"/><origin xyz="0.1 0.2 0.3" rpy="0.3 -0.2 0.5"/></joint>
  <link name="upper"><inertial><origin xyz="0.05 0.2 -0.01" rpy="0.1 0.2 0.3"/><mass value="1.2"/>
    <inertia ixx="0.03" ixy="0.001" ixz="-0.002" iyy="0.02" iyz="0.0005" izz="0.025"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="stand"/><child link="upper"/>
    <origin xyz="0 0 0.2" rpy="0.2 0.1 -0.4"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="10" velocity="2"/><dynamics damping="0.3" friction="0.1"/></joint>
  <link name="tool"><inertial><origin xyz="0.01 -0.02 0.03"/><mass value="0.4"/>
    <inertia ixx="0.002" ixy="0" ixz="0" iyy="0.003" iyz="0" izz="0.004"/></inertial></link>
  <joint name="tool_mount" type="fixed"><parent link="upper"/><child link="tool"/><origin xyz="0.02 0.3 0" rpy="0 0.4 0"/></joint>
  <link name="fore"><inertial><origin xyz="0.15 0.01 0.02" rpy="-0.2 0 0.1"/><mass value="0.8"/>
    <inertia ixx="0.01" ixy="0.0002" ixz="0" iyy="0.012" iyz="-0.0003" izz="0.006"/></inertial></link>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/>
    <origin xyz="0.03 0.35 0.02" rpy="0 0.3 0.2"/><axis xyz="0.6 0 0.8"/>
    <limit lower="-2" upper="2" effort="10" velocity="3"/></joint>
  <link name="slider"><inertial><origin xyz="0 0 0.05"/><mass value="0.3"/>
    <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.0005"/></inertial></link>
  <joint name="slide" type="prismatic"><parent link="fore"/><child link="slider"/>
    <origin xyz="0.3 0 0" rpy="0 0 0.7"/><axis xyz="1 0 0"/>
    <limit lower="-0.1" upper="0.1" effort="10" velocity="0.5"/></joint>
</robot>
"""
HAND_SIDE = {
    "sample_period": 0.01,
    "joints": {k: {"acceleration": 5.0} for k in ("shoulder", "elbow", "slide")},
}


def _hand(tmp_path, side=HAND_SIDE):
    (tmp_path / "hand.urdf").write_text(HAND_URDF)
    (tmp_path / "hand.guardid.yaml").write_text(yaml.safe_dump(side))
    return tmp_path / "hand.urdf"


def test_hand_written_urdf_imports_with_pinocchios_dynamics(tmp_path):
    """Arbitrary frames, tilted axes, fixed links merged, a prismatic joint: guardid's model
    of the imported URDF against pinocchio's of the same file (gravity -9.81 z)."""
    path = _hand(tmp_path)
    desc = load_robot(path)
    assert [j.type for j in desc.joints] == ["revolute", "revolute", "prismatic"]
    assert desc.joints[0].friction.viscous == 0.3 and desc.joints[1].friction is None
    pm = pin.buildModelFromUrdf(str(path))
    data = pm.createData()
    q, qd, qdd = states(3, 300, 2)
    q[:, 2] *= 0.03  # metres
    model = build_model(desc)
    ours = model.inverse_dynamics(q, qd, qdd, friction=False)
    theirs = np.array([pin.rnea(pm, data, a, b, c) for a, b, c in zip(q, qd, qdd, strict=True)])
    assert np.abs(ours - theirs).max() <= 1e-9 * np.abs(theirs).max()
    assert desc.joints[0].limits.position == (-1.0, 1.0) and desc.joints[0].limits.velocity == 2.0


@pytest.mark.parametrize(
    ("side", "needle"),
    [
        ({"joints": {"shoulder": {"acceleration": 5.0}}}, "joints.elbow.acceleration: missing"),
        ({"joints": {"knee": {"acceleration": 1.0}}}, "joints.knee: no such moving joint"),
        ({"colour": "red"}, "colour: unknown key"),
        (
            {"joints": {k: {"acceleration": 5.0, "pid": {"kp": "x", "ki": 0, "kd": 0}}
                        for k in ("shoulder", "elbow", "slide")}},
            "pid.kp: expected a number",
        ),
    ],
)  # fmt: skip
def test_side_yaml_errors_are_one_line_naming_the_key(tmp_path, side, needle):
    with pytest.raises(ConfigError) as err:
        load_robot(_hand(tmp_path, side))
    assert needle in str(err.value) and "\n" not in str(err.value)
    assert "hand.guardid.yaml" in str(err.value)


def test_branching_urdf_is_refused(tmp_path):
    text = HAND_URDF.replace(
        "</robot>",
        '<link name="side"/><joint name="branch" type="revolute"><parent link="upper"/>'
        '<child link="side"/><axis xyz="0 0 1"/><limit effort="1" velocity="1" lower="-1" '
        'upper="1"/></joint></robot>',
    )
    (tmp_path / "b.urdf").write_text(text)
    with pytest.raises(ConfigError, match="b.urdf: link upper: branches into elbow, branch"):
        load_robot(tmp_path / "b.urdf")


def test_mjcf_has_armature_damping_frictionloss(tmp_path):
    desc, _ = identified("guard")
    root = ET.parse(write_mjcf(desc, tmp_path / "arm.xml")).getroot()
    joints = {j.get("name"): j for j in root.iter("joint")}
    for joint in desc.joints:
        el = joints[joint.name]
        assert float(el.get("armature")) == pytest.approx(joint.reflected_inertia, rel=1e-15)
        assert float(el.get("damping")) == joint.friction.viscous
        assert float(el.get("frictionloss")) == joint.friction.coulomb
    assert [float(x) for x in root.find("option").get("gravity").split()] == [0.0, 0.0, -9.81]
    assert joints["tilt"].get("range") is not None and joints["pan"].get("range") is None


def test_cli_export_from_params(tmp_path):
    desc, fit = identified("guard")
    params = {"guardid-params": 1, "robot": "guard", "base_parameters": [], "methods": {}}
    params["consistent"] = yaml_section(fit)
    (tmp_path / "p.yaml").write_text(yaml.safe_dump(params))
    runner = CliRunner()
    args = ["export", str(tmp_path / "p.yaml"), "--urdf", str(tmp_path / "a.urdf")]
    res = runner.invoke(main, [*args, "--mjcf", str(tmp_path / "a.xml")])
    assert res.exit_code == 0, res.output
    back = load_robot(tmp_path / "a.urdf")
    assert [link.mass for link in back.links] == pytest.approx([lk.mass for lk in desc.links])
    again = runner.invoke(main, args)  # never overwrite without --force
    assert again.exit_code != 0 and "exists (give --force" in again.output
    del params["consistent"]
    (tmp_path / "q.yaml").write_text(yaml.safe_dump(params))
    res = runner.invoke(main, ["export", str(tmp_path / "q.yaml"), "--urdf", str(tmp_path / "b")])
    assert res.exit_code != 0 and "consistent: missing" in res.output


def test_guardid_without_urdf_does_not_import_yourdfpy():
    code = (
        "import sys, guardid.cli; from guardid.robot import load_robot; "
        "from guardid.dynamics import build_model; build_model(load_robot('guard')); "
        "print(sorted(m for m in ('yourdfpy', 'trimesh', 'lxml', 'pinocchio') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_urdf_without_the_urdf_extra_is_one_line_naming_it(tmp_path, monkeypatch):
    """yourdfpy is the ``urdf`` extra: without it a URDF robot is one error line that says
    what to install (exit 2), no traceback; robots in YAML never need it."""
    from badinput_tools import invoke

    monkeypatch.setitem(sys.modules, "yourdfpy", None)  # ``import yourdfpy`` raises ImportError
    urdf = tmp_path / "arm.urdf"
    urdf.write_text('<robot name="arm"><link name="base"/></robot>')
    res = invoke("simulate", "--robot", urdf, "--duration", "1", "-o", tmp_path / "t.csv")
    assert res.exit_code == 2, res.output
    assert res.stderr.strip() == (
        "guardid: error: arm.urdf: reading a URDF needs yourdfpy: pip install 'guardid[urdf]'"
    )
    assert res.exception is None or isinstance(res.exception, SystemExit)
    assert not (tmp_path / "t.csv").exists()
