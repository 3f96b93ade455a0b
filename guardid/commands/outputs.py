"""Output files of the commands (capture, identify, simulate): never one of the inputs,
and (capture) never an existing recording unless --force."""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

from guardid.errors import ConfigError


def same_file(a, b) -> bool:
    """True when paths ``a`` and ``b`` name the same file (hard or symbolic links
    included; for paths that do not exist yet, the same resolved path)."""
    pa, pb = Path(a), Path(b)
    try:
        return os.path.samefile(pa, pb)
    except OSError:  # one of them does not exist (yet)
        return pa.resolve() == pb.resolve()


def check_output(
    output,
    inputs: Iterable[tuple[str, object]],
    option: str = "-o",
    force: bool | None = None,
) -> None:
    """ConfigError naming ``option`` when ``output`` is one of ``inputs`` (pairs of the
    input's option name and path; None paths are skipped), or when it exists and ``force``
    is False (``force`` None: existing files may be replaced, as for derived results)."""
    if output is None:
        return
    for name, path in inputs:
        if path is not None and same_file(output, path):
            raise ConfigError(
                f"{option} {output}: is also the input {name} {path}; choose another output file"
            )
    if force is False and os.path.lexists(output):
        raise ConfigError(
            f"{option} {output}: already exists; a recorded log is never replaced "
            "(choose another name, or give --force to replace it)"
        )


def robot_file(robot) -> str | None:
    """``--robot``'s value when it names an existing file (not a shipped robot), else None."""
    return str(robot) if robot and Path(str(robot)).is_file() else None
