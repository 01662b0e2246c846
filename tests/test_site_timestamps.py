"""measurements.csv exports that break the conventions in a known way: each is named at its line with its cause,
and the option or conversion the message gives reads the valid site's data back.

Every case builds the faulty file from a valid site (written by ``write_site``), checks the one-line error, then
follows the hint and compares with the valid site: a daylight-saving clock (spring's missing hour, autumn's
repeated one; ``[measurements] time_zone``), end-of-hour stamps (``stamped = "end"``), a cumulative meter register
(``cumulative = true``), consumption in MWh or GJ.
"""

from __future__ import annotations

import datetime as dt
import re
import zoneinfo
from pathlib import Path

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.errors import SiteError
from buildenv.sites import load_site, write_site

AREA = 4982.0
UTC = dt.timezone.utc


def _valid(path: Path, start: dt.date, weeks: int = 2, seed: int = 0, weather: str = "usa_il_chicago") -> Path:
    """A valid site (local standard time, start-of-hour stamps, kWh) of ``weeks`` weeks from Monday ``start``."""
    rng = np.random.default_rng(seed)
    lo, hi = cat.bounds("settings")
    settings = np.round(lo + (hi - lo) * rng.random((weeks, 7, len(lo))), 1).clip(lo, hi)
    settings[..., -1] = np.round(settings[..., -1])  # hvac_operating: 1 or 0
    return write_site(
        path,
        name="office",
        weather=weather,
        start=start,
        floor_area_m2=AREA,
        number_of_floors=3,
        settings=settings,
        temperature_c=np.round(21 + 2 * rng.standard_normal((weeks, 168)), 3),
        consumption_kwh=np.round(20 + 80 * rng.random((weeks, 168)), 4),
    )


def _rows(site_dir: Path) -> tuple[str, list[list[str]]]:
    header, *rows = (site_dir / "measurements.csv").read_text().splitlines()
    return header, [row.split(",") for row in rows]


def _write_rows(site_dir: Path, header: str, rows: list[list[str]]) -> None:
    (site_dir / "measurements.csv").write_text("\n".join([header, *(",".join(r) for r in rows)]) + "\n")


def _set_weather(site_dir: Path, weather: str | Path) -> None:
    """Point site.toml's ``weather`` at ``weather`` (a short name or an EPW path)."""
    toml = site_dir / "site.toml"
    toml.write_text(re.sub(r'(?m)^weather = ".*"$', f'weather = "{weather}"', toml.read_text()))


def _weather_at(path: Path, place: str, utc_h: float) -> Path:
    """A copy of Chicago's EPW whose header names ``place`` and standard time UTC``utc_h`` h (the reader reads
    only the header's location; the weather of the place is not at hand)."""
    from buildenv.weather.epw import resolve_epw

    head, rest = resolve_epw("usa_il_chicago").read_text(encoding="latin-1").split("\n", 1)
    fields = head.split(",")
    fields[1], fields[8] = place, f"{utc_h:.1f}"
    path.write_text(",".join(fields) + "\n" + rest, encoding="latin-1")
    return path


def _declare(site_dir: Path, table: str) -> None:
    """Append a ``[measurements]`` table (its body ``table``) to site.toml."""
    toml = site_dir / "site.toml"
    toml.write_text(toml.read_text() + f"\n[measurements]\n{table}\n")


def _line_of(site_dir: Path, stamp: str) -> int:
    """1-based line of the (first) row stamped ``stamp``."""
    lines = (site_dir / "measurements.csv").read_text().splitlines()
    return next(i for i, line in enumerate(lines, start=1) if line.startswith(stamp + ","))


def _same(
    site_dir: Path,
    valid_dir: Path,
    *,
    missing: tuple[int, ...] = (),
    missing_q: tuple[int, ...] = (),
    rtol: float = 0.0,
) -> None:
    """The site reads as the valid one, but for the flat hours ``missing`` (NaN in both columns) and
    ``missing_q`` (NaN consumption)."""
    site, valid = load_site(site_dir), load_site(valid_dir)
    assert site.start == valid.start and site.weeks == valid.weeks
    t, q = valid.temperature_c.copy().ravel(), valid.consumption_kwh.copy().ravel()
    t[list(missing)] = np.nan
    q[list(missing + missing_q)] = np.nan
    np.testing.assert_array_equal(site.temperature_c.ravel(), t)
    np.testing.assert_allclose(site.consumption_kwh.ravel(), q, rtol=rtol, atol=1e-9)
    np.testing.assert_array_equal(site.settings, valid.settings)


def _error(site_dir: Path) -> str:
    with pytest.raises(SiteError) as info:
        load_site(site_dir)
    message = str(info.value)
    assert "\n" not in message
    return message


# --------------------------------------------------------------------------- a daylight-saving clock
def _local_export(valid_dir: Path, out: Path, zone: str, *, stamped_end: bool = False) -> Path:
    """The valid site's data as a BMS on ``zone``'s clock exports them: whole weeks of the local clock, each row
    stamped with the local time of the start (or end) of its hour; an hour outside the valid site gets 0 kWh."""
    tz = zoneinfo.ZoneInfo(zone)
    valid = load_site(valid_dir)
    start = dt.datetime.combine(valid.start, dt.time())
    standard = min(dt.datetime(start.year, m, 1, tzinfo=tz).utcoffset() for m in (1, 7))
    t, q = valid.temperature_c.ravel(), valid.consumption_kwh.ravel()
    end = dt.timedelta(hours=1) if stamped_end else dt.timedelta(0)
    first = (start + end).replace(tzinfo=tz).astimezone(UTC)  # local Monday 00:00 (01:00 for end stamps)
    last = (start + end + dt.timedelta(weeks=valid.weeks, hours=-1)).replace(tzinfo=tz).astimezone(UTC)
    rows = []
    instant = first
    while instant <= last:
        local = instant.astimezone(tz).replace(tzinfo=None)
        hour = int((instant.replace(tzinfo=None) + standard - end - start).total_seconds()) // 3600
        inside = 0 <= hour < t.size
        cells = [f"{t[hour]:.3f}", f"{q[hour]:.4f}"] if inside else ["21.000", "0.0000"]
        rows.append([local.strftime("%Y-%m-%d %H:%M"), *cells])
        instant += dt.timedelta(hours=1)
    out = _valid(out, valid.start, valid.weeks)
    header, _ = _rows(out)
    _write_rows(out, header, rows)
    return out


@pytest.mark.parametrize(
    ("zone", "start", "missing", "utc_h"),
    [
        ("America/Chicago", dt.date(2024, 3, 4), "2024-03-10 02:00", -6.0),  # 2nd Sunday of March
        ("Europe/Paris", dt.date(2024, 3, 25), "2024-03-31 02:00", 1.0),  # last Sunday of March
        ("Europe/London", dt.date(2024, 3, 25), "2024-03-31 01:00", 0.0),
        ("Australia/Sydney", dt.date(2024, 9, 30), "2024-10-06 02:00", 10.0),  # 1st Sunday of October
    ],
)
def test_spring_daylight_saving_is_named_and_time_zone_reads_it(
    tmp_path: Path, zone: str, start: dt.date, missing: str, utc_h: float
):
    valid = _valid(tmp_path / "valid", start)
    site = _local_export(valid, tmp_path / "site", zone)
    _set_weather(site, _weather_at(tmp_path / "place.epw", zone.split("/")[1], utc_h))  # the weather of the place
    suggested = zone  # the zone of the weather file's standard time and place
    after = (dt.datetime.fromisoformat(missing) + dt.timedelta(hours=1)).strftime("%Y-%m-%d %H:%M")
    line = _line_of(site, after)
    message = _error(site)
    assert re.search(
        rf"measurements\.csv:{line}: no row for {missing}, on the \w+ Sunday clocks go forward \(e\.g\. in "
        rf"{suggested}.*\): the timestamps look like local daylight-saving time.*"
        rf'\[measurements\] time_zone = "{suggested}',
        message,
    ), message
    assert f"add the row {missing} with empty cells" in message

    _declare(site, f'time_zone = "{zone}"')
    # The export ends at the local clock's Sunday 23:00, in summer standard time's 22:00: the last hour is not in
    # it (Sydney's export starts in winter, its week ends in summer too).
    _same(site, valid, missing=(2 * 168 - 1,))


def test_an_export_an_hour_late_from_03_00_is_named(tmp_path: Path):
    """Rows moved on an hour from 03:00 (no clock does this; the US clock skips 02:00): named all the same."""
    site = _valid(tmp_path / "site", dt.date(2024, 3, 4))
    header, rows = _rows(site)
    for row in rows:
        stamp = dt.datetime.fromisoformat(row[0])
        if stamp >= dt.datetime(2024, 3, 10, 3):
            row[0] = (stamp + dt.timedelta(hours=1)).strftime("%Y-%m-%d %H:%M")
    _write_rows(site, header, rows)
    message = _error(site)
    assert re.search(r'measurements\.csv:\d+: no row for 2024-03-10 03:00, .*time_zone = "America/Chicago"', message)


def test_autumn_daylight_saving_is_named_and_time_zone_reads_it(tmp_path: Path):
    valid = _valid(tmp_path / "valid", dt.date(2024, 10, 28))  # US clocks go back on Sunday 2024-11-03 02:00
    site = _local_export(valid, tmp_path / "site", "America/Chicago")
    second = _line_of(site, "2024-11-03 01:00") + 1
    message = _error(site)
    assert message.startswith(
        f"{site / 'measurements.csv'}:{second}: duplicate timestamp 2024-11-03 01:00 (also on line {second - 1}), "
        "on a November Sunday, the hour clocks go back (e.g. in America/Chicago): the timestamps look like local "
        "daylight-saving time; declare the zone of the BMS clock in site.toml, [measurements] time_zone = "
        '"America/Chicago"'
    ), message
    _declare(site, 'time_zone = "America/Chicago"')
    # The export starts at local Monday 00:00 (CDT), standard time's Sunday 23:00: that row is left out.
    _same(site, valid)


@pytest.mark.parametrize("stamped_end", [False, True])
def test_time_zone_reads_a_year_of_local_clock_exactly(tmp_path: Path, stamped_end: bool):
    """From winter through spring, summer and autumn to winter: the standard-time data, every hour."""
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1), weeks=50)
    site = _local_export(valid, tmp_path / "site", "America/Chicago", stamped_end=stamped_end)
    _declare(site, 'time_zone = "America/Chicago"' + ('\nstamped = "end"' if stamped_end else ""))
    _same(site, valid)


def test_a_time_zone_off_the_weather_is_named_and_either_fix_reads_the_data(tmp_path: Path):
    """A zone whose standard time is not the weather file's would put the data hours off the weather: an error
    naming both, and the right zone (a Chicago clock) or the right weather (a New York clock) reads the data."""
    valid = _valid(tmp_path / "valid", dt.date(2024, 10, 28))  # clocks go back on Sunday 2024-11-03
    for clock, fix in (("America/Chicago", "zone"), ("America/New_York", "weather")):
        site = _local_export(valid, tmp_path / fix, clock)
        _declare(site, 'time_zone = "America/New_York"')
        line = (site / "site.toml").read_text().splitlines().index("[measurements]") + 1
        assert _error(site) == (
            f"{site / 'site.toml'}:{line}: [measurements] time_zone 'America/New_York' keeps standard time UTC-5 h, "
            "the weather file (usa_il_chicago) UTC-6 h: the data would be 1 h off the weather's; give the zone of "
            "the BMS clock (time_zone), or the weather file of the building's place (weather)"
        )
        if fix == "zone":
            toml = site / "site.toml"
            toml.write_text(toml.read_text().replace("America/New_York", clock))
        else:
            _set_weather(site, "usa_nj_newark")  # New York's standard time, UTC-5 h
        _same(site, valid)


def test_time_zone_on_a_standard_time_file_names_the_hour_the_clock_skips(tmp_path: Path):
    site = _valid(tmp_path / "site", dt.date(2024, 3, 4))
    _declare(site, 'time_zone = "America/Chicago"')
    line = _line_of(site, "2024-03-10 02:00")
    assert re.fullmatch(
        rf".*measurements\.csv:{line}: timestamp 2024-03-10 02:00 does not exist on the clock of America/Chicago "
        r"\(time_zone, .*site\.toml:\d+\), which goes forward over it: a file in local standard time needs no "
        r"time_zone; a file on that clock has no such row",
        _error(site),
    )


def test_a_plain_gap_is_not_daylight_saving(tmp_path: Path):
    site = _valid(tmp_path / "site", dt.date(2024, 3, 4))
    header, rows = _rows(site)
    _write_rows(site, header, [r for r in rows if r[0] not in ("2024-03-09 02:00", "2024-03-10 05:00")])
    assert np.isnan(load_site(site).temperature_c[0, [5 * 24 + 2, 6 * 24 + 5]]).all()  # a Saturday; 05:00


def test_time_zone_errors_name_the_line(tmp_path: Path):
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    toml = (site / "site.toml").read_text()
    lines = len(toml.splitlines())
    for table, error in [
        ('time_zone = "America/Chicgo"', r"unknown time zone 'America/Chicgo' \(did you mean 'America/Chicago'\?\)"),
        ("time_zone = -6", r"\[measurements\] time_zone must be the IANA name .*, got -6"),
        ('stamped = "begin"', r'\[measurements\] stamped must be "start" .* or "end" .*, got \'begin\''),
        ('cumulative = "yes"', r"\[measurements\] cumulative must be true .*, got 'yes'"),
        ("unit = 'MWh'", r"unknown key 'unit' in \[measurements\]; allowed: file, time_zone, stamped, cumulative"),
    ]:
        (site / "site.toml").write_text(toml + f"\n[measurements]\n{table}\n")
        with pytest.raises(SiteError, match=rf"site\.toml:{lines + 3}: {error}"):
            load_site(site)


def test_the_measurements_table_names_the_file(tmp_path: Path):
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    (site / "measurements.csv").rename(site / "bms.csv")
    _declare(site, 'file = "bms.csv"')
    assert load_site(site).weeks == 2


# --------------------------------------------------------------------------- end-of-hour stamps
def _end_stamped(site: Path, *, midnight: str = "00:00") -> None:
    """Stamp every row with the end of its hour (01:00 for 00:00-01:00); a day's last hour ``midnight``
    (``00:00`` of the next day, or ``24:00`` of the day)."""
    header, rows = _rows(site)
    for row in rows:
        end = dt.datetime.fromisoformat(row[0]) + dt.timedelta(hours=1)
        row[0] = end.strftime("%Y-%m-%d %H:%M")
        if end.hour == 0 and midnight == "24:00":
            row[0] = f"{end - dt.timedelta(days=1):%Y-%m-%d} 24:00"
    _write_rows(site, header, rows)


def test_end_of_hour_stamps_are_named_and_stamped_end_reads_them(tmp_path: Path):
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    _end_stamped(site)
    message = _error(site)
    assert message == (
        f"{site / 'measurements.csv'}:2: the first timestamp 2024-01-01 01:00 is a Monday at 01:00: data must start "
        "on a Monday at 00:00; this file runs to Monday 2024-01-15 00:00 (line 337): its rows are stamped at the "
        'end of their hour (01:00 for 00:00-01:00); declare it in site.toml: [measurements] stamped = "end"'
    )
    _declare(site, 'stamped = "end"')
    _same(site, valid)


def test_days_to_24_00_are_named_and_stamped_end_reads_them(tmp_path: Path):
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    _end_stamped(site, midnight="24:00")
    assert _error(site) == (
        f"{site / 'measurements.csv'}:25: timestamp '2024-01-01 24:00' is 24:00, the end of a day: if the rows are "
        "stamped at the end of their hour (24:00 for 23:00-24:00), declare it in site.toml: "
        '[measurements] stamped = "end"; if the column holds meter register readings (this one the reading at the '
        "day's end), declare [measurements] cumulative = true"
    )
    _declare(site, 'stamped = "end"')
    _same(site, valid)


def test_a_first_row_at_01_00_offers_both_readings(tmp_path: Path):
    """Without a last row at 00:00 the file may be end-stamped, or its first hour missing: both fixes are named,
    and the second reads a start-stamped file right."""
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    header, rows = _rows(site)
    _write_rows(site, header, rows[1:])
    assert _error(site) == (
        f"{site / 'measurements.csv'}:2: the first timestamp 2024-01-01 01:00 is a Monday at 01:00: data must start "
        "on a Monday at 00:00: if the rows are stamped at the end of their hour (01:00 for 00:00-01:00), declare it "
        'in site.toml: [measurements] stamped = "end"; if the hour from 00:00 was not measured, add the row '
        "2024-01-01 00:00 with empty cells"
    )
    _write_rows(site, header, [["2024-01-01 00:00", "", ""], *rows[1:]])
    _same(site, valid, missing=(0,))


def test_a_last_row_at_monday_00_00_names_end_stamps(tmp_path: Path):
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    header, rows = _rows(site)
    _write_rows(site, header, [*rows, ["2024-01-15 00:00", "21", "50"]])
    message = _error(site)
    assert message.startswith(f"{site / 'measurements.csv'}:338: the data end at Monday 2024-01-15 00:00")
    assert message.endswith(
        "(or, if the rows are stamped at the end of their hour, 00:00 for 23:00-24:00, declare it in site.toml: "
        '[measurements] stamped = "end")'
    )
    _declare(site, 'stamped = "end"')  # the first row, 00:00, then covers Sunday 23:00-24:00
    assert re.search(r"measurements\.csv:2: the first row, 2024-01-01 00:00, stamped at the end", _error(site))


# --------------------------------------------------------------------------- units and registers
@pytest.mark.parametrize(("unit", "kwh"), [("MWh", 1000.0), ("GJ", 1000 / 3.6)])
def test_consumption_in_mwh_or_gj_is_named_and_the_conversion_reads_it(tmp_path: Path, unit: str, kwh: float):
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    header, rows = _rows(site)
    for row in rows:
        row[2] = repr(float(row[2]) / kwh)
    _write_rows(site, header, rows)
    q = load_site(valid).consumption_kwh.ravel()
    peak = int(np.argmax(q))
    message = _error(site)
    assert re.fullmatch(
        rf".*measurements\.csv:{peak + 2}: heat_consumption_kwh=[\d.e-]+ is the largest in the file, [\d.]+ W/m2 "
        r"for 4982 m2: below the 0\.6 W/m2 a building whose meter includes lighting and plug_loads uses in its "
        r"busiest hour \(a tenth of the catalogue's least installed power\); looks like MWh \(multiply by 1000\) "
        r"or GJ \(multiply by 1000/3\.6 = 277\.78\)",
        message,
    ), message
    for row in rows:
        row[2] = repr(float(row[2]) * kwh)
    _write_rows(site, header, rows)
    _same(site, valid, rtol=1e-12)


def test_consumption_in_wh_is_still_named(tmp_path: Path):
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    header, rows = _rows(site)
    for row in rows:
        row[2] = repr(float(row[2]) * 1000)
    _write_rows(site, header, rows)
    first = next(i for i, row in enumerate(rows) if float(row[2]) > AREA)
    assert re.search(rf"measurements\.csv:{first + 2}: .* looks like Wh \(divide by 1000\)$", _error(site))
    for row in rows:
        row[2] = repr(float(row[2]) / 1000)
    _write_rows(site, header, rows)
    _same(site, valid, rtol=1e-12)


def _meter(site: Path, *end_uses: str) -> None:
    (site / "site.toml").write_text((site / "site.toml").read_text() + f"\n[meters]\nconsumption = {list(end_uses)}\n")


def _scale(site: Path, factor: float) -> None:
    """Multiply the consumption column by ``factor``."""
    header, rows = _rows(site)
    for row in rows:
        row[2] = repr(float(row[2]) * factor)
    _write_rows(site, header, rows)


@pytest.mark.parametrize(
    ("use", "start", "weather"),
    [("heating", dt.date(2024, 1, 1), "usa_il_chicago"), ("cooling", dt.date(2024, 7, 1), "usa_az_phoenix")],
)
def test_a_heating_or_cooling_meter_in_mwh_is_named_and_the_conversion_reads_it(
    tmp_path: Path, use: str, start: dt.date, weather: str
):
    """A meter of heating (cooling) alone is checked in the weeks that need it: 15 K or more colder outdoors than
    the 17-24 degC measured indoors (no cooler outdoors than indoors)."""
    valid = _valid(tmp_path / "valid", start, weather=weather)
    site = _valid(tmp_path / "site", start, weather=weather)
    _meter(valid, use)
    _meter(site, use)
    _scale(site, 1 / 1000)
    peak = int(np.argmax(load_site(valid).consumption_kwh.ravel()))
    message = _error(site)
    assert re.fullmatch(
        rf".*measurements\.csv:{peak + 2}: heat_consumption_kwh=[\d.e-]+ is the largest in the 2 week\(s\) that need "
        rf"{use} \(.*\), 0\.0[12]\d* W/m2 for 4982 m2: below the 1 W/m2 a {use} meter of an office delivers in its "
        r"busiest hour of such weeks; looks like MWh \(multiply by 1000\) or GJ \(multiply by 1000/3\.6 = 277\.78\)",
        message,
    ), message
    _scale(site, 1000)
    _same(site, valid, rtol=1e-12)


def test_a_heating_meter_in_mwh_is_named_in_a_mild_week_and_in_kwh_accepted(tmp_path: Path):
    """San Francisco in January, outdoors 8-13 degC on average: a heating meter (a passive-house office, 0.3 W/(m2 K),
    whose free heat covers 2 W/m2 at night and 8 W/m2 when occupied) peaks at a few W/m2; in MWh it is named against
    the weeks' mean need beyond free heat, in kWh it loads."""
    from buildenv.sites.consumption import _outdoor_c

    start, weather = dt.date(2024, 1, 8), "usa_ca_san_francisco"
    site = _valid(tmp_path / "site", start, weather=weather)
    _meter(site, "heating")
    header, rows = _rows(site)
    hour = np.arange(len(rows)) % 168
    occupied = (hour // 24 < 5) & (hour % 24 >= 8) & (hour % 24 < 18)
    indoor = np.array([float(row[1]) for row in rows])
    heating_w_m2 = np.maximum(0.3 * (indoor - _outdoor_c(weather, start, 2)) - np.where(occupied, 8.0, 2.0), 0.0)
    for row, w_m2 in zip(rows, heating_w_m2):
        row[2] = repr(float(w_m2) * AREA / 1e6)  # MWh
    _write_rows(site, header, rows)
    peak = int(np.argmax(heating_w_m2))
    assert 2 < heating_w_m2.max() < 5
    assert re.fullmatch(
        rf".*measurements\.csv:{peak + 2}: heat_consumption_kwh=[\d.e-]+ is the largest in the 2 week\(s\) that need "
        r"heating \(.*more than 11\.7 K below it needs 0\.3 W/m2, .*\), 0\.00[2-5]\d* W/m2 for 4982 m2: below the "
        r"0\.[1-9]\d* W/m2 a heating meter of an office delivers in its busiest hour of such weeks; looks like MWh .*",
        _error(site),
    )
    _scale(site, 1000)
    np.testing.assert_allclose(load_site(site).consumption_kwh.ravel(), heating_w_m2 * AREA / 1000)


def test_a_heating_dominated_meter_in_gj_is_named_by_the_heating_weeks(tmp_path: Path):
    """Heating and plug loads at up to 120 W/m2, in GJ: above the plug loads' 0.2 W/m2, below the 1 W/m2 of heating
    that Chicago's January weeks need."""
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    for folder, factor in ((valid, 6.0), (site, 6.0 * 3.6 / 1000)):
        _meter(folder, "heating", "plug_loads")
        _scale(folder, factor)
    peak = int(np.argmax(load_site(valid).consumption_kwh.ravel()))
    assert re.fullmatch(
        rf".*measurements\.csv:{peak + 2}: heat_consumption_kwh=[\d.e-]+ is the largest in the 2 week\(s\) that need "
        r"heating \(.*\), 0\.4\d* W/m2 for 4982 m2: below the 1 W/m2 a heating meter .*; looks like MWh .* or GJ .*",
        _error(site),
    )
    _scale(site, 1000 / 3.6)
    _same(site, valid, rtol=1e-12)


def test_small_heating_or_cooling_is_accepted_in_weeks_that_need_none(tmp_path: Path):
    """A heating meter in summer, a cooling meter in winter, a heating meter that reads nothing in winter (the
    heating off): no smallest peak."""
    for use, start, factor in (("heating", dt.date(2024, 7, 1), 1e-3), ("cooling", dt.date(2024, 1, 1), 1e-3)):
        site = _valid(tmp_path / use, start)
        _meter(site, use)
        _scale(site, factor)
        assert load_site(site).consumption_kwh.max() < 0.1
    site = _valid(tmp_path / "off", dt.date(2024, 1, 1))
    _meter(site, "heating")
    _scale(site, 0.0)
    assert load_site(site).consumption_kwh.max() == 0


def _register(site: Path, *, stamped_end: bool = False, offset: float = 123456.0) -> list[list[str]]:
    """Replace the consumption by readings of a register that counts it (at the start of each row's hour, or at
    its end); returns the rows."""
    header, rows = _rows(site)
    q = np.array([float(r[2]) for r in rows])
    readings = offset + np.concatenate([[0.0], np.cumsum(q)])
    for row, reading in zip(rows, readings[1:] if stamped_end else readings[:-1]):
        row[2] = f"{reading:.4f}"
    _write_rows(site, header, rows)
    return rows


def test_a_cumulative_register_is_named_and_cumulative_reads_it(tmp_path: Path):
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    rows = _register(site)
    assert _error(site) == (
        f"{site / 'measurements.csv'}:2: heat_consumption_kwh never falls, from 123456 here to {float(rows[-1][2]):g} "
        "on line 337: a cumulative meter register, not the energy of each hour; give the hourly differences, or "
        "declare it in site.toml: [measurements] cumulative = true"
    )
    _declare(site, "cumulative = true")
    _same(site, valid, missing_q=(2 * 168 - 1,))  # no reading closes the last hour


def _register_closed_at(tmp_path: Path, stamp: str) -> tuple[Path, Path, list[list[str]]]:
    """A valid two-week site and a copy whose consumption is a register read at each hour's start, with a last row
    at ``stamp`` holding the reading that closes the last hour: ``(valid, site, the site's rows)``."""
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    header, _ = _rows(site)
    total = float(np.nansum(load_site(valid).consumption_kwh))
    rows = [*_register(site), [stamp, "", f"{123456.0 + total:.4f}"]]
    _write_rows(site, header, rows)
    return valid, site, rows


def test_a_register_with_its_closing_reading_is_named_and_cumulative_reads_every_hour(tmp_path: Path):
    """A register read at each hour's start and at the end of the last (the Monday 00:00 after the weeks): named
    as a register, not as a row past whole weeks; declared, the closing reading completes the last hour."""
    valid, site, rows = _register_closed_at(tmp_path, "2024-01-15 00:00")
    assert _error(site) == (
        f"{site / 'measurements.csv'}:2: heat_consumption_kwh never falls, from 123456 here to {float(rows[-1][2]):g} "
        "on line 338: a cumulative meter register, not the energy of each hour; give the hourly differences, or "
        "declare it in site.toml: [measurements] cumulative = true"
    )
    _declare(site, "cumulative = true")
    _same(site, valid, rtol=1e-9)


def test_a_register_closing_reading_at_24_00_is_named_and_cumulative_reads_it(tmp_path: Path):
    """A register read at each hour's start whose closing reading is stamped Sunday 24:00: undeclared, the message
    names the declaration; declared cumulative, 24:00 is the instant the next day starts and every hour reads."""
    valid, site, _ = _register_closed_at(tmp_path, "2024-01-14 24:00")
    assert _error(site).endswith(
        "measurements.csv:338: timestamp '2024-01-14 24:00' is 24:00, the end of a day: if the rows are stamped at "
        'the end of their hour (24:00 for 23:00-24:00), declare it in site.toml: [measurements] stamped = "end"; '
        "if the column holds meter register readings (this one the reading at the day's end), declare "
        "[measurements] cumulative = true"
    )
    _declare(site, "cumulative = true")
    _same(site, valid, rtol=1e-9)


def test_a_register_read_at_the_end_of_each_hour(tmp_path: Path):
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    _end_stamped(site)
    _register(site, stamped_end=True)
    _declare(site, 'cumulative = true\nstamped = "end"')
    site_q = load_site(site).consumption_kwh.ravel()
    valid_q = load_site(valid).consumption_kwh.ravel()
    assert np.isnan(site_q[0])  # no reading opens the first hour
    np.testing.assert_allclose(site_q[1:], valid_q[1:], atol=1e-6, rtol=0)


def test_a_register_reset_is_named_and_an_empty_reading_reads_the_rest(tmp_path: Path):
    valid = _valid(tmp_path / "valid", dt.date(2024, 1, 1))
    site = _valid(tmp_path / "site", dt.date(2024, 1, 1))
    header, rows = _rows(site)
    rows = _register(site)
    rows[100][2] = "5.0000"  # a meter replaced for an hour
    _write_rows(site, header, rows)
    _declare(site, "cumulative = true")
    assert re.search(
        r"measurements\.csv:102: the register reading 5 is below the previous hour's [\d.]+ \(line 101\): a meter "
        r"reset or replacement\? leave this reading empty",
        _error(site),
    )
    rows[100][2] = ""
    _write_rows(site, header, rows)
    _same(site, valid, missing_q=(99, 100, 2 * 168 - 1))


def test_the_shipped_default_site_still_loads():
    default = Path(__file__).resolve().parents[1] / "buildenv" / "data" / "sites" / "default"
    assert load_site(default).weeks > 0
