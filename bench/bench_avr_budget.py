"""The AVR binary in the loop (firmware=avr): 60 s closed-loop runs and the cycle budget.

Run: python bench/bench_avr_budget.py [--seconds 60] [--mcu atmega328p] [--seed 1]

1. Tracking excitation (guardid excite --base-freq 0.2 --harmonics 3), captured through
   sim://guard?firmware=avr and through firmware=py on the same seed: rows, lost rows, CRC
   errors, tracking rms of both; guardid identify on the AVR log: every base parameter with a
   relative std under 5 % checked against the truth (within 3 std).
2. Full speed: voltage mode, pan at +12 V, tilt bang-bang +-12 V between its limits, telemetry
   every tick.
3. SET_PID landing at every phase of the tick (its gain arithmetic runs in the main loop).
For each: worst and mean cycles from the Timer1 interrupt to the end of the tick's work
against 240 000 cycles per tick, CPU share per interrupt, worst interrupt latency, the UART
transmit ring's high-water mark, encoder edges put on the pins vs counted, main-loop overruns,
and the simulation speed in multiples of real time (process CPU time; wall under load).
"""

from __future__ import annotations

import argparse
import struct
import tempfile
import time
from pathlib import Path

import numpy as np

BUDGET = 240_000


def report(dev, label: str, cpu_s: float, wall_s: float, sim_s: float) -> None:
    st = dev.stats()
    total = st["cycle"]
    work_mean = st["work_sum"] / max(st["work_n"], 1)
    overruns = struct.unpack("<H", dev.read_ram("overruns", 2))[0]
    print(f"--- {label} ({dev.mcu}, {sim_s:.0f} s simulated)")
    print(f"tick work: worst {st['work_max']} cycles ({100 * st['work_max'] / BUDGET:.1f} % of "
          f"{BUDGET}), mean {work_mean:.0f} ({100 * work_mean / BUDGET:.1f} %), "
          f"{st['work_n']} ticks; outputs late for the plant: {st['late_outputs']}; worst "
          f"at tick {st['work_max_tick']}; ticks raised before the previous tick's work "
          f"ended: {st['late_ticks']}")  # fmt: skip
    lat = 0
    for name, v in st["vectors"].items():
        lat = max(lat, v["max_latency"])
        share = 100 * v["cycles"] / total
        print(f"  ISR {name:20s} {v['count']:8d} calls  CPU {share:5.2f} %  longest "
              f"{v['max_cycles']:4d} cycles  worst latency {v['max_latency']:4d}")  # fmt: skip
    counted = st["vectors"][next(k for k in st["vectors"] if k.startswith("PCINT2"))]["count"]
    print(f"worst interrupt latency {lat} cycles ({lat / 16:.1f} us); UART TX ring high-water "
          f"{st['tx_hwm']} of 127 bytes; main-loop overruns {overruns}")  # fmt: skip
    print(f"encoder edges put on the pins {st['edges0']} + {st['edges1']}, pin-change interrupts "
          f"{counted}, firmware count vs pins: worst error {st['count_err_max']} counts "
          f"({st['count_err_ticks']} ticks off)")  # fmt: skip
    print(
        f"speed: {sim_s / cpu_s:.2f}x real time (process CPU), {sim_s / wall_s:.2f}x wall "
        "(shared machine)"
    )


def tracking(args, tmp: Path) -> None:
    from click.testing import CliRunner

    from guardid.capture import capture
    from guardid.cli import main as cli
    from guardid.dynamics import build_model
    from guardid.excitation import load_trajectory
    from guardid.identify import identify
    from guardid.identify.runs import load_run
    from guardid.link import Session, open_port
    from guardid.robot import load_robot

    guard = load_robot("guard")
    traj = tmp / "track.yaml"
    CliRunner().invoke(cli, ["excite", "--base-freq", "0.2", "--harmonics", "3", "-o", str(traj)],
                       catch_exceptions=False)  # fmt: skip
    trajectory = load_trajectory(traj)
    results = {}
    for fw in ("py", "avr"):
        mcu = f"&mcu={args.mcu}" if fw == "avr" else ""
        port = open_port(f"sim://guard?seed={args.seed}&firmware={fw}{mcu}")
        log = tmp / f"{fw}.csv"
        c0, w0 = time.process_time(), time.perf_counter()
        session = Session(port)
        session.handshake()
        res = capture(session, guard, trajectory, args.seconds, log,
                      {"robot": "guard", "trajectory": trajectory.to_dict()})  # fmt: skip
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        results[fw] = (res, log)
        rms = np.degrees(res.rms_tracking_error_rad)
        print(f"firmware={fw}: {res.rows} rows of {res.ticks_expected} ({res.lost_rows} lost), "
              f"CRC errors {res.link.get('crc_errors')}, sequence gaps {res.link.get('seq_gaps')}, "
              f"rms tracking {rms[0]:.3f} deg, {rms[1]:.3f} deg")  # fmt: skip
        if fw == "avr":
            report(port.engine.device, "tracking excitation", cpu, wall, args.seconds)
        port.close()
    r_py = np.array(results["py"][0].rms_tracking_error_rad)
    r_avr = np.array(results["avr"][0].rms_tracking_error_rad)
    print(f"tracking rms avr/py - 1: {np.round(100 * (r_avr / r_py - 1), 2)} % (limit 10 %)")
    run = load_run(results["avr"][1])
    ident = identify([run], guard)  # the header's highest harmonic: 0.2 Hz x 3
    model = build_model(guard)
    truth = dict(zip(model.base.names, model.base.values(model.params), strict=True))
    for method in ("ls", "wls"):
        r = ident.results[method]
        good = r.rel_std_pct < 5.0
        t = np.array([truth[n] for n in ident.names])
        z = np.abs(r.theta - t) / r.std
        bad = [n for n, g, zz in zip(ident.names, good, z, strict=True) if g and zz > 3]
        print(
            f"identify {method}: {int(good.sum())} parameters with rel std < 5 %, "
            f"worst |error|/std among them {z[good].max():.2f}; outside 3 std: {bad or 'none'}"
        )


def full_speed(args) -> None:
    from guardid.firmware.avr_sim.device import AvrFirmware
    from guardid.plant import Plant
    from guardid.protocol import MESSAGES, Encoder, FrameParser
    from guardid.robot import load_robot

    guard = load_robot("guard")
    dev = AvrFirmware(guard, Plant(guard, seed=args.seed), mcu=args.mcu, seed=args.seed)
    enc, parser = Encoder(), FrameParser()
    dev.receive(enc.encode(MESSAGES["SET_MODE"](mode=2)))
    dev.receive(enc.encode(MESSAGES["START_STREAM"](decimation=1)))
    lo, hi = guard.joints[1].limits.position
    tilt = 12000
    rows = 0
    c0, w0 = time.process_time(), time.perf_counter()
    for _ in range(round(args.seconds / 0.015)):
        q = dev.plant.state.q[1]
        if q > hi - 0.1:
            tilt = -12000
        elif q < lo + 0.1:
            tilt = 12000
        dev.receive(enc.encode(MESSAGES["SET_VOLTAGE"](voltage=[12000, tilt])))
        dev.advance()
        rows += sum(type(f.msg).__name__ == "Telemetry" for f in parser.feed(dev.take_output()))
    cpu, wall = time.process_time() - c0, time.perf_counter() - w0
    print(f"full speed: {rows} telemetry frames of {round(args.seconds / 0.015)} ticks")
    report(dev, "full speed (pan +12 V, tilt +-12 V)", cpu, wall, args.seconds)
    dev.close()


def set_pid_sweep(args) -> None:
    """SET_PID (128-bit gain arithmetic in the main loop) landing at every phase of a tick."""
    from guardid.firmware.avr_sim.device import AvrFirmware
    from guardid.plant import Plant
    from guardid.protocol import MESSAGES, Encoder
    from guardid.robot import load_robot

    guard = load_robot("guard")
    dev = AvrFirmware(guard, Plant(guard, seed=args.seed), mcu=args.mcu, seed=args.seed)
    frame = Encoder().encode(MESSAGES["SET_PID"](0, 40_000_000, 10_000_000, 1_000_000))
    dev.advance()
    for fill in range(176):  # one byte time (1/176 of a tick) apart
        dev.receive(b"\x00" * fill + frame)
        for _ in range(3):
            dev.advance()
        dev.take_output()
    st = dev.stats()
    print(f"--- SET_PID at each of 176 phases of the tick ({dev.mcu}): worst tick work "
          f"{st['work_max']} cycles ({100 * st['work_max'] / BUDGET:.1f} % of {BUDGET}), "
          f"ticks late {st['late_ticks']}")  # fmt: skip
    dev.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--mcu", default="atmega328p", choices=("atmega328p", "atmega2560"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--only", choices=("tracking", "speed", "set_pid"), default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        if args.only in (None, "tracking"):
            tracking(args, Path(tmp))
        if args.only in (None, "speed"):
            full_speed(args)
        if args.only in (None, "set_pid"):
            set_pid_sweep(args)


if __name__ == "__main__":
    main()
