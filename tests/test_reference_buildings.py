"""Reference buildings beyond the default site's: one short (1 week) EnergyPlus run each, read as sensors."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pandas as pd
import pytest

from buildenv import catalogue as cat
from buildenv.energyplus.idf import of_type, read_idf
from buildenv.energyplus.reference import (
    _run_period_rows,
    detect_schedule_map,
    historical_settings,
    reference_idf,
    run_reference,
    serves_24h_space,
)

START = dt.date(2019, 11, 4)  # a Monday; Chicago in November: mild enough for the ASHRAE large office


def _check_run(run) -> None:
    assert run.temperature_c.shape == run.consumption_kwh.shape == (1, cat.HOURS_PER_WEEK)
    assert run.warmup_temperature_c.shape == (cat.HOURS_PER_WEEK,)
    hours = np.arange(cat.HOURS_PER_WEEK)
    occupied = (hours // 24 < 5) & (hours % 24 >= 9) & (hours % 24 < 17)  # weekdays 9-17 h
    t = run.temperature_c[0][occupied]
    assert np.all((t > 15.0) & (t < 30.0)), (t.min(), t.max())
    assert np.all(run.consumption_kwh > 0.0)
    assert run.floor_area_m2 > 10_000


def test_run_period_rows_drop_design_days_by_stamp():
    first = dt.date(2019, 1, 14)
    stamps = [f" 01/{d:02d}  {h:02d}:00:00" for d in (14, 15) for h in range(1, 25)]
    frame = pd.DataFrame(
        {"Date/Time": [" 01/01  01:00:00", *stamps[:30], " 07/21  01:00:00", *stamps[30:]], "x": np.arange(50)}
    )
    rows = _run_period_rows(frame, first, 48, "eplusout.csv")
    assert list(rows["Date/Time"]) == stamps
    with pytest.raises(Exception, match="expected 24 consecutive hours"):
        _run_period_rows(frame, dt.date(2019, 1, 16), 24, "eplusout.csv")


def test_data_centre_keeps_its_schedules():
    objects = read_idf(reference_idf("large_office_2019"))
    mapping = detect_schedule_map(objects)
    assert "HTGSETP_DC_SCH" not in mapping.heating_setpoint
    assert "CLGSETP_DC_SCH" not in mapping.cooling_setpoint
    data_centre = [o for o in of_type(objects, "Controller:OutdoorAir") if serves_24h_space(o)]
    assert len(data_centre) == 4  # the AirLoop DataCenter ... OA controllers
    offices = [o for o in of_type(objects, "Controller:OutdoorAir") if not serves_24h_space(o)]
    assert len(offices) == 4


@pytest.mark.parametrize("building", ["large_office", "large_office_2019"])
def test_reference_building_one_week(building):
    run = run_reference(building, "usa_il_chicago", START, historical_settings(1))
    _check_run(run)


def test_a_stand_in_is_sized_with_the_design_days_of_its_own_climate():
    from buildenv.energyplus.design_days import climate_design_days, design_conditions
    from buildenv.weather.epw import resolve_epw

    miami, chicago = design_conditions(resolve_epw("usa_fl_miami")), design_conditions(resolve_epw("usa_il_chicago"))
    phoenix = design_conditions(resolve_epw("usa_az_phoenix"))
    assert miami["heating"]["dry_bulb_c"] > chicago["heating"]["dry_bulb_c"] + 20  # a mild winter
    assert phoenix["cooling"]["dry_bulb_c"] > miami["cooling"]["dry_bulb_c"]  # a hotter summer...
    assert phoenix["cooling"]["dew_point_c"] < miami["cooling"]["dew_point_c"] - 5  # ...and a drier one
    assert (
        -23 < chicago["heating"]["dry_bulb_c"] < -18 and 30 < chicago["cooling"]["dry_bulb_c"] < 34
    )  # ASHRAE: -20.6, 31.2

    objects = read_idf(reference_idf("medium_office"))  # a Chicago model
    assert climate_design_days(objects, resolve_epw("usa_il_chicago")) is objects  # its own climate: unchanged
    moved = climate_design_days(objects, resolve_epw("usa_fl_miami"))
    assert "Miami" in of_type(moved, "Site:Location")[0][1]
    days = of_type(moved, "SizingPeriod:DesignDay")
    assert [(d[4], float(d[5])) for d in days] == [
        ("WinterDesignDay", miami["heating"]["dry_bulb_c"]),
        ("SummerDesignDay", miami["cooling"]["dry_bulb_c"]),
    ]
