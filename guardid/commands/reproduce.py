"""``guardid reproduce``: rerun a seed paper's experiment and print ours beside the paper's."""

from __future__ import annotations

import time

import click

from guardid.commands.outputs import force_option

NAMES = ("seed000-step", "seed000-slow", "seed000-fast", "seed001-table1")


@click.command()
@click.argument("experiment", type=click.Choice(NAMES))
@click.option(
    "--plot",
    "plot_dir",
    default=None,
    help="Write the paper's figures (PNG) to this directory (created if missing; one that "
    "holds files already only with --force).",
)
@force_option("the figures in a --plot directory that holds files")
@click.option("--seed", default=0, show_default=True, help="First seed of the measurement noise.")
@click.option(
    "--seeds",
    "n_seeds",
    default=15,
    show_default=True,
    type=click.IntRange(min=1),
    help="Noise draws (seeds SEED, SEED+1, ...): every row that depends on the noise is"
    " printed as the median and the worst over them. Time grows with it (15 seeds:"
    " about 30 s of CPU for seed001-table1 or seed000-fast).",
)
@click.option(
    "--exact-acceleration",
    is_flag=True,
    help="seed001-table1 only: give the estimators the exact q, q', q'' and tau plus small"
    " white noise (the easy variant) instead of noisy quantised q and noisy tau through"
    " guardid's conditioning (the default).",
)
def reproduce(experiment, plot_dir, seed, n_seeds, exact_acceleration, force):
    """Simulate EXPERIMENT, run the estimators, print our numbers beside the paper's.

    Each printout names the model repairs applied and every assumption made where the
    paper is silent, and ends with the wall time. --plot needs matplotlib.
    """
    from guardid.reproduce import EXPERIMENTS

    module = EXPERIMENTS[experiment]
    if exact_acceleration and experiment != "seed001-table1":
        raise click.UsageError("--exact-acceleration applies to seed001-table1 only")
    if plot_dir is not None:
        from guardid.commands.outputs import check_new_directory_files
        from guardid.reproduce.plots import require_matplotlib

        require_matplotlib()
        check_new_directory_files(plot_dir, "--plot", force=force)
    t0 = time.perf_counter()
    kwargs = {"exact_acceleration": True} if exact_acceleration else {}
    report = module.run(seed, seeds=n_seeds, **kwargs)
    click.echo(report.text())
    if plot_dir is not None:
        for path in module.plot(report, plot_dir):
            click.echo(f"wrote {path}")
        click.echo(f"wall time with plots: {time.perf_counter() - t0:.1f} s")
