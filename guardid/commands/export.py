"""``guardid export``: the identified robot as URDF (+ side YAML) and / or MuJoCo MJCF."""

from __future__ import annotations

import click

from guardid.commands.outputs import force_option
from guardid.errors import ConfigError


def consistent_description(params_path, robot_opt=None):
    """The robot description with params.yaml's consistent standard parameters (SI); the
    robot is ``robot_opt`` when given, else the description stored in the params file (a
    user's robot need not be findable by its name), else (older files) its name."""
    from guardid.dynamics import build_model
    from guardid.identify.report import read_params
    from guardid.identify.validation import stored_robot
    from guardid.physical import description_with
    from guardid.robot import ChainDescription, load_robot

    params = read_params(params_path)
    stored = None if robot_opt else stored_robot(params_path, params)  # the description kept
    description = load_robot(robot_opt) if robot_opt else stored
    if isinstance(description, str):  # an older params file: the robot's name only
        description = load_robot(description)
    if not isinstance(description, ChainDescription):
        raise ConfigError(f"{params_path}: robot {description.name}: only serial chains export")
    section = params.get("consistent")
    if not isinstance(section, dict) or "standard_parameters" not in section:
        raise ConfigError(
            f"{params_path}: consistent: missing (run guardid identify --consistent -o ...)"
        )
    entries = section["standard_parameters"]
    try:
        names = [str(e["name"]) for e in entries]
        values = [float(e["value"]) for e in entries]
    except (KeyError, TypeError, ValueError):
        raise ConfigError(f"{params_path}: consistent.standard_parameters: malformed") from None
    expected = build_model(description).param_names
    if names != list(expected):
        raise ConfigError(
            f"{params_path}: consistent.standard_parameters: {names} do not match robot "
            f"{description.name}'s {expected}"
        )
    if section.get("violations"):
        raise ConfigError(f"{params_path}: consistent.violations: {section['violations'][0]}")
    return description_with(description, names, values)


@click.command()
@click.argument("params", required=False, type=click.Path(dir_okay=False))
@click.option("--robot", default=None, help="Robot (shipped, YAML or URDF) [default: params'].")
@click.option("--urdf", "urdf_path", default=None, help="Write URDF here (+ <stem>.guardid.yaml).")
@click.option("--mjcf", "mjcf_path", default=None, help="Write MuJoCo MJCF here.")
@force_option()
def export(params, robot, urdf_path, mjcf_path, force):
    """Write the identified robot (PARAMS from identify --consistent) as URDF and/or MJCF.

    Without PARAMS, writes --robot's description as it is (e.g. a shipped robot as URDF).
    Rotor inertia and the friction offset, which URDF has no field for, go to the side YAML
    beside the URDF; see docs/URDF.md for every field.
    """
    from guardid.commands.outputs import check_distinct, check_output, robot_file, write_texts
    from guardid.export import mjcf_text, side_path, urdf_texts
    from guardid.robot import ChainDescription, load_robot

    if not (urdf_path or mjcf_path):
        raise click.UsageError("give --urdf PATH and/or --mjcf PATH")
    inputs = [("PARAMS", params), ("--robot", robot_file(robot))]
    outputs = [("--urdf", urdf_path), ("--urdf", urdf_path and side_path(urdf_path))]
    outputs.append(("--mjcf", mjcf_path))
    for option, path in outputs:
        check_output(path, inputs, option=option, force=force)
    check_distinct(outputs)
    if params:
        description = consistent_description(params, robot)
    elif robot:
        description = load_robot(robot)
        if not isinstance(description, ChainDescription):
            raise ConfigError(f"--robot {robot}: only serial chains export")
    else:
        raise click.UsageError("give PARAMS (from identify --consistent) or --robot")
    texts = []
    if urdf_path:
        urdf, side = urdf_texts(description, urdf_path)
        texts += [(side_path(urdf_path), side, "--urdf"), (urdf_path, urdf, "--urdf")]
    if mjcf_path:
        texts.append((mjcf_path, mjcf_text(description), "--mjcf"))
    write_texts(texts)  # all or none
    if urdf_path:
        click.echo(f"wrote {urdf_path} and {side_path(urdf_path)}")
    if mjcf_path:
        click.echo(f"wrote {mjcf_path}")
