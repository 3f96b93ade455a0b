"""guardid: host-side bridge and dynamic identification toolkit for the guard robot."""

__version__ = "0.1.0"
