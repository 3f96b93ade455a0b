"""A log is read by its names (issue 26): columns found by name and put in the robot's joint
order, angles checked against the encoder counts, and every malformed log a one-line error
(exit 2, nothing written) or, for a footer that miscounts, a warning.

Truth: the intact capture's result computed separately, the robot YAML's values, the
encoder scale from the log header's firmware counts per revolution, and line / row numbers
counted here with str.split.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from badinput_tools import ERROR_PREFIX, invoke
from logedit import column, data_rows, swapped, with_header_line, without_rows

from guardid.errors import ConfigError
from guardid.identify.checks import ANGLE_TOLERANCE_COUNTS, check_distinct, check_log_robot
from guardid.identify.runs import load_run
from guardid.log import read_log
from guardid.robot import load_robot
from guardid.robot.loader import shipped_path

PAN_COUNTS_PER_REV = 24000  # the capture header's firmware counts_per_rev (48 x gear 500)


def _one_line_error(res, code: int, words, output=None) -> str:
    """The one ``guardid: error:`` line of ``res`` (exit ``code``), holding ``words``; no
    traceback, and ``output`` (if given) not written."""
    exc = res.exception
    assert exc is None or isinstance(exc, SystemExit), f"{type(exc).__name__}: {exc}"
    assert res.exit_code == code, (res.exit_code, res.stderr)
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith(ERROR_PREFIX), res.stderr
    for word in words:
        assert word in lines[0], (word, lines[0])
    if output is not None:
        assert not output.exists()
    return lines[0]


def _identify(log, out, *more):
    return invoke("identify", log, "--method", "wls", "-o", out, *more)


def _values(path) -> dict:
    data = yaml.safe_load(path.read_text())
    out = {"wls": data["methods"]["wls"]["values"], "std": data["methods"]["wls"]["std"]}
    for m in data.get("motors", []):
        out[m["joint"]] = (m["resistance_ohm"], m["ke_v_s_per_rad"])
    return out


@pytest.fixture(scope="module")
def capture(gap_guard_captures):
    return gap_guard_captures[1]


@pytest.fixture(scope="module")
def intact(gap_guard_wls_params):
    return _values(gap_guard_wls_params[1])


# --- read by name --------------------------------------------------------------------------


@pytest.mark.parametrize(
    "pair",
    [
        ("q_pan_rad", "q_tilt_rad"),
        ("i_pan_A", "i_tilt_A"),
        ("counts_pan", "counts_tilt"),
        ("v_pan_V", "v_tilt_V"),
    ],  # fmt: skip
)
def test_columns_swapped_with_their_names_give_the_intact_result(capture, intact, tmp_path, pair):
    log = tmp_path / "swapped.csv"
    log.write_text(swapped(capture.read_text(), *pair, names_too=True))
    res = _identify(log, tmp_path / "p.yaml")
    assert res.exit_code == 0, res.stderr
    got = _values(tmp_path / "p.yaml")
    assert got == intact  # the same data by name: the same numbers, motors included
    data = yaml.safe_load((tmp_path / "p.yaml").read_text())
    truth = np.array([p["yaml_value"] for p in data["base_parameters"]])
    assert np.all(np.abs(np.array(got["wls"]) - truth) < 3 * np.array(got["std"]))


def test_values_swapped_under_unchanged_names_name_the_column_and_row(capture, tmp_path):
    text = capture.read_text()
    log, out = tmp_path / "swapvals.csv", tmp_path / "p.yaml"
    log.write_text(swapped(text, "q_pan_rad", "q_tilt_rad", names_too=False))
    # the first row whose pan angle (now the tilt's) is not counts_pan x 2 pi / 24000
    counts, tilt = column(text, "counts_pan"), column(text, "q_tilt_rad")
    per_count = 2 * math.pi / PAN_COUNTS_PER_REV
    row = next(k for k, (c, q) in enumerate(zip(counts, tilt, strict=True))
               if abs(q - c * per_count) > 1e-6)  # fmt: skip
    words = ["swapvals.csv", "column q_pan_rad", f"data row {row + 1}:", "counts_pan"]
    _one_line_error(_identify(log, out), 2, words, out)


def test_the_angle_check_holds_to_a_thousandth_of_a_count(capture):
    """A float round trip (the logged 9 decimals, or a relative 1e-15) passes; an angle a
    count off, in one row, is refused at that row."""
    run = load_run(capture)
    per_count = 2 * math.pi / PAN_COUNTS_PER_REV
    assert ANGLE_TOLERANCE_COUNTS * per_count > 100 * 5e-10  # far above the 9 printed decimals
    run.q = run.q * (1 + 1e-15)
    check_log_robot(run, load_robot("guard"), "test")  # no error
    run.q[1234, 0] += per_count
    with pytest.raises(ConfigError, match=r"column q_pan_rad, data row 1235: "):
        check_log_robot(run, load_robot("guard"), "test")


def test_the_headers_sample_period_must_be_the_robots_to_one_percent(capture):
    """A guardid log whose header sample_period_s is 1.3 % off the guard's sample_period
    (0.0152 s against 0.015 s) is refused, naming the field and both periods; one 0.33 % off
    (0.01505 s) is not refused by this check. Called on the run directly: load_run's own
    check against the firmware's tick_period (0.5 us) would refuse the edited header first."""
    guard = load_robot("guard")
    assert guard.sample_period == 0.015
    run = load_run(capture)
    run.sample_period_s = 0.01505  # |0.01505 - 0.015| = 5e-5 s < 1 % of 0.015 s = 1.5e-4 s
    check_log_robot(run, guard, "test")  # no error
    run = load_run(capture)
    run.sample_period_s = 0.0152  # 2e-4 s off > 1.5e-4 s
    with pytest.raises(ConfigError, match=r"sample_period_s 0\.0152 s, but robot guard .*"
                                          r"sample_period 0\.015 s"):  # fmt: skip
        check_log_robot(run, guard, "test")


def test_two_logs_differing_only_in_one_current_are_distinct(capture, tmp_path):
    """check_distinct refuses a copy of a log (another file, the same samples), but a copy
    whose currents differ in one value by 1 mA (times and angles the same) is a different
    recording: accepted."""
    text = capture.read_text()
    lines, rows = data_rows(text)
    c = lines[0].rstrip("\n").split(",").index("i_pan_A")
    parts = lines[rows[100]].rstrip("\n").split(",")
    parts[c] = f"{float(parts[c]) + 0.001:.3f}"
    moved = list(lines)
    moved[rows[100]] = ",".join(parts) + "\n"
    (tmp_path / "copy.csv").write_text(text)
    (tmp_path / "moved.csv").write_text("".join(moved))
    original, copy, other = (load_run(p) for p in (capture, tmp_path / "copy.csv",
                                                   tmp_path / "moved.csv"))  # fmt: skip
    assert np.array_equal(other.t, original.t) and np.array_equal(other.q, original.q)
    assert abs(other.current[100, 0] - original.current[100, 0] - 0.001) < 1e-9
    check_distinct([original, other])  # no error
    with pytest.raises(ConfigError, match=r"copy\.csv: the same samples as .*run1\.csv"):
        check_distinct([original, copy])


def test_a_log_whose_joints_are_not_the_robots_names_the_column(capture, tmp_path):
    text = capture.read_text()
    lines, _ = data_rows(text)
    head = lines[0].replace("_tilt", "_elbow")  # every tilt column renamed, data unchanged
    log, out = tmp_path / "elbow.csv", tmp_path / "p.yaml"
    log.write_text(head + "".join(lines[1:]))
    _one_line_error(_identify(log, out), 2, ["elbow.csv", "column counts_elbow", "pan, tilt"],
                    out)  # fmt: skip


def test_a_column_of_no_logged_joint_is_named(capture, tmp_path):
    lines, _ = data_rows(capture.read_text())
    head = lines[0].replace("i_tilt_A", "i_elbow_A")
    log, out = tmp_path / "stray.csv", tmp_path / "p.yaml"
    log.write_text(head + "".join(lines[1:]))
    _one_line_error(_identify(log, out), 2, ["stray.csv", "column i_elbow_A"], out)


def test_a_joint_name_twice_in_a_log_is_refused(capture, tmp_path):
    lines, _ = data_rows(capture.read_text())
    head = lines[0].replace("counts_tilt", "counts_pan")
    log, out = tmp_path / "twice.csv", tmp_path / "p.yaml"
    log.write_text(head + "".join(lines[1:]))
    _one_line_error(_identify(log, out), 2, ["twice.csv", "line 1", "'counts_pan' given twice"],
                    out)  # fmt: skip


# --- ticks, version, footer ----------------------------------------------------------------


@pytest.mark.parametrize("kind", ["repeated", "decreasing"])
def test_a_repeated_or_decreasing_tick_names_its_line(capture, tmp_path, kind):
    lines, rows = data_rows(capture.read_text())
    k = rows[500]
    if kind == "repeated":
        lines.insert(k + 1, lines[k])  # line k + 2 (1-based) repeats line k + 1
    else:
        lines[k], lines[k + 1] = lines[k + 1], lines[k]  # line k + 2 holds the earlier tick
    log, out = tmp_path / f"{kind}.csv", tmp_path / "p.yaml"
    log.write_text("".join(lines))
    tick = lines[k + 1].split(",")[0]
    words = [f"{kind}.csv", f"line {k + 2}:", f"tick {tick} after"]
    line = _one_line_error(_identify(log, out), 2, words, out)
    assert ("repeated tick" in line) == (kind == "repeated")


def test_an_unknown_log_format_version_says_which_are_known(capture, tmp_path):
    log, out = tmp_path / "v99.csv", tmp_path / "p.yaml"
    log.write_text(with_header_line(capture.read_text(), "guardid-log", "99"))
    _one_line_error(_identify(log, out), 2, ["v99.csv", "guardid-log", "99", "version 1"], out)


def test_a_footer_that_miscounts_the_rows_is_a_warning(capture, tmp_path):
    log, out = tmp_path / "cut.csv", tmp_path / "p.yaml"
    log.write_text(without_rows(capture.read_text(), 3000, 1000))  # footer: rows: 4000
    res = _identify(log, out)
    assert res.exit_code == 0, res.stderr
    warned = [x for x in res.stderr.splitlines() if x.startswith("guardid: warning: ")]
    assert warned == [
        f"guardid: warning: {log}: footer: rows: 4000, but the file holds 3000 data rows "
        "(rows removed or added after the capture?)"
    ]
    assert out.exists()


# --- encoding and delimiters ---------------------------------------------------------------


def test_a_byte_order_mark_is_read_past(capture, tmp_path):
    log = tmp_path / "bom.csv"
    log.write_bytes(b"\xef\xbb\xbf" + capture.read_bytes())
    plain, bom = read_log(capture), read_log(log)
    assert list(bom.columns) == list(plain.columns)
    for name, values in plain.columns.items():
        assert np.array_equal(bom.columns[name], values), name


@pytest.mark.parametrize(("sep", "what"), [("\t", "tabs"), (";", "semicolons")])
def test_another_delimiter_is_named_in_a_short_line(capture, tmp_path, sep, what):
    lines, rows = data_rows(capture.read_text())
    for k in [0, *rows]:
        lines[k] = lines[k].replace(",", sep)
    log, out = tmp_path / "other.csv", tmp_path / "p.yaml"
    log.write_text("".join(lines))
    line = _one_line_error(_identify(log, out), 2, ["other.csv", "line 1", f"separated by {what}",
                                                    "comma-separated"], out)  # fmt: skip
    assert "counts_pan" not in line  # the header is not quoted back


# --- robot YAML ----------------------------------------------------------------------------


def test_a_robot_with_two_joints_of_one_name_is_refused(tmp_path):
    data = yaml.safe_load(shipped_path("guard").read_text())
    data["joints"][1]["name"] = data["joints"][0]["name"]
    robot, out = tmp_path / "twopans.yaml", tmp_path / "traj.yaml"
    robot.write_text(yaml.safe_dump(data, sort_keys=False))
    res = invoke("excite", "--robot", robot, "--no-optimise", "-o", out)
    _one_line_error(res, 2, ["twopans.yaml", "joints[1].name", "'pan'", "unique"], out)
    res = invoke("capture", "--robot", robot, "--trajectory", out, "--duration", 1, "-o",
                 tmp_path / "run.csv")  # fmt: skip
    _one_line_error(res, 2, ["twopans.yaml", "joints[1].name"], tmp_path / "run.csv")


def test_the_python_api_reads_the_columns_by_name_too(capture, intact, tmp_path):
    """identify(runs, ...) on load_run(path) (README's Python API): a log whose counts_*
    columns (and so its joint order) are swapped with their names holds the same data, so
    the intact result; load_run keeps the file's order and identify took it as the
    description's (tilt's data as pan's: parameters tens of std off, exit 0)."""
    from guardid.identify import IdentifyOptions, identify

    log = tmp_path / "swapped.csv"
    log.write_text(swapped(capture.read_text(), "counts_pan", "counts_tilt", names_too=True))
    run = load_run(str(log))
    assert run.joint_names == ("tilt", "pan")  # the file's order: the case this test is for
    result = identify([run], load_robot("guard"), IdentifyOptions(methods=("wls",)))
    assert np.allclose(result.results["wls"].theta, intact["wls"], rtol=1e-9, atol=0)


def test_the_consistent_fit_of_the_python_api_reads_by_name_too(capture, tmp_path):
    """identify_consistent(runs, ...) conditions the runs again for the consistent fit:
    the same joint order as identify's (it used the file's: tilt's data as pan's)."""
    from guardid.identify import IdentifyOptions
    from guardid.physical.report import identify_consistent

    log = tmp_path / "swapped.csv"
    log.write_text(swapped(capture.read_text(), "counts_pan", "counts_tilt", names_too=True))
    options = IdentifyOptions(methods=("ls",))
    guard = load_robot("guard")
    swapped_fit = identify_consistent([load_run(str(log))], guard, options)[0]
    intact_fit = identify_consistent([load_run(str(capture))], guard, options)[0]
    got, want = (r.results["consistent"].theta for r in (swapped_fit, intact_fit))
    assert np.allclose(got, want, rtol=1e-9, atol=0)


def test_identify_keeps_only_the_columns_it_reads(capture):
    """The columns load_run copies are the file's (an independent parse with numpy), and
    identify drops counts once the joints are in the robot's order (kept when they must be
    reordered and checked, and for iv, didim and the bootstrap, whose simulations start
    from them) and setpoints unless iv, didim or the bootstrap read them (--report does
    not)."""
    from dataclasses import replace

    from guardid.commands.identify import _lean

    path = capture
    text = [ln for ln in Path(path).read_text().splitlines()[1:] if not ln.startswith("#")]
    names = Path(path).read_text().splitlines()[0].split(",")
    raw = np.loadtxt(text, delimiter=",")
    run = load_run(path)
    for key, group in (("q", "q_{}_rad"), ("current", "i_{}_A"), ("setpoint", "sp_{}_rad"),
                       ("counts", "counts_{}")):  # fmt: skip
        want = raw[:, [names.index(group.format(j)) for j in run.joint_names]]
        assert np.array_equal(getattr(run, key), want), key
    guard = load_robot(shipped_path("guard"))
    lean = _lean(run, guard, ("ls", "wls", "rls", "hopfield"))
    assert lean.counts is None and lean.setpoint is None and lean.q is run.q
    for simulated in (_lean(run, guard, ("ls", "iv")), _lean(run, guard, ("DIDIM",)),
                      _lean(run, guard, ("ls",), bootstrap=True)):  # fmt: skip
        assert simulated.setpoint is run.setpoint and simulated.counts is run.counts
    other = replace(run, joint_names=run.joint_names[::-1])
    assert _lean(other, guard, ("ls",)).counts is run.counts
