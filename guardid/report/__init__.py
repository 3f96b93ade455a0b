"""Reports a person reads: one self-contained HTML page per identification or validation.

:func:`identification_report` and :func:`validation_report` return the page as a string;
:func:`write_report` writes it without overwriting anything but a previous report.
Figures are inline SVG drawn with matplotlib (the ``plot`` extra); nothing is fetched.
``identify --plot``'s PNG is :mod:`guardid.report.png`; long series are thinned by
:mod:`guardid.report.series`.
"""

from __future__ import annotations

from guardid._lazy import lazy_attributes

_LAZY = {  # loaded on first use: a command that reads one constant of series.py loads no page
    "SECTIONS": "html",
    "ReportInputs": "html",
    "identification_report": "html",
    "validation_report": "html",
    "write_report": "html",
}

__getattr__ = lazy_attributes(__name__, _LAZY)

__all__ = [
    "SECTIONS",
    "ReportInputs",
    "identification_report",
    "validation_report",
    "write_report",
]
