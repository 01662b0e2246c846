"""EPW weather files read into the catalogue's weather channels."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError, WeatherError
from buildenv.weather.epw import HOURS_PER_YEAR, Weather, load_weather, resolve_epw, shipped_weather

DAYS_PER_MONTH = np.array([31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31])
MONTH_START_H = np.concatenate([[0], np.cumsum(DAYS_PER_MONTH * 24)])


@pytest.fixture(scope="module")
def chicago() -> Weather:
    return load_weather("usa_il_chicago")


def _month(series: np.ndarray, month: int) -> np.ndarray:
    """``month`` 1-12."""
    return series[MONTH_START_H[month - 1] : MONTH_START_H[month]]


# --------------------------------------------------------------------------- resolve_epw
def test_shipped_weather_lists_chicago():
    shipped = shipped_weather()
    assert "usa_il_chicago" in shipped
    assert len(shipped) >= 10
    assert all(Path(p).suffix.lower() == ".epw" for p in shipped.values())


def test_resolve_short_name_and_path():
    path = resolve_epw("usa_il_chicago")
    assert path.is_file() and path.suffix.lower() == ".epw"
    again = resolve_epw(str(path))
    assert again.is_file()
    assert again == path.resolve()
    assert resolve_epw(path) == path.resolve()  # a Path object works too


def test_resolve_missing_path_names_it(tmp_path):
    missing = tmp_path / "nowhere" / "city.epw"
    with pytest.raises(WeatherError, match="not found") as info:
        resolve_epw(missing)
    assert str(missing) in str(info.value)
    with pytest.raises(WeatherError, match="nowhere.epw"):
        resolve_epw("nowhere.epw")


def test_resolve_unknown_name_names_it_and_lists_choices():
    with pytest.raises(WeatherError) as info:
        resolve_epw("usa_il_chicagoo")
    msg = str(info.value)
    assert "'usa_il_chicagoo'" in msg
    assert "usa_il_chicago" in msg.replace("'usa_il_chicagoo'", "")
    assert isinstance(info.value, BuildenvError)


# --------------------------------------------------------------------------- load_weather
def test_load_chicago_shape_and_metadata(chicago):
    assert isinstance(chicago, Weather)
    assert chicago.name == "usa_il_chicago"
    assert chicago.hourly.shape == (HOURS_PER_YEAR, len(cat.WEATHER_NAMES)) == (8760, 9)
    assert np.isfinite(chicago.hourly).all()
    assert chicago.latitude_deg == pytest.approx(41.98, abs=0.2)
    assert chicago.longitude_deg == pytest.approx(-87.9, abs=0.3)
    assert chicago.timezone_h == -6
    assert not chicago.hourly.flags.writeable


def test_values_within_catalogue_ranges(chicago):
    cat.check_values("weather", chicago.hourly, "usa_il_chicago")
    assert chicago.channel("RHUM").max() <= 100
    assert chicago.channel("WIND_DIR").max() <= 360


def test_channel_by_name_and_alias(chicago):
    tamb = chicago.channel("TAMB")
    assert tamb.shape == (8760,)
    np.testing.assert_array_equal(tamb, chicago.hourly[:, cat.WEATHER_NAMES.index("TAMB")])
    with pytest.raises(BuildenvError):
        chicago.channel("NOT_A_CHANNEL")


def test_load_by_path_equals_load_by_name(chicago):
    by_path = load_weather(resolve_epw("usa_il_chicago"))
    np.testing.assert_array_equal(by_path.hourly, chicago.hourly)


def test_chicago_seasons(chicago):
    tamb = chicago.channel("TAMB")
    assert _month(tamb, 1).mean() < 0
    assert _month(tamb, 7).mean() > 20
    monthly = chicago.monthly_mean_temperature_c()
    assert monthly.shape == (12,)
    assert monthly[0] == pytest.approx(_month(tamb, 1).mean())
    assert monthly[6] == pytest.approx(_month(tamb, 7).mean())
    assert np.argmax(monthly) in (5, 6, 7) and np.argmin(monthly) in (0, 1, 11)


def test_irradiance_zero_at_night(chicago):
    hour_of_day = np.arange(8760) % 24
    night = (hour_of_day <= 2) | (hour_of_day >= 22)  # local standard time, Chicago
    for name in ("DNI", "IBEAM_H", "IBEAM_N", "IDIFF_H", "IGLOB_H"):
        assert chicago.channel(name)[night].max() == 0, name


def test_beam_horizontal_consistent_with_global_minus_diffuse(chicago):
    ghi, dhi = chicago.channel("IGLOB_H"), chicago.channel("IDIFF_H")
    beam_h, dni = chicago.channel("IBEAM_H"), chicago.channel("DNI")
    assert np.all(beam_h <= ghi + 1)
    assert np.all(beam_h <= dni + 1e-9)
    assert np.all(beam_h >= 0)
    up = ghi > 20
    assert up.sum() > 3000
    diff = np.abs(beam_h - (ghi - dhi))[up]
    assert np.median(diff) < 5
    assert np.percentile(diff, 90) < 25
    # beam is a sizeable share of global in the sunny hours, not zero by accident
    assert beam_h.sum() > 0.3 * ghi.sum()


def test_north_facade_beam(chicago):
    beam_n, dni = chicago.channel("IBEAM_N"), chicago.channel("DNI")
    assert np.all(beam_n >= 0) and np.all(beam_n <= dni + 1e-9)
    # midwinter at 42 N: the sun always stays south of east-west, no beam on a north facade
    winter = np.r_[0 : MONTH_START_H[1], MONTH_START_H[11] : 8760]
    assert beam_n[winter].max() == 0
    assert dni[winter].max() > 500  # ... although the sun does shine
    # June: the sun rises and sets north of east/west -> north facade lit early and late, never at noon
    june = _month(beam_n, 6).reshape(30, 24)
    assert june[:, 4:8].max() > 20
    assert june[:, 16:20].max() > 20
    assert june[:, 10:14].max() == 0
    # around noon the sun is south all year long at this latitude
    assert beam_n.reshape(365, 24)[:, 10:14].max() == 0


def test_weeks(chicago):
    two = chicago.weeks(0, 2)
    assert two.shape == (2, 168, 9)
    np.testing.assert_array_equal(two[1], chicago.hourly[168:336])
    last = chicago.weeks(51, 1)
    assert last.shape == (1, 168, 9)
    np.testing.assert_array_equal(last[0], chicago.hourly[51 * 168 : 52 * 168])


@pytest.mark.parametrize("start, n", [(52, 1), (51, 2), (-1, 1), (0, 53)])
def test_weeks_outside_the_year_raise(chicago, start, n):
    with pytest.raises(WeatherError, match="outside the year"):
        chicago.weeks(start, n)


# --------------------------------------------------------------------------- malformed files
def test_garbage_epw_raises(tmp_path):
    bad = tmp_path / "garbage.epw"
    bad.write_text("this is not\nan EPW file\n\x00\x01 at all\n")
    with pytest.raises(WeatherError) as info:
        load_weather(bad)
    assert str(bad) in str(info.value)


def test_truncated_epw_raises(tmp_path):
    lines = resolve_epw("usa_il_chicago").read_text(errors="replace").splitlines(keepends=True)
    short = tmp_path / "short.epw"
    short.write_text("".join(lines[: 8 + 100]))  # header + 100 hours
    with pytest.raises(WeatherError, match="8760.*found 100"):
        load_weather(short)


def test_empty_epw_raises(tmp_path):
    empty = tmp_path / "empty.epw"
    empty.write_text("")
    with pytest.raises(WeatherError):
        load_weather(empty)
