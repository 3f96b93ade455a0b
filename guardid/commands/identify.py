"""``guardid identify`` and ``guardid validate``."""

from __future__ import annotations

import math
from pathlib import Path

import click
import numpy as np
import yaml

from guardid.errors import ConfigError, UntrustedResult
from guardid.identify.checks import (
    check_cutoff,
    check_distinct,
    check_log_robot,
    check_params_robot,
)


def _robot_for(run, robot_opt):
    from guardid.robot import load_robot

    spec = robot_opt or run.robot
    if not spec:
        raise ConfigError(f"{run.path}: the log names no robot: give --robot")
    if not robot_opt and not Path(str(spec)).exists():
        spec = Path(str(spec)).stem if str(spec).endswith(".yaml") else spec
    return load_robot(spec)


def _foreign_options(f):
    """--columns, --sample-period, --mat-var, --mat-columns (foreign logs; both commands)."""
    opts = [
        click.option(
            "--columns",
            multiple=True,
            help="Foreign log: KEY=COLUMN[*FACTOR],... with keys time, q<j> [rad|m], "
            "tau<j> [N m|N] or i<j> [A], v<j> [V]; or a mapping YAML file "
            "(docs/FOREIGN_LOGS.md). Repeatable; later entries win.",
        ),
        click.option(
            "--sample-period", type=float, default=None, help="Foreign log without time [s]."
        ),
        click.option("--mat-var", default=None, help=".mat: 2-D array variable (N, k)."),
        click.option("--mat-columns", default=None, help=".mat: names of --mat-var's columns."),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


def _load(log, robot_opt, columns, sample_period, mat_var, mat_columns):
    """(run, description): a guardid log, or a foreign one when a mapping option is given."""
    from guardid.identify.runs import load_run
    from guardid.robot import load_robot

    if not (columns or sample_period is not None or mat_var or mat_columns):
        run = load_run(log)
        description = _robot_for(run, robot_opt)
        check_log_robot(run, description, f"--robot {robot_opt}" if robot_opt else "its header")
        return run, description
    from guardid.identify.foreign import parse_mapping

    mapping = parse_mapping(columns, sample_period, mat_var, mat_columns)
    if not robot_opt:
        raise ConfigError(f"{log}: a foreign log names no robot: give --robot")
    description = load_robot(robot_opt)
    return load_run(log, mapping=mapping, description=description), description


def _highest_harmonic(log, run):
    """The excitation's highest frequency [Hz] from a guardid log's header, or None."""
    from guardid.online.offline import log_highest_harmonic

    if run.ticks is None or getattr(run, "torque", False) or str(log).lower().endswith(".mat"):
        return None
    return log_highest_harmonic(log)  # None for a foreign layout: the spectrum rule applies


def _load_all(logs, robot_opt, foreign):
    """(runs, description) of one or more logs; every log must name the same robot."""
    runs, description = [], None
    for log in logs:
        run, desc = _load(log, robot_opt, **foreign)
        if description is not None and desc.name != description.name:
            raise ConfigError(f"{log}: robot {desc.name}, but {logs[0]} is {description.name}")
        runs.append(run)
        description = description or desc
    check_distinct(runs)
    return runs, description


class _PositiveFinite(click.ParamType):
    """A finite number > 0 (click's FloatRange lets NaN and inf through)."""

    name = "float"

    def convert(self, value, param, ctx):
        x = value if isinstance(value, float) else click.FLOAT.convert(value, param, ctx)
        if not (math.isfinite(x) and x > 0):
            self.fail(f"{value!r} is not a finite number > 0", param, ctx)
        return x


_POSITIVE = _PositiveFinite()

_PARALLEL_HELP = (
    "Gautier's parallel filter: low-pass the regressor and the torque at HZ [Hz] after the "
    "cut-off filter, then decimate (docs/FOREIGN_LOGS.md) [default: off]."
)


@click.command()
@click.argument("log", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--robot", default=None, help="Shipped robot or YAML path [default: the log's].")
@click.option(
    "--method",
    default="ls,wls,rls,hopfield",
    show_default=True,
    help="Comma-separated: ls, wls, rls, hopfield, gradient, mlp.",
)
@click.option(
    "--cutoff", type=_POSITIVE, default=None, help="Low-pass cut-off [Hz] [default: auto]."
)
@click.option("--beta", type=_POSITIVE, default=0.01, show_default=True, help="Hopfield gain beta.")
@click.option(
    "--lam",
    type=click.FloatRange(0.0, 1.0, min_open=True),
    default=1.0,
    show_default=True,
    help="RLS forgetting factor, in (0, 1].",
)
@click.option("--eta", type=_POSITIVE, default=1e-3, show_default=True, help="Gradient gain.")
@click.option("--current-units", is_flag=True, help="Identify in current units (gain unknown).")
@click.option("-o", "--output", default=None, help="Write the parameters to this YAML file.")
@click.option("--plot", "plot_path", default=None, help="Write a PNG report (matplotlib).")
@click.option("--parallel-filter", "parallel_hz", type=float, default=None, help=_PARALLEL_HELP)
@click.option(
    "--force",
    is_flag=True,
    help="Report and write the parameters even when the identification cannot be trusted "
    "(zero, rank-deficient or nearly unexcited regressor, non-finite estimates; exit 4 "
    "without it).",
)
@_foreign_options
def identify(
    log, robot, method, cutoff, beta, lam, eta, current_units, output, plot_path, parallel_hz,
    force, **foreign,
):  # fmt: skip
    """Identify the robot's base parameters and motor constants from LOG [LOG ...].

    LOG is a guardid log, or a foreign CSV / MATLAB .mat log read through --columns (the
    same options apply to every LOG). Several logs: each is conditioned on its own and the
    identification rows are stacked (one fit), and so are the motor equations.
    """
    from guardid.identify import identify as run_identify
    from guardid.identify.pipeline import stacked_rows
    from guardid.identify.report import plot, table, to_yaml_dict

    logs, (runs, description) = log, _load_all(log, robot, foreign)
    check_cutoff(cutoff, runs)
    run, log = runs[0], logs[0]
    if len({r.torque for r in runs}) > 1:
        raise ConfigError(f"{logs[-1]}: mixes measured torque and motor current with {log}")
    methods = tuple(m.strip() for m in method.split(",") if m.strip())
    several = len(runs) > 1
    arrays = {
        k: [getattr(r, k) for r in runs] if several else getattr(run, k)
        for k in ("t", "q", "current", "voltage", "ticks")
    }
    if several and any(v is None for v in arrays["voltage"] + arrays["ticks"]):
        arrays["voltage"] = arrays["ticks"] = None
    result = run_identify(
        arrays["t"], arrays["q"], arrays["current"], description, methods=methods,
        cutoff_hz=cutoff, beta=beta, lam=lam, gradient_eta=eta, voltage_v=arrays["voltage"],
        ticks=arrays["ticks"], in_current_units=current_units, effort_is_torque=run.torque,
        highest_harmonic_hz=_highest_harmonic(log, run), parallel_filter_hz=parallel_hz,
    )  # fmt: skip
    if result.untrusted and not force:
        raise UntrustedResult(
            f"{log}: identification cannot be trusted: {'; '.join(result.untrusted)} "
            "(--force reports and writes it anyway)"
        )
    click.echo(table(result, methods))
    for w in result.untrusted:
        click.echo(f"warning: {log}: cannot be trusted (--force): {w}", err=True)
    for w in result.warnings:
        click.echo(f"warning: {w}", err=True)
    from guardid.online.offline import track_log

    tracker = track_log(run, description, methods, lam, beta, log_path=log)
    if tracker is not None and tracker.reports:
        times = sorted({round(r.at_s, 1) for r in tracker.reports})
        when = ", ".join(f"{t:.1f} s" for t in times)
        click.echo(
            f"warning: {log}: the parameters changed at {when}; the table's batch estimates "
            "mix the motion before and after it (the tracker's reports give both sides)",
            err=True,
        )
    if output:
        with open(output, "w", encoding="utf-8") as f:
            source = log if not several else ", ".join(str(x) for x in logs)
            data = to_yaml_dict(result, description, source)
            if parallel_hz:
                data["parallel_filter_hz"] = float(parallel_hz)
            if result.untrusted:  # written with --force: the file says why not to trust it
                data["untrusted"] = list(result.untrusted)
            yaml.safe_dump(data, f, sort_keys=False)
        click.echo(f"parameters written to {output}")
    if plot_path:
        _, A, y = stacked_rows(
            [(r.t, r.q, r.current) for r in runs], description, result.cutoff_hz,
            current_units, run.torque, parallel_filter_hz=parallel_hz,
        )  # fmt: skip
        plot(result, plot_path, A, y, tracker=tracker)
        click.echo(f"plot written to {plot_path}")


@click.command()
@click.argument("log", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--params", "params_path", required=True, help="params.yaml from guardid identify.")
@click.option(
    "--robot",
    default=None,
    help="Shipped robot or YAML path [default: each log's; a foreign log: the params'].",
)
@click.option("--cutoff", type=_POSITIVE, default=None, help="Low-pass cut-off [Hz].")
@click.option(
    "--parallel-filter",
    "parallel_hz",
    type=float,
    default=None,
    help="Parallel filter [Hz] [default: the params' (parallel_filter_hz), else off].",
)
@_foreign_options
def validate(log, params_path, robot, cutoff, parallel_hz, **foreign):
    """Torque prediction error (d_tau) of identified parameters on other runs (LOG [LOG ...]).

    Several logs: their rows are stacked (each conditioned on its own), one d_tau.
    """
    from guardid.estimators import d_tau
    from guardid.identify.pipeline import stacked_rows
    from guardid.identify.report import read_params

    params = read_params(params_path)
    foreign_log = any(v not in (None, ()) for v in foreign.values())
    runs, description = _load_all(log, robot or params["robot"] if foreign_log else robot, foreign)
    check_params_robot(params_path, params, description, robot)
    check_cutoff(cutoff, runs)
    run = runs[0]
    names = [p["name"] for p in params["base_parameters"]]
    from guardid.identify.pipeline import identified_names

    model_names = list(identified_names(description))
    if names != model_names:
        raise ConfigError(
            f"{params_path}: base_parameters: {names} do not match robot "
            f"{description.name}'s {model_names}"
        )
    current_units = params.get("torque_unit") != "N m"
    if parallel_hz is None:
        parallel_hz = params.get("parallel_filter_hz")
    cond, A, y = stacked_rows(
        [(r.t, r.q, r.current) for r in runs], description, cutoff or params.get("cutoff_hz"),
        current_units, run.torque, parallel_filter_hz=parallel_hz,
    )  # fmt: skip
    joints = [j.name for j in description.joints]
    for m, entry in params["methods"].items():
        try:
            theta = np.asarray(entry["values"], dtype=float)
        except (TypeError, ValueError):
            theta = np.array([])
        if theta.shape != (len(names),) or not np.all(np.isfinite(theta)):
            raise ConfigError(
                f"{params_path}: methods.{m}.values: expected {len(names)} finite numbers"
            )
        per_joint = d_tau(A, y, theta, per_joint=True)
        detail = ", ".join(f"{j} {100 * v:.2f} %" for j, v in zip(joints, per_joint, strict=True))
        click.echo(f"{m.upper():9s} d_tau {100 * d_tau(A, y, theta):.2f} %  ({detail})")
