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
        "print('LOADED', 'scipy.optimize' in sys.modules, 'guardid.excitation' in sys.modules,\n"
        "      sorted(m for m in sys.modules if m.startswith(('scipy', 'matplotlib'))))\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "LOADED False True []"  # no scipy at all
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


UNUSED_BY_HELP = ("scipy.signal", "scipy.stats", "scipy.interpolate", "matplotlib", "pinocchio")
"""What no command's --help needs (scipy.signal alone is about 75 MiB of memory and 0.6 s)."""


def _loaded_unused(calls) -> str:
    """Run the guardid command lines ``calls`` in one fresh process, in turn; the last line
    printed: after each call, the modules of :data:`UNUSED_BY_HELP` loaded so far."""
    probe = "import sys\nfrom guardid.cli import main\nseen = []\n"
    for args in calls:
        probe += (
            f"try:\n    main({args!r}, prog_name='guardid')\n"
            "except SystemExit as e:\n    assert not e.code, e.code\n"
            f"seen.append(({args[0]!r}, sorted(m for m in sys.modules\n"
            f"                                  if m.startswith({UNUSED_BY_HELP!r}))))\n"
        )
    probe += "print('LOADED', [x for x in seen if x[1]])\n"
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return done.stdout.strip().splitlines()[-1]


def test_no_command_help_loads_signal_processing_or_plotting():
    """``guardid CMD --help``, every command in turn in one process, imports only what the
    help needs (issue 30 item 4): excite's once loaded scipy.signal, scipy.stats and
    scipy.interpolate for one constant (about 75 MiB of memory)."""
    assert _loaded_unused([[name, "--help"] for name, *_ in COMMANDS]) == "LOADED []"


def test_excite_runs_without_signal_processing(tmp_path):
    """``guardid excite`` makes a trajectory (scipy.linalg; scipy.optimize when it
    optimises) and loads no scipy.signal, scipy.stats or scipy.interpolate (issue 30 item 4)."""
    out = tmp_path / "traj.yaml"
    assert _loaded_unused([["excite", "--no-optimise", "-o", str(out)]]) == "LOADED []"
    assert out.stat().st_size > 0
