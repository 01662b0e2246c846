"""Sites: a measured building (or a reference-office stand-in) as a folder. :mod:`.model` holds the
:class:`Site` and the format's names, :mod:`.reader` loads and validates a folder, :mod:`.writer` writes one
(and a calibration), :mod:`.week_simulator` turns a calibrated site into a week simulator."""

from buildenv.sites.model import MEASUREMENT_COLUMNS, SETTINGS_COLUMNS, Site
from buildenv.sites.reader import known_parameter, load_site
from buildenv.sites.writer import save_calibration, write_site

__all__ = [
    "MEASUREMENT_COLUMNS",
    "SETTINGS_COLUMNS",
    "Site",
    "known_parameter",
    "load_site",
    "save_calibration",
    "write_site",
]
