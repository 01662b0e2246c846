"""Reading an EnergyPlus Schedule:Compact day by day."""

from __future__ import annotations

import numpy as np
import pytest

from buildenv.energyplus.compact_schedules import daily_means, steady_copy
from buildenv.errors import ReferenceBuildingError

SCHEDULE = [
    "Schedule:Compact",
    "office",
    "Fraction",
    "Through: 1/31",
    "For: Weekdays SummerDesignDay",
    "Until: 06:00",
    "0.2",
    "Until: 18:00",
    "1.0",
    "Until: 24:00",
    "0.2",
    "For WinterDesignDay",  # EnergyPlus accepts the keyword without its colon
    "Until: 24:00",
    "0",
    "For: AllOtherDays",
    "Until: 24:00",
    "0.1",
    "Through: 12/31",
    "For: AllDays",
    "Interpolate:No",
    "Until: 24:00",
    "0.5",
]


def test_each_day_takes_its_periods_clause_weighted_by_the_hours():
    days = daily_means(SCHEDULE, 2019)  # 1 January 2019 is a Tuesday
    assert len(days) == 365
    weekday = (6 * 0.2 + 12 * 1.0 + 6 * 0.2) / 24
    assert days[0] == pytest.approx(weekday)
    assert days[4] == pytest.approx(0.1)  # Saturday 5 January: all other days
    assert np.allclose(days[31:], 0.5)
    assert len(daily_means(SCHEDULE, 2020)) == 366


def test_a_steady_copy_holds_one_value_and_keeps_the_design_days():
    copy = steady_copy(SCHEDULE, "steady", 0.3)
    assert np.allclose(daily_means(copy, 2019), 0.3)
    assert copy[3:5] == ["Through: 12/31", "For: summerdesignday"]  # the hours of the clause it shared with weekdays
    assert copy[5:11] == ["Until: 06:00", "0.2", "Until: 18:00", "1", "Until: 24:00", "0.2"]
    assert copy[11:14] == ["For: winterdesignday", "Until: 24:00", "0"]


def test_a_schedule_that_leaves_a_day_undefined_or_is_not_compact_is_refused():
    gap = ["Schedule:Compact", "gap", "Fraction", "Through: 6/30", "For: AllDays", "Until: 24:00", "1"]
    with pytest.raises(ReferenceBuildingError, match="gap gives no value for 01 July"):
        daily_means(gap, 2019)
    with pytest.raises(ReferenceBuildingError, match="cannot read the field 'Through: 12/31/2019'"):
        daily_means([*gap[:3], "Through: 12/31/2019", *gap[4:]], 2019)
    with pytest.raises(ReferenceBuildingError, match="only a Schedule:Compact"):
        daily_means(["Schedule:Constant", "c", "", "1"], 2019)
