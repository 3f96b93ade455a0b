"""guardid ports: latency timer read from a fake sysfs tree."""

from types import SimpleNamespace

from guardid.link import ports as mod


def test_latency_warning_names_the_port_and_the_fix(tmp_path, monkeypatch):
    (tmp_path / "ttyUSB0").mkdir()
    (tmp_path / "ttyUSB0" / "latency_timer").write_text("16\n")
    (tmp_path / "ttyUSB1").mkdir()
    (tmp_path / "ttyUSB1" / "latency_timer").write_text("1\n")
    fake = [
        SimpleNamespace(device="/dev/ttyUSB1", description="FT232R", hwid="USB VID:PID=0403:6001"),
        SimpleNamespace(device="/dev/ttyUSB0", description="FT232R", hwid="USB VID:PID=0403:6001"),
        SimpleNamespace(device="/dev/ttyACM0", description="Arduino", hwid="USB VID:PID=2341:0042"),
    ]
    monkeypatch.setattr(mod.list_ports, "comports", lambda: fake)
    found = mod.serial_ports(sysfs=tmp_path)
    assert [p.device for p in found] == ["/dev/ttyACM0", "/dev/ttyUSB0", "/dev/ttyUSB1"]
    assert [p.latency_ms for p in found] == [None, 16, 1]
    warn = found[1].latency_warning
    assert "/dev/ttyUSB0" in warn and "16 ms" in warn and "latency_timer" in warn
    assert found[0].latency_warning is None and found[2].latency_warning is None
