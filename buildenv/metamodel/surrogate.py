"""The metamodel as "simulate a week fast": catalogue data in, hourly outputs in physical units out.

Encoding (one row per hour, ``context_hours + 168`` rows per week):

- weather: the W_k channels of :data:`WEATHER_INPUTS` (the paper's seven plus wind speed);
- the hourly schedules of :mod:`buildenv.schedules` (setpoints in force, comfort masks, ventilation on and
  flow, supply temperature, occupancy);
- calendar: sine and cosine of the hour of day;
- theta_build, the same on every hour;
- ``is_context``: 1 on the context hours, 0 on the week;
- ``ground_temperature_c``: the temperature under the slab (degC), the month's value of the weather file's
  ground temperatures (:func:`buildenv.energyplus.shoebox.hourly_ground_temperature_c`); a week of weather
  does not show it. Checkpoints whose metadata lists no such channel are given the others only.
- optionally (``buildenv train --temperature-before``, :attr:`Surrogate.uses_temperature_before`), the two
  :data:`TEMPERATURE_BEFORE_CHANNELS`: the indoor temperature measured over the context hours (degC) and a
  flag that it is known; where it is not, the model reads the channel's training mean.

The context is the hours before the week (:data:`CONTEXT_HOURS` unless a checkpoint records another whole
number of days): a week starts from the state the previous days left. When the previous week is unknown,
the week's own first day, repeated, stands in for it, as EnergyPlus's warm-up does.

Outputs are the 8 catalogue outputs, standardised per channel with training-split statistics saved in the
checkpoint. Loading a checkpoint made for another catalogue raises :class:`CheckpointError`.
"""

from __future__ import annotations

import hashlib
import logging
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import BuildenvError
from buildenv.metamodel.threads import MetamodelWorkers, split_calls
from buildenv.schedules import HOURLY_CHANNELS, hourly_encoding

#: Hours before the week the model sees by default (a checkpoint records its own, ``metadata["context_hours"]``)
CONTEXT_HOURS = 24
WEATHER_INPUTS: tuple[str, ...] = ("DNI", "IBEAM_H", "IBEAM_N", "IDIFF_H", "IGLOB_H", "RHUM", "TAMB", "WIND_SPEED")
CALENDAR_INPUTS: tuple[str, ...] = ("hour_sin", "hour_cos")
GROUND_CHANNEL = "ground_temperature_c"
INPUT_CHANNELS: tuple[str, ...] = (
    *WEATHER_INPUTS,
    *HOURLY_CHANNELS,
    *CALENDAR_INPUTS,
    *cat.THETA_NAMES,
    "is_context",
    GROUND_CHANNEL,
)
#: the channels of a metamodel without the ground temperature (checkpoints made before it was an input)
NO_GROUND_CHANNELS: tuple[str, ...] = INPUT_CHANNELS[:-1]
_IS_CONTEXT = INPUT_CHANNELS.index("is_context")
_GROUND = INPUT_CHANNELS.index(GROUND_CHANNEL)
#: the optional channels appended after :data:`INPUT_CHANNELS`: the indoor temperature measured before the week
#: (degC, on the context hours) and whether it is known (1) or not (0)
TEMPERATURE_BEFORE_CHANNELS: tuple[str, str] = ("indoor_temperature_before_c", "indoor_temperature_before_known")
#: every channel a metamodel can read, in the order a checkpoint lists them
ALL_CHANNELS: tuple[str, ...] = (*INPUT_CHANNELS, *TEMPERATURE_BEFORE_CHANNELS)
TEMPERATURE_CHANNELS: list[int] = [cat.OUTPUT_NAMES.index(n) for n in cat.TEMPERATURE_OUTPUTS]
_T_OUT = TEMPERATURE_CHANNELS[0]  # the output a site's temperature sensor reads
CONSUMPTION_CHANNELS: list[int] = [i for i in range(len(cat.OUTPUT_NAMES)) if i not in TEMPERATURE_CHANNELS]
log = logging.getLogger(__name__)
DEFAULT_CHECKPOINT = Path(__file__).resolve().parents[1] / "data" / "metamodel_default.pt"
#: the earlier default, kept beside it for the gap diagnosis' blind checks, which ran with it
DIAGNOSIS_CHECKPOINT = DEFAULT_CHECKPOINT.with_name("metamodel_diagnosis.pt")
#: the checkpoints shipped in the package, by the name :func:`load_metamodel` takes
SHIPPED_CHECKPOINTS: dict[str, Path] = {"default": DEFAULT_CHECKPOINT, "diagnosis": DIAGNOSIS_CHECKPOINT}
#: weeks per model call (any number of weeks is accepted); the fastest measured on a 2-core CPU with the calls
#: spread over two workers (:class:`buildenv.metamodel.threads.MetamodelWorkers`)
INFERENCE_BATCH = 64


class CheckpointError(BuildenvError):
    """A checkpoint is missing or was made for another catalogue or encoding."""


def _calendar(hours: int) -> np.ndarray:
    angle = 2 * np.pi * (np.arange(hours) % 24) / 24.0
    return np.stack([np.sin(angle), np.cos(angle)], axis=-1)


_W_IDX: list[int] | slice = [cat.WEATHER_NAMES.index(c) for c in WEATHER_INPUTS]
if _W_IDX == list(range(_W_IDX[0], _W_IDX[0] + len(_W_IDX))):  # a view instead of a copy
    _W_IDX = slice(_W_IDX[0], _W_IDX[0] + len(_W_IDX))
_SCHEDULES = slice(len(WEATHER_INPUTS), len(WEATHER_INPUTS) + len(HOURLY_CHANNELS))
_CALENDAR = slice(_SCHEDULES.stop, _SCHEDULES.stop + len(CALENDAR_INPUTS))
_THETA = slice(_CALENDAR.stop, _CALENDAR.stop + len(cat.THETA_NAMES))


def _fill_rows(out: np.ndarray, settings: np.ndarray, occupancy: np.ndarray, weather: np.ndarray, hours: slice) -> None:
    """Write the weather and schedule channels of the week's ``hours`` into ``out`` ``(N, len(hours), C)``."""
    out[..., : len(WEATHER_INPUTS)] = np.asarray(weather)[:, hours][..., _W_IDX]
    out[..., _SCHEDULES] = hourly_encoding(settings, occupancy)[:, hours]


def check_context_hours(hours: int) -> int:
    """``hours`` of context as an int; a whole number of days (1 to 6) or :class:`CheckpointError`."""
    if int(hours) != hours or hours % cat.HOURS_PER_DAY or not 0 < hours < cat.HOURS_PER_WEEK:
        raise CheckpointError(f"context_hours must be a whole number of days from 24 to 144, got {hours}")
    return int(hours)


def context_of(x) -> int:
    """Context hours of encoded inputs ``(N, context + 168, C)`` (numpy or torch)."""
    return int(x.shape[-2]) - cat.HOURS_PER_WEEK


def first_day_repeated(week, hours: int):
    """The first 24 hours of ``week`` (hours on axis 1) repeated to ``hours``: the context of a week whose
    preceding week is unknown, as EnergyPlus's warm-up repeats the first day (numpy or torch)."""
    day = week[:, : cat.HOURS_PER_DAY]
    reps = [1, hours // cat.HOURS_PER_DAY] + [1] * (week.ndim - 2)
    return np.tile(day, reps) if isinstance(day, np.ndarray) else day.repeat(*reps)


def ground_hours(
    hourly_ground_c: np.ndarray, first_hours: np.ndarray, context_hours: int = CONTEXT_HOURS
) -> np.ndarray:
    """``(N, context_hours + 168)`` ground temperature (degC) of weeks starting at hours ``first_hours`` ``(N,)``
    of the year, context included, from a year of hourly values ``(8760,)`` (wrapping around the year's ends)."""
    hourly = np.asarray(hourly_ground_c, dtype=np.float32)
    return hourly[_week_hours(first_hours, context_hours, len(hourly))]


def _week_hours(first_hours: np.ndarray, context_hours: int, year_hours: int) -> np.ndarray:
    """``(N, context_hours + 168)`` hour-of-year indices of weeks starting at ``first_hours``, context included."""
    offsets = np.arange(-check_context_hours(context_hours), cat.HOURS_PER_WEEK)
    return (np.asarray(first_hours, dtype=np.int64)[:, None] + offsets) % year_hours


def encode_weeks(
    theta: np.ndarray,
    settings: np.ndarray,
    occupancy: np.ndarray,
    weather: np.ndarray,
    previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    has_previous: np.ndarray | None = None,
    context_hours: int = CONTEXT_HOURS,
    ground_c: np.ndarray | None = None,
    temperature_before_c: np.ndarray | None = None,
) -> np.ndarray:
    """Model inputs of weeks, physical units (not yet standardised).

    Args:
        theta: ``(N, 21)``; settings: ``(N, 7, 13)``; occupancy: ``(N, 5, 2)``; weather: ``(N, 168, 9)``.
        previous: settings, occupancy and weather of each week's preceding week (same shapes), or ``None``.
        has_previous: ``(N,)`` booleans, False where ``previous`` holds no real preceding week.
        context_hours: hours before the week, a whole number of days (the checkpoint's:
            :attr:`Surrogate.context_hours`).
        ground_c: ``(N, context_hours + 168)`` ground temperature under the slab, degC (:func:`ground_hours`);
            ``None`` leaves the channel NaN, which a metamodel without it never reads and one with it refuses.
        temperature_before_c: ``(N, context_hours)`` indoor temperature measured over the context hours, degC,
            NaN where unknown; given, the two :data:`TEMPERATURE_BEFORE_CHANNELS` are appended.
    Returns:
        ``(N, context_hours + 168, C)`` float32: ``len(INPUT_CHANNELS)`` channels, or ``len(ALL_CHANNELS)``
        with ``temperature_before_c``.
    """
    n, ctx = len(theta), check_context_hours(context_hours)
    channels = len(INPUT_CHANNELS) if temperature_before_c is None else len(ALL_CHANNELS)
    x = np.empty((n, ctx + cat.HOURS_PER_WEEK, channels), dtype=np.float32)
    _fill_rows(x[:, ctx:], settings, occupancy, weather, slice(None))
    x[:, ctx:, _CALENDAR] = _calendar(cat.HOURS_PER_WEEK)
    x[:, :, _THETA] = np.asarray(theta, dtype=np.float32)[:, None, :]
    x[:, :ctx, : _CALENDAR.stop] = first_day_repeated(x[:, ctx:, : _CALENDAR.stop], ctx)  # EnergyPlus's warm-up
    if previous is not None:
        use = np.ones(n, bool) if has_previous is None else np.asarray(has_previous, bool)
        if use.any():
            prev_settings, prev_occ, prev_weather = (np.asarray(a)[use] for a in previous)
            rows = np.empty((int(use.sum()), ctx, len(INPUT_CHANNELS)), dtype=np.float32)
            _fill_rows(rows, prev_settings, prev_occ, prev_weather, slice(cat.HOURS_PER_WEEK - ctx, None))
            x[use, :ctx, : _SCHEDULES.stop] = rows[..., : _SCHEDULES.stop]
    x[:, :, _IS_CONTEXT] = 0.0
    x[:, :ctx, _IS_CONTEXT] = 1.0
    x[..., _GROUND] = np.nan if ground_c is None else np.asarray(ground_c, dtype=np.float32).reshape(n, -1)
    if temperature_before_c is not None:
        set_temperature_before(x, temperature_before_c)
    return x


def set_temperature_before(x: np.ndarray, temperature_c: np.ndarray | None) -> np.ndarray:
    """Write the indoor temperature measured before each week into inputs ``x`` ``(N, context + 168,
    len(ALL_CHANNELS))`` (in place, returned): ``temperature_c`` ``(N, context)`` degC on the context hours, NaN
    where unknown (``None``: unknown everywhere); the flag is 1 where it is known."""
    ctx = context_of(x)
    value, known = len(INPUT_CHANNELS), len(INPUT_CHANNELS) + 1
    x[..., value] = np.nan
    x[..., known] = 0.0
    if temperature_c is not None:
        t = np.asarray(temperature_c, dtype=np.float32).reshape(len(x), -1)
        if t.shape[1] != ctx:
            raise ValueError(f"temperature before the week: {t.shape[1]} hours given, the context has {ctx}")
        x[:, :ctx, value] = t
        x[:, :ctx, known] = np.isfinite(t)
    return x


def _read(ds, name: str, ids: np.ndarray) -> np.ndarray:
    """Rows ``ids`` (any order, repeats allowed) of a dataset array; h5py wants increasing unique indices."""
    unique, back = np.unique(ids, return_inverse=True)
    return getattr(ds, name)[unique][back]


def encode_dataset(
    ds, indices: np.ndarray, chunk: int = 2048, context_hours: int = CONTEXT_HOURS, temperature_before: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Inputs ``(n, context_hours + 168, C)`` and outputs ``(n, 168, 8)`` of dataset weeks (in ``indices``
    order), each with its real preceding hours as context where the dataset has them (``temperature_before``:
    with the previous week's simulated indoor temperature as the temperature measured before the week, unknown
    on a run's first week)."""
    indices = np.asarray(indices)
    previous = ds.previous_week()
    ground = dataset_ground_c(ds)
    climate, week_of_year = (getattr(ds, name)[:].astype(np.int64) for name in ("weather_index", "week_of_year"))
    xs, ys = [], []
    for start in range(0, len(indices), chunk):
        idx = indices[start : start + chunk]
        has = previous[idx] >= 0
        prev_idx = np.where(has, previous[idx], idx)
        prev = tuple(_read(ds, name, prev_idx) for name in ("settings", "occupancy", "weather"))
        week = [_read(ds, name, idx) for name in ("theta", "settings", "occupancy", "weather")]
        hours = _week_hours(week_of_year[idx] * cat.HOURS_PER_WEEK, context_hours, ground.shape[1])
        before = None
        if temperature_before:
            before = _read(ds, "outputs", prev_idx)[:, -context_hours:, _T_OUT].astype(np.float32)
            before[~has] = np.nan
        xs.append(encode_weeks(*week, prev, has, context_hours, ground[climate[idx][:, None], hours], before))
        ys.append(_read(ds, "outputs", idx))
    return np.concatenate(xs), np.concatenate(ys).astype(np.float32)


def dataset_ground_c(ds) -> np.ndarray:
    """``(climates, 8760)`` hourly ground temperature (degC) of each weather file of a dataset, in
    ``ds.weather_names`` order (week ``k`` of a campaign starts at hour ``168 k`` of its file).

    Raises:
        WeatherError: a weather file of the campaign can no longer be read (the message names it).
    """
    return np.stack([weather_ground_c(name) for name in ds.weather_names])


def weather_ground_c(weather: str | Path) -> np.ndarray:
    """``(8760,)`` hourly ground temperature under the slab (degC) of a weather file (short name or EPW path),
    as the shoebox sets it (:func:`buildenv.energyplus.shoebox.hourly_ground_temperature_c`).

    Raises:
        WeatherError: the file is missing or unreadable.
    """
    from buildenv.energyplus.shoebox import hourly_ground_temperature_c
    from buildenv.weather.epw import load_weather

    return hourly_ground_temperature_c(load_weather(weather))


def input_channels(ground: bool = True, temperature_before: bool = False) -> tuple[str, ...]:
    """The channels a metamodel reads: with or without the ground temperature, with or without the temperature
    measured before the week (which needs the ground temperature too)."""
    if temperature_before and not ground:
        raise CheckpointError("the temperature before the week is an input only with the ground temperature")
    return ALL_CHANNELS if temperature_before else INPUT_CHANNELS if ground else NO_GROUND_CHANNELS


def metadata(context_hours: int = CONTEXT_HOURS, ground: bool = True, temperature_before: bool = False) -> dict:
    """What a checkpoint records about its encoding: the catalogue and channels it must share with this
    buildenv to be usable (:func:`input_channels`), and its context length."""
    return {
        "catalogue_hash": cat.catalogue_hash(),
        "input_channels": list(input_channels(ground, temperature_before)),
        "output_channels": list(cat.OUTPUT_NAMES),
        "context_hours": check_context_hours(context_hours),
    }


@dataclass
class Surrogate:
    """A trained metamodel that simulates weeks: ``predict`` takes catalogue arrays, returns physical outputs.

    ``jit=True`` runs inference through the model traced and frozen by ``torch.jit`` (linear + ReLU fused,
    about 1.3x faster on CPU, same outputs to float32 rounding); models that cannot be traced run eagerly.
    ``workers``: threads that run the model calls of one ``predict`` side by side, each with torch on one thread
    (:class:`buildenv.metamodel.threads.MetamodelWorkers`; ``None``: as many as torch has threads, 1: torch
    alone); the outputs do not depend on it (at most float32 rounding on CPUs whose products depend on threads).
    """

    checkpoint: object  # metamodels.checkpoint.Checkpoint
    path: Path | None = None
    jit: bool = True
    workers: int | None = None
    _runner: object = field(default=None, repr=False, compare=False)
    _pool: MetamodelWorkers | None = field(default=None, repr=False, compare=False)
    _gather: tuple | None = field(default=None, repr=False, compare=False)
    _warned: bool = field(default=False, repr=False, compare=False)
    _earlier: tuple | None = field(default=None, repr=False, compare=False)
    #: the first 16 hex digits of the checkpoint file's SHA-256 (``None`` for one not read from a file)
    identity: str | None = field(default=None, compare=False)

    @property
    def name(self) -> str | None:
        """How calibrations record it: a shipped checkpoint's name (``"default"``, ``"diagnosis"``), else its path."""
        if self.path is None:
            return None
        resolved = Path(self.path).resolve()
        return next((n for n, p in SHIPPED_CHECKPOINTS.items() if p == resolved), str(self.path))

    @property
    def zoning(self) -> str:
        """Zoning of the shoebox whose simulations trained it (``single`` for checkpoints made before the
        choice existed); EnergyPlus runs that stand for this metamodel use the same."""
        return str(self.checkpoint.metadata.get("zoning", "single"))

    @property
    def context_hours(self) -> int:
        """Hours before each week this metamodel sees (:func:`encode_weeks`' ``context_hours``)."""
        return int(self.checkpoint.metadata.get("context_hours", CONTEXT_HOURS))

    @property
    def uses_ground(self) -> bool:
        """Whether the ground temperature is one of its inputs (checkpoints made before it was are not)."""
        return GROUND_CHANNEL in self.checkpoint.metadata.get("input_channels", ())

    @property
    def uses_temperature_before(self) -> bool:
        """Whether the indoor temperature measured before the week is one of its inputs
        (:data:`TEMPERATURE_BEFORE_CHANNELS`; ``buildenv train --temperature-before``)."""
        return TEMPERATURE_BEFORE_CHANNELS[0] in self.checkpoint.metadata.get("input_channels", ())

    def _inference_model(self):
        """The module ``predict_encoded`` calls: physical inputs ``(N, context_hours + 168, C)`` -> physical
        outputs of the week ``(N, 168, 8)``, standardisation included (traced once, on first use)."""
        if self._runner is None:
            import torch

            from metamodels.normalisation import StandardisedModel

            ck = self.checkpoint
            model = StandardisedModel(ck.model.eval(), ck.input_norm, ck.output_norm, self.context_hours).eval()
            self._runner = model
            if self.jit:
                example = torch.zeros(2, self.context_hours + cat.HOURS_PER_WEEK, ck.inputs)
                try:
                    with torch.no_grad(), warnings.catch_warnings():
                        warnings.simplefilter("ignore")  # tracer warnings about shape-dependent Python checks
                        traced = torch.jit.optimize_for_inference(torch.jit.trace(model, example))
                        traced(example)
                    self._runner = traced
                except (RuntimeError, TypeError, ValueError) as exc:  # an architecture the tracer cannot follow
                    log.info("metamodel runs eagerly (tracing failed: %s)", exc)
        return self._runner

    def predict(
        self,
        theta: np.ndarray,
        settings: np.ndarray,
        occupancy: np.ndarray,
        weather: np.ndarray,
        previous: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
        has_previous: np.ndarray | None = None,
        batch_size: int = INFERENCE_BATCH,
        ground_c: np.ndarray | None = None,
        temperature_before_c: np.ndarray | None = None,
    ) -> np.ndarray:
        """Hourly outputs ``(N, 168, 8)`` (Wh/m2, degC) of N weeks in as few model calls as the batch allows.

        Arguments as :func:`encode_weeks`; ``ground_c`` is needed where :attr:`uses_ground`;
        ``temperature_before_c`` is read where :attr:`uses_temperature_before` (unknown where not given) and
        ignored otherwise.
        """
        n = len(theta)
        self.check_implied(theta)
        out = np.empty((n, cat.HOURS_PER_WEEK, len(cat.OUTPUT_NAMES)), dtype=np.float32)
        model = self._inference_model()

        def call(part: slice) -> None:  # encoded call by call: the inputs of many weeks never all exist
            prev = None if previous is None else tuple(a[part] for a in previous)
            has = None if has_previous is None else np.asarray(has_previous)[part]
            ground = None if ground_c is None or not self.uses_ground else np.asarray(ground_c)[part]
            before = None
            if self.uses_temperature_before:
                before = (
                    np.full((len(theta[part]), self.context_hours), np.nan, np.float32)
                    if temperature_before_c is None
                    else np.asarray(temperature_before_c)[part]
                )
            x = encode_weeks(
                theta[part],
                settings[part],
                occupancy[part],
                weather[part],
                prev,
                has,
                self.context_hours,
                ground,
                before,
            )
            self._check_inputs(x)
            out[part] = self._call(model, x, own=True)

        self._spread(n, batch_size, call)
        return out

    def predict_encoded(self, x: np.ndarray, batch_size: int = INFERENCE_BATCH) -> np.ndarray:
        """Outputs ``(N, 168, 8)`` in physical units from inputs ``(N, context_hours + 168, C)`` encoded for it.

        ``batch_size`` weeks go through the model at a time (:data:`INFERENCE_BATCH`); any N is accepted.
        """
        self._check_inputs(x)
        model = self._inference_model()
        out = np.empty((len(x), cat.HOURS_PER_WEEK, len(cat.OUTPUT_NAMES)), dtype=np.float32)

        def call(part: slice) -> None:
            out[part] = self._call(model, x[part], own=False)

        self._spread(len(x), batch_size, call)
        return out

    def _call(self, model, x: np.ndarray, own: bool) -> np.ndarray:
        """One model call on encoded inputs ``x`` (under ``torch.inference_mode``)."""
        import torch

        return model(torch.from_numpy(self.model_inputs(x, in_place=own))).numpy()

    def _check_inputs(self, x: np.ndarray) -> None:
        """:class:`CheckpointError` where encoded inputs ``x`` do not suit this metamodel."""
        if context_of(x) != self.context_hours:
            raise CheckpointError(
                f"inputs carry {context_of(x)} context hours, this metamodel was trained with "
                f"{self.context_hours}: encode them with context_hours={self.context_hours}"
            )
        if x.shape[-1] not in (len(INPUT_CHANNELS), len(ALL_CHANNELS)):
            raise CheckpointError(
                f"inputs carry {x.shape[-1]} channels, encode_weeks gives {len(INPUT_CHANNELS)} "
                f"({len(ALL_CHANNELS)} with the temperature before the week)"
            )
        if self.uses_ground and np.isnan(x[..., _GROUND]).any():
            raise CheckpointError(
                "this metamodel needs the ground temperature under the slab: pass ground_c "
                "(buildenv.metamodel.surrogate.ground_hours of the weather file's hourly values)"
            )

    def _spread(self, n: int, batch_size: int, call) -> None:
        """``call(part)`` for the model calls ``n`` weeks split into (:func:`buildenv.metamodel.threads.split_calls`),
        spread over this metamodel's workers."""
        if self._pool is None or self._pool.workers != self.workers:
            self._pool = MetamodelWorkers(self.workers)
        self._pool.run(split_calls(n, batch_size, self._pool.count()), call)

    def model_inputs(self, x: np.ndarray, in_place: bool = False) -> np.ndarray:
        """The channels of encoded inputs ``x`` this metamodel reads, physical units, float32: those it does not
        read are dropped; the temperature before the week is added as unknown where ``x`` lacks it, and where it
        is unknown (NaN) the model reads the channel's training mean (written into ``x`` itself when
        ``in_place`` and ``x`` already has the model's channels, saving a copy). A checkpoint of an earlier
        catalogue of other variables gets its own channels, picked by name and converted (:attr:`earlier`)."""
        wanted = self.checkpoint.inputs
        if self.earlier is not None and not self.earlier.same_variables:
            return self._earlier_inputs(x)
        if not self.uses_temperature_before:
            return np.ascontiguousarray(x[..., :wanted], dtype=np.float32)
        if in_place and x.shape[-1] == wanted and x.dtype == np.float32 and x.flags.c_contiguous:
            full = x
        else:
            full = np.empty(x.shape[:-1] + (wanted,), dtype=np.float32)
            full[..., : x.shape[-1]] = x
        if x.shape[-1] < wanted:
            set_temperature_before(full, None)
        value = full[..., len(INPUT_CHANNELS)]
        value[np.isnan(value)] = self.checkpoint.input_norm.mean[len(INPUT_CHANNELS)]
        return full

    @property
    def earlier(self) -> cat.EarlierCatalogue | None:
        """The earlier catalogue this checkpoint was made with (:data:`buildenv.catalogue.EARLIER_CATALOGUES`),
        ``None`` for this one."""
        if self._earlier is None:
            found = self.checkpoint.metadata.get("catalogue_hash")
            if found != cat.catalogue_hash() and found not in cat.EARLIER_CATALOGUES:
                raise CheckpointError(f"{self.path}: made for catalogue {found}, neither this one nor an earlier one")
            self._earlier = (cat.EARLIER_CATALOGUES.get(found),)
        return self._earlier[0]

    @property
    def domain(self) -> dict[str, tuple[float, float]]:
        """``{name: (min, max)}`` of every theta_build and settings variable over the range this metamodel was
        trained on: the catalogue's, or an earlier catalogue's where it drew from another range."""
        ranges = {v.name: (v.min, v.max) for v in (*cat.THETA_BUILD, *cat.SETTINGS)}
        if self.earlier is not None:
            ranges.update({name: (lo, hi) for name, (lo, hi, _) in self.earlier.ranges.items()})
        return ranges

    @property
    def implied(self) -> dict[str, float]:
        """``{name: value}`` of the theta_build variables this metamodel does not read: the value the building
        model it learnt had (empty for a checkpoint of this catalogue)."""
        return {} if self.earlier is None else dict(self.earlier.implied)

    def channel_map(self) -> tuple[np.ndarray, np.ndarray]:
        """For each channel the checkpoint reads, its index into :data:`ALL_CHANNELS` and the factor that
        converts this catalogue's value into the checkpoint's (``(inputs,)`` each; identity but for a
        checkpoint of an earlier catalogue)."""
        if self._gather is None:
            renamed = {} if self.earlier is None else self.earlier.renamed
            index, scale = [], []
            for name in self.checkpoint.metadata.get("input_channels", ALL_CHANNELS[: self.checkpoint.inputs]):
                new, factor = renamed.get(name, (name, 1.0))
                index.append(ALL_CHANNELS.index(new))
                scale.append(1.0 / factor)
            self._gather = (np.array(index), np.array(scale, np.float32))
        return self._gather

    def _earlier_inputs(self, x: np.ndarray) -> np.ndarray:
        """The channels of a checkpoint of an earlier catalogue, by name, from inputs ``x`` encoded for this one."""
        index, scale = self.channel_map()
        if self.uses_temperature_before and x.shape[-1] < len(ALL_CHANNELS):
            x = set_temperature_before(np.concatenate([x, np.empty(x.shape[:-1] + (2,), x.dtype)], axis=-1), None)
        full = np.ascontiguousarray(x[..., index] * scale, dtype=np.float32)
        if self.uses_temperature_before:
            pos = int(np.flatnonzero(index == len(INPUT_CHANNELS))[0])
            value = full[..., pos]
            value[np.isnan(value)] = self.checkpoint.input_norm.mean[pos]
        return full

    def check_implied(self, theta: np.ndarray) -> None:
        """Warn once where theta_build ``(N, 21)`` sets a variable this metamodel does not read
        (:attr:`implied`) to another value than the one it learnt: its predictions ignore that value."""
        if self._warned or not self.implied:
            return
        theta = np.asarray(theta, dtype=float).reshape(-1, len(cat.THETA_NAMES))
        for name, value in self.implied.items():
            column = theta[:, cat.THETA_NAMES.index(name)]
            if not np.allclose(column, value):
                self._warned = True
                log.warning(
                    "metamodel %s does not read %s: it learnt %g, this building has %g; "
                    "its predictions are for %g (train a metamodel on this catalogue)",
                    self.path,
                    name,
                    value,
                    float(column[~np.isclose(column, value)][0]),
                    value,
                )
                return


def checkpoint_identity(path: str | Path) -> str:
    """The first 16 hex digits of the SHA-256 of a checkpoint file (what calibrations record)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()[:16]


def load_metamodel(path: str | Path | None = None) -> Surrogate:
    """Load a metamodel checkpoint: a path, or the name of one shipped in the package (:data:`SHIPPED_CHECKPOINTS`;
    ``None`` or ``"default"``: the default, ``"diagnosis"``: the one the gap diagnosis was measured with).

    Raises:
        CheckpointError: missing file; a file that is empty, truncated, damaged or written by another tool (the
            message, one line, names it and what is wrong); or a checkpoint made for another catalogue or input
            encoding.
    """
    from metamodels.checkpoint import CheckpointFormatError, load_checkpoint

    path = SHIPPED_CHECKPOINTS.get("default" if path is None else str(path), None) or Path(path)
    if not path.is_file():
        raise CheckpointError(f"metamodel checkpoint not found: {path}")
    try:
        ck = load_checkpoint(path)
    except CheckpointFormatError as exc:
        raise CheckpointError(str(exc)) from None
    found = ck.metadata.get("catalogue_hash")
    earlier = cat.EARLIER_CATALOGUES.get(found)
    channels = ck.metadata.get("input_channels", ())
    if earlier is not None and not earlier.same_variables:
        unknown = [c for c in channels if earlier.renamed.get(c, (c, 1.0))[0] not in ALL_CHANNELS]
        if unknown or ck.metadata.get("output_channels") != list(cat.OUTPUT_NAMES):
            raise CheckpointError(f"{path}: its channels {unknown or 'outputs'} are not this buildenv's; retrain it")
        return Surrogate(ck, path, identity=checkpoint_identity(path))
    try:
        expected = metadata(
            ck.metadata.get("context_hours", CONTEXT_HOURS),
            GROUND_CHANNEL in channels,
            TEMPERATURE_BEFORE_CHANNELS[0] in channels,
        )
    except CheckpointError as exc:
        raise CheckpointError(f"{path}: {exc}") from None
    if earlier is not None:  # of this catalogue's variables: checked as one of this catalogue
        expected["catalogue_hash"] = found
    for key, value in expected.items():
        if ck.metadata.get(key) != value:
            if key == "catalogue_hash":
                raise CheckpointError(
                    f"{path} was trained for catalogue {found}, this buildenv has {value}: "
                    "retrain it on a dataset simulated with this catalogue"
                )
            raise CheckpointError(f"{path}: its {key} differs from this buildenv's; retrain it")
    return Surrogate(ck, path, identity=checkpoint_identity(path))
