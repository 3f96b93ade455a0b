"""A package's names loaded from their submodules on first use (PEP 562 ``__getattr__``):
importing the package, or one light constant of it, then loads nothing heavy."""

from __future__ import annotations

import importlib


def lazy_attributes(package: str, source: dict[str, str]):
    """The module ``__getattr__`` of ``package``: name -> its submodule in ``source``."""

    def __getattr__(name):
        if name in source:
            return getattr(importlib.import_module(f"{package}.{source[name]}"), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
