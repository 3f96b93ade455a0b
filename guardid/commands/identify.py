"""``guardid identify`` and ``guardid validate``."""

from __future__ import annotations

from pathlib import Path

import click
import numpy as np
import yaml

from guardid.errors import ConfigError


def _robot_for(run, robot_opt):
    from guardid.robot import load_robot

    spec = robot_opt or run.robot
    if not spec:
        raise ConfigError(f"{run.path}: the log names no robot: give --robot")
    if not robot_opt and not Path(str(spec)).exists():
        spec = Path(str(spec)).stem if str(spec).endswith(".yaml") else spec
    return load_robot(spec)


@click.command()
@click.argument("log", type=click.Path(dir_okay=False))
@click.option("--robot", default=None, help="Shipped robot or YAML path [default: the log's].")
@click.option(
    "--method",
    default="ls,wls,rls,hopfield",
    show_default=True,
    help="Comma-separated: ls, wls, rls, hopfield, gradient.",
)
@click.option("--cutoff", type=float, default=None, help="Low-pass cut-off [Hz] [default: auto].")
@click.option("--beta", type=float, default=0.01, show_default=True, help="Hopfield gain beta.")
@click.option("--lam", type=float, default=1.0, show_default=True, help="RLS forgetting factor.")
@click.option("--eta", type=float, default=1e-3, show_default=True, help="Gradient gain.")
@click.option("--current-units", is_flag=True, help="Identify in current units (gain unknown).")
@click.option("-o", "--output", default=None, help="Write the parameters to this YAML file.")
@click.option("--plot", "plot_path", default=None, help="Write a PNG report (matplotlib).")
def identify(log, robot, method, cutoff, beta, lam, eta, current_units, output, plot_path):
    """Identify the robot's base parameters and motor constants from LOG."""
    from guardid.identify import identification_rows
    from guardid.identify import identify as run_identify
    from guardid.identify.report import plot, table, to_yaml_dict
    from guardid.identify.runs import load_run

    run = load_run(log)
    description = _robot_for(run, robot)
    methods = tuple(m.strip() for m in method.split(",") if m.strip())
    result = run_identify(
        run.t, run.q, run.current, description, methods=methods, cutoff_hz=cutoff, beta=beta,
        lam=lam, gradient_eta=eta, voltage_v=run.voltage, ticks=run.ticks,
        in_current_units=current_units,
    )  # fmt: skip
    click.echo(table(result, methods))
    for w in result.warnings:
        click.echo(f"warning: {w}", err=True)
    if output:
        with open(output, "w", encoding="utf-8") as f:
            yaml.safe_dump(to_yaml_dict(result, description, log), f, sort_keys=False)
        click.echo(f"parameters written to {output}")
    if plot_path:
        _, A, y = identification_rows(
            run.t, run.q, run.current, description, result.cutoff_hz, current_units
        )
        plot(result, plot_path, A, y)
        click.echo(f"plot written to {plot_path}")


@click.command()
@click.argument("log", type=click.Path(dir_okay=False))
@click.option("--params", "params_path", required=True, help="params.yaml from guardid identify.")
@click.option("--robot", default=None, help="Shipped robot or YAML path [default: the params'].")
@click.option("--cutoff", type=float, default=None, help="Low-pass cut-off [Hz].")
def validate(log, params_path, robot, cutoff):
    """Torque prediction error (d_tau) of identified parameters on another run."""
    from guardid.estimators import d_tau
    from guardid.identify import identification_rows
    from guardid.identify.report import read_params
    from guardid.identify.runs import load_run

    params = read_params(params_path)
    run = load_run(log)
    description = _robot_for(run, robot or params["robot"])
    names = [p["name"] for p in params["base_parameters"]]
    from guardid.dynamics import build_model

    model_names = list(build_model(description).base.names)
    if names != model_names:
        raise ConfigError(
            f"{params_path}: base_parameters: {names} do not match robot "
            f"{description.name}'s {model_names}"
        )
    current_units = params.get("torque_unit") != "N m"
    cond, A, y = identification_rows(
        run.t, run.q, run.current, description, cutoff or params.get("cutoff_hz"), current_units
    )
    joints = [j.name for j in description.joints]
    for m, entry in params["methods"].items():
        theta = np.asarray(entry["values"], dtype=float)
        if theta.shape != (len(names),):
            raise ConfigError(f"{params_path}: methods.{m}.values: expected {len(names)} numbers")
        per_joint = d_tau(A, y, theta, per_joint=True)
        detail = ", ".join(f"{j} {100 * v:.2f} %" for j, v in zip(joints, per_joint, strict=True))
        click.echo(f"{m.upper():9s} d_tau {100 * d_tau(A, y, theta):.2f} %  ({detail})")
