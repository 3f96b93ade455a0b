"""``guardid convert``: a capture log in another format (MCAP, for Foxglove and
PlotJuggler)."""

from __future__ import annotations

import click

from guardid.commands.outputs import force_option


@click.command()
@click.argument("log", type=click.Path(dir_okay=False))
@click.option(
    "--mcap",
    "mcap_path",
    required=True,
    type=click.Path(dir_okay=False),
    help="MCAP file to write (an existing file only with --force): one JSON message per "
    "row on /guardid/joints (fields as capture --stream sends them: timestamp [s], "
    "<joint>/q_rad, setpoint_rad, v_V, i_A, counts), log time = the header's start_time "
    "+ the row's time_s, the header and footer as metadata guardid.header and "
    "guardid.footer. Needs pip install 'guardid[mcap]'. docs/LIVE.md.",
)
@force_option("an existing MCAP file")
def convert(log, mcap_path, force):
    """Write the capture log LOG as an MCAP file for Foxglove and PlotJuggler.

    LOG is a guardid log (a capture, or any log in guardid's columns with a time_s column,
    the messages' time). The output is written to a temporary file and renamed into place
    when complete.
    """
    from guardid.commands.outputs import check_output, replacing
    from guardid.live.mcap_log import TOPIC, require_mcap, write_mcap
    from guardid.log import read_log

    check_output(mcap_path, [("LOG", log)], option="--mcap", force=force)
    require_mcap()
    data = read_log(log)
    with replacing(mcap_path, "--mcap") as tmp:
        rows = write_mcap(data, tmp)
    click.echo(f"{rows} rows of {log} written to {mcap_path} (topic {TOPIC}, header as metadata)")
