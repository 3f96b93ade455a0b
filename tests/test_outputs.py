"""The one output rule (guardid.commands.outputs): refused when existing unless --force,
checked writable before any work, written to a temporary file and renamed into place when
complete; a full disk or a read-only file system is one line and leaves nothing behind.

Disk full is made two ways: a write that fails with ENOSPC half-way (monkeypatched, runs
everywhere) and, where this process may mount one (root), a real 64 KiB tmpfs filled up.
"""

from __future__ import annotations

import errno
import os
import re
import shlex
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml
from badinput_tools import ERROR_PREFIX, invoke, short_capture
from capturetools import gentle_trajectory, witnessed

from guardid.commands import outputs
from guardid.robot.loader import shipped_path

REPO = Path(__file__).resolve().parent.parent


def _files(d: Path) -> dict[str, bytes]:
    """Every file under ``d`` (hidden temporary files too) -> its bytes."""
    return {str(p.relative_to(d)): p.read_bytes() for p in sorted(d.rglob("*")) if p.is_file()}


def _one_error(res, code: int, *words) -> str:
    assert res.exception is None or isinstance(res.exception, SystemExit), res.exception
    assert res.exit_code == code, (res.exit_code, res.stderr)
    lines = [x for x in res.stderr.splitlines() if not x.startswith(("warning: ", "guardid: w"))]
    assert len(lines) == 1 and lines[0].startswith(ERROR_PREFIX), res.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


@pytest.fixture(scope="module")
def a_run(tmp_path_factory):
    return short_capture(tmp_path_factory.mktemp("outputs"), seconds=10)


class FullDisk:
    """``open`` for guardid.commands.outputs whose files take ``room`` bytes, then fail
    with ENOSPC (as a full file system does: a short write, then the error); only files
    whose name ends with ``suffix``, when given (the disk fills at that file)."""

    def __init__(self, room: int, suffix: str = "") -> None:
        self.room, self.suffix = room, suffix

    def __call__(self, path, mode="r", **kwargs):
        f = open(path, mode, **kwargs)  # noqa: SIM115
        if not str(path).endswith(self.suffix):
            return f
        room = self.room

        class Full:
            def __enter__(self):
                return self

            def __exit__(self, *exc):
                f.close()

            def write(self, text):
                f.write(text[:room])
                f.flush()
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

            def flush(self):
                f.flush()

        return Full()


def test_identify_on_a_full_disk_is_one_line_and_leaves_nothing(tmp_path, a_run, monkeypatch):
    """Was: a traceback after the whole fit and a zero-byte params.yaml."""
    monkeypatch.setattr(outputs, "open", FullDisk(100), raising=False)
    out = tmp_path / "params.yaml"
    res = invoke("identify", a_run, "--method", "ls", "-o", out)
    _one_error(res, 2, "-o", "params.yaml", "cannot write", "No space left on device")
    assert _files(tmp_path) == {}  # no params.yaml, no temporary file
    out.write_text("kept\n")  # an existing file, replaced only when complete
    res = invoke("identify", a_run, "--method", "ls", "-o", out, "--force")
    _one_error(res, 2, "No space left on device")
    assert _files(tmp_path) == {"params.yaml": b"kept\n"}


@pytest.mark.parametrize("fills_at", ["", ".urdf", ".xml"])
def test_export_on_a_full_disk_then_again_when_there_is_room(tmp_path, monkeypatch, fills_at):
    """Was: zero-byte files, and a rerun refused them ('exists'). The disk fills at the
    first file (the side YAML), the URDF or the MJCF: no file at all is left (a side YAML
    alone would make the rerun refuse it)."""
    urdf = tmp_path / "r.urdf"
    monkeypatch.setattr(outputs, "open", FullDisk(0, fills_at), raising=False)
    res = invoke("export", "--robot", "guard", "--urdf", urdf, "--mjcf", tmp_path / "r.xml")
    _one_error(res, 2, "No space left on device")
    assert _files(tmp_path) == {}
    monkeypatch.undo()
    res = invoke("export", "--robot", "guard", "--urdf", urdf, "--mjcf", tmp_path / "r.xml")
    assert res.exit_code == 0, res.stderr
    assert set(_files(tmp_path)) == {"r.urdf", "r.guardid.yaml", "r.xml"}
    assert urdf.read_text().startswith("<?xml") or "<robot" in urdf.read_text()


@pytest.fixture
def tiny_tmpfs(tmp_path):
    """A 64 KiB tmpfs at tmp_path/fs (skipped where this process may not mount)."""
    mnt = tmp_path / "fs"
    mnt.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(mnt)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_real_full_file_system(tiny_tmpfs):
    """A tmpfs filled to its last bytes: export fails in one line, leaves no file, and
    succeeds once there is room (nothing left behind refuses the rerun)."""
    filler = tiny_tmpfs / "filler"
    with open(filler, "wb", buffering=0) as f:
        try:
            while True:
                f.write(b"x" * 512)
        except OSError as exc:
            assert exc.errno == errno.ENOSPC
    before = _files(tiny_tmpfs)
    urdf = tiny_tmpfs / "r.urdf"
    res = invoke("export", "--robot", "guard", "--urdf", urdf)
    _one_error(res, 2, "--urdf", str(tiny_tmpfs), "No space left on device")
    assert _files(tiny_tmpfs) == before  # no zero-byte r.urdf, no temporary file
    filler.unlink()
    res = invoke("export", "--robot", "guard", "--urdf", urdf)
    assert res.exit_code == 0, res.stderr
    assert urdf.stat().st_size > 1000


def test_read_only_file_system_is_found_before_any_work(tmp_path, monkeypatch):
    """identify -o on a read-only file system (was: found only after the whole fit): the
    error names -o, before the log is even read (here a log that is not one)."""

    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    monkeypatch.setattr(outputs.tempfile, "mkstemp", read_only)
    garbage = tmp_path / "garbage.csv"
    garbage.write_bytes(bytes(range(256)))
    res = invoke("identify", garbage, "-o", tmp_path / "p.yaml")
    _one_error(res, 2, "-o", "p.yaml", "Read-only file system")


def test_capture_output_checked_before_the_robot_is_contacted(tmp_path, monkeypatch):
    def read_only(*args, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    traj = gentle_trajectory(tmp_path / "t.yaml")
    monkeypatch.setattr(outputs.tempfile, "mkstemp", read_only)
    with witnessed() as robots:
        res = invoke("capture", "--trajectory", traj, "--duration", "1", "-o", tmp_path / "r.csv")
    _one_error(res, 2, "-o", "r.csv", "Read-only file system")
    assert robots == []  # no port opened
    assert not (tmp_path / "r.csv").exists()


def test_written_file_has_the_usual_mode_and_keeps_a_replaced_files(tmp_path):
    """The temporary file (mode 0600) is renamed into place: the result gets the mode a
    plain open would give (0666 less the umask), or the mode of the file it replaces."""
    old = os.umask(0o022)
    try:
        new = tmp_path / "t.yaml"
        assert invoke("excite", "--no-optimise", "-o", new).exit_code == 0
        assert stat.S_IMODE(new.stat().st_mode) == 0o644
        new.chmod(0o640)
        assert invoke("excite", "--no-optimise", "-o", new, "--force").exit_code == 0
        assert stat.S_IMODE(new.stat().st_mode) == 0o640
    finally:
        os.umask(old)


def test_force_onto_a_device_writes_through_it(tmp_path):
    """-o /dev/null --force writes into the device; /dev/null stays a device (renaming a
    temporary file onto it, as root, would have replaced it)."""
    res = invoke("excite", "--no-optimise", "-o", "/dev/null", "--force")
    assert res.exit_code == 0, res.stderr
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_force_onto_a_symlink_replaces_the_file_it_names(tmp_path):
    target = tmp_path / "real.yaml"
    target.write_text("old\n")
    link = tmp_path / "link.yaml"
    link.symlink_to(target)
    assert invoke("excite", "--no-optimise", "-o", link, "--force").exit_code == 0
    assert link.is_symlink() and target.read_text().startswith("kind: fourier")


def test_same_wording_for_every_option(tmp_path):
    """Every command refuses an existing output with EXISTS's words (and only those)."""
    existing = tmp_path / "x"
    existing.write_text("keep\n")
    runs = {
        "-o": invoke("excite", "--no-optimise", "-o", existing),
        "--urdf": invoke("export", "--robot", "guard", "--urdf", existing),
    }
    for option, res in runs.items():
        line = _one_error(res, 2)
        assert line == ERROR_PREFIX + outputs.EXISTS.format(option=option, path=existing)
    assert existing.read_text() == "keep\n"


def _user_robot_params(tmp_path) -> Path:
    """A params file (with a consistent fit) of a user's robot 'my_arm' whose YAML is gone:
    the file stores the description; only the name would not find it."""
    from test_export_urdf import identified

    from guardid.physical.report import yaml_section

    _, fit = identified("guard")
    raw = yaml.safe_load(shipped_path("guard").read_text())
    raw["name"] = "my_arm"
    params = {"guardid-params": 1, "robot": "my_arm", "robot_description": raw,
              "base_parameters": [], "methods": {}, "consistent": yaml_section(fit)}  # fmt: skip
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(params, sort_keys=False))
    return path


def test_export_uses_the_description_stored_in_the_params_file(tmp_path):
    """Was: 'my_arm: no such robot file' (the robot looked up by name)."""
    params = _user_robot_params(tmp_path)
    res = invoke("export", params, "--urdf", tmp_path / "a.urdf", "--mjcf", tmp_path / "a.xml")
    assert res.exit_code == 0, res.stderr
    assert '<robot name="my_arm"' in (tmp_path / "a.urdf").read_text()


def test_mjcf_comment_prints_a_plain_number():
    """A friction offset from an identified model (a numpy float) was printed in the MJCF
    comment as np.float64(0.029)."""
    from dataclasses import replace

    from guardid.export import mjcf_text
    from guardid.robot import load_robot

    desc = load_robot("guard")
    joint = desc.joints[0]
    friction = replace(joint.friction, offset=np.float64(0.029), offset_modelled=True)
    desc = replace(desc, joints=(replace(joint, friction=friction), *desc.joints[1:]))
    text = mjcf_text(desc)
    assert "friction offset 0.029 N m of pan" in text
    assert "np." not in text


def test_a_disk_error_starts_on_its_own_line_after_the_progress(tmp_path, monkeypatch):
    """Was: 'rows ... tracking rms ...guardid: error: ...' on one line."""
    from guardid.log import LogWriter

    calls = []

    def write(fd, data):
        data = bytes(data)
        if data[:1].isdigit():
            calls.append(1)
            if len(calls) > 30:
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return os.write(fd, data)

    monkeypatch.setattr(LogWriter, "_write", staticmethod(write))
    traj = gentle_trajectory(tmp_path / "t.yaml")
    res = invoke("capture", "--trajectory", traj, "--duration", "2", "-o", tmp_path / "r.csv")
    assert res.exit_code == 2, res.stderr
    last = res.stderr.split("\n")[-2]  # the text ends with a newline
    assert last.startswith(ERROR_PREFIX) and "No space left on device" in last, res.stderr
    assert res.stderr.count(ERROR_PREFIX) == 1


def test_a_link_error_starts_on_its_own_line_after_the_progress(tmp_path):
    """A port that vanishes mid-capture: the progress line is ended first, then one error
    line (exit 3) saying how many rows were kept."""
    traj = gentle_trajectory(tmp_path / "t.yaml")
    port = "sim://guard?disconnect_s=1"
    res = invoke("capture", "--trajectory", traj, "--duration", "5", "--port", port,
                 "-o", tmp_path / "r.csv")  # fmt: skip
    assert res.exit_code == 3, res.stderr
    lines = res.stderr.split("\n")
    assert lines[-1] == "" and lines[-2].startswith(ERROR_PREFIX), res.stderr
    assert "disconnected" in lines[-2] and "rows kept in" in lines[-2]
    assert res.stderr.count(ERROR_PREFIX) == 1 and lines[-3].startswith("\rrows")


def _readme_job() -> str:
    """The README's main job without its venv set-up, for this interpreter; shortened (the
    starting guess, 10 s, least squares) where only the time it takes changes."""
    text = (REPO / "README.md").read_text()
    line = next(x.strip() for x in text.splitlines() if "guardid excite" in x and "&&" in x)
    job = line.split("pip install -q -e . && ", 1)[1]
    job = job.replace(".venv/bin/guardid", f"{shlex.quote(sys.executable)} -m guardid")
    shorter = (
        ("--duration 60", "--duration 10"),
        ("excite -o", "excite --no-optimise -o"),
        ("-o $d/params.yaml", "--method ls -o $d/params.yaml"),
    )
    for long, short in shorter:
        assert long in job, long
        job = job.replace(long, short)
    return job


def test_readme_main_job_runs_twice_into_its_own_folders(tmp_path):
    """Run twice in a row, the README's line gives a result each time, in out/<time>/
    (ignored by git), and creates nothing else."""
    job = _readme_job()
    assert "mkdir -p out" in job
    for _ in range(2):
        done = subprocess.run(["bash", "-c", job], cwd=tmp_path, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
    runs = sorted((tmp_path / "out").iterdir())
    assert [p.name for p in tmp_path.iterdir()] == ["out"]
    assert len(runs) == 2 and all(re.fullmatch(r"\d{8}T\d{6}", p.name) for p in runs)
    for run in runs:
        assert sorted(p.name for p in run.iterdir()) == ["params.yaml", "run.csv", "traj.yaml"]
    assert "/out/" in (REPO / ".gitignore").read_text().split()


def test_capture_room_estimate_covers_a_real_row(a_run):
    """capture's free-space check (--duration 1e9: terabytes, refused before anything
    moves) estimates a row's bytes from above: every row of a real log fits it."""
    from guardid.commands.capture import ROW_BYTES_BASE, ROW_BYTES_PER_JOINT

    rows = [x for x in a_run.read_text().splitlines(keepends=True) if x[:1].isdigit()]
    assert len(rows) > 600
    widest = max(len(x.encode()) for x in rows)
    assert widest + 8 <= ROW_BYTES_BASE + 2 * ROW_BYTES_PER_JOINT  # + room for longer ticks


def test_cv_with_an_output_is_refused_before_any_work(tmp_path, a_run):
    """identify --cv prints the held-out table only: -o / --plot / --report with it were
    accepted and silently never written (exit 0, no file)."""
    out = tmp_path / "p.yaml"
    other = tmp_path / "seed5.csv"  # a second run of the same robot
    traj = Path(a_run).parent / "traj.yaml"
    res = invoke("capture", "--port", "sim://guard?seed=5", "--trajectory", traj,
                 "--duration", 10, "--quiet", "-o", other)  # fmt: skip
    assert res.exit_code == 0, res.output
    res = invoke("identify", "--cv", a_run, other, "--method", "ls", "-o", out)
    _one_error(res, 2, "--cv", "-o")
    assert not out.exists() and "held-out run" not in res.stdout


@pytest.mark.parametrize("option", ["-o", "--plot", "--report"])
def test_an_empty_output_name_is_refused(tmp_path, a_run, option):
    """`-o "$OUT"` with an empty $OUT: identify ran, exit 0, and wrote nothing (an empty
    name was taken as no output); now one line before any work, and nothing written."""
    res = invoke("identify", a_run, "--method", "ls", option, "")
    _one_error(res, 2, option, "empty file name")
    assert "parameter" not in res.stdout  # refused before the fit
    assert _files(tmp_path) == {}
