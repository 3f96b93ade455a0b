"""Live signals in other tools: ``capture --stream udp://HOST:PORT`` sends every logged row
as one JSON datagram grouped per joint (PlotJuggler's UDP server), never slowing or breaking
the capture; ``convert LOG --mcap OUT`` writes an MCAP file (Foxglove, PlotJuggler) equal to
the CSV, with the header as metadata. The logs are read back here with the csv text and
YAML alone (tests/capturetools), not with guardid's reader."""

from __future__ import annotations

import datetime as dt
import json
import socket
import sys
from pathlib import Path

import pytest
import yaml
from badinput_tools import invoke
from capturetools import footer_dict, gentle_trajectory, log_fields, parse_rows, witnessed

JOINTS = ("pan", "tilt")
CAPTURE_S = 1.5  # 100 rows of guard's 15 ms period
# the log's column -> where the JSON object keeps it, written out by hand (docs/LIVE.md)
WHERE = {"tick": ("tick",), "time_s": ("timestamp",), "status": ("status",)}
for _j in JOINTS:
    WHERE |= {f"counts_{_j}": (_j, "counts"), f"q_{_j}_rad": (_j, "q_rad"),
              f"v_{_j}_V": (_j, "v_V"), f"i_{_j}_A": (_j, "i_A"),
              f"sp_{_j}_rad": (_j, "setpoint_rad")}  # fmt: skip
# half the last printed digit of each column's format in the CSV (LogWriter.write_row)
PRINTED = {"time_s": 5e-7, "q": 5e-10, "sp": 5e-10, "v": 5e-4, "i": 5e-4}


def _listener() -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
    sock.bind(("127.0.0.1", 0))
    sock.setblocking(False)
    return sock


def _received(sock: socket.socket) -> list[dict]:
    """Every datagram waiting (loopback delivers within the sender's sendto)."""
    out = []
    while True:
        try:
            out.append(json.loads(sock.recv(65536)))
        except BlockingIOError:
            return out


def _capture(tmp_path: Path, *extra, seconds=CAPTURE_S):
    traj = gentle_trajectory(tmp_path / "traj.yaml")
    log = tmp_path / "run.csv"
    res = invoke("capture", "--trajectory", traj, "--duration", seconds, "--quiet", "-o", log,
                 *extra)  # fmt: skip
    return res, log


def _csv(log: Path) -> tuple[list[str], list[list[float]]]:
    names = log.read_text().splitlines()[0].split(",")
    return names, parse_rows(log, log_fields(len(JOINTS)))


def _header(log: Path) -> dict:
    lines = log.read_text().splitlines()[1:]
    head = []
    for line in lines:
        if not line.startswith("#"):
            break
        head.append(line[2:])
    return yaml.safe_load("\n".join(head))


def _at(message: dict, path: tuple[str, ...]):
    for key in path:
        message = message[key]
    return message


def _assert_row_equal(message: dict, names: list[str], row: list[float], tol: dict) -> None:
    assert set(message) == {"tick", "timestamp", "status", *JOINTS}, message
    for j in JOINTS:
        assert set(message[j]) == {"counts", "q_rad", "v_V", "i_A", "setpoint_rad"}, message
    for name, value in zip(names, row, strict=True):
        got = _at(message, WHERE[name])
        kind = name if name == "time_s" else name.split("_")[0]
        if kind in ("tick", "counts", "status"):
            assert isinstance(got, int) and got == value, (name, got, value)
        else:
            assert abs(got - value) <= tol.get(kind, 0.0), (name, got, value)


@pytest.fixture(scope="module")
def streamed(tmp_path_factory):
    """A lock-step capture of sim://guard streamed to a listener here: (log, datagrams,
    capture output)."""
    d = tmp_path_factory.mktemp("streamed")
    sock = _listener()
    try:
        port = sock.getsockname()[1]
        res, log = _capture(d, "--stream", f"udp://127.0.0.1:{port}")
        assert res.exit_code == 0, res.output + res.stderr
        return log, _received(sock), res.stdout
    finally:
        sock.close()


def test_stream_sends_every_row_of_the_log_grouped_per_joint(streamed):
    log, messages, out = streamed
    names, rows = _csv(log)
    assert len(rows) == round(CAPTURE_S / 0.015)
    assert len(messages) == len(rows)  # every row, none twice, in order
    for message, row in zip(messages, rows, strict=True):
        _assert_row_equal(message, names, row, PRINTED)
    assert f"stream: {len(rows)} rows sent to udp://127.0.0.1:" in out
    assert ", 0 dropped" in out


def test_a_datagram_that_cannot_be_sent_is_counted_and_the_capture_goes_on(tmp_path, monkeypatch):
    """Every third send fails as a full socket buffer would (EAGAIN): the log keeps every
    row, the listener gets the others, the summary counts the failures."""
    from guardid.live import udp

    calls = []
    real = udp.UdpStream._send

    def flaky(self, data):
        calls.append(data)
        if len(calls) % 3 == 0:
            raise BlockingIOError(11, "Resource temporarily unavailable")
        real(self, data)

    monkeypatch.setattr(udp.UdpStream, "_send", flaky)
    sock = _listener()
    try:
        res, log = _capture(tmp_path, "--stream", f"udp://127.0.0.1:{sock.getsockname()[1]}",
                            seconds=0.45)  # fmt: skip
        got = _received(sock)
    finally:
        sock.close()
    assert res.exit_code == 0, res.output + res.stderr
    _, rows = _csv(log)
    assert len(rows) == 30 and len(calls) == 30
    assert len(got) == 20
    assert [m["tick"] for m in got] == [int(r[0]) for k, r in enumerate(rows) if k % 3 != 2]
    assert "stream: 20 rows sent" in res.stdout and ", 10 dropped (first: " in res.stdout


@pytest.mark.parametrize(
    ("url", "says"),
    [
        ("tcp://127.0.0.1:9870", "not a udp:// URL"),
        ("udp://127.0.0.1", "no port"),
        ("udp://127.0.0.1:0", "no port"),
        ("udp://127.0.0.1:70000", "1-65535"),
        ("udp://127.0.0.1:98x0", "1-65535"),
        ("udp://:9870", "no host"),
        ("udp://127.0.0.1:9870/plot", "only a host and a port"),
        ("  ", "empty"),
    ],
)
def test_a_bad_stream_url_is_one_line_before_anything_moves(tmp_path, url, says):
    with witnessed() as robots:
        res, log = _capture(tmp_path, "--stream", url)
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith("guardid: error: --stream ") and says in res.stderr
    assert len(res.stderr.splitlines()) == 1 and "udp://HOST:PORT" in res.stderr
    assert robots == [] and not log.exists()  # no port opened, no log begun


# ------------------------------------------------------------------ MCAP
def _mcap(path: Path):
    from mcap.reader import make_reader  # the test extra installs it

    with open(path, "rb") as fh:
        reader = make_reader(fh, validate_crcs=True)
        messages = list(reader.iter_messages(log_time_order=False))
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        summary = reader.get_summary()  # the index viewers seek with
    assert summary.statistics.message_count == len(messages)
    return messages, metadata


def _epoch_ns(iso: str) -> int:
    t = dt.datetime.fromisoformat(iso)
    whole = int(t.replace(microsecond=0).timestamp())
    return whole * 10**9 + t.microsecond * 1000


def test_mcap_equals_the_csv_and_carries_the_header(streamed, tmp_path):
    log = streamed[0]
    out = tmp_path / "run.mcap"
    res = invoke("convert", log, "--mcap", out)
    assert res.exit_code == 0, res.stderr
    names, rows = _csv(log)
    header = _header(log)
    messages, metadata = _mcap(out)
    assert len(messages) == len(rows)
    start = _epoch_ns(header["start_time"])
    exact = {}  # the CSV's text, parsed by both sides: no tolerance beyond float parsing
    for k, ((schema, channel, msg), row) in enumerate(zip(messages, rows, strict=True)):
        assert channel.topic == "/guardid/joints" and channel.message_encoding == "json"
        assert schema.encoding == "jsonschema"
        message = json.loads(msg.data)
        _assert_row_equal(message, names, row, exact)
        assert msg.sequence == k
        assert msg.log_time == start + round(row[1] * 1e9)  # start_time + time_s [ns]
    props = json.loads(schema.data)["properties"]
    assert props["pan"]["properties"]["q_rad"]["type"] == "number"
    assert props["tick"]["type"] == "integer" and props["tilt"]["properties"]["counts"]
    head = {k: json.loads(v) for k, v in metadata["guardid.header"].items()}
    assert head == header
    foot = {k: json.loads(v) for k, v in metadata["guardid.footer"].items()}
    assert foot == footer_dict(log)


def test_convert_never_replaces_an_existing_file_without_force(streamed, tmp_path):
    log = streamed[0]
    out = tmp_path / "run.mcap"
    out.write_bytes(b"an earlier recording")
    res = invoke("convert", log, "--mcap", out)
    assert res.exit_code == 2
    assert (
        res.stderr == f"guardid: error: --mcap {out}: already exists (give --force to replace it)\n"
    )
    assert out.read_bytes() == b"an earlier recording"
    res = invoke("convert", log, "--mcap", log, "--force")  # never the input, even --force
    assert res.exit_code == 2 and "is also the input LOG" in res.stderr
    res = invoke("convert", log, "--mcap", out, "--force")
    assert res.exit_code == 0, res.stderr
    assert len(_mcap(out)[0]) == len(_csv(log)[1])
    assert [p.name for p in tmp_path.iterdir()] == ["run.mcap"]  # no temporary file left


def test_convert_without_the_mcap_package_names_the_extra(streamed, tmp_path, monkeypatch):
    for name in [m for m in sys.modules if m == "mcap" or m.startswith("mcap.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "mcap", None)  # import mcap -> ImportError
    out = tmp_path / "run.mcap"
    res = invoke("convert", streamed[0], "--mcap", out)
    assert res.exit_code == 2
    assert res.stderr == (
        "guardid: error: --mcap: needs the mcap package, not installed: "
        "pip install 'guardid[mcap]'\n"
    )
    assert not out.exists()


def test_convert_refuses_a_log_without_time(tmp_path):
    """A foreign CSV (no time_s column) has no log time for MCAP: one line, no file."""
    log = tmp_path / "foreign.csv"
    log.write_text("time,pos_meas1\n0.0,0.1\n0.002,0.2\n")
    out = tmp_path / "foreign.mcap"
    res = invoke("convert", log, "--mcap", out)
    assert res.exit_code == 2
    assert res.stderr.startswith(f"guardid: error: {log}: no time_s column")
    assert len(res.stderr.splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["foreign.csv"]
