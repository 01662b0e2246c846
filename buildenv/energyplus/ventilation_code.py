"""ASHRAE 62.1's minimum outdoor air for offices, in the unit of the catalogue's ``ventilation_ach``."""

from __future__ import annotations

from buildenv.energyplus.shoebox import FLOOR_HEIGHT_M

#: ASHRAE 62.1 ventilation rate procedure, office space: outdoor air per person (L/s) and per floor area (L/s m2)
OFFICE_OUTDOOR_AIR_L_S = (2.5, 0.3)


def code_minimum_ventilation_ach(occupants_per_m2: float) -> float:
    """Outdoor air (air changes per hour of a storey :data:`~buildenv.energyplus.shoebox.FLOOR_HEIGHT_M` high, the
    unit of ``ventilation_ach``) that ASHRAE 62.1 requires in an office with ``occupants_per_m2`` people per m2:
    ``(2.5 L/s x occupants_per_m2 + 0.3 L/s per m2) x 3.6 / height``."""
    per_person, per_area = OFFICE_OUTDOOR_AIR_L_S
    return (per_person * float(occupants_per_m2) + per_area) * 3.6 / FLOOR_HEIGHT_M
