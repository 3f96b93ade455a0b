"""User-facing errors: one line, names the file, field or port, exits non-zero."""

import sys
import warnings


class GuardidError(Exception):
    """An error caused by user input or the environment, shown as a single line.

    The CLI catches it, prints ``guardid: error: <message>`` to stderr and exits
    with :attr:`exit_code`; no traceback is shown.
    """

    exit_code = 2


class ConfigError(GuardidError):
    """A robot description or other configuration file is invalid."""


class LogFormatError(GuardidError):
    """A log file cannot be read."""


class GuardidWarning(UserWarning):
    """Something tolerated that the user should know of; the CLI shows it as one line,
    ``guardid: warning: <message>``."""


class LogWarning(GuardidWarning):
    """A log was read with something left out (a last row cut by a killed writer)."""


class LinkError(GuardidError):
    """The serial link failed (missing port, disconnect, protocol mismatch)."""

    exit_code = 3


class UntrustedResult(GuardidError):
    """A result was computed but cannot be trusted (e.g. an unexcited regressor); nothing
    is written unless the user insists (``--force``)."""

    exit_code = 4


def report_errors(call, *args, **kwargs):
    """Run ``call``; a :class:`GuardidError` becomes ``guardid: error: ...`` on stderr and
    ``sys.exit(exit_code)`` (no traceback). Used by the CLI's group and standalone commands."""
    with warnings.catch_warnings():
        warnings.simplefilter("always", GuardidWarning)
        shown = warnings.showwarning

        def show(message, category, *rest, **kw):
            if issubclass(category, GuardidWarning):
                sys.stderr.write(f"guardid: warning: {message}\n")
            else:
                shown(message, category, *rest, **kw)

        warnings.showwarning = show
        try:
            return call(*args, **kwargs)
        except GuardidError as exc:
            sys.stderr.write(f"guardid: error: {exc}\n")
            sys.exit(exc.exit_code)
