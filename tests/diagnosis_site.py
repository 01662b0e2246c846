"""The default site as the gap diagnosis' tests diagnose it.

Its history with the supply air at 19 degC (the shipped site now records what its air loops supply) and its
calibration by the diagnosis' metamodel (``load_metamodel("diagnosis")``), in a temporary copy.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from buildenv.env.building_week import DEFAULT_SITE as SHIPPED_SITE

FIXTURES = Path(__file__).parent / "fixtures"


def diagnosis_default_site() -> Path:
    """A temporary copy of the default site with its history and calibration as the diagnosis measured them."""
    folder = Path(tempfile.mkdtemp(prefix="buildenv-diagnosis-site-")) / "default"
    shutil.copytree(SHIPPED_SITE, folder)
    shutil.copy(FIXTURES / "default_site_settings_diagnosis.csv", folder / "settings.csv")
    shutil.copy(FIXTURES / "default_site_calibration_diagnosis.json", folder / "calibration.json")
    return folder


DEFAULT_SITE = diagnosis_default_site()
