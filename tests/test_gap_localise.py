"""Residual localisation (buildenv.diagnosis.localise) on synthetic residuals: fast, no EnergyPlus, no torch."""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pytest

from buildenv import catalogue as cat
from buildenv.diagnosis.localise import LocalisationError, localise, plot_localisation, residual_tests

WEEKS = 6
H = cat.HOURS_PER_WEEK


def _ar1(rng: np.random.Generator, n: int, phi: float) -> np.ndarray:
    x = np.zeros(n)
    e = rng.normal(size=n)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    return x


@pytest.fixture()
def site() -> dict:
    """Six weeks of weather, occupancy (weekdays 08-18) and heating (weekdays 06-19, Saturday 09-13)."""
    rng = np.random.default_rng(0)
    n = WEEKS * H
    hour = np.arange(n) % 24
    day = (np.arange(n) // 24) % 7
    weather = np.zeros((n, len(cat.WEATHER_NAMES)))
    col = {name: i for i, name in enumerate(cat.WEATHER_NAMES)}
    sun = np.clip(np.sin(np.pi * (hour - 6) / 12), 0, None)
    cloud = np.repeat(rng.uniform(0.1, 1.0, n // 24), 24)
    weather[:, col["IGLOB_H"]] = 700 * sun * cloud
    weather[:, col["TAMB"]] = 5 + 4 * np.sin(2 * np.pi * (hour - 9) / 24) + 2 * _ar1(rng, n, 0.98) / 5
    weather[:, col["WIND_SPEED"]] = np.abs(4 + 1.5 * _ar1(rng, n, 0.9))
    weather[:, col["RHUM"]] = 70
    occupied = (day < 5) & (hour >= 8) & (hour < 18)
    heating = ((day < 5) & (hour >= 6) & (hour < 19)) | ((day == 5) & (hour >= 9) & (hour < 13))
    predicted_t = 20 + 1.5 * heating + 0.002 * weather[:, col["IGLOB_H"]]
    predicted_q = 5 + 20 * heating * np.clip(15 - weather[:, col["TAMB"]], 0, None) / 10
    starts = [dt.date(2024, 1, 1) + dt.timedelta(days=7 * w) for w in range(WEEKS)]
    return {
        "weather": weather.reshape(WEEKS, H, -1),
        "occupied": occupied.reshape(WEEKS, H),
        "heating_on": heating.reshape(WEEKS, H),
        "predicted_t": predicted_t.reshape(WEEKS, H),
        "predicted_q": predicted_q.reshape(WEEKS, H),
        "week_starts": starts,
        "rng": rng,
    }


def _run(site: dict, residual_t: np.ndarray, residual_q: np.ndarray | None = None) -> dict:
    if residual_q is None:
        residual_q = site["rng"].normal(0, 1.0, (WEEKS, H))
    return localise(
        site["predicted_t"] + residual_t,
        site["predicted_q"] + residual_q,
        site["predicted_t"],
        site["predicted_q"],
        site["weather"],
        site["occupied"],
        site["heating_on"],
        site["week_starts"],
    )


def test_white_noise_is_white_unbiased_and_has_no_hotspot(site):
    out = _run(site, site["rng"].normal(0, 0.3, (WEEKS, H)))
    t = out["temperature"]
    assert t["tests"]["whiteness"]["white"]
    assert abs(t["tests"]["whiteness"]["lag1_autocorrelation"]) < 0.1
    assert not t["tests"]["bias"]["significant"]
    assert t["hotspots"] == []
    for members in t["groups"].values():
        for g in members.values():
            if g["hours"] >= 100:
                assert 0.7 < g["concentration"] < 1.3
    assert "no hour group concentrates the error" in t["summary"]


def test_wind_driven_residual(site):
    wind = site["weather"][..., cat.WEATHER_NAMES.index("WIND_SPEED")]
    residual = -0.15 * wind + site["rng"].normal(0, 0.1, (WEEKS, H))  # infiltration: colder when windy
    t = _run(site, residual)["temperature"]
    tests = t["tests"]
    assert tests["strongest_driver"] == "wind_speed"
    d = tests["drivers"]["wind_speed"]
    assert d["best_lag"] == 0 and d["best_correlation"] < -0.9 and d["significant"][0]
    others = [abs(v["best_correlation"]) for k, v in tests["drivers"].items() if k != "wind_speed"]
    assert max(others) < abs(d["best_correlation"])
    assert not tests["whiteness"]["white"]
    assert t["groups"]["wind"]["windy"]["concentration"] > 1.2
    assert t["groups"]["wind"]["windy"]["share_sse"] > t["groups"]["wind"]["calm"]["share_sse"]
    assert any(h["name"] == "wind/windy" for h in t["hotspots"])


def test_constant_bias_is_significant(site):
    out = _run(site, -0.5 + site["rng"].normal(0, 0.3, (WEEKS, H)))
    bias = out["temperature"]["tests"]["bias"]
    assert bias["significant"] and bias["p_value"] < 1e-6
    assert bias["mean"] == pytest.approx(-0.5, abs=0.05)
    assert out["temperature"]["bias"] == pytest.approx(bias["mean"])
    assert "measured lower than predicted" in out["temperature"]["summary"]


def test_startup_residual_is_the_top_hotspot(site):
    from buildenv.diagnosis.localise import heating_startup

    startup = heating_startup(site["heating_on"])
    # weekdays 06-09 and Saturday 09-12
    assert startup.sum() == WEEKS * (5 * 3 + 3)
    residual = np.where(startup, -1.0, 0.0) + site["rng"].normal(0, 0.1, (WEEKS, H))
    t = _run(site, residual)["temperature"]
    top = t["hotspots"][0]
    assert top["name"] == "heating/startup"
    assert top["share_sse"] > 0.8 and top["concentration"] > 5
    assert "measured lower than predicted" in top["description"]
    assert t["groups"]["heating"]["startup"]["mean_residual"] == pytest.approx(-1.0, abs=0.05)
    grid = np.array(t["by_hour_weekday"]["mean_residual"], float)
    assert grid[0, 6:9].mean() < -0.9 and abs(grid[0, 12]) < 0.2
    assert t["tests"]["drivers"]["heating_start"]["significant"][0]


def test_nan_hours_are_skipped(site):
    residual = site["rng"].normal(0, 0.3, (WEEKS, H))
    measured_t = site["predicted_t"] + residual
    measured_t[1, 10:60] = np.nan
    measured_t[3] = np.nan
    measured_q = site["predicted_q"].copy()
    measured_q[:, :24] = np.nan
    out = localise(
        measured_t,
        measured_q,
        site["predicted_t"],
        site["predicted_q"],
        site["weather"],
        site["occupied"],
        site["heating_on"],
        site["week_starts"],
    )
    t = out["temperature"]
    assert t["hours"] == WEEKS * H - 50 - H and t["missing_hours"] == 50 + H
    assert t["bias"] == pytest.approx(np.nanmean(measured_t - site["predicted_t"]))
    assert t["groups"]["week"]["2024-01-22"]["hours"] == 0
    assert t["groups"]["week"]["2024-01-22"]["mean_residual"] is None
    assert sum(g["hours"] for g in t["groups"]["occupancy"].values()) == t["hours"]
    assert np.isfinite(t["tests"]["whiteness"]["ljung_box_q"])
    assert out["consumption"]["by_hour_weekday"]["hours"][0][:24] == [0] * 24
    json.dumps(out, allow_nan=False)


def test_all_missing_series(site):
    nan = np.full((WEEKS, H), np.nan)
    out = localise(
        nan,
        site["predicted_q"],
        site["predicted_t"],
        site["predicted_q"],
        site["weather"],
        site["occupied"],
        site["heating_on"],
        site["week_starts"],
    )
    assert out["temperature"]["hours"] == 0 and out["temperature"]["hotspots"] == []
    json.dumps(out, allow_nan=False)


def test_output_is_json_serialisable(site):
    out = _run(site, site["rng"].normal(0, 0.3, (WEEKS, H)))
    text = json.dumps(out, allow_nan=False)
    back = json.loads(text)
    assert set(back) >= {"weeks", "hours", "thresholds", "temperature", "consumption"}
    grid = back["consumption"]["by_hour_weekday"]
    assert np.array(grid["mean_residual"], float).shape == (7, 24)
    assert sum(map(sum, grid["share_sse"])) == pytest.approx(1.0)
    assert sum(g["share_sse"] for g in back["temperature"]["groups"]["week"].values()) == pytest.approx(1.0)


def test_gap_between_weeks_breaks_autocorrelation_pairs(site):
    starts = list(site["week_starts"])
    starts[3] = starts[3] + dt.timedelta(days=14)
    r = site["rng"].normal(0, 1, (WEEKS, H))
    a = residual_tests(r, {}, starts)
    b = residual_tests(r, {}, site["week_starts"])
    assert a["whiteness"]["lag1_autocorrelation"] != b["whiteness"]["lag1_autocorrelation"]


def test_bad_shapes_raise(site):
    with pytest.raises(LocalisationError, match="weather"):
        localise(
            site["predicted_t"],
            site["predicted_q"],
            site["predicted_t"],
            site["predicted_q"],
            site["weather"][..., :7],
            site["occupied"],
            site["heating_on"],
            site["week_starts"],
        )


def test_plot_writes_png(site, tmp_path):
    residual = site["rng"].normal(0, 0.3, (WEEKS, H))
    out = _run(site, residual)
    path = plot_localisation(
        out,
        tmp_path / "gap" / "localisation.png",
        site["predicted_t"] + residual,
        site["predicted_q"],
        site["predicted_t"],
        site["predicted_q"],
        site["occupied"],
    )
    assert path.is_file() and path.stat().st_size > 1000
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    only_maps = plot_localisation(out, tmp_path / "maps.png")
    assert only_maps.stat().st_size > 1000
