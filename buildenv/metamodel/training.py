"""Training and evaluating metamodels on a campaign's dataset (what ``buildenv train`` / ``evaluate`` run).

The split (kind and seed) is stored in the checkpoint, so ``evaluate`` on the same dataset scores exactly
the weeks held out of training. Normalisation statistics come from the training weeks only.
"""

from __future__ import annotations

import os
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import asdict
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.campaign.dataset import SPLIT_VERSION, Dataset, open_dataset
from buildenv.env.objectives import ENERGY_FLOOR_WH_M2, hvac_energy
from buildenv.errors import BuildenvError, DatasetError
from buildenv.metamodel import surrogate as sg
from buildenv.metrics import daily_errors, pooled_scores, response_scores, summarise, week_metrics


@contextmanager
def _checkpoint_errors() -> Iterator[None]:
    """A checkpoint file metamodels cannot read, as buildenv's one-line :class:`.surrogate.CheckpointError`."""
    from metamodels.checkpoint import CheckpointFormatError

    try:
        yield
    except CheckpointFormatError as exc:
        raise sg.CheckpointError(str(exc)) from None


def standardised_tensors(x: np.ndarray, y: np.ndarray, ck):
    """Encoded physical inputs ``(N, context + 168, C)`` and outputs ``(N, 168, 8)`` as the float tensors
    training takes: standardised with the checkpoint's statistics, the outputs padded with zeros over the
    context hours (which the loss's hour mask leaves out)."""
    import torch

    pad = np.zeros((len(y), sg.context_of(x), y.shape[-1]), np.float32)
    y_full = np.concatenate([pad, ck.output_norm.transform(y)], axis=1)
    z = ck.input_norm.transform(x)
    if x.shape[-1] == len(sg.ALL_CHANNELS):  # an unknown temperature before the week reads as its mean
        value = z[..., len(sg.INPUT_CHANNELS)]
        value[np.isnan(value)] = 0.0
    return torch.from_numpy(z), torch.from_numpy(y_full)


#: Share of the training and validation weeks whose temperature before the week is hidden (a seeded draw), so
#: that a metamodel trained with it still predicts weeks before which nothing was measured
TEMPERATURE_BEFORE_HIDDEN = 0.25


def hide_temperature_before(x: np.ndarray, share: float, seed: int) -> np.ndarray:
    """Mark the temperature before the week unknown on a seeded random ``share`` of the weeks of inputs ``x``
    ``(N, context + 168, len(ALL_CHANNELS))`` (in place, returned)."""
    hidden = np.random.default_rng(seed).random(len(x)) < share
    x[hidden, :, len(sg.INPUT_CHANNELS)] = np.nan
    x[hidden, :, len(sg.INPUT_CHANNELS) + 1] = 0.0
    return x


def train_metamodel(
    data: str | os.PathLike | list[str | os.PathLike],
    model: str,
    out: str | Path,
    split: str = "weather_weeks",
    max_weeks: int | None = None,
    model_config: dict | None = None,
    seed: int = 0,
    holdout_climates: list[str] | None = None,
    progress: bool = True,
    context_hours: int = sg.CONTEXT_HOURS,
    init: str | Path | None = None,
    ground_temperature: bool = True,
    temperature_before: bool = False,
    **train_options,
) -> dict:
    """Train one metamodel on a dataset and score it on the held-out test weeks.

    Args:
        data: dataset directory (``buildenv simulate --out``), or a list of them of one zoning, trained on together
            (:func:`training_splits`).
        model: ``transformer``, ``bigru``, ``lstm``, ``convgru`` or ``ffn``.
        out: checkpoint path (``out.last`` and ``out.csv`` are written beside it; a rerun resumes).
        split: ``weather_weeks``, ``buildings``, ``random`` or ``climate`` (:meth:`.Dataset.split`).
        max_weeks: use at most this many training weeks (a seeded random subset), e.g. for learning curves.
        model_config: keyword arguments of the model class.
        seed: seed of the split, the subset, the weights and the batch order.
        holdout_climates: climates kept out of training altogether and scored apart (``"holdout_climate"``).
        progress: progress bars.
        context_hours: hours before each week the model sees (a whole number of days; recorded in the checkpoint).
        init: a checkpoint (or ``"default"``) to fine-tune: the same ``model``, configuration, split and held-out
            climates, split as it was (its ``split_version``), so its test weeks stay unseen; inputs it lacks are
            added with zero weights. It may come from shoeboxes of another zoning (the outputs are the same
            building totals); its zoning is recorded.
        ground_temperature: give the model the ground temperature under the slab (:mod:`buildenv.metamodel.surrogate`);
            ``False`` trains on the other channels only, as checkpoints made before it existed.
        temperature_before: give the model the previous week's ``T_INT_OFFICE`` over the context hours
            (:data:`buildenv.metamodel.surrogate.TEMPERATURE_BEFORE_CHANNELS`), hidden on a
            :data:`TEMPERATURE_BEFORE_HIDDEN` share of the weeks; needs the ground temperature.
        train_options: fields of :class:`metamodels.train.TrainConfig` (epochs, batch_size, lr, patience, ...).
    Returns:
        ``{"model", "train_weeks", "paired_train_weeks", "val_weeks", "test_weeks", "seconds", "fit": {...}, "test":
        {metrics}}`` (``paired_train_weeks``: training weeks with a partner under other settings).
    Raises:
        BuildenvError: a resumed or ``init`` checkpoint does not fit the run, a dataset lacks outputs, or the datasets
            are repeated or of different zonings.
    """
    import torch

    from metamodels.checkpoint import Checkpoint
    from metamodels.models import build
    from metamodels.normalisation import Standardiser
    from metamodels.train import TrainConfig, fit

    wanted = sg.input_channels(ground_temperature, temperature_before)
    channels = slice(0, len(wanted))
    started = time.perf_counter()
    ctx = sg.check_context_hours(context_hours)
    last = Path(out).with_name(Path(out).name + ".last")
    split_version = SPLIT_VERSION
    paths = _dataset_paths(data)
    if last.exists():  # a resumed run keeps the datasets, the encoding and the split it started with
        from metamodels.checkpoint import load_checkpoint

        with _checkpoint_errors():
            was = load_checkpoint(last).metadata
        split_version = int(was.get("split_version", 1))
        trained_on = was.get("datasets", [was.get("dataset")])
        if trained_on != [str(p) for p in paths]:
            given = " ".join(f"--data {d}" for d in trained_on)
            raise BuildenvError(
                f"{last} was trained with {given}: rerun with those, in that order, or remove it to start over"
            )
        if was.get("context_hours", sg.CONTEXT_HOURS) != ctx:
            raise BuildenvError(
                f"{last} was trained with --context-hours {was.get('context_hours')}, not {ctx}: "
                "rerun with that to resume it, or remove it to start over"
            )
        if (sg.GROUND_CHANNEL in was.get("input_channels", ())) != ground_temperature:
            raise BuildenvError(
                f"{last} was trained {'with' if not ground_temperature else 'without'} the ground "
                "temperature: rerun as it was to resume it, or remove it to start over"
            )
        if (sg.TEMPERATURE_BEFORE_CHANNELS[0] in was.get("input_channels", ())) != temperature_before:
            raise BuildenvError(
                f"{last} was trained {'with' if not temperature_before else 'without'} the "
                "temperature before the week: rerun as it was to resume it, or remove it to start over"
            )
    if len(paths) > 1 and split == "climate":
        raise BuildenvError(
            "--split climate draws test climates per campaign, so one campaign's could be another's training: "
            "train on several campaigns with --split weather_weeks (and --holdout-climate for a climate left out)"
        )
    start = None if init is None else _initial_checkpoint(init, model, model_config, split, seed, holdout_climates)
    if start is not None and not last.exists():  # the start's test weeks stay unseen: its split, drawn alike
        split_version = int(start.metadata.get("split_version", 1))
    encoded = _encode_campaigns(paths, split, seed, holdout_climates, max_weeks, split_version, ctx, temperature_before)
    ds_zoning = encoded.pop("zoning")
    partner = encoded.pop("train_partner")
    (x_tr, y_tr), (x_va, y_va), (x_te, y_te) = encoded["train"], encoded["val"], encoded["test"]
    apart = encoded.get("holdout_climate")
    if temperature_before:
        hide_temperature_before(x_tr, TEMPERATURE_BEFORE_HIDDEN, seed)
        hide_temperature_before(x_va, TEMPERATURE_BEFORE_HIDDEN, seed + 1)
    torch.manual_seed(seed)
    config = dict(model_config or {})
    metadata = {
        **sg.metadata(ctx, ground_temperature, temperature_before),
        "dataset": str(paths[0]),
        "datasets": [str(p) for p in paths],
        "split": split,
        "split_seed": seed,
        "split_version": split_version,
        "holdout_climates": list(holdout_climates or []),
        "train_weeks": int(len(x_tr)),
        "zoning": ds_zoning,
    }
    if start is not None:
        metadata["initialised_from"] = {
            "checkpoint": str(init),
            "dataset": start.metadata.get("dataset"),
            "datasets": start.metadata.get("datasets", [start.metadata.get("dataset")]),
            "train_weeks": start.metadata.get("train_weeks"),
            "context_hours": start.metadata.get("context_hours", sg.CONTEXT_HOURS),
            "zoning": start.metadata.get("zoning", "core_perimeter"),
        }
        ck = Checkpoint(model, dict(start.config), start.model, start.input_norm, start.output_norm, metadata)
        had = tuple(start.metadata.get("input_channels", sg.NO_GROUND_CHANNELS))
        if sg.GROUND_CHANNEL in had and not ground_temperature:
            raise BuildenvError(f"--init {init} reads the ground temperature: leave --no-ground-temperature out")
        if sg.TEMPERATURE_BEFORE_CHANNELS[0] in had and not temperature_before:
            raise BuildenvError(f"--init {init} reads the temperature before the week: pass --temperature-before")
        earlier = cat.EARLIER_CATALOGUES.get(start.metadata.get("catalogue_hash"))
        if earlier is not None:
            ck = _onto_catalogue(ck, earlier, had, wanted, x_tr[..., channels])
            metadata["initialised_from"]["added_inputs"] = [w for w in wanted if _earlier_name(earlier, w) not in had]
        elif len(wanted) > len(had):
            ck = _with_inputs(ck, x_tr[..., channels], len(had))
            metadata["initialised_from"]["added_inputs"] = list(wanted[len(had) :])
    else:
        net = build(model, x_tr[..., channels].shape[-1], y_tr.shape[-1], **config)
        ck = Checkpoint(model, config, net, Standardiser.fit(x_tr[..., channels]), Standardiser.fit(y_tr), metadata)
    cfg = TrainConfig(
        seed=seed,
        temperature_channels=sg.TEMPERATURE_CHANNELS,
        consumption_channels=sg.CONSUMPTION_CHANNELS,
        energy_channels=[cat.OUTPUT_NAMES.index(n) for n in cat.HVAC_OUTPUTS],
        energy_floor=ENERGY_FLOOR_WH_M2,
        **train_options,
    )
    hour_mask = torch.tensor([False] * ctx + [True] * cat.HOURS_PER_WEEK)
    with _checkpoint_errors():  # a resumed run reads CKPT.last and the best checkpoint back
        history = fit(
            ck,
            *standardised_tensors(x_tr[..., channels], y_tr, ck),
            *standardised_tensors(x_va[..., channels], y_va, ck),
            hour_mask,
            cfg,
            Path(out),
            progress,
            partner=torch.as_tensor(partner),
        )
    surrogate = sg.Surrogate(ck)
    test = score(surrogate, x_te, y_te)
    extra = (
        {
            "holdout_climate": {
                "climates": list(holdout_climates),
                "weeks": int(len(apart[0])),
                **score(surrogate, *apart),
            }
        }
        if apart
        else {}
    )
    return {
        "model": model,
        "config": ck.config,
        "train": asdict(cfg),
        "train_weeks": int(len(x_tr)),
        "paired_train_weeks": int((partner >= 0).sum()),
        "val_weeks": int(len(x_va)),
        "test_weeks": int(len(x_te)),
        "seconds": round(time.perf_counter() - started, 1),
        "fit": {k: v for k, v in history.items() if k != "history"},
        "test": test,
        **extra,
    }


def _with_inputs(ck, x_tr: np.ndarray, had: int):
    """Checkpoint ``ck`` (which reads the first ``had`` channels) given the other channels of the training inputs
    ``x_tr`` as more inputs: zero weights (it starts out computing what it did), standardised with their mean
    and deviation over ``x_tr`` (known values only)."""
    from metamodels.checkpoint import Checkpoint
    from metamodels.models import with_more_inputs
    from metamodels.normalisation import Standardiser

    added = Standardiser.fit(x_tr[..., had:])
    norm = Standardiser(
        np.concatenate([ck.input_norm.mean, added.mean]), np.concatenate([ck.input_norm.std, added.std])
    )
    net = with_more_inputs(ck.model, ck.name, ck.config, ck.inputs, ck.outputs, x_tr.shape[-1] - had)
    return Checkpoint(ck.name, ck.config, net, norm, ck.output_norm, ck.metadata)


def _earlier_name(earlier: cat.EarlierCatalogue, name: str) -> str:
    """The name a channel of this catalogue had in ``earlier``."""
    return next((old for old, (new, _) in earlier.renamed.items() if new == name), name)


def _onto_catalogue(ck, earlier: cat.EarlierCatalogue, had: tuple[str, ...], wanted: tuple[str, ...], x_tr):
    """Checkpoint ``ck`` of an ``earlier`` catalogue (reading channels ``had``) moved onto this catalogue's
    channels ``wanted``: a channel it read keeps its weights and its statistics (converted where renamed), so
    it computes what it did; a new one gets zero weights, standardised over the training inputs ``x_tr``."""
    from metamodels.checkpoint import Checkpoint
    from metamodels.models import with_inputs
    from metamodels.normalisation import Standardiser

    fitted = Standardiser.fit(x_tr)
    sources, mean, std = [], fitted.mean.copy(), fitted.std.copy()
    for j, name in enumerate(wanted):
        old = _earlier_name(earlier, name)
        if old in had:
            i = had.index(old)
            factor = earlier.renamed.get(old, (name, 1.0))[1]
            sources.append(i)
            mean[j], std[j] = ck.input_norm.mean[i] * factor, ck.input_norm.std[i] * factor
        else:
            sources.append(-1)
    net = with_inputs(ck.model, ck.name, ck.config, ck.inputs, ck.outputs, sources)
    return Checkpoint(ck.name, ck.config, net, Standardiser(mean, std), ck.output_norm, ck.metadata)


def training_split(
    ds,
    split: str,
    seed: int,
    holdout_climates: list[str] | None = None,
    max_weeks: int | None = None,
    version: int = SPLIT_VERSION,
) -> dict[str, np.ndarray]:
    """The weeks a training run uses: :meth:`buildenv.campaign.dataset.Dataset.split` (of split ``version``), its
    training part cut to a seeded random ``max_weeks`` subset when given (the subset :func:`train_metamodel` draws)."""
    return training_splits([ds], split, seed, holdout_climates, max_weeks, version)[0]


def training_splits(
    datasets: list[Dataset],
    split: str,
    seed: int,
    holdout_climates: list[str] | None = None,
    max_weeks: int | None = None,
    version: int = SPLIT_VERSION,
) -> list[dict[str, np.ndarray]]:
    """:func:`training_split` of several open datasets trained on together: each split on its own (the weather_weeks
    split of version 2 puts a (weather file, week) in the same part in every campaign), each holding out those of
    ``holdout_climates`` it has, the ``max_weeks`` subset drawn over their training weeks together.

    Returns:
        one dict of index arrays per dataset, in order (``"holdout_climate"`` empty where a dataset has none of them).
    Raises:
        DatasetError: a held-out climate no dataset has, or a split :meth:`.Dataset.split` refuses.
    """
    held = list(holdout_climates or [])
    missing = [c for c in held if not any(c in ds.weather_names for ds in datasets)]
    if missing:
        raise DatasetError(f"climate(s) {missing} in none of {', '.join(str(ds.path) for ds in datasets)}")
    parts = []
    for ds in datasets:
        mine = [c for c in held if c in ds.weather_names]
        part = ds.split(split, seed=seed, holdout_climates=mine or None, version=version)
        parts.append(
            {**part, "holdout_climate": part.get("holdout_climate", np.array([], dtype=np.int64))} if held else part
        )
    sizes = [len(p["train"]) for p in parts]
    if max_weeks is not None and max_weeks < sum(sizes):
        rng = np.random.default_rng(seed)
        chosen = np.sort(rng.choice(sum(sizes), size=max_weeks, replace=False))
        edges = np.cumsum([0, *sizes])
        for i, p in enumerate(parts):
            mine = chosen[(chosen >= edges[i]) & (chosen < edges[i + 1])] - edges[i]
            p["train"] = p["train"][mine]
    return parts


def _dataset_paths(data: str | os.PathLike | list[str | os.PathLike]) -> list[Path]:
    """The dataset directories of ``data`` (one path or several), resolved; refused when none or repeated."""
    paths = [Path(d).resolve() for d in ([data] if isinstance(data, (str, os.PathLike)) else data)]
    if not paths:
        raise BuildenvError("no dataset given: pass --data DIR (repeatable)")
    repeated = sorted({str(p) for p in paths if paths.count(p) > 1})
    if repeated:
        raise BuildenvError(f"--data {repeated[0]} is given twice: give each dataset once")
    return paths


def _encode_campaigns(
    paths: list[Path],
    split: str,
    seed: int,
    holdout_climates: list[str] | None,
    max_weeks: int | None,
    version: int,
    ctx: int,
    temperature_before: bool,
) -> dict:
    """Encoded ``(x, y)`` of each part (``train``, ``val``, ``test``, and ``holdout_climate`` when climates are held
    out) over the datasets at ``paths``, concatenated in order, their ``zoning``, and ``train_partner``: each
    training week's partner under other settings (:meth:`.Dataset.settings_partners`, an index into the
    concatenated training weeks, or -1).

    Raises:
        BuildenvError: the datasets' shoeboxes are of different zonings, training or validation weeks have
            outputs that are not finite, or no campaign has a week in the training, validation or test part.
    """
    with ExitStack() as stack:
        datasets = [stack.enter_context(open_dataset(p)) for p in paths]
        zonings = {ds.zoning for ds in datasets}
        if len(zonings) > 1:
            each = ", ".join(f"{p} is {ds.zoning}" for p, ds in zip(paths, datasets))
            raise BuildenvError(f"--data: {each}: train on campaigns of one zoning")
        parts = training_splits(datasets, split, seed, holdout_climates, max_weeks, version)
        names = ["train", "val", "test"] + (["holdout_climate"] if holdout_climates else [])
        encoded: dict = {"zoning": zonings.pop()}
        partners, offset = [], 0
        for ds, part in zip(datasets, parts):
            mine = ds.settings_partners(part["train"])
            partners.append(np.where(mine >= 0, mine + offset, -1))
            offset += len(part["train"])
        encoded["train_partner"] = np.concatenate(partners)
        for name in names:
            pieces = []
            for ds, path, part in zip(datasets, paths, parts):
                if not len(part[name]):  # none of this campaign's weeks fell in the part (a small campaign)
                    continue
                x, y = sg.encode_dataset(ds, part[name], context_hours=ctx, temperature_before=temperature_before)
                missing = ~np.isfinite(y).all(axis=(1, 2))
                if name in ("train", "val") and missing.any():
                    raise BuildenvError(
                        f"{path}: {int(missing.sum())} of the {len(y)} {_PART_WORDS[name]} weeks have outputs "
                        "that are not finite (NaN or inf): the dataset lacks them or is damaged; simulate it "
                        "again or train on a subset that has them (--max-weeks of a carried pack)"
                    )
                pieces.append((x, y))
            if not pieces and name != "holdout_climate":
                raise BuildenvError(f"--data: no {_PART_WORDS[name]} weeks in any campaign: simulate more weeks")
            encoded[name] = tuple(np.concatenate(arrays) if len(pieces) > 1 else arrays[0] for arrays in zip(*pieces))
    return encoded


_PART_WORDS = {"train": "training", "val": "validation", "test": "test"}


def _initial_checkpoint(
    init: str | Path,
    model: str,
    model_config: dict | None,
    split: str,
    seed: int,
    holdout_climates: list[str] | None,
):
    """The checkpoint a fine-tuning run starts from, refused where it would not fit the run (see ``init``)."""
    start = sg.load_metamodel(init).checkpoint
    meta = start.metadata
    held = sorted(meta.get("holdout_climates") or [])
    if start.name != model:
        raise BuildenvError(f"--init {init} is a {start.name}, not a {model}: pass --model {start.name}")
    if model_config and dict(model_config) != start.config:
        raise BuildenvError(f"--init {init} has --model-config {start.config}; leave --model-config out")
    if (meta.get("split"), meta.get("split_seed"), held) != (split, seed, sorted(holdout_climates or [])):
        raise BuildenvError(
            f"--init {init} was trained with --split {meta.get('split')} --seed "
            f"{meta.get('split_seed')} and held-out climates {held or 'none'}: use the same, or "
            "its test weeks may be trained on"
        )
    return start


def checkpoint_split(ds, meta: dict) -> dict[str, np.ndarray]:
    """The split a checkpoint was trained with (its metadata's split kind, seed and held-out climates), drawn
    again on ``ds``: its test weeks when ``ds`` is one of its datasets or a copy of one."""
    return ds.split(
        meta["split"],
        seed=meta["split_seed"],
        holdout_climates=meta.get("holdout_climates") or None,
        version=int(meta.get("split_version", 1)),
    )


def week_scores(surrogate: sg.Surrogate, x: np.ndarray, y: np.ndarray, pred: np.ndarray) -> dict[str, np.ndarray]:
    """Per-week metrics (:func:`buildenv.metrics.week_metrics`, in the surrogate's standardised units) of its
    predictions ``pred`` of encoded weeks ``x`` with true outputs ``y``."""
    occupied = x[:, sg.context_of(x) :, sg.INPUT_CHANNELS.index("occupancy_fraction")] > 0
    norm = surrogate.checkpoint.output_norm
    return week_metrics(y, pred, occupied, norm.mean, norm.std)


def score(surrogate: sg.Surrogate, x: np.ndarray, y: np.ndarray, pred: np.ndarray | None = None) -> dict[str, float]:
    """Metrics (mean and std over weeks) of a surrogate on encoded weeks ``x`` with true outputs ``y`` (its
    predictions ``pred``, standardised, when already made)."""
    pred = surrogate.predict_encoded(x) if pred is None else pred
    norm = surrogate.checkpoint.output_norm
    return {
        **summarise(week_scores(surrogate, x, y, pred)),
        **pooled_scores(y, pred, norm.mean, norm.std),
        **daily_errors(y, pred, norm.mean, norm.std),
    }


def evaluate_metamodel(checkpoint: str | Path | None, data: str | Path, subset: str = "test") -> dict:
    """Score a checkpoint on a dataset.

    ``subset="test"`` scores the checkpoint's own held-out weeks when ``data`` is one of the datasets it was
    trained on (same split kind and seed), and every week otherwise; ``subset="holdout_climate"`` the weeks of the
    climates kept out of its training; ``subset="all"`` scores every week. A campaign that simulated each building
    under several settings (``buildenv simulate --settings-draws``) adds the response to settings
    (:func:`buildenv.metrics.response_scores`, each week against the same week under its group's first settings).
    """
    surrogate = sg.load_metamodel(checkpoint)
    meta = surrogate.checkpoint.metadata
    with open_dataset(data) as ds:
        same = str(Path(data).resolve()) in meta.get("datasets", [meta.get("dataset")])
        holdout = meta.get("holdout_climates") or None
        if subset == "holdout_climate":
            if not holdout:
                raise BuildenvError("this checkpoint was trained with no climate held out (see --holdout-climate)")
            idx = checkpoint_split(ds, meta)["holdout_climate"]
        elif subset == "test" and same:
            idx = checkpoint_split(ds, meta)["test"]
        else:
            idx = np.arange(len(ds))
        x, y = sg.encode_dataset(
            ds, idx, context_hours=surrogate.context_hours, temperature_before=surrogate.uses_temperature_before
        )
        slots = ds.settings_slots()
    pred = surrogate.predict_encoded(x)
    result = score(surrogate, x, y, pred)
    if slots is not None:
        norm = surrogate.checkpoint.output_norm
        energy = [hvac_energy(v * norm.std + norm.mean) for v in (y, pred)]
        result.update(response_scores(*energy, slots[idx], ENERGY_FLOOR_WH_M2))
    result["subset"] = subset if subset == "holdout_climate" or (subset == "test" and same) else "all"
    return result
