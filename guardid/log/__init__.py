"""The capture log: CSV with a commented YAML header and footer (format in docs/LOG_FORMAT.md)."""

from guardid.log.csvlog import LogWriteError, LogWriter, column_names
from guardid.log.reader import LogData, read_log

__all__ = ["LogData", "LogWriteError", "LogWriter", "column_names", "read_log"]
