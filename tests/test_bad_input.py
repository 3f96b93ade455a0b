# ruff: noqa: E501  (the matrix reads best one row per line)
"""The bad-input matrix: every case a user met (issues 15 and 26, "What was seen") -> exit
code and one ``guardid: error:`` line naming the file, field, option or port; no traceback;
no file in the module's folder created or changed.

Each row: an id, the command line (built from the module's files; ``''`` is an empty
argument), the expected exit code and the words the error line must contain.
Runs in-process (click's CliRunner); one row goes through the real ``python -m guardid``.
"""

from __future__ import annotations

import gzip
import hashlib
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml
from badinput_tools import ERROR_PREFIX, invoke, short_capture

from guardid.robot.loader import shipped_path


@dataclass
class Files:
    """Every input of the matrix, made once per module in ``d``."""

    d: Path
    run: Path  # a 10 s capture of sim://guard
    params: Path  # identify's params.yaml from ``run``
    traj: Path  # the excitation of ``run``

    def __truediv__(self, name: str) -> Path:
        return self.d / name


def _header_robot(text: str, name: str, source: Path) -> str:
    out = []
    for line in text.splitlines(keepends=True):
        if line.startswith("# robot: "):
            line = f"# robot: {name}\n"
        elif line.startswith("# robot_source: "):
            line = f"# robot_source: {source}\n"
        out.append(line)
    return "".join(out)


def _still_trajectory(traj: Path, out: Path) -> None:
    data = yaml.safe_load(traj.read_text())
    data["a"] = [[0.0] * len(row) for row in data["a"]]
    data["b"] = [[0.0] * len(row) for row in data["b"]]
    data["q0"] = [0.0] * len(data["q0"])
    out.write_text(yaml.safe_dump(data))


def _data_lines(text: str):
    lines = text.splitlines(keepends=True)
    return lines, [k for k, line in enumerate(lines) if line[:1].isdigit()]


def _drop_columns(text: str, names) -> str:
    """The log without the columns ``names`` (header line and data rows)."""
    lines, rows = _data_lines(text)
    head = lines[0].rstrip("\n").split(",")
    keep = [k for k, name in enumerate(head) if name not in names]
    for i in [0, *rows]:
        parts = lines[i].rstrip("\n").split(",")
        lines[i] = ",".join(parts[k] for k in keep) + "\n"
    return "".join(lines)


def _issue26_files(d: Path, f: Files, guard_yaml: str) -> None:
    """Existing outputs of every kind, params files a validate crashed on, a trajectory
    naming the robot's joints in the other order, a robot with a 1e308 kg link."""
    for name in ("existing.yaml", "existing.png", "existing.urdf", "existing.xml",
                 "fresh.online.csv"):  # fmt: skip
        (d / name).write_text("a file the user keeps\n")
    (d / "existing.html").write_text("<!doctype html><p>a report the user keeps</p>\n")
    p = yaml.safe_load(f.params.read_text())
    p["methods"]["ls"]["values"][2] = "abc"
    (d / "params_str.yaml").write_text(yaml.safe_dump(p, sort_keys=False))
    p = yaml.safe_load(f.params.read_text())
    p["methods"]["ls"]["values"][0] = float("nan")
    (d / "params_nan.yaml").write_text(yaml.safe_dump(p, sort_keys=False))
    p["methods"]["wls"] = yaml.safe_load(f.params.read_text())["methods"]["ls"]  # finite
    (d / "params_nan_and_finite.yaml").write_text(yaml.safe_dump(p, sort_keys=False))
    p = yaml.safe_load(f.params.read_text())
    p["methods"] = {}
    (d / "params_nomethod.yaml").write_text(yaml.safe_dump(p, sort_keys=False))
    t = yaml.safe_load(f.traj.read_text())
    t["joints"] = list(reversed(t["joints"]))
    (d / "swapped_names.yaml").write_text(yaml.safe_dump(t))
    heavy = yaml.safe_load(guard_yaml)
    heavy["links"][1]["mass"] = 1e308
    (d / "heavy.yaml").write_text(yaml.safe_dump(heavy, sort_keys=False))


def _snapshot(d: Path) -> dict[str, str]:
    """Every file under ``d`` (hidden ones too: a temporary file left behind) -> digest."""
    return {
        str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(d.rglob("*"))
        if p.is_file()
    }


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("badinput")
    run = short_capture(d)
    params = d / "params.yaml"
    assert invoke("identify", run, "--method", "ls", "-o", params).exit_code == 0
    f = Files(d, run, params, d / "traj.yaml")
    text = run.read_text()
    # robot YAMLs: binary garbage, a YAML syntax error, a mistyped field, another robot
    (d / "garbage.yaml").write_bytes(bytes(range(256)) * 8)
    (d / "broken.yaml").write_text("name: x\njoints: [\n  {type: revolute\n")
    guard = shipped_path("guard").read_text()
    (d / "typo.yaml").write_text(guard.replace("gear_ratio: ", "gear_ratio: abc #", 1))
    other = yaml.safe_load(guard)
    other["name"] = "guard_b"
    other["links"][1]["mass"] = 2.0 * other["links"][1]["mass"]
    (d / "guard_b.yaml").write_text(yaml.safe_dump(other, sort_keys=False))
    # logs: a copy, another robot's, NaN / inf, gzip, two appended, a cut last row
    for name in ("copy.csv", "existing.csv", "own.csv"):
        (d / name).write_text(text)
    (d / "other.csv").write_text(_header_robot(text, "guard_b", d / "guard_b.yaml"))
    lines, rows = _data_lines(text)
    for name, value in (("nan.csv", "nan"), ("inf.csv", "inf")):
        bad = list(lines)
        parts = bad[rows[100]].split(",")
        parts[4] = value  # q_pan_rad of data row 101
        bad[rows[100]] = ",".join(parts)
        (d / name).write_text("".join(bad))
    for name, col, value in (("huge_current.csv", 8, "1e300"), ("huge_voltage.csv", 7, "99")):
        bad = list(lines)  # i_pan_A / v_tilt_V of data row 101, beyond the sensor's range
        parts = bad[rows[100]].rstrip("\n").split(",")
        parts[col] = value
        bad[rows[100]] = ",".join(parts) + "\n"
        (d / name).write_text("".join(bad))
    # the header's sample period edited: against the firmware's tick, against the robot's
    (d / "period_vs_tick.csv").write_text(
        text.replace("# sample_period_s: 0.015", "# sample_period_s: 0.03")
    )
    both = text.replace("# sample_period_s: 0.015", "# sample_period_s: 0.03")
    (d / "period_vs_robot.csv").write_text(
        both.replace("#   tick_period: 0.015", "#   tick_period: 0.03")
    )
    still_pan = list(lines)  # the pan's counts and angle 0 in every row: it never moved
    for k in rows:
        parts = still_pan[k].rstrip("\n").split(",")
        parts[2], parts[4] = "0", "0"
        still_pan[k] = ",".join(parts) + "\n"
    (d / "pan_still.csv").write_text("".join(still_pan))
    # the margin: 2 A + one ADC step (4 A / 1024) + half a mA of the firmware's rounding
    for name, value in (("edge_current.csv", "-2.0043"), ("past_edge_current.csv", "-2.0045")):
        edge = list(lines)
        parts = edge[rows[100]].rstrip("\n").split(",")
        parts[8], parts[9] = value, "1.99609375"
        edge[rows[100]] = ",".join(parts) + "\n"
        (d / name).write_text("".join(edge))
    (d / "robot_nowhere.csv").write_text(_header_robot(text, "nowhere", Path("nowhere.yaml")))
    (d / "gzip.csv").write_bytes(gzip.compress(text.encode()))
    (d / "dropped.csv").write_text(_drop_columns(text, ("q_pan_rad", "i_pan_A")))
    (d / "no_voltage.csv").write_text(_drop_columns(text, ("v_pan_V", "v_tilt_V")))
    no_footer = "".join(lines[: rows[-1] + 1])
    (d / "appended.csv").write_text(no_footer + "".join(lines[k] for k in rows))
    (d / "cut.csv").write_text(no_footer[: -len(lines[rows[-1]]) // 2])
    # another robot's parameters (same structure, another name)
    p = yaml.safe_load(params.read_text())
    p["robot"] = "guard_b"
    (d / "params_b.yaml").write_text(yaml.safe_dump(p, sort_keys=False))
    # a run in which the robot never moves, and an existing output
    _still_trajectory(f.traj, d / "still.yaml")
    res = invoke("capture", "--trajectory", d / "still.yaml", "--duration", 10, "--quiet",
                 "-o", d / "still.csv")  # fmt: skip
    assert res.exit_code == 0, res.output
    _issue26_files(d, f, guard)
    big = yaml.safe_load(f.traj.read_text())
    big["a"] = [[10 * x for x in row] for row in big["a"]]
    big["b"] = [[10 * x for x in row] for row in big["b"]]
    (d / "big.yaml").write_text(yaml.safe_dump(big))
    yield f


# id: (argv of guardid with {placeholders} for Files, exit code, words in the error line)
ROWS = [
    # robot descriptions
    ("yaml-binary-garbage", "excite --robot {garbage.yaml} -o {x.yaml}", 2, ["garbage.yaml", "UTF-8"]),
    ("yaml-syntax", "excite --robot {broken.yaml} -o {x.yaml}", 2, ["broken.yaml", "line"]),
    ("yaml-mistyped-field", "excite --robot {typo.yaml} -o {x.yaml}", 2, ["typo.yaml", "gear_ratio"]),
    ("yaml-missing-file", "excite --robot {nowhere.yaml} -o {x.yaml}", 2, ["nowhere.yaml"]),
    ("excite-base-freq-nan", "excite --base-freq nan -o {x.yaml}", 2, ["--base-freq", "nan"]),
    ("excite-base-freq-inf", "excite --base-freq inf -o {x.yaml}", 2, ["--base-freq", "inf"]),
    ("identify-garbage-robot", "identify {run} --robot {garbage.yaml}", 2, ["garbage.yaml"]),
    # a log and a robot that do not belong together
    ("identify-robot-planar2", "identify {run} --robot planar2", 2, ["run.csv", "guard", "planar2"]),
    ("identify-robot-flexlink", "identify {run} --robot flexlink", 2, ["run.csv", "flexlink"]),
    ("identify-robot-named-other", "identify {run} --robot {guard_b.yaml}", 2, ["run.csv", "guard_b"]),
    ("identify-logs-of-two-robots", "identify {run} {other.csv}", 2, ["other.csv", "guard_b", "guard"]),
    ("identify-same-log-twice", "identify {run} {run}", 2, ["run.csv", "twice"]),
    ("identify-method-twice", "identify {run} --method ls,wls,ls", 2, ["--method", "ls", "twice"]),
    ("identify-copy-of-a-log", "identify {run} {copy.csv}", 2, ["copy.csv", "run.csv", "same samples"]),
    ("validate-other-robots-params", "validate {run} --params {params_b.yaml}", 2, ["params_b.yaml", "guard_b"]),
    ("validate-robot-planar2", "validate {run} --params {params} --robot planar2", 2, ["run.csv", "planar2"]),
    ("validate-params-garbage", "validate {run} --params {garbage.yaml}", 2, ["garbage.yaml"]),
    ("validate-same-log-twice", "validate {run} {run} --params {params}", 2, ["run.csv", "twice"]),
    # results that cannot be trusted
    ("identify-never-moved", "identify {still.csv} -o {p_still.yaml}", 4, ["still.csv", "cannot be trusted", "--force"]),
    ("identify-one-joint-never-moved", "identify {pan_still.csv} -o {p_pan_still.yaml}", 4, ["pan_still.csv", "cannot be trusted", "ZZ1R", "regressor column zero"]),
    # excitation parameters
    ("excite-base-freq-50", "excite --base-freq 50 -o {x.yaml}", 2, ["--base-freq", "Nyquist"]),
    ("excite-schroeder-too-fast", "excite --kind schroeder --base-freq 2 -o {x.yaml}", 2, ["--base-freq", "20 Hz"]),
    ("excite-one-harmonic", "excite --harmonics 1 -o {x.yaml}", 2, ["--harmonics"]),
    ("excite-harmonics-100000", "excite --harmonics 100000 --base-freq 0.0001 -o {x.yaml}", 2, ["--harmonics", "149"]),
    # identify's and validate's options
    ("identify-cutoff-0", "identify {run} --cutoff 0", 2, ["--cutoff"]),
    ("identify-cutoff-above-nyquist", "identify {run} --cutoff 1e9", 2, ["--cutoff", "run.csv", "Nyquist"]),
    ("identify-lam-0", "identify {run} --lam 0", 2, ["--lam"]),
    ("identify-bootstrap-negative", "identify {run} --quantisation-bootstrap -1", 2, ["--quantisation-bootstrap"]),
    ("identify-eta-nan", "identify {run} --method gradient --eta nan", 2, ["--eta"]),
    ("validate-no-params", "validate {run}", 2, ["--params"]),
    ("unknown-command", "identfy {run}", 2, ["identfy"]),
    # a robot the fake port cannot simulate
    ("fake-port-planar2", "fake-port --robot planar2", 2, ["planar2", "drive"]),
    ("fake-port-flexlink", "fake-port --robot flexlink", 2, ["flexlink"]),
    ("capture-sim-planar2", "capture --port sim://planar2 --robot planar2 --trajectory {traj} --duration 1 -o {c.csv}", 2, ["planar2"]),
    # logs the reader must refuse (or warn about)
    ("log-nan", "identify {nan.csv}", 2, ["nan.csv", "line ", "q_pan_rad", "not finite"]),
    ("log-inf", "identify {inf.csv}", 2, ["inf.csv", "line ", "q_pan_rad", "not finite"]),
    ("log-gzip-named-csv", "identify {gzip.csv}", 2, ["gzip.csv"]),
    ("log-current-past-the-margin", "identify {past_edge_current.csv}", 2, ["past_edge_current.csv", "i_pan_A", "-2.0045"]),
    ("log-current-beyond-its-sensor", "identify {huge_current.csv}", 2, ["huge_current.csv", "i_pan_A", "data row 101", "range +-2 A"]),
    ("validate-current-beyond-its-sensor", "validate {huge_current.csv} --params {params}", 2, ["huge_current.csv", "i_pan_A", "data row 101"]),
    ("log-voltage-beyond-its-sensor", "identify {huge_voltage.csv}", 2, ["huge_voltage.csv", "v_tilt_V", "data row 101", "range +-15 V"]),
    ("log-sample-period-not-the-tick", "identify {period_vs_tick.csv}", 2, ["period_vs_tick.csv", "sample_period_s 0.03", "tick_period 0.015"]),
    ("log-sample-period-not-the-robots", "identify {period_vs_robot.csv}", 2, ["period_vs_robot.csv", "sample_period_s 0.03", "guard", "sample_period 0.015"]),
    ("log-robot-source-nowhere", "identify {robot_nowhere.csv}", 2, ["robot_nowhere.csv", "robot_source", "nowhere", "--robot"]),
    ("simulate-shorter-than-a-tick", "simulate --duration 0.001 -o {s.csv}", 2, ["--duration", "0.001", "one tick"]),
    ("simulate-duration-1e12", "simulate --duration 1e12 -o {s.csv}", 2, ["--duration", "s.csv", "free"]),
    ("simulate-payload-mass-nan", "simulate --payload-time 1 --payload-mass nan --duration 1 -o {s.csv}", 2, ["--payload-mass", "finite", "nan"]),
    ("simulate-other-robots-params", "simulate --params {params_b.yaml} --duration 1 -o {s.csv}", 2, ["params_b.yaml", "guard_b", "guard"]),
    ("log-ticks-restart", "identify {appended.csv}", 2, ["appended.csv", "tick"]),
    ("log-missing", "identify {nowhere.csv}", 2, ["nowhere.csv"]),
    ("log-a-joints-columns-dropped", "identify {dropped.csv}", 2, ["dropped.csv", "q_*"]),
    # capture's output and limits (other branches)
    pytest.param("capture-dev-full", "capture --trajectory {traj} --duration 1 -o /dev/full", 2, ["/dev/full"]),
    pytest.param("capture-overwrites-a-log", "capture --trajectory {traj} --duration 1 --quiet -o {existing.csv}", 2, ["existing.csv"]),
    pytest.param("capture-trajectory-10x", "capture --trajectory {big.yaml} --duration 1 -o {c10.csv}", 2, ["big.yaml", "beyond its limit", "nothing moved"]),
    pytest.param("identify-output-is-input", "identify {own.csv} --method ls -o {own.csv}", 2, ["own.csv"]),
    # issue 26: every output refuses an existing file unless --force, in the same words
    ("excite-o-existing", "excite --no-optimise -o {existing.yaml}", 2, ["-o", "existing.yaml", "already exists (give --force to replace it)"]),
    ("identify-o-existing", "identify {run} --method ls -o {existing.yaml}", 2, ["-o", "existing.yaml", "already exists (give --force to replace it)"]),
    ("identify-plot-existing", "identify {run} --method ls --plot {existing.png}", 2, ["--plot", "existing.png", "already exists (give --force"]),
    ("identify-report-existing", "identify {run} --method ls --report {existing.html}", 2, ["--report", "existing.html", "already exists (give --force"]),
    ("identify-o-is-plot", "identify {run} --method ls -o {new.yaml} --plot {new.yaml}", 2, ["--plot", "new.yaml", "also -o"]),
    ("validate-report-existing", "validate {run} --params {params} --report {existing.html}", 2, ["--report", "existing.html", "already exists (give --force"]),
    ("simulate-o-existing", "simulate --duration 0.1 -o {existing.csv}", 2, ["-o", "existing.csv", "already exists (give --force"]),
    ("export-urdf-existing", "export --robot guard --urdf {existing.urdf}", 2, ["--urdf", "existing.urdf", "already exists (give --force"]),
    ("export-mjcf-existing", "export --robot guard --mjcf {existing.xml}", 2, ["--mjcf", "existing.xml", "already exists (give --force"]),
    ("export-mjcf-is-urdf-side", "export --robot guard --urdf {z.urdf} --mjcf {z.guardid.yaml}", 2, ["--mjcf", "z.guardid.yaml", "also --urdf"]),
    ("capture-online-output-existing", "capture --trajectory {traj} --duration 1 --online rls -o {fresh.csv}", 2, ["--online output", "fresh.online.csv", "already exists (give --force"]),
    ("capture-o-existing", "capture --trajectory {traj} --duration 1 -o {existing.csv}", 2, ["-o", "existing.csv", "already exists (give --force"]),
    # ... and is checked writable before any work starts
    ("identify-o-missing-dir", "identify {garbage.yaml} -o {nodir/p.yaml}", 2, ["-o", "nodir", "does not exist"]),
    ("identify-o-under-a-file", "identify {run} -o {params.yaml/p.yaml}", 2, ["-o", "params.yaml", "not a directory"]),
    ("identify-o-is-a-directory", "identify {run} -o {.}", 2, ["-o", "is a directory"]),
    ("excite-o-missing-dir", "excite -o {nodir/t.yaml}", 2, ["-o", "nodir", "does not exist"]),
    ("simulate-o-missing-dir", "simulate -o {nodir/s.csv}", 2, ["-o", "nodir", "does not exist"]),
    ("export-urdf-missing-dir", "export --robot guard --urdf {nodir/r.urdf}", 2, ["--urdf", "nodir", "does not exist"]),
    ("capture-o-missing-dir", "capture --trajectory {traj} --duration 1 -o {nodir/r.csv}", 2, ["-o", "nodir", "does not exist"]),
    # issue 26: tracebacks
    ("validate-params-string-value", "validate {run} --params {params_str.yaml}", 2, ["params_str.yaml", "methods.ls.values[2]", "'abc' is not a number"]),
    ("validate-params-nan-value", "validate {run} --params {params_nan.yaml}", 2, ["params_nan.yaml", "methods.ls", "ZZ1R", "not finite"]),
    ("simulate-params-nan-value", "simulate --params {params_nan.yaml} --duration 1 -o {s.csv}", 2, ["params_nan.yaml", "methods.ls", "ZZ1R", "not finite"]),
    ("validate-params-no-method", "validate {run} --params {params_nomethod.yaml}", 2, ["params_nomethod.yaml", "methods", "empty"]),
    ("identify-method-empty", "identify {run} --method '' -o {p_empty.yaml}", 2, ["--method", "no method"]),
    ("capture-duration-1e9", "capture --trajectory {traj} --duration 1e9 -o {c.csv}", 2, ["--duration", "free", "c.csv"]),
    ("capture-timeout-0", "capture --trajectory {traj} --timeout 0 -o {c.csv}", 2, ["--timeout"]),
    # issue 26: nonsense that went on with exit 0
    ("capture-periods-0", "capture --trajectory {traj} --periods 0 -o {c.csv}", 2, ["--periods", "0"]),
    ("capture-port-empty", "capture --trajectory {traj} --port '' --duration 1 -o {c.csv}", 2, ["--port", "empty"]),
    ("capture-baud-0", "capture --trajectory {traj} --baud 0 --duration 1 -o {c.csv}", 2, ["--baud", "0"]),
    ("capture-joint-names-swapped", "capture --trajectory {swapped_names.yaml} --duration 1 -o {c.csv}", 2, ["swapped_names.yaml", "joints: tilt, pan", "pan, tilt", "nothing moved"]),
    ("excite-link-mass-1e308", "excite --robot {heavy.yaml} -o {x.yaml}", 2, ["heavy.yaml", "links[1].mass", "1e+308"]),
    ("simulate-link-mass-1e308", "simulate --robot {heavy.yaml} --duration 0.1 -o {s.csv}", 2, ["heavy.yaml", "links[1].mass"]),
    # issue 26: a bad sim:// option is bad input (2), not a link failure (3)
    ("capture-sim-seed-abc", "capture --trajectory {traj} --port sim://guard?seed=abc --duration 1 -o {c.csv}", 2, ["sim://guard?seed=abc", "seed", "abc"]),
]  # fmt: skip


def _argv(template: str, files: Files) -> list[str]:
    out = []
    for word in template.split():
        if word == "''":
            word = ""
        elif word.startswith("{") and word.endswith("}"):
            key = word[1:-1]
            word = str(getattr(files, key) if key in ("run", "params", "traj") else files / key)
        out.append(word)
    return out


def _row_id(row):
    return row.values[0] if hasattr(row, "values") else row[0]


@pytest.mark.parametrize(("name", "template", "code", "words"), ROWS, ids=map(_row_id, ROWS))
def test_bad_input_is_one_line(files, name, template, code, words):
    before = _snapshot(files.d)
    result = invoke(*_argv(template, files))
    assert _snapshot(files.d) == before, "a file was created or changed"
    exc = result.exception
    assert exc is None or isinstance(exc, SystemExit), f"{type(exc).__name__}: {exc}"
    assert result.exit_code == code, (result.exit_code, result.stderr)
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith(ERROR_PREFIX), lines[0]
    for word in words:
        assert word in lines[0], (word, lines[0])
    assert "Traceback" not in result.stdout


def test_cut_last_row_is_a_warning_and_exit_0(files):
    """A log cut mid-row (a killed capture) is read without its partial row, with a note."""
    result = invoke("identify", files / "cut.csv", "--method", "ls")
    assert result.exit_code == 0, result.stderr
    assert "Traceback" not in result.stderr
    assert any("cut.csv" in line and "warning" in line for line in result.stderr.splitlines())


def test_the_sensors_extreme_readings_are_taken(files):
    """The range check's other branch: -2.0043 A (within the sensor's 2 A, one ADC step of
    3.9 mA and the firmware's half mA; -2.0045 A is refused above) and 2 A - one step are
    kept (exit 0)."""
    result = invoke("identify", files / "edge_current.csv", "--method", "ls")
    assert result.exit_code == 0, result.stderr


def test_validate_leaves_out_a_set_that_is_not_finite_and_scores_the_rest(files):
    """A params file with LS not finite (written with --force) and WLS finite: validate
    says LS is left out (a warning naming the file, method and parameter) and scores WLS."""
    result = invoke("validate", files.run, "--params", files / "params_nan_and_finite.yaml")
    assert result.exit_code == 0, result.stderr
    assert "methods.ls: ZZ1R = nan is not finite" in result.stderr and "left out" in result.stderr
    assert ":WLS" in result.stdout and ":LS " not in result.stdout


def test_validate_names_a_joint_without_a_usable_row(files, tmp_path):
    """The pan never moved: validate scores the tilt and says the pan has no usable row, in
    its table and its report (it called it passive, with an error of 0, before)."""
    page = tmp_path / "v.html"
    result = invoke("validate", files / "pan_still.csv", "--params", files.params, "--report", page)
    assert result.exit_code == 0, result.stderr
    rows = [x for x in result.stdout.splitlines() if "params.yaml:LS" in x]
    assert rows and all("no usable row" in x and "passive" not in x for x in rows), result.stdout
    assert "pan no usable row" in page.read_text()


def test_a_header_robot_source_is_found_beside_the_log(files, tmp_path):
    """A log whose header names its robot file relative to the log's folder (capture ran
    there) is identified from any working directory."""
    (tmp_path / "guard_b.yaml").write_text((files / "guard_b.yaml").read_text())
    sub = tmp_path / "sub"
    sub.mkdir()
    text = (files / "other.csv").read_text()
    (sub / "rel.csv").write_text(_header_robot(text, "guard_b", Path("../guard_b.yaml")))
    result = invoke("identify", sub / "rel.csv", "--method", "ls")
    assert result.exit_code == 0, result.stderr


def test_a_log_without_voltages_is_identified_without_the_motors(files):
    """The v_* columns are optional: no voltages, no R and Ke, exit 0."""
    result = invoke("identify", files / "no_voltage.csv", "--method", "ls")
    assert result.exit_code == 0, result.stderr
    assert "ZZ1R" in result.stdout and "motor pan" not in result.stdout


def test_never_moved_with_force_writes_and_warns(files):
    """--force reports and writes an untrusted identification, saying why on stderr."""
    out = files / "forced.yaml"
    result = invoke("identify", files / "still.csv", "--method", "ls", "--force", "-o", out)
    assert result.exit_code == 0, result.stderr
    assert "cannot be trusted" in result.stderr and "Fv1" in result.stderr
    written = yaml.safe_load(out.read_text())
    assert any("Fv1" in reason for reason in written["untrusted"])


def test_untrusted_identification_writes_nothing(files):
    out = files / "p_still_refused.yaml"
    result = invoke("identify", files / "still.csv", "--method", "ls", "-o", out)
    assert result.exit_code == 4
    assert not out.exists()


def test_identify_refuses_logs_of_different_robots_but_takes_two_runs_of_one(files, tmp_path):
    """Promise: identify refuses logs of different robots (and only those). A second run of
    the same robot with its own samples (the log cut to its second half) is accepted."""
    lines, rows = _data_lines(files.run.read_text())
    half = lines[: rows[0]] + lines[rows[len(rows) // 2] :]
    second = tmp_path / "second.csv"
    second.write_text("".join(half))
    ok = invoke("identify", files.run, second, "--method", "ls")
    refused = invoke("identify", files.run, files / "other.csv", "--method", "ls")
    refused_forced = invoke("identify", files.run, files / "other.csv", "--force")
    assert ok.exit_code == 0, ok.stderr
    assert refused.exit_code == 2
    assert refused.stderr.startswith(ERROR_PREFIX) and "guard_b" in refused.stderr
    assert refused_forced.exit_code == 2  # --force is for untrusted results, not wrong input


def test_the_real_entry_point_prints_one_line(files):
    """The same row through ``python -m guardid``: what a terminal shows."""
    proc = subprocess.run(
        [sys.executable, "-m", "guardid", "excite", "--robot", str(files / "garbage.yaml"),
         "-o", str(files / "x.yaml")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith(ERROR_PREFIX)
    assert "Traceback" not in proc.stderr


def test_the_header_period_is_the_firmware_tick_to_its_microsecond():
    """The firmware's INFO carries its tick in whole microseconds: a robot of 1/60 s
    (sample_period 0.0166667) reports 0.016667, which capture accepts (within 0.5 us) and
    identify must read; 0.03 against a 0.015 s tick is refused (the matrix above)."""
    from guardid.errors import LogFormatError
    from guardid.identify.runs import _sample_period

    header = {"sample_period_s": 0.0166667, "firmware": {"tick_period": 0.016667}}
    assert _sample_period("x.csv", header, None) == 0.0166667
    header = {"sample_period_s": 0.0166667, "firmware": {"tick_period": 0.016668}}
    with pytest.raises(LogFormatError, match="tick_period"):
        _sample_period("x.csv", header, None)


def test_a_folder_beside_the_log_does_not_hide_a_shipped_robot(files, tmp_path):
    """A log whose header names a shipped robot by name (``guard``, as simulate's logs do)
    in a folder that holds a folder of that name: the shipped robot, not the folder."""
    (tmp_path / "guard").mkdir()
    log = tmp_path / "run.csv"
    log.write_text(_header_robot(files.run.read_text(), "guard", Path("guard")))
    result = invoke("identify", log, "--method", "ls")
    assert result.exit_code == 0, result.stderr
