"""The model side of the effects catalogue: additions to the metamodel that calibration can estimate.

Each effect of :mod:`buildenv.diagnosis.effects` acts at one place of a week, vectorised over ``N`` candidates:

- **inputs** (:func:`transform_inputs`, ``(N, context + 168, C)``): ``wind_infiltration`` makes the
  infiltration hourly, ``calibrated + ach_per_m_s x (share x wind speed - WIND_REFERENCE_M_S)`` (at least 0;
  share :data:`VENTILATED_WIND_SHARE` while the ventilation runs, else 1); ``solar_shading`` scales the irradiance
  inputs by ``1 - blocked_fraction``; ``evening_departure`` keeps the occupancy at ``share`` for ``hours`` after
  each day's occupancy ends (:data:`OCCUPIED_LEVEL`); ``holidays`` (:func:`absent_days_inputs`) lowers each
  day's occupancy by its absence share.
- **building outputs** (:func:`transform_outputs`, ``(N, 168, 8)``): ``night_plug_loads`` adds ``night_w_m2``
  to Q_EQP in unoccupied hours; ``heating_capacity_limit`` caps the heating at ``capacity_w_m2``, the heat not
  delivered lowering T_INT_OFFICE by ``sag_k_per_wh_m2`` per Wh/m2 (decaying over :data:`SAG_TIME_CONSTANT_H`);
  ``heat_recovery`` lowers Q_AHU_H by what an exchanger of effectiveness ``eff`` recovers;
  ``night_cycle_cold_air`` lowers T_INT_OFFICE by ``cooling_k_per_wh_m2`` and raises Q_HEAT_OFFICE by
  ``reheat_share`` per Wh/m2 of predicted heating while the ventilation is off, and after the heating period
  takes the heat ``D`` of supply air ``supply_shortfall_k`` colder than ``supply_air_c`` off Q_AHU_H (and
  ``cooling_k_per_wh_m2 x D`` off T_INT_OFFICE).
- **sensor readings** (:func:`sensor_temperature`; the building's own temperature is untouched):
  ``temperature_sensor_bias`` adds ``bias_k``; ``temperature_sensor_lag`` is the first-order lag ``y_t =
  y_{t-1} + (1 - exp(-1 / tau_h)) (x_t - y_{t-1})``, started at the first hour's value.

Parameters are passed as ``{effect name: array (N, number of its parameters)}``; an effect absent from the
mapping, or at its parameters' ``none`` values, changes nothing (bit for bit).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from buildenv import catalogue as cat
from buildenv.diagnosis.effects import EFFECTS, WIND_REFERENCE_M_S, get_effect
from buildenv.metamodel import surrogate as sg

INPUT_EFFECTS = ("wind_infiltration", "solar_shading", "evening_departure")
OUTPUT_EFFECTS = ("night_plug_loads", "heating_capacity_limit", "heat_recovery", "night_cycle_cold_air")
#: effects of the building itself, simulated for any week (holidays are dates of the measured period, and the
#: sensor effects are measurement matters)
BUILDING_EFFECTS = INPUT_EFFECTS + OUTPUT_EFFECTS
IRRADIANCE_INPUTS = ("DNI", "IBEAM_H", "IBEAM_N", "IDIFF_H", "IGLOB_H")
SAG_TIME_CONSTANT_H = 3.0
#: Share of the wind-driven infiltration left while the air handling unit runs (the building is pressurised):
#: the convention of the DOE reference buildings' infiltration schedules, and the stand-in's own.
VENTILATED_WIND_SHARE = 0.25

_CH = {name: i for i, name in enumerate(sg.INPUT_CHANNELS)}
_OUT = {name: i for i, name in enumerate(cat.OUTPUT_NAMES)}


def none_parameters(name: str) -> np.ndarray:
    """The parameter vector ``(k,)`` at which effect ``name`` changes nothing."""
    return np.array([p.none for p in get_effect(name).parameters], dtype=float)


def parameter_names(effects: tuple[str, ...] | list[str]) -> list[str]:
    """Flat names ``effect.parameter`` of the effects' parameters, in vector order."""
    return [f"{e}.{p.name}" for e in effects for p in get_effect(e).parameters]


def bounds(effects: tuple[str, ...] | list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Calibration bounds ``(lo, hi)`` of the effects' parameters, in vector order."""
    ps = [p for e in effects for p in get_effect(e).parameters]
    return np.array([p.lo for p in ps], dtype=float), np.array([p.hi for p in ps], dtype=float)


def split_parameters(effects: tuple[str, ...] | list[str], values: np.ndarray) -> dict[str, np.ndarray]:
    """``(N, total)`` flat parameter values -> ``{effect: (N, k)}``."""
    values = np.atleast_2d(values)
    out, j = {}, 0
    for e in effects:
        k = len(get_effect(e).parameters)
        out[e] = values[:, j : j + k]
        j += k
    return out


def _column(params: Mapping[str, np.ndarray], name: str, j: int, n: int) -> np.ndarray | None:
    """Parameter ``j`` of effect ``name`` as ``(n, 1)``, or None when the effect is off for every week."""
    if name not in params:
        return None
    v = np.broadcast_to(np.asarray(params[name], dtype=float)[:, j], (n,))
    if np.all(v == EFFECTS[name].parameters[j].none):
        return None
    return v[:, None]


def transform_inputs(x: np.ndarray, params: Mapping[str, np.ndarray]) -> np.ndarray:
    """Apply the input effects to encoded inputs (and take a modelled sensor bias off the temperature measured
    before the week, where the inputs carry it: :data:`buildenv.metamodel.surrogate.TEMPERATURE_BEFORE_CHANNELS`).

    Args:
        x: ``(N, context + 168, C)`` physical inputs of :func:`buildenv.metamodel.surrogate.encode_weeks` (modified
            in place and returned).
        params: ``{effect: (N, k)}`` (or ``(1, k)``, broadcast).
    """
    n = len(x)
    k = _column(params, "wind_infiltration", 0, n)
    if k is not None:
        inf = _CH["infiltration_ach"]
        share = np.where(x[..., _CH["ventilation_on"]] > 0, VENTILATED_WIND_SHARE, 1.0)
        x[..., inf] = np.maximum(x[..., inf] + k * (share * x[..., _CH["WIND_SPEED"]] - WIND_REFERENCE_M_S), 0.0)
    s = _column(params, "solar_shading", 0, n)
    if s is not None:
        for name in IRRADIANCE_INPUTS:
            x[..., _CH[name]] *= 1.0 - s
    share, hours = (_column(params, "evening_departure", j, n) for j in (0, 1))
    if share is not None and hours is not None:  # either at its none value: no tail
        occ = x[..., _CH["occupancy_fraction"]]
        since = hours_since_occupied(occ > OCCUPIED_LEVEL)
        tail = share * np.clip(hours - since + 1.0, 0.0, 1.0) * (since >= 1)
        x[..., _CH["occupancy_fraction"]] = np.maximum(occ, tail)
    bias = _column(params, "temperature_sensor_bias", 0, n)
    if bias is not None and x.shape[-1] == len(sg.ALL_CHANNELS):  # the temperature measured before the week
        x[..., len(sg.INPUT_CHANNELS)] -= bias  # is the sensor's reading: the model wants the building's
    return x


#: An hour is occupied when its occupancy input is above this (the end of a day's occupancy, where a gradual
#: departure's tail starts; a tail above it counts as occupied, for ``night_plug_loads`` too).
OCCUPIED_LEVEL = 0.5


def hours_since_occupied(occupied: np.ndarray) -> np.ndarray:
    """``(N, T)`` hours since the last occupied hour of each sequence of booleans ``(N, T)`` (0 in occupied
    hours, ``inf`` before the first)."""
    t = np.arange(occupied.shape[-1], dtype=float)
    last = np.maximum.accumulate(np.where(occupied, t, -np.inf), axis=-1)
    return t - last


def occupied_hours(x: np.ndarray) -> np.ndarray:
    """``(N, 168)`` booleans: hours of the week the encoded inputs mark occupied (above :data:`OCCUPIED_LEVEL`)."""
    return x[:, sg.context_of(x) :, _CH["occupancy_fraction"]] > OCCUPIED_LEVEL


def absent_days_inputs(x: np.ndarray, absent: np.ndarray) -> np.ndarray:
    """Lower each day's occupancy input by its absence share (``holidays``).

    Args:
        x: ``(N, context + 168, C)`` physical inputs (modified in place and returned).
        absent: ``(N, 7)`` absence shares of the week's days (1 = nobody came, 0 = a normal day).
    """
    share = np.asarray(absent, float)
    if not np.any(share):
        return x
    ctx = sg.context_of(x)
    occ = x[:, ctx:, _CH["occupancy_fraction"]].reshape(len(x), 7, cat.HOURS_PER_DAY)
    x[:, ctx:, _CH["occupancy_fraction"]] = (occ * (1.0 - share[..., None])).reshape(len(x), -1)
    return x


def transform_outputs(outputs: np.ndarray, x: np.ndarray, params: Mapping[str, np.ndarray]) -> np.ndarray:
    """Apply the building-output effects.

    Args:
        outputs: ``(N, 168, 8)`` metamodel outputs (a modified copy is returned).
        x: the encoded inputs the outputs were simulated from ``(N, context + 168, C)`` (occupancy, weather,
            supply air).
        params: ``{effect: (N, k)}``.
    """
    n = len(outputs)
    active = [
        e
        for e in OUTPUT_EFFECTS
        if any(_column(params, e, j, n) is not None for j in range(len(EFFECTS[e].parameters)))
    ]
    if not active:
        return outputs
    out = np.array(outputs, dtype=np.float32, copy=True)
    week = x[:, sg.context_of(x) :]
    p = _column(params, "night_plug_loads", 0, n)
    if p is not None:
        out[..., _OUT["Q_EQP"]] += (p * ~occupied_hours(x)).astype(np.float32)
    eff = _column(params, "heat_recovery", 0, n)
    if eff is not None:
        t_in, t_out = out[..., _OUT["T_INT_OFFICE"]], week[..., _CH["TAMB"]]
        share = np.clip(eff * (t_in - t_out) / _supply_lift(week), 0.0, 1.0)
        ahu = out[..., _OUT["Q_AHU_H"]]
        out[..., _OUT["Q_AHU_H"]] = ahu - (share * np.maximum(ahu, 0.0)).astype(np.float32)
    if "night_cycle_cold_air" in active:
        cool, reheat, shortfall = (_column(params, "night_cycle_cold_air", j, n) for j in (0, 1, 2))
        heat = np.maximum(out[..., _OUT["Q_HEAT_OFFICE"]] + out[..., _OUT["Q_AHU_H"]], 0.0)
        fans_off = week[..., _CH["ventilation_on"]] <= 0
        after_heating = ~fans_off & (week[..., _CH["heating_comfort_on"]] <= 0)
        deficit = 0.0
        if shortfall is not None:
            # heat (Wh/m2) the supply air brings less than the model's, in the hours after the heating period:
            # the model's air handling unit heating per K of lift (its fresh-air flow) times the shortfall in K
            ahu = np.maximum(out[..., _OUT["Q_AHU_H"]], 0.0)
            deficit = shortfall * ahu / _supply_lift(week) * after_heating
            out[..., _OUT["Q_AHU_H"]] -= np.minimum(deficit, ahu).astype(np.float32)
        if cool is not None:
            out[..., _OUT["T_INT_OFFICE"]] -= (cool * (heat * fans_off + deficit)).astype(np.float32)
        if reheat is not None:
            out[..., _OUT["Q_HEAT_OFFICE"]] += (reheat * heat * fans_off).astype(np.float32)
    if "heating_capacity_limit" in active:
        cap = _column(params, "heating_capacity_limit", 0, n)
        sag = _column(params, "heating_capacity_limit", 1, n)
        cap = np.full((n, 1), np.inf) if cap is None else cap
        sag = np.zeros((n, 1)) if sag is None else sag
        heat = out[..., _OUT["Q_HEAT_OFFICE"]] + out[..., _OUT["Q_AHU_H"]]
        excess = np.maximum(heat - cap, 0.0)
        keep = np.where(heat > 0, 1.0 - excess / np.maximum(heat, 1e-9), 1.0)
        out[..., _OUT["Q_HEAT_OFFICE"]] *= keep.astype(np.float32)
        out[..., _OUT["Q_AHU_H"]] *= keep.astype(np.float32)
        decay = np.exp(-1.0 / SAG_TIME_CONSTANT_H)
        drop = np.zeros(n)
        for h in range(cat.HOURS_PER_WEEK):
            drop = drop * decay + sag[:, 0] * excess[:, h]
            out[:, h, _OUT["T_INT_OFFICE"]] -= drop.astype(np.float32)
    return out


def _supply_lift(week: np.ndarray) -> np.ndarray:
    """``(N, 168)`` K the model's air handling unit lifts the outdoor air to ``supply_air_c`` (at least 0.5 K,
    so that a share of its heating per K stays finite) from the week's encoded inputs ``(N, 168, C)``."""
    return np.maximum(week[..., _CH["supply_air_c"]] - week[..., _CH["TAMB"]], 0.5)


def sensor_temperature(temperature_c: np.ndarray, params: Mapping[str, np.ndarray]) -> np.ndarray:
    """What the temperature sensor reads of the building's temperature ``(N, 168)`` (degC) under the
    sensor effects (a new array)."""
    t = np.array(temperature_c, dtype=float, copy=True)
    n = len(t)
    tau = _column(params, "temperature_sensor_lag", 0, n)
    if tau is not None:
        alpha = np.where(tau[:, 0] > 0, 1.0 - np.exp(-1.0 / np.maximum(tau[:, 0], 1e-9)), 1.0)
        y = t[:, 0].copy()
        for h in range(1, t.shape[1]):
            y = y + alpha * (t[:, h] - y)
            t[:, h] = y
    b = _column(params, "temperature_sensor_bias", 0, n)
    if b is not None:
        t = t + b
    return t
