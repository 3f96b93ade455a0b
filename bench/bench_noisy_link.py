"""Captures on a noisy link: do they all start and finish, do their footers count the damage?

Runs ``guardid capture`` (in-process, the CLI's own code path) for seeds 0..N-1 on
``sim://guard?drop=1e-3&flip=1e-4&latency_ms=16&seed=N`` (lock-step), each 20 s of an
excitation from ``guardid excite --no-optimise``. For every run it keeps the clean bytes the
emulated firmware sent (before the link's faults) and the bytes the host read, and counts the
damage from those two streams alone (independent of the host's parser): rejected segments
split into CRC and framing errors, frames missing between the first and the last that arrived
(sequence gaps), and trajectory ticks whose telemetry was lost. It compares these with the
log footer's counts.

Run: python bench/bench_noisy_link.py [runs, default 100] [seconds, default 20]
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import zlib
from pathlib import Path
from unittest import mock

from click.testing import CliRunner
from cobs import cobs

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from linktools import BothWays, teed_devices  # noqa: E402

import guardid.link  # noqa: E402
from guardid.cli import main  # noqa: E402
from guardid.log import read_log  # noqa: E402
from guardid.protocol.codec import MAX_ENCODED  # noqa: E402

URL = "sim://guard?drop=1e-3&flip=1e-4&latency_ms=16&seed={}"
TELEMETRY_ID = 0x85


def classify(segment: bytes) -> str:
    """'crc' or 'framing' for a segment that is not a frame that was sent (own decoder)."""
    if len(segment) > MAX_ENCODED:
        return "framing"
    try:
        raw = cobs.decode(segment)
    except cobs.DecodeError:
        return "framing"
    if len(raw) < 8:
        return "framing"
    if zlib.crc32(raw[:-4]) != int.from_bytes(raw[-4:], "little"):
        return "crc"
    return "framing"  # right CRC, wrong version / id / length


def damage(clean: bytes, delivered: bytes, first_tick: int, n_ticks: int) -> dict:
    """The damage counted from the two byte streams alone."""
    sent = [s for s in clean.split(b"\x00") if s]
    got = [s for s in delivered.split(b"\x00")[:-1] if s]  # the tail is not complete
    sent_set, got_set = set(sent), set(got)
    bad = [classify(s) for s in got if s not in sent_set]
    arrived = [k for k, s in enumerate(sent) if s in got_set]
    lost_between = [s for s in sent[arrived[0] : arrived[-1]] if s not in got_set]
    lost_rows = 0
    for s in sent:
        raw = cobs.decode(s)
        if raw[1] == TELEMETRY_ID and s not in got_set:
            tick = int.from_bytes(raw[4:8], "little")
            lost_rows += 0 <= tick - first_tick < n_ticks
    return {
        "crc_errors": bad.count("crc"),
        "framing_errors": bad.count("framing"),
        "seq_gaps": len(lost_between),
        "lost_rows": lost_rows,
    }


def resends(host_bytes: bytes) -> int:
    """Host frames equal to the frame before them: commands sent again."""
    frames = [s for s in host_bytes.split(b"\x00") if s]
    return sum(1 for a, b in zip(frames, frames[1:], strict=False) if a == b)


def run_one(seed: int, traj: Path, out: Path, seconds: float) -> dict:
    ports: list = []

    def recording_open_port(*args, **kwargs):
        ports.append(BothWays(open_port(*args, **kwargs)))
        return ports[-1]

    open_port = guardid.link.open_port
    log = out / f"run_{seed}.csv"
    with teed_devices() as tees, mock.patch.object(guardid.link, "open_port", recording_open_port):
        result = CliRunner().invoke(
            main,
            ["capture", "--port", URL.format(seed), "--trajectory", str(traj),
             "--duration", str(seconds), "--quiet", "-o", str(log)],
        )  # fmt: skip
    row = {"seed": seed, "exit": result.exit_code, "message": result.output.strip()[-200:]}
    if not log.exists() or not ports:
        return row
    data = read_log(log)
    footer = data.footer or {}
    ticks = data.columns["tick"].astype(int)
    row["rows"] = len(ticks)
    row["ended"] = footer.get("ended")
    if not len(ticks) or not footer:
        return row
    period = data.header.get("sample_period_s", 0.015)
    first = int(ticks[0]) - int(round(float(data.columns["time_s"][0]) / period))
    truth = damage(bytes(tees[0].sent), bytes(ports[0].received), first, footer["ticks_expected"])
    link = footer["link"]
    told = {
        "crc_errors": link["crc_errors"],
        "framing_errors": link["framing_errors"],
        "seq_gaps": link["seq_gaps"],
        "lost_rows": footer["ticks_expected"] - len(ticks),
    }
    injected = ports[0].fault_stats.down
    row.update(
        truth=truth,
        told=told,
        agree=truth == told,
        dropped=injected.bytes_dropped,
        flipped_bits=injected.bits_flipped,
        resends=resends(bytes(ports[0].sent)),
    )
    log.unlink()
    return row


def main_bench(runs: int = 100, seconds: float = 20.0) -> int:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        traj = out / "traj.yaml"
        made = CliRunner().invoke(
            main, ["excite", "--robot", "guard", "--no-optimise", "-o", str(traj)]
        )
        if made.exit_code != 0:
            print(made.output)
            return 1
        rows = []
        for seed in range(runs):
            row = run_one(seed, traj, out, seconds)
            rows.append(row)
            if row.get("exit") != 0 or not row.get("agree"):
                print(f"seed {seed}: {row}")
    started = sum(1 for r in rows if r.get("rows", 0) > 0)
    finished = sum(1 for r in rows if r.get("exit") == 0 and r.get("ended") == "complete")
    agree = sum(1 for r in rows if r.get("agree"))
    print(f"{runs} captures of {seconds:g} s at {URL.format('N')} (lock-step)")
    print(f"started {started}/{runs}, finished {finished}/{runs}")
    print(f"footer == damage counted from the byte streams: {agree}/{runs}")
    for key in ("crc_errors", "framing_errors", "seq_gaps", "lost_rows"):
        vals = [r["told"][key] for r in rows if "told" in r]
        truth = sum(r["truth"][key] for r in rows if "truth" in r)
        if vals:
            print(
                f"  {key}: median {statistics.median(vals):g}, worst {max(vals)} "
                f"(sum footer {sum(vals)}, sum truth {truth})"
            )
    drops = [r["dropped"] for r in rows if "dropped" in r]
    flips = [r["flipped_bits"] for r in rows if "flipped_bits" in r]
    if drops:
        print(
            f"  injected per run: bytes dropped median {statistics.median(drops):g} "
            f"(worst {max(drops)}), bits flipped median {statistics.median(flips):g} "
            f"(worst {max(flips)})"
        )
    sent_again = [r["resends"] for r in rows if "resends" in r]
    if sent_again:
        print(
            f"  commands sent again per run: median {statistics.median(sent_again):g}, "
            f"worst {max(sent_again)}, runs with any {sum(1 for x in sent_again if x)}/{runs}"
        )
    return 0 if started == finished == agree == runs else 1


if __name__ == "__main__":
    args = sys.argv[1:]
    sys.exit(main_bench(int(args[0]) if args else 100, float(args[1]) if len(args) > 1 else 20.0))
