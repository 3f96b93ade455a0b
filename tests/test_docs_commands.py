"""docs/commands/*.md, the command reference, cannot drift from the click definitions: the
pages are what ``python -m guardid.docs`` makes of them, and every option that ``guardid
CMD --help`` prints is on its command's page."""

from __future__ import annotations

import re

import pytest
from click.testing import CliRunner

from guardid.cli import main
from guardid.commands import COMMANDS
from guardid.docs import COMMANDS_DIR, stale
from guardid.docs import main as docs_main


def test_the_command_pages_are_the_generated_ones():
    assert stale() == [], "docs/commands is stale: run python -m guardid.docs"


@pytest.mark.parametrize("name", [c[0] for c in COMMANDS])
def test_every_option_of_help_is_on_the_page(name):
    res = CliRunner().invoke(main, [name, "--help"], terminal_width=200)
    assert res.exit_code == 0, res.output
    options = set(re.findall(r"^\s+(-{1,2}[a-z][\w-]*)", res.output, flags=re.M))
    assert "--help" in options
    page = (COMMANDS_DIR / f"{name}.md").read_text()
    documented = set(re.findall(r"^\| `(-{1,2}[a-z][\w-]*)", page, flags=re.M))
    documented |= set(re.findall(r"^\| `-\w, (--[a-z][\w-]*)", page, flags=re.M))
    assert options <= documented, sorted(options - documented)


def test_check_names_a_stale_page(tmp_path, monkeypatch, capsys):
    import guardid.docs as docs

    monkeypatch.setattr(docs, "COMMANDS_DIR", tmp_path)
    monkeypatch.setattr(docs, "DOCS", tmp_path.parent)
    assert docs_main([]) == 0  # writes the pages into tmp_path
    assert docs_main(["--check"]) == 0
    page = tmp_path / "identify.md"
    page.write_text(page.read_text().replace("--cutoff", "--cut-off"))
    (tmp_path / "gone.md").write_text("a command that no longer exists\n")
    capsys.readouterr()
    assert docs_main(["--check"]) == 1
    out = capsys.readouterr().out
    assert "identify.md" in out and "gone.md" in out and "README.md" not in out
