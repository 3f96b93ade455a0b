"""User-facing errors: one line, names the file, field or port, exits non-zero."""


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


class LinkError(GuardidError):
    """The serial link failed (missing port, disconnect, protocol mismatch)."""

    exit_code = 3
