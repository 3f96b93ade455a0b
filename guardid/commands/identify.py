"""``guardid identify`` and ``guardid validate``."""

from __future__ import annotations

from pathlib import Path

import click
import yaml

from guardid.commands._types import POSITIVE
from guardid.commands.outputs import force_option
from guardid.errors import ConfigError, GuardidError, UntrustedResult
from guardid.report.series import MAX_PLOT_POINTS


def _robot_for(run, robot_opt):
    from guardid.robot import load_robot

    spec = robot_opt or run.robot
    if not spec:
        raise ConfigError(f"{run.path}: the log names no robot: give --robot")
    if robot_opt:
        return load_robot(spec)
    path = Path(str(spec))
    a_file = len(path.parts) > 1 or path.suffix in (".yaml", ".yml", ".urdf")
    beside = Path(str(run.path)).parent / path  # a relative path: from the log's folder
    if a_file and not path.exists() and not path.is_absolute() and beside.is_file():
        path = beside
    if not path.is_file():  # a shipped robot by name, or a YAML that is not here
        path = Path(path.stem) if path.suffix in (".yaml", ".yml", ".urdf") else path
    try:
        return load_robot(str(path))
    except ConfigError as exc:
        raise ConfigError(f"{run.path}: header robot_source {spec}: {exc} (give --robot)") from None


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
    """(run, description): a guardid log, or a foreign one when a mapping option is given.
    ``robot_opt``: a shipped name or YAML path, a loaded description, or None (the log's)."""
    from guardid.identify.runs import load_run
    from guardid.robot import load_robot

    given = robot_opt if robot_opt is not None and not isinstance(robot_opt, (str, Path)) else None
    if not (columns or sample_period is not None or mat_var or mat_columns):
        run = load_run(log)
        description = given or _robot_for(run, robot_opt)
        where = f"--robot {robot_opt}" if isinstance(robot_opt, (str, Path)) else "its header"
        from guardid.identify.checks import check_log_robot

        check_log_robot(run, description, "the params file's robot" if given else where)
        return run, description
    from guardid.identify.foreign import parse_mapping

    mapping = parse_mapping(columns, sample_period, mat_var, mat_columns)
    if not robot_opt:
        raise ConfigError(f"{log}: a foreign log names no robot: give --robot")
    description = given or load_robot(robot_opt)
    return load_run(log, mapping=mapping, description=description), description


def _load_all(logs, robot_opt, foreign):
    """(runs, description) of one or more logs; every log must name the same robot."""
    runs, description = [], None
    for log in logs:
        run, desc = _load(log, robot_opt, **foreign)
        if description is not None and desc.name != description.name:
            raise ConfigError(f"{log}: robot {desc.name}, but {logs[0]} is {description.name}")
        runs.append(run)
        description = description or desc
    from guardid.identify.checks import check_distinct

    check_distinct(runs)
    return runs, description


def _lean(run, description, methods, bootstrap=False):
    """``run`` without the columns this identify will not read, so they do not stay in
    memory (about 8 MB per hour of log and per column pair): ``counts`` once the log's
    joints are in the robot's order, unless the log's closed loop is simulated (a
    closed-loop method, iv or didim, or the quantisation bootstrap's replicas: their PID
    starts from the first rows' counts as the firmware had it,
    :func:`guardid.closedloop.rows.start_of`; without them a log that starts far from its
    first setpoint starts the simulation on a wrong integral); ``setpoint`` unless the
    closed loop is simulated (the --report does not read it)."""
    from dataclasses import replace

    joints = getattr(description, "joints", None)
    drop = {}
    in_order = joints is not None and run.joint_names == tuple(j.name for j in joints)
    closed_loop = bootstrap or {"iv", "didim"} & {m.lower() for m in methods}
    if in_order and not closed_loop:
        drop["counts"] = None
    if not closed_loop:
        drop["setpoint"] = None
    return replace(run, **drop) if drop else run


def _check_outputs(logs, robot, foreign, force=False, **outputs) -> None:
    """ConfigError when -o, --plot or --report names one of the inputs (a log, the robot or
    mapping YAML), an existing file (without --force) or a place that cannot be written:
    checked before any work starts (guardid.commands.outputs)."""
    from guardid.commands.outputs import check_distinct, check_output, robot_file

    inputs = [("LOG", x) for x in logs] + [("--robot", robot_file(robot))]
    inputs += [("--columns", c) for c in foreign.get("columns") or () if Path(c).is_file()]
    paths = [
        ("-o", outputs["output"]),
        ("--plot", outputs["plot_path"]),
        ("--report", outputs["report_path"]),
    ]
    for option, path in paths:
        check_output(path, inputs, option=option, force=force)
    check_distinct(paths)


_CONSISTENT_HELP = (
    "Also fit the full standard parameters under physical consistency (log-Cholesky "
    "pseudo-inertia, rotor inertia and friction >= 0), regularised towards the robot YAML "
    "where the data see nothing; prints them and writes them to params.yaml (consistent:), "
    "which `guardid export` turns into URDF / MJCF (docs/CONSISTENT.md)."
)


_BOOTSTRAP_HELP = (
    "Size the encoder quantisation's effect through the closed loop from the run itself: "
    "simulate the log's closed loop (its setpoints, the robot YAML's PID, motors and "
    "friction, the supply level and ripple measured from its voltages) with the identified "
    "parameters up to K times from start poses a fraction of a count apart, fit each "
    "replica as the log was, and report the verdict's method "
    "(WLS, else LS) as estimate - the replicas' mean error with its std widened by the "
    "part of their spread the residuals do not see (docs/quantisation_bootstrap.md). "
    "Stops early once the bias is known to 0.25 std (at least 4 replicas). Costs K "
    "closed-loop simulations of the log (about 55 us of CPU per tick each: 9x identify's "
    "CPU on a 1 h log at K = 4). Needs a guardid log with setpoints and pid: gains; "
    "otherwise one warning line and the plain estimate. [default: 0, off]"
)

_POSITIVE = POSITIVE

_PARALLEL_HELP = (
    "Gautier's parallel filter: low-pass the regressor and the torque at HZ [Hz] after the "
    "cut-off filter, then decimate (docs/FOREIGN_LOGS.md) [default: chosen from the data "
    "when --cutoff is not given and every row obeys the model (docs/VALIDATION.md), else "
    "off; 0 = off]."
)
_CUTOFF_HELP = (
    "Cut-off [Hz] of the one filter on both sides of the momentum form [default: 2 x the "
    "excitation's highest harmonic (else the positions' 99.5 % band), at least 2 Hz], or of "
    "the low-pass "
    "on positions and efforts of the acceleration form [default: chosen from the data by "
    "cross-validation, docs/VALIDATION.md]."
)
_EQUATION_HELP = (
    "Model equation of the rows: momentum (per period, drive impulse = change of the "
    "momentum M(q) qd + integral of the rest; nothing differentiated twice, one causal "
    "filter on both sides, DESIGN.md 5b) or acceleration (tau = Y(q, qd, qdd) theta on "
    "low-passed, twice-differentiated positions) [default: momentum for motor-current logs "
    "on a tick grid, acceleration for measured torque, uneven time stamps and "
    "--parallel-filter; iv and didim always fit the acceleration form's rows]. Recorded in "
    "params.yaml (conditioning.equation)."
)


_QUANTISATION_HELP = (
    "Leave the encoder's rounding uncompensated. By default, in the momentum form, the "
    "rounding's noise in the regressor's columns is removed from LS's and WLS's normal "
    "equations (bias-compensated least squares; its moments estimated by adding fresh "
    "rounding errors to the counts): without that the quantised velocities bias them by an "
    "amount that does not shrink with the log. It is on when every joint has an encoder in "
    "the robot description and the log's positions are whole counts of it. Recorded in "
    "params.yaml (conditioning.quantisation: what was done)."
)


class _MethodOption(click.Option):
    """--method: its help lists the registered estimators when shown (plugins included)."""

    def get_help_record(self, ctx):
        from guardid.identify.methods import method_help

        self.help = method_help()
        return super().get_help_record(ctx)


_EVERY_TICK_HELP = (
    "Momentum form: a row at every tick whatever the log's length, refused when the log has "
    "fewer usable ticks than 2 x parameters x 2 / cut-off s (about 23 s on the guard). The "
    "default keeps the same rows but falls back to --spaced-rows on such a short log, and "
    "keeps a row every m-th tick on a log longer than 65536 ticks (at most 65536 rows, "
    "each the mean of its m ticks, up to the spaced rows from about 4.4 h on the guard: "
    "identify's memory about that of the spaced rows). LS and WLS count the noise that "
    "neighbouring rows share (each joint's residual autocovariance over 2 / cut-off s; "
    "BLS's std does not)."
)
_SPACED_ROWS_HELP = (
    "Momentum form: one row every 1 / (2 x cut-off) s, whose errors are about independent "
    "(identify's rows before 2026-11-27): faster, with the white std, but less precise (on "
    "simulated runs their rms error was 1.05-2.2x the default rows', median per set). The "
    "spacing used is recorded in params.yaml (conditioning.decimate); docs/IDENTIFY.md."
)


@click.command()
@click.argument("log", nargs=-1, required=True, type=click.Path(dir_okay=False, exists=True))
@click.option("--robot", default=None, help="Shipped robot or YAML path [default: the log's].")
@click.option("--method", cls=_MethodOption, default="ls,wls,rls,hopfield", show_default=True)
@click.option("--cutoff", type=_POSITIVE, default=None, help=_CUTOFF_HELP)
@click.option(
    "--equation", type=click.Choice(["momentum", "acceleration"]), default=None,
    help=_EQUATION_HELP,
)  # fmt: skip
@click.option(
    "--no-quantisation-compensation", "no_quantisation", is_flag=True, help=_QUANTISATION_HELP,
)  # fmt: skip
@click.option("--every-tick", is_flag=True, help=_EVERY_TICK_HELP)
@click.option("--spaced-rows", is_flag=True, help=_SPACED_ROWS_HELP)
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
@click.option(
    "--current-zero",
    "current_zero",
    type=click.Choice(["subtract", "ignore"]),
    default="subtract",
    show_default=True,
    help="The current sensors' zero a guardid log's footer gives (capture --zero-rest reads "
    "it at rest after the run, and before it too with --zero-before): subtract takes it off "
    "the joint's currents (both read: the straight line between them at each row's time) "
    "and every std counts the zeros' own errors; ignore leaves the currents as logged (for "
    "sensors zeroed exactly some other way). A zero beyond 4 of its std errors from 0 is a "
    "warning, and so are two zeros as far apart. docs/IDENTIFY.md 'The current sensors' "
    "zero'.",
)
@click.option(
    "-o",
    "--output",
    default=None,
    help="Write the parameters to this YAML file (an existing file only with --force).",
)
@click.option(
    "--plot",
    "plot_path",
    default=None,
    help="Write a PNG report: the torque fit and the online estimators over time, each line "
    f"drawn with at most {MAX_PLOT_POINTS} points (every k-th row of a longer log; matplotlib; "
    "an existing file only with --force).",
)
@click.option(
    "--report",
    "report_path",
    default=None,
    help="Write a self-contained HTML report (verdict, parameters, fit, residual spectrum, "
    "online estimators, conditioning, motors; needs matplotlib; an existing file only with "
    "--force).",
)
@click.option("--parallel-filter", "parallel_hz", type=float, default=None, help=_PARALLEL_HELP)
@click.option("--consistent", is_flag=True, help=_CONSISTENT_HELP)
@click.option(
    "--quantisation-bootstrap", "bootstrap_k", type=click.IntRange(0, 1000), default=0,
    metavar="K", help=_BOOTSTRAP_HELP,
)  # fmt: skip
@click.option(
    "--cv",
    is_flag=True,
    help="Leave-one-run-out cross-validation over the LOGs (at least 2): fit on all but one, "
    "score the held-out run (stacked relative rms error), print the table (writes no -o, "
    "--plot or --report).",
)
@force_option(
    "existing output files: -o, --plot, --report",
    more=", and report and write the parameters even when the identification cannot be "
    "trusted (zero, rank-deficient or nearly unexcited regressor, non-finite estimates; exit "
    "4 without it)",
)
@_foreign_options
def identify(
    log, robot, method, cutoff, equation, no_quantisation, every_tick, spaced_rows, beta, lam, eta,
    current_units, current_zero, output,
    plot_path, report_path, parallel_hz, consistent, bootstrap_k, cv, force, **foreign,
):  # fmt: skip
    """Identify the robot's base parameters and motor constants from LOG [LOG ...].

    LOG is a guardid log, or a foreign CSV / MATLAB .mat log read through --columns (the
    same options apply to every LOG). Several logs: each is conditioned on its own and the
    identification rows are stacked (one fit), and so are the motor equations.
    """
    from guardid.commands._status import Status
    from guardid.conditioning.options import ConditioningOptions
    from guardid.identify import HopfieldSettings, IdentifyOptions
    from guardid.identify import identify as run_identify
    from guardid.identify.report import table, to_yaml_dict
    from guardid.report.png import plot

    if cv and (output or plot_path or report_path):  # --cv prints its table and fits nothing
        given = [o for o, p in (("-o", output), ("--plot", plot_path), ("--report", report_path))
                 if p]  # fmt: skip
        raise ConfigError(f"--cv writes no {'/'.join(given)}: it prints the held-out error "
                          "table only (identify without --cv writes them)")  # fmt: skip
    _check_outputs(
        log, robot, foreign, force, output=output, plot_path=plot_path, report_path=report_path
    )
    methods = tuple(m.strip() for m in method.split(",") if m.strip())
    if not methods:
        raise ConfigError(f"--method {method!r}: no method named (e.g. --method ls,wls)")
    twice = sorted({m for m in methods if methods.count(m) > 1})
    if twice:
        raise ConfigError(f"--method {method!r}: {', '.join(twice)} named twice")
    status = Status()
    status.stage("reading")
    logs, (runs, description) = log, _load_all(log, robot, foreign)
    from guardid.identify.checks import check_cutoff

    check_cutoff(cutoff, runs)
    run, log = runs[0], logs[0]
    if len({r.torque for r in runs}) > 1:
        raise ConfigError(f"{logs[-1]}: mixes measured torque and motor current with {log}")
    from guardid.identify.methods import methods_for

    methods_for(methods)  # an unknown method is an option error, before any log is named
    if every_tick and spaced_rows:
        raise ConfigError("--every-tick and --spaced-rows: one spacing of the rows, not both")
    if every_tick and (equation == "acceleration" or parallel_hz):
        raise ConfigError(
            "--every-tick: rows of the momentum form only (not with "
            f"{'--equation acceleration' if equation else '--parallel-filter'})"
        )
    conditioning = ConditioningOptions(cutoff_hz=cutoff, parallel_filter_hz=parallel_hz,
                                       equation=equation,
                                       decimate=1 if every_tick else 0 if spaced_rows else None,
                                       quantisation=False if no_quantisation else None)  # fmt: skip
    options = IdentifyOptions(
        methods=methods, conditioning=conditioning, hopfield=HopfieldSettings(beta=beta),
        rls_lambda=lam, gradient_eta=eta, in_current_units=current_units,
        current_zero=current_zero,
    )  # fmt: skip
    if cv:
        _cross_validate(logs, runs, description, options)
        return
    from guardid.identify.prepare import current_on_adc_levels

    runs = [_lean(r, description, methods, bootstrap_k > 0) for r in runs]
    runs = [current_on_adc_levels(r, description, in_place=True) for r in runs]  # for all
    run = runs[0]
    forked = None  # the tracker's replay on another core while the batch fit runs
    if plot_path is None and report_path is None:
        from guardid.online.offline import start_tracking

        forked = start_tracking(run, description, methods, lam, beta, log_path=log)
    status.stage("conditioning and fitting")
    from guardid.identify.checks import call_naming_logs

    result = call_naming_logs(logs, run_identify, runs, description, options)  # names gaps
    if every_tick and result.conditioning.equation != "momentum":  # its rows' std would be white
        raise ConfigError(f"{log}: --every-tick: rows of the momentum form only, and this log's "
                          f"are in the {result.conditioning.equation} form (see the notes "
                          "without --every-tick)")  # fmt: skip
    from guardid.identify.prepare import prepared_runs

    whole, (runs, _, _) = runs, prepared_runs(runs, description, options)  # as identify split them
    if result.untrusted and not force:
        raise UntrustedResult(
            f"{log}: identification cannot be trusted: {'; '.join(result.untrusted)} "
            "(--force reports and writes it anyway)"
        )
    corrected = bootstrap_k and _bootstrap(result, whole, description, options, bootstrap_k,
                                           status, log)  # fmt: skip
    fit = None
    if consistent:
        status.stage("consistent fit")
        fit = _consistent(result, runs, description, run.torque)
    status.clear()
    click.echo(table(result, (*methods, "consistent") if fit else methods, description))
    if corrected:
        click.echo(corrected)
    repeating = _repeating_line(result, description)
    if repeating:
        click.echo(repeating)
    if fit:
        from guardid.physical.report import standard_table

        click.echo(standard_table(fit))
    for w in result.untrusted:
        click.echo(f"warning: {log}: cannot be trusted (--force): {w}", err=True)
    for w in result.warnings:
        click.echo(f"warning: {w}", err=True)
    from guardid.online.offline import track_log

    status.stage("tracking")
    tracker = None
    if forked is not None:
        lines, changes = forked.result()
        for line in lines:
            click.echo(line)
    else:
        tracker = track_log(
            run, description, methods, lam, beta, log_path=log,
            keep_history=plot_path is not None or report_path is not None,
        )  # fmt: skip
        changes = [r.at_s for r in tracker.reports] if tracker is not None else []
    if changes:
        times = sorted({round(t, 1) for t in changes})
        when = ", ".join(f"{t:.1f} s" for t in times)
        click.echo(
            f"warning: {log}: the parameters changed at {when}; the table's batch estimates "
            "mix the motion before and after it (the tracker's reports give both sides)",
            err=True,
        )
    if output:
        from guardid.commands.outputs import write_text

        source = log if len(runs) == 1 else ", ".join(str(x) for x in logs)
        data = to_yaml_dict(result, description, source)
        if fit:
            from guardid.physical.report import yaml_section

            data["consistent"] = yaml_section(fit)
        if result.untrusted:  # written with --force: the file says why not to trust it
            data["untrusted"] = list(result.untrusted)
        write_text(output, yaml.safe_dump(data, sort_keys=False))
        click.echo(f"parameters written to {output}")
    if plot_path or report_path:
        from guardid.identify.rows import stacked_rows

        status.stage("plots")
        cond, A, y = stacked_rows(
            [(r.t, r.q, r.current) for r in runs], description, result.conditioning,
            in_current_units=current_units, effort_is_torque=run.torque,
        )  # fmt: skip
    if plot_path:
        from guardid.commands.outputs import replacing

        with replacing(plot_path, "--plot") as tmp:
            plot(result, tmp, A, y, tracker=tracker)
        click.echo(f"plot written to {plot_path}")
    if report_path:
        from guardid.commands.outputs import write_text
        from guardid.report.cli import identify_page

        page = identify_page(result, description, whole, logs, cond, A, y, tracker)
        write_text(report_path, page, "--report")
        click.echo(f"report written to {report_path}")
    status.done("identify: done")
    if fit and fit.violations:
        raise GuardidError(
            f"--consistent: the fit is not physically consistent: {fit.violations[0]}"
        )


def _repeating_line(result, description) -> str:
    """One line when the reference method's std counts a residual that repeats every
    excitation period (:func:`guardid.identify.rows.period_groups`), else ''."""
    from guardid.identify.report import effort_units
    from guardid.identify.untrusted import reference_method

    m = reference_method(result.results)
    rep = result.results[m].settings.get("repeating_residual") if m else None
    if not rep or not any(x > 0 for x in rep["std_per_joint"]):
        return ""
    unit = effort_units(result, description)
    parts = ", ".join(f"{j.name} {x:.3g}" for j, x in
                      zip(description.joints, rep["std_per_joint"], strict=True))  # fmt: skip
    share = rep.get("variance_share")
    most = ""
    if share and max(share) > 0.0:
        k = max(range(len(share)), key=share.__getitem__)
        most = f"; up to {100 * share[k]:.0f} % of a parameter's variance ({result.names[k]})"
    return (
        f"{m.upper()}: its std counts an error that repeats every excitation period "
        f"({parts} {unit} per row, over {rep['groups']} phase groups{most}; params.yaml: "
        "repeating_residual)"
    )


def _bootstrap(result, runs, description, options, k, status, log):
    """--quantisation-bootstrap K on ``result`` (in place): the line saying what was
    corrected, or '' and one warning line when it cannot run."""
    from guardid.uncertainty import BootstrapOptions
    from guardid.uncertainty.apply import apply_bootstrap

    def progress(done, most, ratio):
        se = "" if ratio != ratio else f", bias known to {ratio:.2f} std"
        status.show(f"quantisation bootstrap: replica {done} of at most {most}{se} ...")

    status.stage("quantisation bootstrap")
    why = apply_bootstrap(result, runs, description, options, BootstrapOptions(replicas=k),
                          progress)  # fmt: skip
    if why:
        click.echo(f"warning: {log}: --quantisation-bootstrap cannot run: {why}", err=True)
        return ""
    from guardid.identify.untrusted import reference_method

    m = reference_method(result.results)
    k = result.results[m].settings["quantisation_bootstrap"]["replicas"]
    return (
        f"{m.upper()}: less the encoder quantisation's bias, its std with the part "
        f"that does not shrink with the log's length ({k} closed-loop replicas; "
        "params.yaml: quantisation_bootstrap)"
    )


def _consistent(result, runs, description, torque):
    from guardid.physical.report import add_consistent

    efforts = [(r.t, r.q, r.current) for r in runs]
    return add_consistent(result, efforts, description, torque)


def _cross_validate(logs, runs, description, options):
    """``identify --cv``: leave one run out, fit the rest, score the held-out run."""
    from guardid.identify.crossval import leave_one_run_out

    if len(runs) < 2:
        raise ConfigError(f"{logs[0]}: --cv needs at least two logs (one is held out)")
    click.echo(leave_one_run_out(logs, runs, description, options))


@click.command()
@click.argument("log", nargs=-1, required=True, type=click.Path(dir_okay=False, exists=True))
@click.option(
    "--params",
    "params_paths",
    multiple=True,
    required=True,
    help="params.yaml from guardid identify, or a reference values file (docs/VALIDATION.md). "
    "Repeatable: the sets are scored side by side under one conditioning.",
)
@click.option(
    "--robot",
    default=None,
    help="Shipped robot or YAML path [default: the description stored in the first params file].",
)
@click.option(
    "--cutoff",
    type=_POSITIVE,
    default=None,
    help="Cut-off [Hz] [default: the first params file's].",
)
@click.option(
    "--parallel-filter",
    "parallel_hz",
    type=float,
    default=None,
    help="Parallel filter [Hz] [default: the first params file's conditioning, else chosen "
    "from the logs with the cut-off; 0 = off].",
)
@click.option(
    "--report",
    "report_path",
    default=None,
    help="Write a self-contained HTML report: the scores per run and set, measured and "
    "predicted effort of the best set, residual spectra (needs matplotlib; an existing file "
    "only with --force).",
)
@click.option(
    "--simulate",
    is_flag=True,
    help="Also replay every set, and the robot YAML's own values, through the closed loop "
    "(the firmware's PID with the robot's pid: gains, motors, stick/slip friction, the set's "
    "rigid body) with the log's setpoints from its first state, and print the simulation "
    "error against the measured joint angles: per run and joint, rms and max in degrees and "
    "encoder counts (--report plots measured and simulated angles). Needs guardid logs with "
    "setpoints (sp_* columns) and a robot with pid: on every joint.",
)
@click.option(
    "--current-zero",
    "current_zero",
    type=click.Choice(["subtract", "ignore"]),
    default=None,
    help="The current sensors' zero a guardid log's footer gives: subtract or ignore, as "
    "identify --current-zero [default: the first params file's, else subtract].",
)
@force_option("an existing --report file")
@_foreign_options
def validate(log, params_paths, robot, cutoff, parallel_hz, report_path, force, simulate,
             current_zero, **foreign):  # fmt: skip
    """Score parameter sets on runs LOG [LOG ...]: torque prediction error, all joints stacked.

    Every set (each method of each params file, each reference values file) is scored under
    the same conditioning: the first params file's (--cutoff / --parallel-filter override
    it; without a params file the cut-off is chosen from these logs). Per run: the stacked
    relative rms error rms(tau - tau_model) / rms(tau) over all joints, and per joint the rms
    error in its unit and the relative error (not for a passive joint).
    """
    from guardid.commands.outputs import check_output

    inputs = [("LOG", x) for x in log] + [("--params", x) for x in params_paths]
    check_output(report_path, inputs, option="--report", force=force)
    keep = {}
    click.echo(scored(log, params_paths, robot, cutoff, parallel_hz, foreign, keep,
                      rows=bool(report_path), simulate=simulate,
                      current_zero=current_zero))  # fmt: skip
    description, sets, current_units = keep["description"], keep["sets"], keep["current_units"]
    runs = keep["runs"]
    replayed = {} if report_path and simulate else None
    if simulate:
        from guardid.replay import replay_sets, table, yaml_set

        scores = replay_sets(runs, log, description, [yaml_set(description), *sets], replayed)
        click.echo(table(scores, description))
        if replayed is not None:
            replayed["scores"] = scores
    if report_path:
        from guardid.commands.outputs import write_text
        from guardid.report.cli import validate_page

        page = validate_page(description, log, sets, keep, current_units, runs, replayed)
        write_text(report_path, page, "--report")
        click.echo(f"report written to {report_path}")


def _stored_zero_mode(path, data) -> str | None:
    """The ``current_zero.mode`` a params file was identified with (None: not recorded, an
    older file); ConfigError naming the file and field when it is malformed."""
    from guardid.identify.current_zero import MODES

    stored = data.get("current_zero")
    if stored is None:
        return None
    if not isinstance(stored, dict):
        raise ConfigError(f"{path}: current_zero: expected a mapping with mode, got {stored!r}")
    mode = stored.get("mode")
    if mode not in MODES:
        raise ConfigError(f"{path}: current_zero: mode: expected {' or '.join(MODES)}, got "
                          f"{mode!r}")  # fmt: skip
    return mode


def scored(logs, params_paths, robot, cutoff, parallel_hz, foreign, keep: dict, rows=True,
           simulate=False, current_zero=None) -> str:  # fmt: skip
    """What ``guardid validate`` prints: every set of ``params_paths`` scored on ``logs``
    under one conditioning (the first params file's, ``cutoff`` / ``parallel_hz`` [Hz]
    override it). ``keep`` receives ``description``, ``sets``, ``current_units``, ``runs``
    and, with ``rows``, what :func:`guardid.identify.validation.validate_runs` keeps
    (``scores``, the conditioned rows, the predictions). ``simulate``: first check that the
    runs and sets can be replayed (``validate --simulate``), one line each when not.
    ``current_zero``: what to do with the logs' current sensors' zeros (None: the first
    params file's ``current_zero.mode``, else subtract)."""
    from guardid.identify import validation as v

    first = v.first_params(params_paths)
    spec = robot or (v.stored_robot(*first) if first else None)
    runs, description = _load_all(logs, spec, foreign)
    if first:
        from guardid.identify.checks import check_params_robot

        check_params_robot(first[0], first[1], description, robot)
    from guardid.identify.checks import check_cutoff

    check_cutoff(cutoff, runs)
    if simulate:
        from guardid.replay import check_replayable

        for run in runs:
            check_replayable(run, description)
    options = v.stored_conditioning(*first) if first else None
    options = (options or v.ConditioningOptions()).with_(
        cutoff_hz=cutoff, parallel_filter_hz=parallel_hz
    )
    sets = [s for path in params_paths for s in v.load_sets(path, description)]
    sets, left_out = v.finite_sets(sets)
    for why in left_out:
        click.echo(f"guardid: warning: {why}: left out", err=True)
    current_units = bool(first) and first[1].get("torque_unit") not in ("N m", None)
    if simulate and current_units:
        unit = first[1].get("torque_unit")
        raise ConfigError(f"--simulate: {first[0]}: torque_unit {unit}: a set in current "
                          "units has no rigid body in N m to simulate")  # fmt: skip
    keep.update(description=description, sets=sets, current_units=current_units, runs=runs)
    kept = keep if rows else None
    if current_zero is None and first:
        current_zero = _stored_zero_mode(*first)
    return v.validate_runs(runs, logs, description, sets, options, current_units, keep=kept,
                           current_zero=current_zero or "subtract")  # fmt: skip
