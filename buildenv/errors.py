"""Errors a user can act on.

Every error the toolkit raises on bad input is a subclass of :class:`BuildenvError` and carries a one-line
message saying what is wrong, where (file:line, variable name) and, when it helps, how to fix it.
"""

from __future__ import annotations


class BuildenvError(Exception):
    """Base class of every error buildenv raises on bad input or a failed simulation."""


class CatalogueError(BuildenvError, KeyError):
    """A variable name is unknown or a value lies outside the catalogue range."""

    def __str__(self) -> str:  # KeyError would otherwise quote the message
        return str(self.args[0]) if self.args else ""


class WeatherError(BuildenvError):
    """A weather file is missing, unreadable or not hourly."""


class SimulationError(BuildenvError):
    """EnergyPlus stopped with a severe or fatal error."""


class ReferenceBuildingError(BuildenvError):
    """A reference building cannot be found, mapped or run."""


class DatasetError(BuildenvError):
    """A dataset directory is missing, incomplete or made for another catalogue."""


class NonFiniteError(BuildenvError, ValueError):
    """A result holds NaN or an infinity where a number is due (the message names which value)."""


class SiteError(BuildenvError):
    """A site folder (site.toml, measurements.csv, settings.csv, ...) is missing or invalid."""


class BuildingEnvError(BuildenvError, ValueError):
    """BuildingWeek-v0 was given an unknown argument, a bad action or a site it cannot run."""
