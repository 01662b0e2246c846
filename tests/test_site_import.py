"""``buildenv site import``: raw BMS exports (sub-hourly, local daylight-saving clock, end stamps, degF or K, Wh, MWh
or GJ, meter registers) become site folders that read back as the same hourly data as a hand-made hourly site.

Each export is built from known hourly values (temperature degC, consumption kWh in local standard time) with the
standard library's zoneinfo, independently of the importer, and compared with a site written from those values by
``write_site``.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
import zoneinfo
from pathlib import Path

import numpy as np
import pytest

from buildenv.cli.main import main
from buildenv.defaults import default_week
from buildenv.errors import SiteError
from buildenv.sites import load_site, write_site
from buildenv.sites.importer import ImportOptions, import_export

AREA = 4982.0
WEEKS = 2
HOURS = WEEKS * 168
SITE = {"name": "office", "weather": "usa_il_chicago", "floor_area_m2": AREA, "number_of_floors": 3}


def _truth(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Hourly ``(temperature degC, consumption kWh)`` of two weeks, rounded as a site file holds them."""
    rng = np.random.default_rng(seed)
    return np.round(21 + 2 * rng.standard_normal(HOURS), 3), np.round(20 + 80 * rng.random(HOURS), 4)


def _handmade(path: Path, start: dt.date, t: np.ndarray, q: np.ndarray) -> Path:
    """The hourly site a user would have written by hand, with the typical settings."""
    shape = (WEEKS, 168)
    return write_site(
        path,
        start=start,
        settings=default_week(WEEKS)[0],
        temperature_c=t.reshape(shape),
        consumption_kwh=q.reshape(shape),
        **SITE,
    )


def _hourly_rows(start: dt.date, t: np.ndarray, q: np.ndarray) -> list[list[str]]:
    """Rows ``[timestamp, temperature, energy]`` of an hourly export starting on ``start`` at midnight."""
    midnight = dt.datetime.combine(start, dt.time())
    return [[f"{midnight + dt.timedelta(hours=h):%Y-%m-%d %H:%M}", f"{t[h]:.3f}", f"{q[h]:.4f}"] for h in range(HOURS)]


def _export(path: Path, header: list[str], rows: list[list[str]]) -> Path:
    path.write_text("\n".join(",".join(r) for r in [header, *rows]) + "\n", encoding="utf-8")
    return path


def _same(imported: Path, handmade: Path) -> None:
    a, b = load_site(imported), load_site(handmade)
    assert (a.start, a.weeks) == (b.start, b.weeks)
    np.testing.assert_allclose(a.temperature_c, b.temperature_c, atol=1.5e-3)
    np.testing.assert_allclose(a.consumption_kwh, b.consumption_kwh, atol=1.5e-3)
    np.testing.assert_array_equal(a.settings, b.settings)


def _dst_export(path: Path, start: dt.date, t: np.ndarray, q: np.ndarray, *, offsets: bool = False) -> Path:
    """A 15-minute export on Chicago's clock (daylight saving from 2024-03-10 02:00 to 2024-11-03 02:00; with
    ``offsets``, each stamp with its UTC offset), temperature in degF (four samples averaging the hour), a Wh
    register read at the start of each interval, and a closing reading."""
    zone, standard_offset = zoneinfo.ZoneInfo("America/Chicago"), dt.timedelta(hours=-6)
    share = (0.1, 0.2, 0.3, 0.4)
    register = 1_234_567.0
    rows = []
    for k in range(HOURS * 4 + 1):
        standard = dt.datetime.combine(start, dt.time()) + dt.timedelta(minutes=15 * k)
        local = (standard - standard_offset).replace(tzinfo=dt.timezone.utc).astimezone(zone)
        h = k // 4
        temperature = "" if h == HOURS else f"{(t[h] + (-0.3, -0.1, 0.1, 0.3)[k % 4]) * 1.8 + 32:.4f}"
        rows.append(
            [local.strftime("%Y-%m-%dT%H:%M%z" if offsets else "%Y-%m-%d %H:%M"), temperature, f"{register:.3f}"]
        )
        if h < HOURS:
            register += 1000 * q[h] * share[k % 4]
    return _export(path, ["Timestamp", "Zone Temp (°F)", "Main meter [Wh]"], rows)


def test_15_minute_degf_export_on_a_dst_clock_with_a_wh_register(tmp_path):
    start = dt.date(2024, 3, 4)  # Chicago's clocks go forward on Sunday 2024-03-10 02:00
    t, q = _truth(0)
    export = _dst_export(tmp_path / "bms.csv", start, t, q)
    text = export.read_text()
    assert "2024-03-10 01:45" in text and "2024-03-10 02:00" not in text and "2024-03-18 00:45" in text

    options = ImportOptions(time_zone="America/Chicago", cumulative=True)
    report = import_export(export, tmp_path / "site", options=options, **SITE)
    assert (report.start, report.weeks, report.interval_minutes) == ("2024-03-04", 2, 15)
    assert report.columns == {"Zone Temp (°F)": "degF", "Main meter [Wh]": "Wh register"}
    assert report.missing_temperature_hours == report.missing_consumption_hours == 0 and not report.notes
    _same(tmp_path / "site", _handmade(tmp_path / "hand", start, t, q))


def test_15_minute_export_across_the_autumn_repeated_hour(tmp_path):
    start = dt.date(2024, 10, 28)  # Chicago's clocks go back from 02:00 to 01:00 on Sunday 2024-11-03
    t, q = _truth(4)
    export = _dst_export(tmp_path / "bms.csv", start, t, q)
    lines = export.read_text().splitlines()
    repeated = [n for n, line in enumerate(lines, start=1) if line.startswith("2024-11-03 01:00,")]
    assert len(repeated) == 2 and lines[repeated[1] - 2].startswith("2024-11-03 01:45,")

    with pytest.raises(SiteError) as error:
        import_export(export, tmp_path / "refused", options=ImportOptions(cumulative=True), **SITE)
    assert str(error.value) == (
        f"{export}:{repeated[1]}: timestamp 2024-11-03 01:00 is earlier than the previous row's 2024-11-03 01:45 "
        f"(line {repeated[1] - 1}), on a November Sunday, the hour clocks go back (e.g. in America/Chicago): the "
        "timestamps look like local daylight-saving time; give the export's zone, --time-zone America/Chicago (an "
        "IANA name), which reads the repeated hour as the next hour of standard time"
    )
    assert not (tmp_path / "refused").exists()

    options = ImportOptions(time_zone="America/Chicago", cumulative=True)
    report = import_export(export, tmp_path / "site", options=options, **SITE)
    assert (report.start, report.weeks, report.interval_minutes) == ("2024-10-28", 2, 15)
    assert report.missing_temperature_hours == report.missing_consumption_hours == 0 and not report.notes
    _same(tmp_path / "site", _handmade(tmp_path / "hand", start, t, q))


def test_timestamps_with_utc_offsets_are_read_at_their_instant(tmp_path):
    start = dt.date(2024, 3, 4)
    t, q = _truth(0)
    export = _dst_export(tmp_path / "bms.csv", start, t, q, offsets=True)
    assert "2024-03-10T01:45-0600" in export.read_text() and "2024-03-10T03:00-0500" in export.read_text()
    options = ImportOptions(time_format="%Y-%m-%dT%H:%M%z", cumulative=True)
    report = import_export(export, tmp_path / "site", options=options, **SITE)
    assert (report.start, report.weeks, report.missing_consumption_hours) == ("2024-03-04", 2, 0)
    _same(tmp_path / "site", _handmade(tmp_path / "hand", start, t, q))

    options = dataclasses.replace(options, time_zone="America/Chicago")
    with pytest.raises(SiteError, match=r"bms.csv:2: the timestamps carry UTC offsets .*: leave --time-zone out$"):
        import_export(export, tmp_path / "refused", options=options, **SITE)
    with pytest.raises(SiteError, match=r"bms.csv:2: timestamp '2024-03-04T00:00-0600' .*--time-format, %z"):
        import_export(export, tmp_path / "refused", options=ImportOptions(cumulative=True), **SITE)


def _register_export(path: Path, start: dt.date, t: np.ndarray, q: np.ndarray, *, opening: bool) -> Path:
    """A 15-minute export in standard time, each row stamped at the end of its interval: temperature degC, a kWh
    register read at the stamp; with ``opening``, a first row (Monday 00:00) with the reading before the first
    interval."""
    register, rows = 5000.0, []
    for k in range(0 if opening else 1, HOURS * 4 + 1):
        stamp = dt.datetime.combine(start, dt.time()) + dt.timedelta(minutes=15 * k)
        h, i = (k - 1) // 4, (k - 1) % 4
        if k:
            register += q[h] * (0.1, 0.2, 0.3, 0.4)[i]
        temperature = f"{t[h] + (i - 1.5) / 10:.4f}" if k else ""
        rows.append([f"{stamp:%Y-%m-%d %H:%M}", temperature, f"{register:.4f}"])
    return _export(path, ["Time", "Room temp degC", "Energy meter kWh"], rows)


def test_end_stamped_register_export(tmp_path):
    start = dt.date(2024, 1, 8)
    t, q = _truth(5)
    export = _register_export(tmp_path / "bms.csv", start, t, q, opening=True)
    options = ImportOptions(stamped="end", cumulative=True)
    report = import_export(export, tmp_path / "site", options=options, **SITE)
    assert (report.start, report.weeks, report.interval_minutes) == ("2024-01-08", 2, 15)
    assert report.columns == {"Room temp degC": "degC", "Energy meter kWh": "kWh register"}
    assert report.missing_temperature_hours == report.missing_consumption_hours == 0 and not report.notes
    _same(tmp_path / "site", _handmade(tmp_path / "hand", start, t, q))

    export = _register_export(tmp_path / "bms.csv", start, t, q, opening=False)  # from 00:15 to Monday 00:00
    with pytest.raises(SiteError) as error:
        import_export(export, tmp_path / "refused", options=ImportOptions(cumulative=True), **SITE)
    assert str(error.value) == (
        f"{export}:2: the readings run from 2024-01-08 00:15 to 2024-01-22 00:00 (line {HOURS * 4 + 1}), 15 minutes "
        "after a midnight to a midnight: stamped at the end of their interval? pass --stamped end; if at its start, "
        "add the row 2024-01-08 00:00 with empty cells"
    )
    report = import_export(export, tmp_path / "no_opening", options=options, **SITE)
    assert report.missing_consumption_hours == 1 and report.missing_temperature_hours == 0  # nothing opens hour 0
    imported = load_site(tmp_path / "no_opening").consumption_kwh.ravel()
    assert np.isnan(imported[0])
    np.testing.assert_allclose(imported[1:], q[1:], atol=1.5e-3)


def test_a_register_export_closed_at_24_00_is_named_a_register_and_cumulative_reads_it(tmp_path):
    """An hourly register read at each hour's start, the last row its closing reading stamped Sunday 24:00 (not an
    end-stamped export): named a register, and --cumulative reads every hour of the hand-made site."""
    start = dt.date(2024, 1, 8)
    t, q = _truth(7)
    register = 5000.0 + np.concatenate([[0.0], np.cumsum(q)])
    rows = [[stamp, temperature, f"{r:.4f}"] for (stamp, temperature, _), r in zip(_hourly_rows(start, t, q), register)]
    rows.append(["2024-01-21 24:00", "", f"{register[-1]:.4f}"])
    export = _export(tmp_path / "bms.csv", ["timestamp", "temperature_c", "energy_kwh"], rows)
    with pytest.raises(SiteError, match=r"bms.csv:2: energy_kwh never falls, .* on line 338: .*; pass --cumulative$"):
        import_export(export, tmp_path / "refused", **SITE)
    report = import_export(export, tmp_path / "site", options=ImportOptions(cumulative=True), **SITE)
    assert report.missing_consumption_hours == report.missing_temperature_hours == 0 and not report.notes
    _same(tmp_path / "site", _handmade(tmp_path / "hand", start, t, q))


def test_a_semicolon_export_with_a_bom_blank_lines_and_empty_rows(tmp_path):
    start = dt.date(2024, 1, 8)
    t, q = _truth(6)
    rows = _hourly_rows(start, t, q)
    lines = [";".join(r) for r in [["timestamp", "temperature_c", "energy_kwh"], *rows[:50], ["", "", ""], *rows[50:]]]
    export = tmp_path / "bms.csv"
    export.write_text("\ufeff\n" + "\n".join(lines[:30] + [""] + lines[30:]) + "\n", encoding="utf-8")
    import_export(export, tmp_path / "site", **SITE)
    _same(tmp_path / "site", _handmade(tmp_path / "hand", start, t, q))


def test_5_minute_end_stamped_export_in_kelvin_and_kw(tmp_path):
    start = dt.date(2024, 1, 8)
    t, q = _truth(1)
    rows = []
    for k in range(1, HOURS * 12 + 1):  # row k covers the 5 minutes to its stamp
        stamp = dt.datetime.combine(start, dt.time()) + dt.timedelta(minutes=5 * k)
        text = stamp.strftime("%Y-%m-%dT%H:%M:%S")
        if stamp.time() == dt.time():  # midnight as the end of the day before
            text = (stamp - dt.timedelta(days=1)).strftime("%Y-%m-%dT24:00:00")
        h, i = (k - 1) // 12, (k - 1) % 12
        wobble = (i - 5.5) / 10  # averages to 0 over the hour
        rows.append([text, f"{t[h] + 273.15 + wobble:.4f}", f"{q[h] + wobble:.4f}"])
    export = _export(tmp_path / "bms.csv", ["date_time", "room_temp_K", "Total power kW"], rows)
    with pytest.raises(
        SiteError, match=r"bms.csv:\d+: timestamp '2024-01-08T24:00:00' is 24:00, .*pass --stamped end$"
    ):
        import_export(export, tmp_path / "site", **SITE)
    report = import_export(export, tmp_path / "site", options=ImportOptions(stamped="end"), **SITE)
    assert (report.start, report.weeks, report.interval_minutes) == ("2024-01-08", 2, 5)
    assert report.columns == {"room_temp_K": "K", "Total power kW": "kW"}
    _same(tmp_path / "site", _handmade(tmp_path / "hand", start, t, q))


def _heat_and_power(start: dt.date, stamp: str, cells) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[list[str]]]:
    """``(temperature, heat kWh, electricity kWh, rows)``: two weeks of hourly rows from ``start``, each a timestamp
    in the format ``stamp``, the temperature and ``cells(heat, power)``'s energy cells."""
    t, q = _truth(2)
    heat, power = np.round(0.6 * q, 4), np.round(q - np.round(0.6 * q, 4), 4)
    midnight = dt.datetime.combine(start, dt.time())
    rows = [
        [f"{midnight + dt.timedelta(hours=h):{stamp}}", f"{t[h]:.3f}", *cells(heat[h], power[h])] for h in range(HOURS)
    ]
    return t, heat, power, rows


def test_hourly_export_in_mwh_and_gj_with_a_settings_file_through_the_cli(tmp_path, capsys):
    start = dt.date(2024, 1, 8)
    t, heat, power, rows = _heat_and_power(
        start, "%Y/%m/%d %H:%M", lambda h, p: [f"{h / 1000:.7f}", f"{p * 0.0036:.8f}"]
    )
    export = _export(tmp_path / "bms.csv", ["Time", "Indoor temp degC", "Heating [MWh]", "Electricity [GJ]"], rows)
    hand = _handmade(tmp_path / "hand", start, t, heat + power)
    argv = ["site", "import", str(export), "--out", str(tmp_path / "site"), "--epw", "usa_il_chicago"]
    argv += ["--floor-area", str(AREA), "--floors", "3", "--name", "office", "--settings", str(hand / "settings.csv")]
    assert main(argv) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["columns"] == {"Indoor temp degC": "degC", "Heating [MWh]": "MWh", "Electricity [GJ]": "GJ"}
    assert info["settings"] == str(hand / "settings.csv")
    _same(tmp_path / "site", hand)


def test_heat_and_electricity_columns_become_two_meters(tmp_path, capsys):
    start = dt.date(2024, 1, 8)
    _, heat, power, rows = _heat_and_power(start, "%Y-%m-%d %H:%M", lambda h, p: [f"{h:.4f}", *[f"{p / 2:.5f}"] * 2])
    header = ["Time", "Indoor temp degC", "Gas [kWh]", "Lights [kWh]", "Sockets [kWh]"]
    export = _export(tmp_path / "bms.csv", header, rows)
    argv = ["site", "import", str(export), "--out", str(tmp_path / "site"), "--epw", "usa_il_chicago"]
    argv += ["--floor-area", str(AREA), "--floors", "3", "--meter", "heating"]
    argv += ["--electricity-column", "Lights [kWh]", "--electricity-column", "Sockets [kWh]"]
    assert main([*argv, "--electricity-meter", "lighting,plug_loads"]) == 0
    site = load_site(tmp_path / "site")
    np.testing.assert_allclose(site.consumption_kwh.ravel(), heat, atol=1.5e-4)
    np.testing.assert_allclose(site.electricity_kwh.ravel(), power, atol=1.5e-4)
    assert (site.consumption_end_uses, site.electricity_end_uses) == (("heating",), ("lighting", "plug_loads"))
    capsys.readouterr()
    assert main(["site", "show", str(tmp_path / "site")]) == 0
    assert json.loads(capsys.readouterr().out)["electricity_meter"] == ["lighting", "plug_loads"]
    assert main([*argv[:4], str(tmp_path / "other"), *argv[5:]]) == 2  # columns without their end uses
    assert "give both" in capsys.readouterr().err and not (tmp_path / "other").exists()


def test_temperature_gaps_are_reported_or_filled_when_asked(tmp_path):
    start = dt.date(2024, 1, 8)
    t, q = _truth(3)
    rows = _hourly_rows(start, t, q)
    for h in (30, 31, 100, 101, 102):  # a 2-hour gap and a 3-hour one
        rows[h][1] = ""
    export = _export(tmp_path / "bms.csv", ["timestamp", "temperature_c", "energy_kwh"], rows)
    report = import_export(export, tmp_path / "gaps", **SITE)
    assert report.missing_temperature_hours == 5 and report.filled_temperature_hours == 0
    assert report.notes == [
        f"{export}: 5 hour(s) without temperature, the first from 2024-01-09 06:00 standard time (after line 31); "
        "they stay gaps, masked in comparisons"
    ]
    assert np.isnan(load_site(tmp_path / "gaps").temperature_c.ravel()[[30, 31, 100, 101, 102]]).all()

    report = import_export(export, tmp_path / "filled", options=ImportOptions(fill_temperature_gaps=True), **SITE)
    assert report.filled_temperature_hours == 2 and report.missing_temperature_hours == 3
    filled = load_site(tmp_path / "filled").temperature_c.ravel()
    np.testing.assert_allclose(filled[[30, 31]], t[29] + (t[32] - t[29]) * np.array([1, 2]) / 3, atol=1e-3)
    assert np.isnan(filled[[100, 101, 102]]).all()


def test_a_bad_column_name_gives_one_line_and_no_folder(tmp_path, capsys):
    start = dt.date(2024, 3, 4)
    export = _dst_export(tmp_path / "bms.csv", start, *_truth(0))
    out = tmp_path / "new" / "site"
    argv = ["site", "import", str(export), "--out", str(out), "--epw", "usa_il_chicago", "--floor-area", str(AREA)]
    argv += ["--floors", "3", "--time-zone", "America/Chicago", "--cumulative", "--temperature-column", "Zone Tmp (F)"]
    assert main(argv) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"buildenv site: error: {export}:1: no column 'Zone Tmp (F)'")
    assert "did you mean 'Zone Temp (°F)'?" in lines[0] and "give --temperature-column one of" in lines[0]
    assert not (tmp_path / "new").exists()


@pytest.mark.parametrize(
    "change, options, expected",
    [
        (
            lambda rows: rows[500].__setitem__(2, "1000.000"),
            {"cumulative": True, "time_zone": "America/Chicago"},
            r"bms.csv:502: Main meter \[Wh\] reading 1000 is below the previous .* \(line 501\): a meter reset",
        ),
        (
            lambda rows: None,
            {"time_zone": "America/Chicago"},
            r"bms.csv:2: Main meter \[Wh\] never falls, .*pass --cumulative",
        ),
        (
            lambda rows: None,
            {"cumulative": True},
            r"bms.csv:\d+: no row for 2024-03-10 02:00, on the March Sunday clocks go forward .*--time-zone America/",
        ),
        (
            lambda rows: None,
            {"cumulative": True, "time_zone": "America/New_York"},
            r"bms.csv: --time-zone America/New_York keeps standard time UTC-5 h, the weather file \(usa_il_chicago\) "
            r"UTC-6 h: the data would be 1 h off the weather's; give the zone of the export's clock \(--time-zone\), "
            r"or the weather file of the building's place \(--epw\)$",
        ),
        (
            lambda rows: None,
            {"cumulative": True, "time_zone": "America/Chicgo"},
            r"^--time-zone 'America/Chicgo': unknown time zone \(did you mean 'America/Chicago'\?\): .* needs no "
            r"--time-zone\)$",
        ),
        (
            lambda rows: None,
            {"cumulative": True, "time_zone": "America/Chicago", "units": {"Main meter [Wh]": "kWh"}},
            r"bms.csv:\d+: the hourly sum of 'Main meter \[Wh\]', [\d.]+ kWh, is above 1 kWh/m2 in one hour .*; looks "
            r"like Wh: check the columns' units, --unit COLUMN=UNIT$",
        ),
        (
            lambda rows: rows[7].__setitem__(1, "150"),
            {"cumulative": True, "time_zone": "America/Chicago"},
            r"bms.csv:9: Zone Temp \(°F\)=150 read in degF is 65.6 degC, outside \[-20, 50\]",
        ),
        (
            lambda rows: rows[9].__setitem__(0, "2024-03-04 02:20"),
            {"cumulative": True, "time_zone": "America/Chicago"},
            r"bms.csv:11: the reading at 2024-03-04 02:20:00 standard time is off the export's 15-minute grid",
        ),
    ],
)
def test_what_the_importer_cannot_fix_is_one_line_at_its_line_and_leaves_nothing(tmp_path, change, options, expected):
    export = _dst_export(tmp_path / "bms.csv", dt.date(2024, 3, 4), *_truth(0))
    header, *rows = [line.split(",") for line in export.read_text(encoding="utf-8").splitlines()]
    change(rows)
    _export(export, header, rows)
    out = tmp_path / "new" / "site"
    with pytest.raises(SiteError, match=expected) as error:
        import_export(export, out, options=ImportOptions(**options), **SITE)
    assert "\n" not in str(error.value)
    assert not (tmp_path / "new").exists()


def test_a_site_that_does_not_load_is_not_left_half_written(tmp_path):
    export = _dst_export(tmp_path / "bms.csv", dt.date(2024, 3, 4), *_truth(0))
    options = ImportOptions(time_zone="America/Chicago", cumulative=True)
    with pytest.raises(SiteError, match="pc_night_percent"):  # refused by load_site after writing
        import_export(export, tmp_path / "new" / "site", options=options, known={"pc_night_percent": 500.0}, **SITE)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bms.csv"]


def test_a_closing_midnight_row_does_not_make_a_week_of_its_own(tmp_path):
    start = dt.date(2024, 1, 8)
    t, q = _truth(4)
    rows = _hourly_rows(start, t, q)
    rows.append([f"{start + dt.timedelta(weeks=WEEKS):%Y-%m-%d} 00:00", "21.000", "30.0000"])  # the next Monday's
    export = _export(tmp_path / "bms.csv", ["timestamp", "temperature_c", "energy_kwh"], rows)
    report = import_export(export, tmp_path / "site", **SITE)
    _same(tmp_path / "site", _handmade(tmp_path / "handmade", start, t, q))
    assert report.notes == [
        f"{export}: the week of 2024-01-22 holds 1 measured hour(s), under a day: left out (an export's closing "
        "midnight row, or an hour daylight saving time moved across a Monday)"
    ]


def test_a_heating_meter_in_mwh_is_named_and_its_unit_reads_it(tmp_path):
    """A meter of heating alone, in MWh under a kWh name, in January: named by the weeks that need heating; the
    unit it names reads the hand-made site."""
    start = dt.date(2024, 1, 8)
    t, q = _truth(6)
    rows = [
        [stamp, temperature, f"{mwh:.7f}"] for (stamp, temperature, _), mwh in zip(_hourly_rows(start, t, q), q / 1000)
    ]
    export = _export(tmp_path / "bms.csv", ["timestamp", "temperature_c", "heat_kwh"], rows)
    site = {**SITE, "end_uses": ("heating",)}
    with pytest.raises(
        SiteError,
        match=r"bms.csv:\d+: .* that need heating .*: below the 1 W/m2 .*looks like MWh or GJ: "
        r"check the columns' units, --unit COLUMN=UNIT$",
    ):
        import_export(export, tmp_path / "site", **site)
    import_export(export, tmp_path / "site", options=ImportOptions(units={"heat_kwh": "MWh"}), **site)
    handmade = _handmade(tmp_path / "handmade", start, t, q)
    toml = handmade / "site.toml"
    toml.write_text(toml.read_text() + '\n[meters]\nconsumption = ["heating"]\n')
    _same(tmp_path / "site", handmade)


@pytest.mark.parametrize("unit, offset, right", [("K", 0.0, "degC"), ("degC", 273.15, "K"), ("degC", 50.0, "degF")])
def test_a_temperature_read_in_the_wrong_unit_names_the_unit_that_fits(tmp_path, unit, offset, right):
    start = dt.date(2024, 1, 8)
    t, q = _truth(5)
    t = t + offset if right != "degF" else t * 1.8 + 32.0
    export = _export(tmp_path / "bms.csv", ["timestamp", "zone_temp", "energy_kwh"], _hourly_rows(start, t, q))
    options = ImportOptions(units={"zone_temp": unit})
    with pytest.raises(SiteError, match=rf"--unit 'zone_temp={right}'"):
        import_export(export, tmp_path / "site", options=options, **SITE)
