"""Morphed weather files: what a morph changes, what it keeps, and the errors a user can act on."""

from __future__ import annotations

import json

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.cli.main import main
from buildenv.errors import WeatherError
from buildenv.weather.epw import load_weather, resolve_epw
from buildenv.weather.morph import (
    MORPH_RANGES,
    Morph,
    draw_morph,
    morph_epw,
    morph_many,
    morph_rows,
    morph_source,
    morph_weather,
    weather_year,
)

DAYS = np.array([31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31])


def _channel(w, name):
    return w.hourly[:, cat.WEATHER_NAMES.index(name)]


def _rows(path):
    lines = path.read_text(encoding="latin-1").splitlines()
    return lines[:8], [line.split(",") for line in lines[8:] if line.strip()]


def test_the_identity_morph_leaves_every_channel_as_it_was(tmp_path):
    out = morph_epw("usa_il_chicago", tmp_path / "same.epw", Morph())
    np.testing.assert_array_equal(load_weather(out).hourly, load_weather("usa_il_chicago").hourly)


def test_a_morph_shifts_and_stretches_the_temperature_and_scales_solar_and_wind(tmp_path):
    morph = Morph(shift_k=3.0, stretch=1.2, solar_scale=0.8, wind_scale=1.5)
    base, new = load_weather("usa_il_chicago"), load_weather(morph_epw("usa_il_chicago", tmp_path / "m.epw", morph))
    t = _channel(base, "TAMB")
    month = np.repeat(np.arange(12), DAYS * 24)
    mean = np.array([t[month == m].mean() for m in range(12)])[month]
    np.testing.assert_allclose(_channel(new, "TAMB"), t + 3.0 + 0.2 * (t - mean), atol=0.051)  # 0.1 K in the file
    assert _channel(new, "TAMB").std() > t.std()  # the stretch widens the swings
    for name in ("IGLOB_H", "DNI", "IDIFF_H"):
        np.testing.assert_allclose(_channel(new, name), 0.8 * _channel(base, name), atol=0.51)
    np.testing.assert_allclose(_channel(new, "WIND_SPEED"), 1.5 * _channel(base, "WIND_SPEED"), atol=0.051)
    np.testing.assert_array_equal(_channel(new, "WIND_DIR"), _channel(base, "WIND_DIR"))
    rh = _channel(new, "RHUM")
    assert rh.min() >= 0 and rh.max() <= 100
    assert abs(rh.mean() - _channel(base, "RHUM").mean()) < 3  # the dew-point depression is kept
    header, rows = _rows(tmp_path / "m.epw")
    _, source_rows = _rows(resolve_epw("usa_il_chicago"))
    assert all(float(r[7]) <= float(r[6]) for r in rows)  # dew point never above the dry bulb
    assert [r[:6] for r in rows] == [r[:6] for r in source_rows]  # calendar and flags kept
    assert [r[9] for r in rows] == [r[9] for r in source_rows]  # pressure kept
    warmer = [float(r[12]) > float(s[12]) for r, s in zip(rows, source_rows) if float(r[6]) > float(s[6])]
    assert np.mean(warmer) > 0.9  # a warmer hour has a warmer sky
    ground = header[3].split(",")
    source_ground = _rows(resolve_epw("usa_il_chicago"))[0][3].split(",")
    assert float(ground[6]) == pytest.approx(float(source_ground[6]) + 3.0)
    assert header[6].startswith("COMMENTS 2,buildenv morph of") and '"shift_k": 3.0' in header[6]


def test_values_marked_missing_stay_missing():
    rows = np.zeros((8760, 35))
    rows[:, 6], rows[:, 7], rows[:, 8], rows[:, 12], rows[:, 13], rows[:, 21] = 10.0, 5.0, 70.0, 300.0, 200.0, 3.0
    rows[5, 12], rows[6, 13], rows[7, 21], rows[8, 6] = 9999.0, 9999.0, 999.0, 99.9
    new = morph_rows(rows, Morph(shift_k=2.0, solar_scale=1.1, wind_scale=1.3))
    assert (new[5, 12], new[6, 13], new[7, 21], new[8, 6]) == (9999.0, 9999.0, 999.0, 99.9)
    assert new[0, 6] == 12.0 and new[0, 13] == pytest.approx(220.0) and new[0, 21] == pytest.approx(3.9)


def test_random_morphs_are_seeded_and_listed(tmp_path):
    a = morph_many(["usa_il_chicago", "usa_fl_miami"], tmp_path / "a", seed=4, stretch=1.0)
    b = morph_many(["usa_il_chicago", "usa_fl_miami"], tmp_path / "b", seed=4, stretch=1.0)
    assert [{k: v for k, v in r.items() if k != "file"} for r in a] == [
        {k: v for k, v in r.items() if k != "file"} for r in b
    ]
    assert a[0]["shift_k"] != a[1]["shift_k"] and all(r["stretch"] == 1.0 for r in a)
    for r in a:
        for name, (low, high) in MORPH_RANGES.items():
            assert low <= r[name] <= high
    assert json.loads((tmp_path / "a" / "morphs.json").read_text()) == a
    assert load_weather(a[1]["file"]).latitude_deg == load_weather("usa_fl_miami").latitude_deg
    assert morph_source(a[1]["file"]) == resolve_epw("usa_fl_miami").name
    assert morph_source("usa_fl_miami") is None and morph_source(tmp_path / "missing.epw") is None


def test_bad_morphs_and_files_are_refused_with_the_line(tmp_path):
    with pytest.raises(WeatherError, match="wind_scale"):
        Morph(wind_scale=-0.1)
    with pytest.raises(WeatherError, match="unknown morph value"):
        draw_morph(np.random.default_rng(0), shift=2.0)
    lines = resolve_epw("usa_il_chicago").read_text(encoding="latin-1").splitlines()
    fields = lines[20].split(",")
    fields[6] = "warm"
    bad = tmp_path / "bad.epw"
    bad.write_text("\n".join(lines[:20] + [",".join(fields)] + lines[21:]) + "\n", encoding="latin-1")
    with pytest.raises(WeatherError, match=r"bad.epw, line 21, field 7: 'warm'"):
        morph_epw(bad, tmp_path / "out.epw", Morph(shift_k=1.0))
    with pytest.raises(WeatherError, match="weather file not found"):
        morph_epw(tmp_path / "missing.epw", tmp_path / "out.epw", Morph())


def test_the_command_writes_one_morph_or_a_seeded_set(tmp_path, capsys):
    out = tmp_path / "chicago_plus2.epw"
    assert main(["morph-weather", "--epw", "usa_il_chicago", "--out", str(out), "--shift-k", "2"]) == 0
    assert json.loads(capsys.readouterr().out)[0]["file"] == str(out)
    assert _channel(load_weather(out), "TAMB").mean() == pytest.approx(
        _channel(load_weather("usa_il_chicago"), "TAMB").mean() + 2.0, abs=0.01
    )
    assert (
        main(
            [
                "morph-weather",
                "--epw",
                "usa_il_chicago",
                "usa_fl_miami",
                "--out-dir",
                str(tmp_path / "set"),
                "--seed",
                "3",
            ]
        )
        == 0
    )
    assert len(json.loads(capsys.readouterr().out)) == 2
    assert main(["morph-weather", "--epw", "usa_il_chicago", "usa_fl_miami", "--out", str(out)]) == 2
    assert "give one --epw" in capsys.readouterr().err


def test_energyplus_runs_a_morphed_file_and_a_warmer_january_needs_less_heat(tmp_path):
    from buildenv.defaults import DEFAULT_THETA, default_week
    from buildenv.energyplus.simulate import simulate_weeks

    settings, occupancy = default_week()
    warm = morph_epw("usa_il_chicago", tmp_path / "warm.epw", Morph(shift_k=6.0))
    heat = {}
    for label, epw in (("as is", "usa_il_chicago"), ("+6 K", warm)):
        result = simulate_weeks(DEFAULT_THETA, settings, occupancy, epw, 2)
        np.testing.assert_allclose(
            result.weather[0][:, cat.WEATHER_NAMES.index("TAMB")],
            load_weather(epw).weeks(2, 1)[0][:, cat.WEATHER_NAMES.index("TAMB")],
        )
        heat[label] = float(
            result.outputs[0][:, [i for i, n in enumerate(cat.OUTPUT_NAMES) if n != "T_INT_OFFICE"]].sum()
        )
    assert heat["+6 K"] < 0.9 * heat["as is"]


def test_the_morph_in_memory_reads_as_the_morphed_file(tmp_path):
    morph = Morph(shift_k=2.0, stretch=1.15, solar_scale=0.9, wind_scale=1.2)
    source = load_weather("usa_il_chicago")
    in_memory = morph_weather(source, morph)
    from_file = load_weather(morph_epw("usa_il_chicago", tmp_path / "m.epw", morph))
    # the file rounds to its fields' precision: 0.1 K, 0.1 m/s, whole Wh/m2 and %
    for name, tolerance in (("TAMB", 0.051), ("WIND_SPEED", 0.051), ("IGLOB_H", 0.51), ("DNI", 0.51), ("RHUM", 1.0)):
        column = cat.WEATHER_NAMES.index(name)
        np.testing.assert_allclose(in_memory.hourly[:, column], from_file.hourly[:, column], atol=tolerance)

    # the humidity keeps the dew-point depression: the dew point (Magnus) moves with the dry bulb
    def dew_point(w):
        t, rh = w.channel("TAMB"), np.clip(w.channel("RHUM"), 0.1, 100.0)
        gamma = np.log(rh / 100.0) + 17.625 * t / (243.04 + t)
        return 243.04 * gamma / (17.625 - gamma)

    moved = dew_point(in_memory) - dew_point(source)
    shift = in_memory.channel("TAMB") - source.channel("TAMB")
    kept = in_memory.channel("RHUM") < 99.9  # not capped at saturation
    np.testing.assert_allclose(moved[kept], shift[kept], atol=0.01)
    assert np.abs(shift).max() > 4.0
    warmer = in_memory.channel("TAMB").mean() - source.channel("TAMB").mean()
    assert warmer == pytest.approx(2.0, abs=1e-6) and not in_memory.hourly.flags.writeable
    assert in_memory.latitude_deg == source.latitude_deg and np.array_equal(
        source.channel("TAMB"), load_weather("usa_il_chicago").channel("TAMB")
    )


def test_weather_years_are_the_same_morph_every_time_and_year_0_is_the_file():
    assert weather_year(0) == Morph()
    assert weather_year(3) == weather_year(3) != weather_year(4)
    for name, (low, high) in MORPH_RANGES.items():
        assert low <= getattr(weather_year(3), name) <= high
