"""The command line answers ``--help`` without importing the numerical stack.

No timing here (speed is not asserted in tests): what is checked is what makes it fast,
that listing the commands imports none of numpy, scipy or matplotlib, and that the listing's
short help is each command's own.
"""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

from guardid.commands import COMMANDS

HEAVY = ("numpy", "scipy", "matplotlib", "yaml")  # pyserial is light: sim:// registers on import


def _modules_after(code: str) -> set[str]:
    probe = (
        "import sys\n"
        f"{code}\n"
        "print('MODULES', ' '.join(sorted(m.split('.')[0] for m in sys.modules)))\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    last = done.stdout.strip().splitlines()[-1].split()
    assert last[0] == "MODULES"
    return set(last[1:])


def test_group_help_imports_no_heavy_module():
    loaded = _modules_after(
        "from guardid.cli import main\n"
        "try:\n    main(['--help'], prog_name='guardid')\nexcept SystemExit:\n    pass"
    )
    assert not loaded & set(HEAVY), loaded & set(HEAVY)


def test_unknown_command_is_one_usage_error_without_heavy_imports():
    done = subprocess.run(
        [sys.executable, "-m", "guardid", "idnetify"], capture_output=True, text=True
    )
    assert done.returncode == 2 and "No such command 'idnetify'" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize(("name", "module", "attr", "short"), COMMANDS)
def test_listed_short_help_is_the_commands_own(name, module, attr, short):
    command = getattr(importlib.import_module(module), attr)
    assert command.name == name
    assert command.help.strip().splitlines()[0] == short


def test_every_command_is_listed_in_help():
    done = subprocess.run(
        [sys.executable, "-m", "guardid", "--help"], capture_output=True, text=True
    )
    assert done.returncode == 0
    for name, *_ in COMMANDS:
        assert f"  {name} " in done.stdout


def test_a_missing_log_is_one_line_without_heavy_imports(tmp_path):
    missing = tmp_path / "nope.csv"
    loaded = _modules_after(
        "from guardid.cli import main\n"
        f"try:\n    main(['identify', {str(missing)!r}], prog_name='guardid')\n"
        "except SystemExit:\n    pass"
    )
    numeric = {"numpy", "scipy", "matplotlib"}  # the command module itself may load yaml
    assert not loaded & numeric, loaded & numeric
    done = subprocess.run(
        [sys.executable, "-m", "guardid", "identify", str(missing)], capture_output=True, text=True
    )
    assert done.returncode == 2
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("guardid: error:") and "nope.csv" in lines[0]


def test_capture_imports_no_optimiser(gap_guard_captures, tmp_path):
    """``capture`` runs without scipy.optimize (0.25-0.5 s of imports it never uses; issue
    30): the trajectory is read and run, the optimiser is the ``excite`` command's."""
    traj = gap_guard_captures[1].parent / "traj.yaml"  # the session's (read only)
    probe = (
        "import sys\n"
        "from guardid.cli import main\n"
        f"args = ['capture', '--trajectory', {str(traj)!r}, '--duration', '0.3', '--quiet',\n"
        f"        '-o', {str(tmp_path / 'log.csv')!r}]\n"
        "try:\n    main(args, prog_name='guardid')\nexcept SystemExit as e:\n"
        "    assert not e.code, e.code\n"
        "print('LOADED', 'scipy.optimize' in sys.modules, 'guardid.excitation' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "LOADED False True"
    assert (tmp_path / "log.csv").stat().st_size > 0


@pytest.mark.parametrize(("given", "threads"), [(None, 1), ("2", 2)])
def test_a_command_runs_one_blas_thread_unless_told(given, threads):
    """The command line sets one BLAS thread before numpy loads (issue 30: the forked
    tracker and the fit of ``identify`` then do not fight over the cores); a value in the
    environment wins."""
    import os

    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS",
                                                             "OMP_NUM_THREADS")}  # fmt: skip
    if given is not None:
        env["OPENBLAS_NUM_THREADS"] = given
    probe = (  # a command (here --help) first, numpy after it, as a command loads it
        "from guardid.cli import main\n"
        "try:\n    main(['--help'], prog_name='guardid')\nexcept SystemExit:\n    pass\n"
        "import numpy, threadpoolctl\n"
        "info = [i for i in threadpoolctl.threadpool_info() if i['user_api'] == 'blas']\n"
        "print('THREADS', info[0]['num_threads'])\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          env=env)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == f"THREADS {threads}"
