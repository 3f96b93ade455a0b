"""Reports a person reads: one self-contained HTML page per identification or validation.

:func:`identification_report` and :func:`validation_report` return the page as a string;
:func:`write_report` writes it without overwriting anything but a previous report.
Figures are inline SVG drawn with matplotlib (the ``plot`` extra); nothing is fetched.
"""

from guardid.report.html import (
    SECTIONS,
    ReportInputs,
    identification_report,
    validation_report,
    write_report,
)

__all__ = [
    "SECTIONS",
    "ReportInputs",
    "identification_report",
    "validation_report",
    "write_report",
]
