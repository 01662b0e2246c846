"""The ``[measurements]`` options of ``site.toml`` as read: how ``measurements.csv`` departs from the conventions.

:class:`_MeasurementOptions` is what :mod:`buildenv.sites.reader` builds from ``site.toml`` and what
:mod:`.measurements`, :mod:`.timestamps` and :mod:`.consumption` read: the file, the clock's time zone, end-of-hour
stamps, a cumulative register, and where the table is (for messages).
"""

from __future__ import annotations

import zoneinfo
from dataclasses import dataclass

from buildenv.sites.model import DEFAULT_MEASUREMENTS


@dataclass(frozen=True)
class _MeasurementOptions:
    """How ``measurements.csv`` departs from the conventions (``[measurements]`` of ``site.toml``)."""

    file: str = DEFAULT_MEASUREMENTS
    time_zone: zoneinfo.ZoneInfo | None = None
    stamped_end: bool = False
    cumulative: bool = False
    where: str = ""  # "<site.toml>:<line>" of the table, for messages
