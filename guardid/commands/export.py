"""``guardid export``: the identified robot as URDF (+ side YAML) and / or MuJoCo MJCF."""

from __future__ import annotations

from pathlib import Path

import click

from guardid.errors import ConfigError


def consistent_description(params_path, robot_opt=None):
    """The robot description with params.yaml's consistent standard parameters (SI)."""
    from guardid.dynamics import build_model
    from guardid.identify.report import read_params
    from guardid.physical import description_with
    from guardid.robot import ChainDescription, load_robot

    params = read_params(params_path)
    description = load_robot(robot_opt or params["robot"])
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


def _check_new(path, force) -> None:
    if path and Path(path).exists() and not force:
        raise ConfigError(f"{path}: exists (give --force to replace it)")


@click.command()
@click.argument("params", required=False, type=click.Path(dir_okay=False))
@click.option("--robot", default=None, help="Robot (shipped, YAML or URDF) [default: params'].")
@click.option("--urdf", "urdf_path", default=None, help="Write URDF here (+ <stem>.guardid.yaml).")
@click.option("--mjcf", "mjcf_path", default=None, help="Write MuJoCo MJCF here.")
@click.option("--force", is_flag=True, help="Replace existing output files.")
def export(params, robot, urdf_path, mjcf_path, force):
    """Write the identified robot (PARAMS from identify --consistent) as URDF and/or MJCF.

    Without PARAMS, writes --robot's description as it is (e.g. a shipped robot as URDF).
    Rotor inertia and the friction offset, which URDF has no field for, go to the side YAML
    beside the URDF; see docs/URDF.md for every field.
    """
    from guardid.export import side_path, write_mjcf, write_urdf
    from guardid.robot import ChainDescription, load_robot

    if not (urdf_path or mjcf_path):
        raise click.UsageError("give --urdf PATH and/or --mjcf PATH")
    if params:
        description = consistent_description(params, robot)
    elif robot:
        description = load_robot(robot)
        if not isinstance(description, ChainDescription):
            raise ConfigError(f"--robot {robot}: only serial chains export")
    else:
        raise click.UsageError("give PARAMS (from identify --consistent) or --robot")
    for path in (urdf_path, urdf_path and side_path(urdf_path), mjcf_path):
        _check_new(path, force)
    if urdf_path:
        out, side = write_urdf(description, urdf_path)
        click.echo(f"wrote {out} and {side}")
    if mjcf_path:
        click.echo(f"wrote {write_mjcf(description, mjcf_path)}")
