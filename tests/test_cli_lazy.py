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
