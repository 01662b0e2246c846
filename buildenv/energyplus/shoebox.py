"""The building energy model: a shoebox office generated from theta_build as epJSON.

Modelling choices (each a constant below, so that a reader can find and change it):

- Geometry: a square footprint of side ``sqrt(floor_area / floors)``, ``floors * FLOOR_HEIGHT_M`` high; facades
  face north, east, south and west (catalogue order 1-4), each with one centred window band of its ratio.
- Zoning (``zoning=``): ``single`` is one thermal zone (the paper's); ``core_perimeter`` a perimeter ring
  ``PERIMETER_DEPTH_M`` deep with the facades, windows and infiltration around a core that meets only the
  perimeter, roof and ground; ``five_zone`` that ring cut on its diagonals into one perimeter zone per facade, as
  the DOE reference offices are zoned. Gains, mass and HVAC are split by floor area, infiltration among the zones
  with facades; every zone follows one thermostat schedule.
- Envelope: walls concrete / insulation (theta) / plasterboard; roof membrane / insulation / slab; ground
  floor insulation under a slab, on ground at the annual mean + ``GROUND_SWING`` x (previous month's mean -
  annual mean) of the weather file; simple glazing (``GLAZING_U``, ``GLAZING_SHGC``).
- Capacitance: an InternalMass of concrete (both faces exposed) whose thickness gives ``capacitance x volume``.
- Infiltration: theta's air changes per hour of the volume while the air handling unit is off, its
  ``infiltration_fans_on_share`` of them while it ventilates (the fans pressurise the building); no wind or stack
  dependence.
- Internal gains: ``PERSON_ACTIVITY_W`` per occupant, theta's plug loads (``ElectricEquipment``) and lighting
  power (``Lights``) per m2, following the hourly occupancy; lights and equipment at theta's night percentage
  outside it.
- Fan coils: ``ZoneHVAC:IdealLoadsAirSystem`` on a dual-setpoint thermostat, limited to theta's heating and
  cooling power, sensible only (Q_HEAT_OFFICE / Q_AC_OFFICE), setpoints from :mod:`buildenv.schedules`.
- Economiser: theta's ``economiser_share`` of the cooling load goes first to a second set of fan coils with that
  share of the cooling power and an air-side economiser (differential dry-bulb; outdoor air up to their cooling
  air flow while it is cooler than the zone air); they do not heat. Both sets count in Q_AC_OFFICE.
- Air handling unit: ``ZoneHVAC:OutdoorAirUnit`` supplying outdoor air (``ventilation_ach`` x volume while on)
  heated by an electric coil (Q_AHU_H) or cooled by a DX coil (Q_AHU_C) to the day's supply temperature
  (``TemperatureControl``), supply fan heat included, balanced by an exhaust fan. With a heat recovery
  effectiveness above 0, a sensible plate exchanger (``HeatExchanger:AirToAir:SensibleAndLatent``, no latent
  transfer) first passes the exhaust stream's heat (leaving the exhaust fan) to the outdoor air, bypassed where
  it would carry that air past, or away from, the supply temperature; at 0 there is no exchanger.
- Night cycling (``five_zone`` with a minimum supply flow, a VAV system): outside the ventilation period every
  zone's air handling unit supplies return air brought to the supply temperature as the warmest zone nears the
  cooling setback (an EMS program), up to the minimum supply flow at the setback, as the reference offices' VAV
  systems start on their warmest zone (their on/off cycles averaged over a proportional band); likewise, up to
  theta's ``night_cycle_heating_share`` of that flow, as the coldest zone nears the heating setback (the zones
  reheat the cold supply air, as VAV boxes with reheat do; at 0 the setback is held zone by zone); a 100 %
  outdoor air unit does not night-cycle.
- Mixed air: with ``minimum_supply_air_ach`` above the outdoor air the unit supplies that minimum, the rest
  return air, as VAV systems at their boxes' minimum flow do (the zones reheat it). The exchanger then has
  effectiveness 1 on an exhaust stream of the return air plus the heat-recovered share of the outdoor air, so
  its outlet is the mixed air (computed on the smaller stream; EnergyPlus's 2:1 imbalance report is expected:
  :data:`ACCEPTED_SEVERE`),
  and its bypass is the economiser that brings in more outdoor air where that is nearer the supply temperature.
- Schedules: every hourly schedule is a column of one Schedule:File, so every week may differ.
- Outputs: hourly, the zones' floor-area weighted mean air temperature and the seven energies summed over
  the zones, in Wh per m2 of floor area.
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.schedules import hourly_schedules, usage_fraction
from buildenv.weather.epw import Weather, month_of_hour

FLOOR_HEIGHT_M = 3.5
WALL_CONCRETE_M = 0.20
ROOF_CONCRETE_M = 0.20
GROUND_INSULATION_M = 0.05
GROUND_SWING = 0.3
GLAZING_U = 2.4  # W/(m2 K)
GLAZING_SHGC = 0.40
PERIMETER_DEPTH_M = 4.57  # depth of the perimeter zone (the DOE reference offices' 15 ft), at most side / 4
PARTITION_AIR_GAP_M2K_W = 0.15  # thermal resistance of the air gap in the core/perimeter partition
# EnergyPlus's day-to-day warm-up loads tolerance for two zones (its default 0.04 is missed by a core's few watts);
# a warm-up whose temperatures converged is accepted anyway (runner.warmup_settled)
CORE_WARMUP_LOADS_TOLERANCE = 0.1
#: Severe reports of a sound shoebox run (runner.run_energyplus ``accepted_severe``): the mixed-air exchanger's
#: supply and exhaust flows differ by more than 2:1, and EnergyPlus computes it on the smaller stream and goes on
ACCEPTED_SEVERE = ("unbalanced air volume flow ratio through the heat exchanger",)
WINDOW_MARGIN = 0.05  # share of the facade width left opaque at each end of the window band
PERSON_ACTIVITY_W = 120.0
AHU_FAN_PRESSURE_PA = 300.0
AHU_MAX_SUPPLY_DELTA_K = 60.0  # heating coil sized to lift the maximum outdoor air flow by this much
DX_FLOW_PER_CAPACITY = 6.0e-5  # m3/s per W of rated cooling capacity (EnergyPlus admits 4.03e-5..6.04e-5)
DX_RATED_FLOW_FACTOR = 2.0  # DX coil rated at twice the AHU flow: ~29 kJ/kg of cooling at full flow
TIMESTEPS_PER_HOUR = 4

CONCRETE = {"conductivity": 1.95, "density": 2240.0, "specific_heat": 900.0}
INSULATION = {"conductivity": 0.035, "density": 30.0, "specific_heat": 1400.0}
PLASTERBOARD = {"conductivity": 0.25, "density": 900.0, "specific_heat": 1000.0}
MEMBRANE = {"conductivity": 0.17, "density": 1100.0, "specific_heat": 1000.0}

ZONE = "Office"  # the single zone
PERIMETER, CORE = "Perimeter", "Core"  # the two zones of core_perimeter; five_zone's are "Perimeter <facade>"
ZONINGS = ("single", "core_perimeter", "five_zone")
DEFAULT_ZONING = "core_perimeter"
# HVAC objects of each zone are named f"{zone} {part}" (see zone_hvac_names)
FAN_COILS, AHU_HEATING_COIL, AHU_COOLING_COIL = "Fan Coils", "AHU Heating Coil", "AHU Cooling Coil"
ECONOMISER_FAN_COILS = "Economiser Fan Coils"
AHU_HEAT_RECOVERY = "AHU Heat Recovery"

#: EnergyPlus report variable (HVAC parts of the key, name) behind each catalogue output, summed over the parts;
#: the key is the zone name for zone variables, else ``f"{zone} {part}"``.
OUTPUT_VARIABLES: dict[str, tuple[tuple[str, ...], str]] = {
    "Q_AC_OFFICE": ((FAN_COILS, ECONOMISER_FAN_COILS), "Zone Ideal Loads Supply Air Total Cooling Energy"),
    "Q_HEAT_OFFICE": ((FAN_COILS, ECONOMISER_FAN_COILS), "Zone Ideal Loads Supply Air Total Heating Energy"),
    "Q_PEOPLE": (("",), "Zone People Total Heating Energy"),
    "Q_EQP": (("",), "Zone Electric Equipment Electricity Energy"),
    "Q_LIGHT": (("",), "Zone Lights Electricity Energy"),
    "Q_AHU_C": ((AHU_COOLING_COIL,), "Cooling Coil Total Cooling Energy"),
    "Q_AHU_H": ((AHU_HEATING_COIL,), "Heating Coil Heating Energy"),
    "T_INT_OFFICE": (("",), "Zone Mean Air Temperature"),
}
#: cooling air flow of the economiser fan coils per W of their cooling capacity (m3/s): air supplied 11 K below
#: the zone at 1.2 kg/m3 and 1005 J/(kg K)
ECONOMISER_FLOW_PER_W = 1.0 / (1.2 * 1005.0 * 11.0)

#: Columns of the Schedule:File, in order.
SCHEDULE_COLUMNS: tuple[str, ...] = (
    "heating_setpoint_c",
    "cooling_setpoint_c",
    "occupancy_fraction",
    "lighting_fraction",
    "equipment_fraction",
    "ventilation_on",
    "infiltration_fraction",
    "supply_fraction",
    "exhaust_fraction",
    "supply_air_c",
)

FACADES = ("north", "east", "south", "west")

#: The schedules an air handling unit runs on: the Schedule:File's columns, or under night cycling
#: (:func:`_add_night_cycle`) constants an EMS program sets every timestep.
FILE_AIR_SCHEDULES = {"on": "ventilation_on", "supply": "supply_fraction", "exhaust": "exhaust_fraction"}
NIGHT_CYCLE_AIR_SCHEDULES = {"on": "AHU on", "supply": "AHU supply fraction", "exhaust": "AHU exhaust fraction"}
#: Night cycling's proportional band (K): the air handling units' flow rises from none to the minimum supply flow as
#: the most extreme zone comes this close to its setback (the fan coils hold it there), the hourly mean of on/off
#: cycles on a thermostat tolerance of that width (the DOE prototypes': 1 K)
NIGHT_CYCLE_BAND_K = 1.0


@dataclass(frozen=True)
class Geometry:
    """Derived geometry of the shoebox (m, m2, m3)."""

    floor_area_m2: float
    floors: int
    side_m: float
    height_m: float
    volume_m3: float

    @classmethod
    def from_theta(cls, theta: dict[str, float]) -> Geometry:
        """Geometry from theta_build values (``floor_area_m2``, ``number_of_floors``)."""
        area, floors = float(theta["floor_area_m2"]), int(round(theta["number_of_floors"]))
        side = math.sqrt(area / floors)
        return cls(area, floors, side, floors * FLOOR_HEIGHT_M, area * FLOOR_HEIGHT_M)

    @property
    def perimeter_depth_m(self) -> float:
        """Depth of the perimeter zone of ``core_perimeter`` zoning (m)."""
        return min(PERIMETER_DEPTH_M, self.side_m / 4.0)

    def core_facade(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Like :meth:`facade` for the core's side facing that facade (core_perimeter zoning)."""
        p, q = self.perimeter_depth_m, self.side_m - self.perimeter_depth_m
        return {
            "south": (np.array([p, p, 0.0]), np.array([1.0, 0.0, 0.0])),
            "east": (np.array([q, p, 0.0]), np.array([0.0, 1.0, 0.0])),
            "north": (np.array([q, q, 0.0]), np.array([-1.0, 0.0, 0.0])),
            "west": (np.array([p, q, 0.0]), np.array([0.0, -1.0, 0.0])),
        }[name]

    def corner_partitions(self) -> list[tuple[str, tuple[np.ndarray, np.ndarray], str]]:
        """``[(facade, (corner, unit vector), next facade)]``: the diagonal wall from each outer corner to the
        core's corner between a facade's perimeter zone and the next one counter-clockwise seen from above
        (five_zone zoning), its corner and direction as :meth:`facade` gives them, seen from the next zone."""
        s = self.side_m
        d = 1.0 / math.sqrt(2.0)
        return [
            ("south", (np.array([s, 0.0, 0.0]), np.array([-d, d, 0.0])), "east"),
            ("east", (np.array([s, s, 0.0]), np.array([-d, -d, 0.0])), "north"),
            ("north", (np.array([0.0, s, 0.0]), np.array([d, -d, 0.0])), "west"),
            ("west", (np.array([0.0, 0.0, 0.0]), np.array([d, d, 0.0])), "south"),
        ]

    def facade(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Bottom-left corner seen from outside and the unit vector along the facade, for a facade name."""
        s = self.side_m
        return {
            "south": (np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])),
            "east": (np.array([s, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])),
            "north": (np.array([s, s, 0.0]), np.array([-1.0, 0.0, 0.0])),
            "west": (np.array([0.0, s, 0.0]), np.array([0.0, -1.0, 0.0])),
        }[name]


def check_zoning(zoning: str) -> str:
    """``zoning`` if it is one of :data:`ZONINGS`; raises ``ValueError`` naming them otherwise."""
    if zoning not in ZONINGS:
        raise ValueError(f"zoning {zoning!r}: expected one of {', '.join(ZONINGS)}")
    return zoning


def zone_shares(g: Geometry, zoning: str) -> dict[str, float]:
    """``{zone: share of the floor area (and volume)}`` of a zoning; the shares sum to 1."""
    if check_zoning(zoning) == "single":
        return dict(zip(zone_names(zoning), (1.0,)))
    core = (g.side_m - 2.0 * g.perimeter_depth_m) ** 2 / g.side_m**2
    perimeters = len(zone_names(zoning)) - 1
    return dict(zip(zone_names(zoning), (*[(1.0 - core) / perimeters] * perimeters, core)))


def zone_hvac_names(zone: str) -> dict[str, str]:
    """Names of a zone's fan coils (ideal loads, without and with an economiser), air handling unit, its heat
    exchanger and its coils."""
    return {
        "fan_coils": f"{zone} {FAN_COILS}",
        "economiser_fan_coils": f"{zone} {ECONOMISER_FAN_COILS}",
        "ahu": f"{zone} AHU",
        "heat_recovery": f"{zone} {AHU_HEAT_RECOVERY}",
        "heating_coil": f"{zone} {AHU_HEATING_COIL}",
        "cooling_coil": f"{zone} {AHU_COOLING_COIL}",
    }


def output_keys(name: str, zoning: str) -> dict[str, list[tuple[str, str]]]:
    """``{zone: [(key, report variable), ...]}``: the pairs behind catalogue output ``name``, summed in a zone."""
    parts, variable = OUTPUT_VARIABLES[name]
    return {zone: [(f"{zone} {part}" if part else zone, variable) for part in parts] for zone in zone_names(zoning)}


def zone_names(zoning: str) -> tuple[str, ...]:
    """Zone names of a zoning."""
    if check_zoning(zoning) == "single":
        return (ZONE,)
    if zoning == "five_zone":
        return (*(perimeter_zone(zoning, facade) for facade in FACADES), CORE)
    return (PERIMETER, CORE)


def perimeter_zone(zoning: str, facade: str) -> str:
    """The zone holding ``facade``'s wall and windows: the single zone, the perimeter ring, or (``five_zone``)
    the perimeter zone of that orientation."""
    if zoning == "single":
        return ZONE
    return f"{PERIMETER} {facade}" if zoning == "five_zone" else PERIMETER


def output_variables(zoning: str) -> list[tuple[str, str]]:
    """Every (key, report variable) pair the model reports hourly."""
    return [pair for name in cat.OUTPUT_NAMES for pairs in output_keys(name, zoning).values() for pair in pairs]


def _horizontal_outlines(g: Geometry, zoning: str) -> dict[str, tuple[str, list[tuple[float, float]]]]:
    """``{name suffix: (zone, [(x, y), ...] counter-clockwise seen from above)}`` of the roof and floor pieces."""
    s = g.side_m
    if zoning == "single":
        return {"": (ZONE, [(0.0, s), (0.0, 0.0), (s, 0.0), (s, s)])}
    p, q = g.perimeter_depth_m, s - g.perimeter_depth_m
    outlines = {"core": (CORE, [(p, q), (p, p), (q, p), (q, q)])}
    south = [(0.0, 0.0), (s, 0.0), (q, p), (p, p)]
    for turn, facade in enumerate(("south", "east", "north", "west")):  # each a quarter turn about the centre
        c = s / 2.0
        piece = south
        for _ in range(turn):
            piece = [(c - (y - c), c + (x - c)) for x, y in piece]
        outlines[facade] = (perimeter_zone(zoning, facade), [(round(x, 4), round(y, 4)) for x, y in piece])
    return outlines


def theta_dict(theta: np.ndarray | dict[str, float], check: bool = True) -> dict[str, float]:
    """theta_build as ``{name: value}``, validated against the catalogue (``check=False``: a vector outside its
    ranges is kept, for sensitivity studies past them; the metamodel knows nothing there)."""
    if isinstance(theta, dict):
        vector = (
            cat.from_mapping("theta_build", theta, where="theta_build")
            if check
            else np.array([float(theta[name]) for name in cat.THETA_NAMES])
        )
    else:
        vector = np.asarray(theta, dtype=float)
        if check:
            cat.check_values("theta_build", vector, "theta_build")
    return dict(zip(cat.THETA_NAMES, (float(x) for x in vector)))


def _rect(origin: np.ndarray, along: np.ndarray, x0: float, width: float, z0: float, height: float) -> list[dict]:
    """Four vertices, upper-left first, counter-clockwise seen from outside."""
    up = np.array([0.0, 0.0, 1.0])
    pts = [
        origin + along * x0 + up * (z0 + height),
        origin + along * x0 + up * z0,
        origin + along * (x0 + width) + up * z0,
        origin + along * (x0 + width) + up * (z0 + height),
    ]
    return [
        {
            "vertex_x_coordinate": round(float(p[0]), 4),
            "vertex_y_coordinate": round(float(p[1]), 4),
            "vertex_z_coordinate": round(float(p[2]), 4),
        }
        for p in pts
    ]


def _xyz(points: list[tuple[float, float, float]]) -> list[dict]:
    return [{"vertex_x_coordinate": x, "vertex_y_coordinate": y, "vertex_z_coordinate": z} for x, y, z in points]


def _material(thickness: float, props: dict, roughness: str = "MediumRough") -> dict:
    return {
        "roughness": roughness,
        "thickness": round(thickness, 5),
        **props,
        "thermal_absorptance": 0.9,
        "solar_absorptance": 0.6,
        "visible_absorptance": 0.6,
    }


def ground_temperatures_c(weather: Weather) -> list[float]:
    """Monthly temperature under the slab (degC): annual mean + GROUND_SWING x (last month's mean - annual)."""
    monthly = weather.monthly_mean_temperature_c()
    lagged = np.roll(monthly, 1)
    return [round(float(monthly.mean() + GROUND_SWING * (t - monthly.mean())), 2) for t in lagged]


def hourly_ground_temperature_c(weather: Weather) -> np.ndarray:
    """``(8760,)`` temperature under the slab in each hour of the year (degC): the month's
    :func:`ground_temperatures_c` value, as EnergyPlus applies it."""
    return np.asarray(ground_temperatures_c(weather), dtype=np.float32)[month_of_hour()]


def schedule_table(theta: dict[str, float], settings: np.ndarray, occupancy: np.ndarray, start_week: int) -> np.ndarray:
    """The Schedule:File contents: ``(8760, len(SCHEDULE_COLUMNS))`` for weeks starting at ``start_week``.

    Args:
        theta: theta_build values.
        settings: I_k of each simulated week, ``(weeks, 7, 13)``.
        occupancy: O_k of each simulated week, ``(weeks, 5, 2)``.
        start_week: week of year (0 = the week starting January 1st) of the first simulated week.
    Hours outside the simulated weeks repeat the first week (EnergyPlus never uses them).
    """
    weeks = settings.shape[0]
    series = hourly_schedules(settings, occupancy)
    columns = {
        "heating_setpoint_c": series["heating_setpoint_c"],
        "cooling_setpoint_c": series["cooling_setpoint_c"],
        "occupancy_fraction": series["occupancy_fraction"],
        "lighting_fraction": usage_fraction(series["occupancy_fraction"], theta["light_night_percent"]),
        "equipment_fraction": usage_fraction(series["occupancy_fraction"], theta["pc_night_percent"]),
        "ventilation_on": series["ventilation_on"],
        "infiltration_fraction": 1.0 - (1.0 - theta["infiltration_fans_on_share"]) * series["ventilation_on"],
        **dict(zip(("supply_fraction", "exhaust_fraction"), air_unit_flows(theta, series["ventilation_ach"]))),
        "supply_air_c": series["supply_air_c"],
    }
    block = np.stack([columns[c].reshape(-1) for c in SCHEDULE_COLUMNS], axis=1)  # (weeks*168, n)
    table = np.tile(block[: cat.HOURS_PER_WEEK], (53, 1))[:8760]
    lo = start_week * cat.HOURS_PER_WEEK
    table[lo : lo + weeks * cat.HOURS_PER_WEEK] = block
    return table


def air_unit_largest_ach(theta: dict[str, float]) -> float:
    """The air handling unit's largest flow (air changes per hour): the catalogue's most outdoor air, or the
    minimum supply flow where that is larger."""
    return max(theta["minimum_supply_air_ach"], cat.get("ventilation_ach").max)


def air_unit_flows(theta: dict[str, float], ventilation_ach: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The air handling unit's supply and exhaust flows for hourly outdoor air ``ventilation_ach`` (air changes
    per hour), as fractions of :func:`air_unit_largest_ach` (each shaped as ``ventilation_ach``).

    Without a minimum supply flow the unit supplies and exhausts the outdoor air. With one, it supplies at least
    ``minimum_supply_air_ach`` and exhausts, through an exchanger of effectiveness 1, the return air it mixes in
    plus the heat-recovered share of the outdoor air, so that the exchanger's outlet is the mixed air.
    """
    largest = air_unit_largest_ach(theta)
    minimum = theta["minimum_supply_air_ach"]
    if minimum <= 0.0:
        fraction = ventilation_ach / largest
        return fraction, fraction
    supply = np.where(ventilation_ach > 0.0, np.maximum(ventilation_ach, minimum), 0.0)
    exhaust = supply - (1.0 - theta["heat_recovery_effectiveness"]) * ventilation_ach
    return supply / largest, exhaust / largest


def write_schedule_file(
    path: Path, theta: dict[str, float], settings: np.ndarray, occupancy: np.ndarray, start_week: int
) -> Path:
    """Write the Schedule:File CSV (header row + 8760 rows) of :func:`schedule_table`; returns ``path``."""
    table = schedule_table(theta, settings, occupancy, start_week)
    np.savetxt(path, table, delimiter=",", fmt="%.4f", header=",".join(SCHEDULE_COLUMNS), comments="")
    return Path(path)


def build_epjson(
    theta: np.ndarray | dict[str, float],
    weather: Weather,
    schedule_csv: Path,
    start_week: int,
    n_weeks: int,
    zoning: str = DEFAULT_ZONING,
    check: bool = True,
) -> dict:
    """Generate the shoebox as an epJSON document.

    Args:
        theta: theta_build (catalogue order array or ``{name: value}``).
        weather: the weather the model runs with (site location and ground temperatures come from it).
        schedule_csv: path of the Schedule:File written by :func:`schedule_table` (made absolute here).
        start_week: week of year of the first simulated week (weeks start on Mondays; Jan 1st is a Monday).
        n_weeks: number of consecutive weeks to simulate.
        zoning: ``single`` (one zone, the paper's) or ``core_perimeter`` (see the module docstring).
        check: refuse a theta outside the catalogue's ranges (:func:`theta_dict`).
    Returns:
        The epJSON model as a dict (``json.dump`` it to a ``.epJSON`` file).
    """
    t = theta_dict(theta, check)
    g = Geometry.from_theta(t)
    check_zoning(zoning)
    csv = str(Path(schedule_csv).resolve())
    if start_week < 0 or start_week + n_weeks > cat.WEEKS_PER_YEAR:
        raise ValueError(
            f"weeks {start_week}..{start_week + n_weeks - 1} do not fit in weeks "
            f"0..{cat.WEEKS_PER_YEAR - 1} of the year"
        )
    first = dt.date(2001, 1, 1) + dt.timedelta(days=7 * start_week)
    last = first + dt.timedelta(days=7 * n_weeks - 1)

    m: dict[str, dict] = {}

    def add(kind: str, name: str, **fields) -> None:
        m.setdefault(kind, {})[name] = fields

    add("Version", "Version 1", version_identifier="25.2")
    add(
        "SimulationControl",
        "SimulationControl 1",
        do_zone_sizing_calculation="No",
        do_system_sizing_calculation="No",
        do_plant_sizing_calculation="No",
        run_simulation_for_sizing_periods="No",
        run_simulation_for_weather_file_run_periods="Yes",
    )
    warmup = (
        {}
        if zoning == "single"
        else {"loads_convergence_tolerance_value": CORE_WARMUP_LOADS_TOLERANCE, "maximum_number_of_warmup_days": 50}
    )
    add(
        "Building",
        "buildenv shoebox",
        north_axis=0.0,
        terrain="City",
        solar_distribution="FullExterior",
        **{"maximum_number_of_warmup_days": 25, "minimum_number_of_warmup_days": 6, **warmup},
    )
    add("Timestep", "Timestep 1", number_of_timesteps_per_hour=TIMESTEPS_PER_HOUR)
    add(
        "GlobalGeometryRules",
        "GlobalGeometryRules 1",
        starting_vertex_position="UpperLeftCorner",
        vertex_entry_direction="Counterclockwise",
        coordinate_system="Relative",
    )
    add(
        "Site:Location",
        weather.name,
        latitude=weather.latitude_deg,
        longitude=weather.longitude_deg,
        time_zone=weather.timezone_h,
        elevation=weather.elevation_m,
    )
    add(
        "RunPeriod",
        "weeks",
        begin_month=first.month,
        begin_day_of_month=first.day,
        end_month=last.month,
        end_day_of_month=last.day,
        day_of_week_for_start_day="Monday",
        use_weather_file_holidays_and_special_days="No",
        use_weather_file_daylight_saving_period="No",
        apply_weekend_holiday_rule="No",
        use_weather_file_rain_indicators="Yes",
        use_weather_file_snow_indicators="Yes",
    )
    months = [
        "january",
        "february",
        "march",
        "april",
        "may",
        "june",
        "july",
        "august",
        "september",
        "october",
        "november",
        "december",
    ]
    add(
        "Site:GroundTemperature:BuildingSurface",
        "ground",
        **{f"{mo}_ground_temperature": tg for mo, tg in zip(months, ground_temperatures_c(weather))},
    )
    add(
        "OutputControl:Files",
        "OutputControl:Files 1",
        output_csv="Yes",
        output_eso="No",
        output_mtr="No",
        output_eio="No",
        output_tabular="No",
        output_sqlite="No",
        output_json="No",
        output_audit="No",
        output_bnd="No",
        output_rdd="No",
        output_mdd="No",
        output_mtd="No",
        output_end="No",
        output_shd="No",
        output_dfs="No",
        output_perflog="No",
        output_sln="No",
        output_sci="No",
        output_wrl="No",
        output_screen="No",
        output_extshd="No",
        output_tarcog="No",
        output_dxf="No",
        output_edd="No",
        output_dbg="No",
        output_space_sizing="No",
        output_zone_sizing="No",
        output_system_sizing="No",
        output_plant_component_sizing="No",
        output_delightin="No",
        output_delighteldmp="No",
        output_delightdfdmp="No",
        output_glhe="No",
    )

    # Materials and constructions.
    add("Material", "Concrete wall", **_material(WALL_CONCRETE_M, CONCRETE))
    add("Material", "Concrete roof", **_material(ROOF_CONCRETE_M, CONCRETE))
    add("Material", "Plasterboard", **_material(0.013, PLASTERBOARD, "Smooth"))
    add("Material", "Membrane", **_material(0.01, MEMBRANE, "Rough"))
    add("Material", "Ground insulation", **_material(GROUND_INSULATION_M, INSULATION))
    for facade in FACADES:
        add("Material", f"Insulation {facade}", **_material(t[f"wall_insulation_{facade}_m"], INSULATION))
        add(
            "Construction",
            f"Wall {facade}",
            outside_layer="Concrete wall",
            layer_2=f"Insulation {facade}",
            layer_3="Plasterboard",
        )
    add("Material", "Insulation roof", **_material(t["roof_insulation_m"], INSULATION))
    add("Construction", "Roof", outside_layer="Membrane", layer_2="Insulation roof", layer_3="Concrete roof")
    add("Construction", "Ground floor", outside_layer="Ground insulation", layer_2="Concrete roof")
    add(
        "WindowMaterial:SimpleGlazingSystem",
        "Glazing",
        u_factor=GLAZING_U,
        solar_heat_gain_coefficient=GLAZING_SHGC,
        visible_transmittance=0.6,
    )
    add("Construction", "Window", outside_layer="Glazing")

    # Zones and surfaces.
    add("Material:AirGap", "Partition air gap", thermal_resistance=PARTITION_AIR_GAP_M2K_W)
    add("Construction", "Partition", outside_layer="Plasterboard", layer_2="Partition air gap", layer_3="Plasterboard")
    shares = zone_shares(g, zoning)
    for zone, share in shares.items():
        add(
            "Zone",
            zone,
            ceiling_height=FLOOR_HEIGHT_M,
            volume=round(share * g.volume_m3, 3),
            floor_area=round(share * g.floor_area_m2, 3),
            part_of_total_floor_area="Yes",
        )
    s, h = g.side_m, g.height_m
    for facade in FACADES:
        origin, along = g.facade(facade)
        add(
            "BuildingSurface:Detailed",
            f"Wall {facade}",
            surface_type="Wall",
            construction_name=f"Wall {facade}",
            zone_name=perimeter_zone(zoning, facade),
            outside_boundary_condition="Outdoors",
            sun_exposure="SunExposed",
            wind_exposure="WindExposed",
            vertices=_rect(origin, along, 0.0, s, 0.0, h),
        )
        wwr = t[f"window_to_wall_{facade}_percent"] / 100.0
        width = s * (1.0 - 2.0 * WINDOW_MARGIN)
        height = wwr * s * h / width
        fields = {
            "surface_type": "Window",
            "construction_name": "Window",
            "building_surface_name": f"Wall {facade}",
            "number_of_vertices": 4,
        }
        for i, v in enumerate(_rect(origin, along, s * WINDOW_MARGIN, width, (h - height) / 2.0, height), 1):
            fields.update({f"vertex_{i}_{axis}_coordinate": v[f"vertex_{axis}_coordinate"] for axis in "xyz"})
        add("FenestrationSurface:Detailed", f"Window {facade}", **fields)
    for name, (zone, outline) in _horizontal_outlines(g, zoning).items():
        add(
            "BuildingSurface:Detailed",
            f"Roof {name}".strip(),
            surface_type="Roof",
            construction_name="Roof",
            zone_name=zone,
            outside_boundary_condition="Outdoors",
            sun_exposure="SunExposed",
            wind_exposure="WindExposed",
            vertices=_xyz([(x, y, h) for x, y in outline]),
        )
        add(
            "BuildingSurface:Detailed",
            f"Ground floor {name}".strip(),
            surface_type="Floor",
            construction_name="Ground floor",
            zone_name=zone,
            outside_boundary_condition="Ground",
            sun_exposure="NoSun",
            wind_exposure="NoWind",
            vertices=_xyz([(x, y, 0.0) for x, y in outline[::-1]]),
        )
    if zoning != "single":
        inner = s - 2.0 * g.perimeter_depth_m
        partitions = []  # (name, zone facing outwards, zone on the other side, vertices seen from the other side)
        for facade in FACADES:  # the core's walls face the perimeter; the perimeter's face the core
            origin, along = g.core_facade(facade)
            partitions.append((facade, CORE, perimeter_zone(zoning, facade), _rect(origin, along, 0.0, inner, 0.0, h)))
        if zoning == "five_zone":  # the perimeter zones meet on the diagonals from the corners
            for facade, corner, other in g.corner_partitions():
                origin, along = corner
                vertices = _rect(origin, along, 0.0, g.perimeter_depth_m * math.sqrt(2.0), 0.0, h)
                partitions.append(
                    (f"corner {facade}", perimeter_zone(zoning, facade), perimeter_zone(zoning, other), vertices)
                )
        for name, zone, other, vertices in partitions:
            for a, b, v in ((zone, other, vertices), (other, zone, vertices[::-1])):
                add(
                    "BuildingSurface:Detailed",
                    f"Partition {name} {a}",
                    surface_type="Wall",
                    construction_name="Partition",
                    zone_name=a,
                    outside_boundary_condition="Surface",
                    outside_boundary_condition_object=f"Partition {name} {b}",
                    sun_exposure="NoSun",
                    wind_exposure="NoWind",
                    vertices=v,
                )

    # Schedules: constants and one Schedule:File column per hourly series.
    add("ScheduleTypeLimits", "Any Number")
    add("Schedule:Constant", "Always on", schedule_type_limits_name="Any Number", hourly_value=1.0)
    add("Schedule:Constant", "Always off", schedule_type_limits_name="Any Number", hourly_value=0.0)
    # the economiser fan coils' minimum outdoor air: none (EnergyPlus's economiser acts only with an outdoor air
    # object, so it is a trace)
    add(
        "DesignSpecification:OutdoorAir",
        "Economiser outdoor air",
        outdoor_air_method="Flow/Area",
        outdoor_air_flow_per_zone_floor_area=1e-7,
    )
    add("Schedule:Constant", "Dual setpoint", schedule_type_limits_name="Any Number", hourly_value=4.0)
    add("Schedule:Constant", "Activity", schedule_type_limits_name="Any Number", hourly_value=PERSON_ACTIVITY_W)
    for column, name in enumerate(SCHEDULE_COLUMNS, 1):
        add(
            "Schedule:File",
            name,
            schedule_type_limits_name="Any Number",
            file_name=csv,
            column_number=column,
            rows_to_skip_at_top=1,
            number_of_hours_of_data=8760,
            column_separator="Comma",
            interpolate_to_timestep="No",
            minutes_per_item=60,
        )
    add(
        "ThermostatSetpoint:DualSetpoint",
        "Setpoints",
        heating_setpoint_temperature_schedule_name="heating_setpoint_c",
        cooling_setpoint_temperature_schedule_name="cooling_setpoint_c",
    )
    add(
        "Curve:Biquadratic",
        "Constant biquadratic",
        coefficient1_constant=1.0,
        coefficient2_x=0.0,
        coefficient3_x_2=0.0,
        coefficient4_y=0.0,
        coefficient5_y_2=0.0,
        coefficient6_x_y=0.0,
        minimum_value_of_x=-50.0,
        maximum_value_of_x=60.0,
        minimum_value_of_y=-50.0,
        maximum_value_of_y=60.0,
    )
    add(
        "Curve:Quadratic",
        "Constant quadratic",
        coefficient1_constant=1.0,
        coefficient2_x=0.0,
        coefficient3_x_2=0.0,
        minimum_value_of_x=0.0,
        maximum_value_of_x=1.5,
    )

    capacity_j_per_k = t["capacitance_kj_per_k_m3"] * 1000.0 * g.volume_m3
    mass_thickness = capacity_j_per_k / (CONCRETE["density"] * CONCRETE["specific_heat"] * 2.0 * g.floor_area_m2)
    add("Material", "Internal mass concrete", **_material(mass_thickness, CONCRETE, "Smooth"))
    add("Construction", "Internal mass", outside_layer="Internal mass concrete")
    envelope = {perimeter_zone(zoning, facade) for facade in FACADES}
    envelope_share = sum(shares[z] for z in envelope)
    night_cycle = night_cycling(zoning, t)
    air_schedules = NIGHT_CYCLE_AIR_SCHEDULES if night_cycle else FILE_AIR_SCHEDULES
    for zone, share in shares.items():
        _add_zone_loads(add, zone, share, t, g, infiltration=share / envelope_share if zone in envelope else 0.0)
        _add_zone_hvac(add, zone, share, t, g, air_schedules)
    if night_cycle:
        fraction = t["minimum_supply_air_ach"] / air_unit_largest_ach(t)
        _add_night_cycle(add, tuple(shares), fraction, t["night_cycle_heating_share"])

    for i, (key, variable) in enumerate(output_variables(zoning)):
        add("Output:Variable", f"Output {i}", key_value=key, variable_name=variable, reporting_frequency="Hourly")
    return m


def _add_zone_loads(add, zone: str, share: float, t: dict[str, float], g: Geometry, infiltration: float) -> None:
    """Internal mass, people, lighting, plug loads (each ``share`` of the building's) and ``infiltration`` (a share
    of the whole building's: the zones with the envelope divide it by floor area) of one zone."""
    area = share * g.floor_area_m2
    add(
        "InternalMass",
        f"{zone} internal mass",
        construction_name="Internal mass",
        zone_or_zonelist_name=zone,
        surface_area=round(2.0 * area, 3),
    )
    add(
        "People",
        f"{zone} occupants",
        zone_or_zonelist_or_space_or_spacelist_name=zone,
        number_of_people_schedule_name="occupancy_fraction",
        number_of_people_calculation_method="People",
        number_of_people=round(t["occupant_density_per_m2"] * area, 3),
        fraction_radiant=0.3,
        sensible_heat_fraction="Autocalculate",
        activity_level_schedule_name="Activity",
    )
    add(
        "Lights",
        f"{zone} lighting",
        zone_or_zonelist_or_space_or_spacelist_name=zone,
        schedule_name="lighting_fraction",
        design_level_calculation_method="LightingLevel",
        lighting_level=round(t["lighting_power_w_m2"] * area, 3),
        fraction_radiant=0.42,
        fraction_visible=0.18,
    )
    add(
        "ElectricEquipment",
        f"{zone} plug loads",
        zone_or_zonelist_or_space_or_spacelist_name=zone,
        schedule_name="equipment_fraction",
        design_level_calculation_method="EquipmentLevel",
        design_level=round(t["plug_load_w_m2"] * area, 3),
        fraction_radiant=0.3,
    )
    if infiltration > 0.0:  # air changes of the whole building's volume, through the envelope
        add(
            "ZoneInfiltration:DesignFlowRate",
            f"{zone} infiltration",
            zone_or_zonelist_or_space_or_spacelist_name=zone,
            schedule_name="infiltration_fraction",
            design_flow_rate_calculation_method="Flow/Zone",
            design_flow_rate=round(infiltration * t["infiltration_ach"] * g.volume_m3 / 3600.0, 6),
            constant_term_coefficient=1.0,
            temperature_term_coefficient=0.0,
            velocity_term_coefficient=0.0,
            velocity_squared_term_coefficient=0.0,
        )


def night_cycling(zoning: str, t: dict[str, float]) -> bool:
    """Whether the shoebox night-cycles its air handling units: ``five_zone`` zoning with a minimum supply flow
    (a VAV system with mixed air)."""
    return zoning == "five_zone" and t["minimum_supply_air_ach"] > 0.0


def _add_night_cycle(add, zones: tuple[str, ...], fraction: float, heating_share: float) -> None:
    """Night cycling as VAV systems do it: outside the ventilation period, as the warmest zone comes within
    :data:`NIGHT_CYCLE_BAND_K` of the cooling setback, every zone's air handling unit supplies return air brought
    to the supply temperature, its flow rising in proportion up to ``fraction`` of its largest flow (the minimum
    supply flow) at the setback, where the fan coils hold the warmest zone; as the coldest zone comes as near the
    heating setback, up to ``heating_share`` x ``fraction`` (the larger call wins), the fan coils reheating the
    supply air and holding every zone at its setback. Within the ventilation period the units follow the
    Schedule:File."""
    for name in NIGHT_CYCLE_AIR_SCHEDULES.values():
        add("Schedule:Constant", name, schedule_type_limits_name="Any Number", hourly_value=0.0)
    sensors = {
        "vent_on": ("ventilation_on", "Schedule Value"),
        "supply_file": ("supply_fraction", "Schedule Value"),
        "exhaust_file": ("exhaust_fraction", "Schedule Value"),
        "cooling_sp": ("cooling_setpoint_c", "Schedule Value"),
        "heating_sp": ("heating_setpoint_c", "Schedule Value"),
        **{f"zone_t_{i}": (zone, "Zone Mean Air Temperature") for i, zone in enumerate(zones)},
    }
    for name, (key, variable) in sensors.items():
        add(
            "EnergyManagementSystem:Sensor",
            name,
            output_variable_or_output_meter_index_key_name=key,
            output_variable_or_output_meter_name=variable,
        )
    actuators = dict(zip(("ahu_on", "ahu_supply", "ahu_exhaust"), NIGHT_CYCLE_AIR_SCHEDULES.values()))
    for name, schedule in actuators.items():
        add(
            "EnergyManagementSystem:Actuator",
            name,
            actuated_component_unique_name=schedule,
            actuated_component_type="Schedule:Constant",
            actuated_component_control_type="Schedule Value",
        )
    extremes = []
    for name, pick in (("warmest", "@Max"), ("coldest", "@Min")):
        extremes.append(f"SET {name} = zone_t_0")
        extremes += [f"SET {name} = {pick} {name} zone_t_{i}" for i in range(1, len(zones))]
    band = NIGHT_CYCLE_BAND_K
    lines = [
        "IF vent_on > 0.5",
        "SET ahu_on = 1",
        "SET ahu_supply = supply_file",
        "SET ahu_exhaust = exhaust_file",
        "ELSE",
        *extremes,
        f"SET call = (warmest - cooling_sp + {band}) / {band}",
        "SET call = @Min call 1",
        "SET call = @Max call 0",
        f"SET heating_call = (heating_sp + {band} - coldest) / {band}",
        "SET heating_call = @Min heating_call 1",
        "SET heating_call = @Max heating_call 0",
        f"SET heating_call = {heating_share:.6g} * heating_call",
        "SET call = @Max call heating_call",
        "IF call > 0",
        "SET ahu_on = 1",
        "ELSE",
        "SET ahu_on = 0",
        "ENDIF",
        f"SET ahu_supply = {fraction:.6g} * call",
        f"SET ahu_exhaust = {fraction:.6g} * call",
        "ENDIF",
    ]
    add("EnergyManagementSystem:Program", "night_cycle", lines=[{"program_line": line} for line in lines])
    add(
        "EnergyManagementSystem:ProgramCallingManager",
        "night cycle",
        energyplus_model_calling_point="BeginTimestepBeforePredictor",
        programs=[{"program_name": "night_cycle"}],
    )


def _add_zone_hvac(
    add, zone: str, share: float, t: dict[str, float], g: Geometry, air_schedules: dict[str, str]
) -> None:
    """Thermostat, fan coils (ideal loads) and air handling unit of one zone, each ``share`` of the building's;
    the unit runs on ``air_schedules`` (:data:`FILE_AIR_SCHEDULES` or :data:`NIGHT_CYCLE_AIR_SCHEDULES`)."""
    area = share * g.floor_area_m2
    names = zone_hvac_names(zone)
    add(
        "ZoneControl:Thermostat",
        f"{zone} thermostat",
        zone_or_zonelist_name=zone,
        control_type_schedule_name="Dual setpoint",
        control_1_object_type="ThermostatSetpoint:DualSetpoint",
        control_1_name="Setpoints",
    )
    add(
        "NodeList",
        f"{zone} inlets",
        nodes=[
            {"node_name": f"{zone} fan coil supply"},
            {"node_name": f"{zone} economiser supply"},
            {"node_name": f"{zone} AHU supply"},
        ],
    )
    add(
        "NodeList",
        f"{zone} exhausts",
        nodes=[
            {"node_name": f"{zone} fan coil exhaust"},
            {"node_name": f"{zone} economiser exhaust"},
            {"node_name": f"{zone} AHU exhaust"},
        ],
    )
    add(
        "ZoneHVAC:EquipmentConnections",
        zone,
        zone_name=zone,
        zone_conditioning_equipment_list_name=f"{zone} equipment",
        zone_air_inlet_node_or_nodelist_name=f"{zone} inlets",
        zone_air_exhaust_node_or_nodelist_name=f"{zone} exhausts",
        zone_air_node_name=f"{zone} air",
        zone_return_air_node_or_nodelist_name=f"{zone} return",
    )
    add(
        "ZoneHVAC:EquipmentList",
        f"{zone} equipment",
        load_distribution_scheme="SequentialLoad",
        equipment=[
            {
                "zone_equipment_object_type": "ZoneHVAC:OutdoorAirUnit",
                "zone_equipment_name": names["ahu"],
                "zone_equipment_cooling_sequence": 1,
                "zone_equipment_heating_or_no_load_sequence": 1,
            },
            {
                "zone_equipment_object_type": "ZoneHVAC:IdealLoadsAirSystem",
                "zone_equipment_name": names["economiser_fan_coils"],
                "zone_equipment_cooling_sequence": 2,
                "zone_equipment_heating_or_no_load_sequence": 2,
                "zone_equipment_sequential_cooling_fraction_schedule_name": f"{zone} economiser share",
                "zone_equipment_sequential_heating_fraction_schedule_name": "Always off",
            },
            {
                "zone_equipment_object_type": "ZoneHVAC:IdealLoadsAirSystem",
                "zone_equipment_name": names["fan_coils"],
                "zone_equipment_cooling_sequence": 3,
                "zone_equipment_heating_or_no_load_sequence": 3,
            },
        ],
    )
    # the fan coils: the economiser's share of the cooling first (its capacity that share of theta's), the rest
    # and all heating by the others; an economiser share of 0 leaves it off
    economiser = t["economiser_share"]
    cooling_w = t["cooling_power_w_m2"] * area
    add(
        "Schedule:Constant", f"{zone} economiser share", schedule_type_limits_name="Any Number", hourly_value=economiser
    )
    _add_fan_coils(
        add, zone, names["fan_coils"], "fan coil", t["heating_power_w_m2"] * area, (1 - economiser) * cooling_w
    )
    _add_economiser_fan_coils(add, zone, names["economiser_fan_coils"], economiser * cooling_w)

    # Air handling unit: outdoor air -> [heat exchanger ->] DX cooling coil -> electric heating coil -> supply
    # fan -> zone; zone -> exhaust fan [-> heat exchanger] -> outdoors. With a minimum supply flow the exchanger
    # passes the exhaust whole (effectiveness 1) and its outlet is the mix of outdoor and return air.
    flow = air_unit_largest_ach(t) * share * g.volume_m3 / 3600.0
    if t["minimum_supply_air_ach"] > 0.0:
        sensible, latent = 1.0, 1.0
    else:
        sensible, latent = t["heat_recovery_effectiveness"], 0.0
    _add_air_unit(add, zone, names, flow, sensible, latent, air_schedules)


def _add_economiser_fan_coils(add, zone: str, name: str, cooling_w: float) -> None:
    """Ideal-loads fan coils of ``cooling_w`` (W) cooling capacity, no heating, with an air-side economiser
    (differential dry-bulb: outdoor air up to their cooling air flow while it is cooler than the zone air); off at
    0 W."""
    outdoor_air = f"{zone} economiser outdoor air"
    add("OutdoorAir:NodeList", outdoor_air, nodes=[{"node_or_nodelist_name": outdoor_air}])
    economiser = {
        "availability_schedule_name": "Always on" if cooling_w > 0.0 else "Always off",
        "cooling_limit": "LimitFlowRateAndCapacity",
        "maximum_cooling_air_flow_rate": round(max(cooling_w * ECONOMISER_FLOW_PER_W, 1e-6), 6),
        "outdoor_air_inlet_node_name": outdoor_air,
        "design_specification_outdoor_air_object_name": "Economiser outdoor air",
        "outdoor_air_economizer_type": "DifferentialDryBulb",
    }
    _add_fan_coils(add, zone, name, "economiser", 0.0, cooling_w, economiser)


def _add_fan_coils(
    add, zone: str, name: str, node: str, heating_w: float, cooling_w: float, extra: dict | None = None
) -> None:
    """Ideal-loads fan coils of ``heating_w`` and ``cooling_w`` (W) sensible capacity, supplying node
    ``f"{zone} {node} supply"``; ``extra`` epJSON fields replace the defaults."""
    add(
        "ZoneHVAC:IdealLoadsAirSystem",
        name,
        zone_supply_air_node_name=f"{zone} {node} supply",
        zone_exhaust_air_node_name=f"{zone} {node} exhaust",
        maximum_heating_supply_air_temperature=50.0,
        minimum_cooling_supply_air_temperature=13.0,
        maximum_heating_supply_air_humidity_ratio=0.0156,
        minimum_cooling_supply_air_humidity_ratio=0.0077,
        heating_limit="LimitCapacity",
        maximum_sensible_heating_capacity=round(heating_w, 3),
        maximum_total_cooling_capacity=round(cooling_w, 3),
        dehumidification_control_type="None",
        humidification_control_type="None",
        **{"cooling_limit": "LimitCapacity", **(extra or {})},
    )


def _add_air_unit(
    add,
    zone: str,
    names: dict[str, str],
    flow_m3_s: float,
    effectiveness: float,
    latent: float,
    schedules: dict[str, str] = FILE_AIR_SCHEDULES,
) -> None:
    """A zone's air handling unit (``ZoneHVAC:OutdoorAirUnit``) bringing air to the day's supply temperature,
    on while ``schedules["on"]`` (by default ``ventilation_on``), its supply and exhaust flows following
    ``schedules["supply"]`` and ``schedules["exhaust"]``.

    Args:
        add: the epJSON builder's ``add(kind, name, **fields)``.
        zone: the zone it serves.
        names: the zone's :func:`zone_hvac_names`.
        flow_m3_s: its largest supply (and exhaust) air flow (m3/s).
        effectiveness: sensible effectiveness of the heat exchanger between exhaust and outdoor air (0: none).
        latent: its latent effectiveness (0-1).
        schedules: the schedules it runs on (:data:`FILE_AIR_SCHEDULES`, :data:`NIGHT_CYCLE_AIR_SCHEDULES`).
    """
    unit, on = names["ahu"], schedules["on"]
    recovery = effectiveness > 0.0
    cooling_inlet = f"{unit} recovered air" if recovery else f"{unit} outdoor air"
    add(
        "ZoneHVAC:OutdoorAirUnit",
        unit,
        availability_schedule_name=on,
        zone_name=zone,
        outdoor_air_flow_rate=round(flow_m3_s, 5),
        outdoor_air_schedule_name=schedules["supply"],
        supply_fan_name=f"{unit} supply fan",
        supply_fan_placement="DrawThrough",
        exhaust_fan_name=f"{unit} exhaust fan",
        exhaust_air_flow_rate=round(flow_m3_s, 5),
        exhaust_air_schedule_name=schedules["exhaust"],
        unit_control_type="TemperatureControl",
        high_air_control_temperature_schedule_name="supply_air_c",
        low_air_control_temperature_schedule_name="supply_air_c",
        outdoor_air_node_name=f"{unit} outdoor air",
        airoutlet_node_name=f"{unit} supply",
        airinlet_node_name=f"{unit} exhaust",
        supply_fanoutlet_node_name=f"{unit} supply",
        outdoor_air_unit_list_name=f"{unit} components",
    )
    components = [
        ("CoilSystem:Cooling:DX", f"{unit} cooling system"),
        ("Coil:Heating:Electric", names["heating_coil"]),
    ]
    if recovery:
        components.insert(0, ("HeatExchanger:AirToAir:SensibleAndLatent", names["heat_recovery"]))
        _add_heat_recovery(add, unit, names["heat_recovery"], effectiveness, latent, flow_m3_s, on)
    add(
        "ZoneHVAC:OutdoorAirUnit:EquipmentList",
        f"{unit} components",
        **{
            field: value
            for i, (kind, name) in enumerate(components, 1)
            for field, value in ((f"component_{i}_object_type", kind), (f"component_{i}_name", name))
        },
    )
    add(
        "CoilSystem:Cooling:DX",
        f"{unit} cooling system",
        availability_schedule_name=on,
        dx_cooling_coil_system_inlet_node_name=cooling_inlet,
        dx_cooling_coil_system_outlet_node_name=f"{unit} cooled air",
        dx_cooling_coil_system_sensor_node_name=f"{unit} cooled air",
        cooling_coil_object_type="Coil:Cooling:DX:SingleSpeed",
        cooling_coil_name=names["cooling_coil"],
    )
    add(
        "Coil:Cooling:DX:SingleSpeed",
        names["cooling_coil"],
        availability_schedule_name=on,
        gross_rated_total_cooling_capacity=round(DX_RATED_FLOW_FACTOR * flow_m3_s / DX_FLOW_PER_CAPACITY, 2),
        gross_rated_sensible_heat_ratio=0.75,
        gross_rated_cooling_cop=3.0,
        rated_air_flow_rate=round(DX_RATED_FLOW_FACTOR * flow_m3_s, 5),
        air_inlet_node_name=cooling_inlet,
        air_outlet_node_name=f"{unit} cooled air",
        total_cooling_capacity_function_of_temperature_curve_name="Constant biquadratic",
        total_cooling_capacity_function_of_flow_fraction_curve_name="Constant quadratic",
        energy_input_ratio_function_of_temperature_curve_name="Constant biquadratic",
        energy_input_ratio_function_of_flow_fraction_curve_name="Constant quadratic",
        part_load_fraction_correlation_curve_name="Constant quadratic",
    )
    add(
        "Coil:Heating:Electric",
        names["heating_coil"],
        availability_schedule_name=on,
        efficiency=1.0,
        nominal_capacity=round(flow_m3_s * 1.2 * 1005.0 * AHU_MAX_SUPPLY_DELTA_K, 1),
        air_inlet_node_name=f"{unit} cooled air",
        air_outlet_node_name=f"{unit} heated air",
    )
    _add_fan(add, f"{unit} supply fan", flow_m3_s, f"{unit} heated air", f"{unit} supply", on)
    _add_fan(add, f"{unit} exhaust fan", flow_m3_s, f"{unit} exhaust", f"{unit} relief", on)


def _add_fan(add, name: str, flow_m3_s: float, inlet: str, outlet: str, on: str) -> None:
    """One constant-volume fan of the air handling unit (``AHU_FAN_PRESSURE_PA``), on while schedule ``on``."""
    add(
        "Fan:ConstantVolume",
        name,
        availability_schedule_name=on,
        fan_total_efficiency=0.6,
        pressure_rise=AHU_FAN_PRESSURE_PA,
        maximum_flow_rate=round(flow_m3_s, 5),
        motor_efficiency=0.9,
        motor_in_airstream_fraction=1.0,
        air_inlet_node_name=inlet,
        air_outlet_node_name=outlet,
    )


def _add_heat_recovery(
    add, unit: str, name: str, effectiveness: float, latent: float, flow_m3_s: float, on: str
) -> None:
    """A plate heat exchanger of an air handling unit: outdoor air (supply side) against the exhaust fan's
    outlet (exhaust side), at ``effectiveness`` whatever the flow (no effectiveness curves), available while
    schedule ``on``. A setpoint manager puts the day's supply temperature on its supply outlet, so it bypasses
    outdoor air rather than heat or cool it past that temperature, or away from it.

    Args:
        add: the epJSON builder's ``add(kind, name, **fields)``.
        unit: the unit's name (node names follow it).
        name: the exchanger's name.
        effectiveness: sensible effectiveness, heating and cooling (0-1).
        latent: latent effectiveness, heating and cooling (0-1).
        flow_m3_s: the unit's maximum air flow, the exchanger's nominal flow (m3/s).
        on: its availability schedule.
    """
    add(
        "HeatExchanger:AirToAir:SensibleAndLatent",
        name,
        availability_schedule_name=on,
        nominal_supply_air_flow_rate=round(flow_m3_s, 5),
        sensible_effectiveness_at_100_heating_air_flow=effectiveness,
        latent_effectiveness_at_100_heating_air_flow=latent,
        sensible_effectiveness_at_100_cooling_air_flow=effectiveness,
        latent_effectiveness_at_100_cooling_air_flow=latent,
        supply_air_inlet_node_name=f"{unit} outdoor air",
        supply_air_outlet_node_name=f"{unit} recovered air",
        exhaust_air_inlet_node_name=f"{unit} relief",
        exhaust_air_outlet_node_name=f"{unit} exhaust outlet",
        nominal_electric_power=0.0,
        supply_air_outlet_temperature_control="Yes",
        heat_exchanger_type="Plate",
        frost_control_type="None",
        economizer_lockout="No",
    )
    add(
        "SetpointManager:Scheduled",
        f"{name} setpoint",
        control_variable="Temperature",
        schedule_name="supply_air_c",
        setpoint_node_or_nodelist_name=f"{unit} recovered air",
    )
