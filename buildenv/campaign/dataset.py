"""Reading a campaign's dataset and splitting it for training.

A dataset directory holds ``dataset.h5`` (chunked HDF5, read lazily: nothing is loaded until sliced) and
``manifest.json`` (package versions, seed, catalogue hash). Arrays, all float32 in catalogue units:

==============  =========================  ==========================================================
name            shape                      content
==============  =========================  ==========================================================
theta           (weeks, 25)                theta_build of the week's building
settings        (weeks, 7, 13)             I_k, day x setting
occupancy       (weeks, 5, 2)              O_k, weekday x (start hour, end hour)
weather         (weeks, 168, 9)            W_k, hourly
outputs         (weeks, 168, 8)            simulated outputs, hourly
run_id          (weeks,)                   EnergyPlus run the week comes from
week_in_run     (weeks,)                   0 for a run's first week; week i-1 of a run precedes week i
week_of_year    (weeks,)                   0-51 (weeks start on Mondays)
weather_index   (weeks,)                   index into ``weather_names`` (the climate)
==============  =========================  ==========================================================

The manifest records, under ``files``, each data file's size, modification time and SHA-256
(:func:`data_file_record`), and under ``command`` the ``buildenv simulate`` command that made it.
:func:`open_dataset` hashes ``dataset.h5`` again when its size or modification time differs from the
manifest's (a copy, an edit) and refuses a file whose bytes changed, or that HDF5 cannot read, with one line
naming the file and the command to regenerate it. A manifest written before checksums were recorded loads
without the check. A dataset of an earlier catalogue that lacked variables reads with them at the values its
building model had (:class:`PaddedTheta`).
"""

from __future__ import annotations

import hashlib
import json
import shlex
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from buildenv import catalogue as cat
from buildenv.errors import DatasetError

DATA_FILE = "dataset.h5"
MANIFEST_FILE = "manifest.json"
SPLITS = ("random", "weather_weeks", "buildings", "climate")
#: How :meth:`Dataset.split` assigns weather weeks: 1 permuted the weather weeks a dataset holds, so two campaigns
#: split them differently; 2 draws each (weather name, week of year) from the seed alone, the same in every
#: campaign, so a fine-tune on another campaign keeps its starting checkpoint's test weather weeks unseen.
SPLIT_VERSION = 2
ARRAYS = (
    "theta",
    "settings",
    "occupancy",
    "weather",
    "outputs",
    "run_id",
    "week_in_run",
    "week_of_year",
    "weather_index",
)


@dataclass
class Dataset:
    """An open dataset. Arrays are ``h5py.Dataset`` objects: slice them to read (``ds.outputs[:100]``)."""

    path: Path
    manifest: dict
    weather_names: list[str]
    _h5: object

    def __getattr__(self, name: str):
        if name == "theta":
            earlier = cat.EARLIER_CATALOGUES.get(self.manifest.get("catalogue_hash"))
            return self._h5[name] if earlier is None else PaddedTheta(self._h5[name], earlier)
        if name in ARRAYS:
            return self._h5[name]
        raise AttributeError(name)

    def __len__(self) -> int:
        return int(self._h5["outputs"].shape[0])

    @property
    def zoning(self) -> str:
        """The zoning of the simulated shoebox (``single`` for campaigns made before it was a choice)."""
        return str(self.manifest.get("config", {}).get("zoning", "single"))

    def close(self) -> None:
        """Close the HDF5 file."""
        self._h5.close()

    def __enter__(self) -> Dataset:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def previous_week(self) -> np.ndarray:
        """Index of the week that precedes each week in its EnergyPlus run, or -1 for a run's first week."""
        run = self._h5["run_id"][:]
        week = self._h5["week_in_run"][:]
        index = np.full(len(run), -1, dtype=np.int64)
        key = {(int(r), int(w)): i for i, (r, w) in enumerate(zip(run, week))}
        for i, (r, w) in enumerate(zip(run, week)):
            if w > 0:
                index[i] = key.get((int(r), int(w) - 1), -1)
        return index

    def settings_slots(self) -> np.ndarray | None:
        """One integer per week, the same for the same building and week under other settings draws (a campaign
        with ``settings_draws`` above 1), or ``None`` when every run was drawn anew."""
        draws = int(self.manifest.get("config", {}).get("settings_draws", 1))
        if draws < 2:
            return None
        return self._h5["run_id"][:] // draws * cat.WEEKS_PER_YEAR + self._h5["week_in_run"][:]

    def settings_partners(self, idx: np.ndarray) -> np.ndarray:
        """For each week of ``idx``, the position in ``idx`` of its partner: the week of the same building and
        weather under the next settings draw of its group (the draws in a ring), or -1 when ``idx`` holds none."""
        every = self.settings_slots()
        partner = np.full(len(idx), -1, dtype=np.int64)
        if every is None or not len(idx):
            return partner
        slots = every[idx]
        order = np.lexsort((np.asarray(idx), slots))
        start = np.r_[True, slots[order][1:] != slots[order][:-1]]
        first = np.maximum.accumulate(np.where(start, np.arange(len(order)), 0))
        end = np.r_[start[1:], True]
        nxt = np.where(end, first, np.arange(len(order)) + 1)  # the next in the slot, the last to the first
        partner[order] = np.where(nxt != np.arange(len(order)), order[nxt], -1)
        return partner

    def _climate_ids(self, names: list[str]) -> list[int]:
        unknown = [c for c in names if c not in self.weather_names]
        if unknown:
            raise DatasetError(f"climate(s) {unknown} not in {self.path} ({', '.join(self.weather_names)})")
        return [self.weather_names.index(c) for c in names]

    def split(
        self,
        kind: str = "random",
        fractions: tuple[float, float, float] = (0.8, 0.1, 0.1),
        seed: int = 0,
        test_climates: list[str] | None = None,
        holdout_climates: list[str] | None = None,
        version: int = SPLIT_VERSION,
    ) -> dict[str, np.ndarray]:
        """Indices of train / validation / test weeks.

        Args:
            kind: ``random`` (weeks shuffled), or whole groups to one split only: ``weather_weeks`` (a climate's
                week of year), ``buildings`` (EnergyPlus runs, as a calibrated site's building is unseen) or
                ``climate`` (``test_climates`` names the test ones, else the fractions pick).
            fractions: train, validation, test shares (by weeks for ``random``, by groups otherwise).
            seed: shuffling seed.
            test_climates: weather names held out as test set (``climate`` split only).
            holdout_climates: weather names whose weeks are taken out of all three parts and returned apart
                as ``"holdout_climate"`` (``random`` or ``weather_weeks`` only).
            version: the weather-week assignment (:data:`SPLIT_VERSION`; 1 for checkpoints trained before it).
        Returns:
            ``{"train": idx, "val": idx, "test": idx}`` (plus ``"holdout_climate"``), sorted int arrays.
        Raises:
            DatasetError: an unknown kind or climate, or fractions that are negative or do not sum to 1.
        """
        if holdout_climates:
            if kind == "climate":
                raise DatasetError("holdout_climates goes with the random or weather_weeks split, not climate")
            ids = self._climate_ids(holdout_climates)
            apart = np.isin(self._h5["weather_index"][:], ids)
            parts = self.split(kind, fractions, seed, version=version)
            parts = {name: idx[~apart[idx]] for name, idx in parts.items()}
            return {**parts, "holdout_climate": np.flatnonzero(apart)}
        if kind not in SPLITS:
            raise DatasetError(f"unknown split {kind!r}; choose one of {', '.join(SPLITS)}")
        if not np.isclose(sum(fractions), 1.0) or min(fractions) < 0:
            raise DatasetError(f"split fractions must be >= 0 and sum to 1 (got {fractions})")
        if kind == "weather_weeks" and version >= 2:
            return self._weather_week_parts(fractions, seed)
        rng = np.random.default_rng(seed)
        n = len(self)
        climate = self._h5["weather_index"][:].astype(np.int64)
        if kind == "random":
            groups = np.arange(n)
        elif kind == "weather_weeks":
            groups = climate * 100 + self._h5["week_of_year"][:].astype(np.int64)
        elif kind == "buildings":
            groups = self._h5["run_id"][:].astype(np.int64)
        else:
            groups = climate
            if test_climates:
                is_test = np.isin(climate, self._climate_ids(test_climates))
                rest = np.unique(climate[~is_test])
                rest = rest[rng.permutation(len(rest))]
                n_val = max(1, int(round(fractions[1] / max(fractions[0] + fractions[1], 1e-9) * len(rest))))
                val_ids = set(rest[:n_val].tolist()) if len(rest) > 1 else set()
                is_val = np.isin(climate, list(val_ids))
                return {
                    "train": np.flatnonzero(~is_test & ~is_val),
                    "val": np.flatnonzero(is_val),
                    "test": np.flatnonzero(is_test),
                }
        unique = np.unique(groups)
        unique = unique[rng.permutation(len(unique))]
        cuts = np.round(np.cumsum(fractions)[:2] * len(unique)).astype(int)
        parts = np.split(unique, cuts)
        return {name: np.flatnonzero(np.isin(groups, part)) for name, part in zip(("train", "val", "test"), parts)}

    def _weather_week_parts(self, fractions: tuple[float, float, float], seed: int) -> dict[str, np.ndarray]:
        """Train / validation / test by weather week, each (weather name, week of year) drawn from ``seed`` alone."""
        climate = self._h5["weather_index"][:].astype(np.int64)
        week = self._h5["week_of_year"][:].astype(np.int64)
        groups, of_group = np.unique(np.stack([climate, week], axis=1), axis=0, return_inverse=True)
        crc = [zlib.crc32(name.encode("utf-8")) for name in self.weather_names]
        draw = np.array([np.random.default_rng([seed, crc[c], w]).random() for c, w in groups])
        of_week = np.searchsorted(np.cumsum(fractions)[:2], draw, side="right")[of_group.ravel()]
        return {name: np.flatnonzero(of_week == i) for i, name in enumerate(("train", "val", "test"))}


def data_file_record(path: str | Path) -> dict:
    """What a manifest records of a data file: ``{"bytes": size, "mtime_ns": modification time (ns),
    "sha256": hex digest}``."""
    stat = Path(path).stat()
    return {"bytes": stat.st_size, "mtime_ns": stat.st_mtime_ns, "sha256": _sha256(path)}


def _sha256(path: str | Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while block := handle.read(1 << 20):
            digest.update(block)
    return digest.hexdigest()


def simulate_command(directory: str | Path, config: dict) -> str:
    """The ``buildenv simulate`` command (shell-quoted) that makes the dataset of a manifest's ``config`` in
    ``directory``."""
    flags = {"weeks": "--weeks", "seed": "--seed", "weeks_per_run": "--weeks-per-run", "sampling": "--sampling"}
    words = ["buildenv", "simulate"]
    for key, flag in flags.items():
        if key in config:
            words += [flag, str(config[key])]
    if config.get("epw"):
        words += ["--epw", *map(str, config["epw"])]
    words += ["--zoning", str(config.get("zoning", "single"))]
    if config.get("floor_area_scale", "linear") != "linear":
        words += ["--floor-area-scale", str(config["floor_area_scale"])]
    for site in dict.fromkeys(c["site"] for c in config.get("around", [])):
        words += ["--around", str(site)]
    if config.get("around"):
        words += ["--spread", str(config.get("spread", 0.1))]
    if config.get("settings_draws", 1) > 1:
        words += ["--settings-draws", str(config["settings_draws"])]
    words += ["--out", str(directory)]
    return shlex.join(words)


def _regenerate(directory: Path, manifest: dict) -> str:
    """How to make a damaged dataset again (the end of its error messages): the command of the manifest's
    config, writing into ``directory`` where the dataset is now (it may have been moved since)."""
    config = manifest.get("config")
    command = simulate_command(directory, config) if isinstance(config, dict) else manifest.get("command")
    if not command:
        return f"regenerate it: remove {directory} and rerun the `buildenv simulate` command that made it"
    return f"regenerate it: rm -r {shlex.quote(str(directory))} && {command}"


def readable_catalogue(made_with: object) -> bool:
    """Whether a dataset made under catalogue ``made_with`` (a :func:`buildenv.catalogue.catalogue_hash`) reads as
    one of this catalogue: the same, or an earlier one whose variables are this one's less those it implies
    (:attr:`buildenv.catalogue.EarlierCatalogue.read_by_padding`; :class:`PaddedTheta` adds them)."""
    if made_with == cat.catalogue_hash():
        return True
    earlier = cat.EARLIER_CATALOGUES.get(made_with) if isinstance(made_with, str) else None
    return earlier is not None and earlier.read_by_padding


class PaddedTheta:
    """The ``theta`` array of a dataset made under an ``earlier`` catalogue, read as this catalogue's ``(weeks,
    len(THETA_NAMES))``: its columns by name, those it lacked at the value its building model had. Indexed by rows
    as an ``h5py.Dataset`` is (an int, a slice, increasing indices)."""

    def __init__(self, stored, earlier: cat.EarlierCatalogue):
        self._stored = stored
        self._stored_at = np.array(
            [earlier.theta_names.index(n) if n in earlier.theta_names else 0 for n in cat.THETA_NAMES]
        )
        self._stored_has = np.array([n in earlier.theta_names for n in cat.THETA_NAMES])
        self._implied = np.array([earlier.implied.get(n, np.nan) for n in cat.THETA_NAMES])

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self._stored.shape[0]), len(cat.THETA_NAMES))

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, rows) -> np.ndarray:
        stored = np.asarray(self._stored[rows])
        flat = stored.reshape(-1, stored.shape[-1])
        out = np.where(self._stored_has, flat[:, self._stored_at], self._implied)
        return out.astype(stored.dtype).reshape(*stored.shape[:-1], len(cat.THETA_NAMES))


def verify_data_file(path: str | Path, record: dict | None, regenerate: str = "", always: bool = False) -> None:
    """Check a data file against its manifest ``record`` (:func:`data_file_record`; ``None``: nothing recorded,
    nothing checked): the size, then the SHA-256 where the modification time differs (``always``: in any case).

    Raises:
        DatasetError: the file is missing, or its size or checksum differs from the record; one line naming the
            file, ending with ``regenerate`` (how to make it again).
    """
    path = Path(path)
    tail = f"; {regenerate}" if regenerate else ""
    if record is None:
        return
    try:
        stat = path.stat()
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read it ({exc.strerror}){tail}") from None
    if stat.st_size != record.get("bytes"):
        raise DatasetError(
            f"{path}: {stat.st_size} bytes, the manifest recorded {record.get('bytes')} (truncated or changed){tail}"
        )
    if not always and stat.st_mtime_ns == record.get("mtime_ns"):
        return
    digest = _sha256(path)
    if digest != record.get("sha256"):
        raise DatasetError(
            f"{path}: SHA-256 {digest[:16]}... differs from the manifest's {str(record.get('sha256'))[:16]}... "
            f"(bytes changed since it was written){tail}"
        )


def open_dataset(directory: str | Path) -> Dataset:
    """Open a finished campaign directory.

    Raises:
        DatasetError: the directory is missing, unfinished (no manifest: rerun the same ``buildenv simulate``
            command to resume it) or was made with another variable catalogue; its manifest is not JSON; its
            ``dataset.h5`` is missing, differs from the checksum in the manifest (:func:`verify_data_file`), is
            not a readable HDF5 file or lacks an array. Each in one line naming the file and, for the data file,
            the command that makes it again.
    """
    import h5py

    directory = Path(directory)
    manifest_path = directory / MANIFEST_FILE
    if not directory.is_dir():
        raise DatasetError(f"dataset directory not found: {directory}")
    if not manifest_path.is_file():
        raise DatasetError(
            f"{directory} is not a finished dataset (no manifest.json); rerun the same "
            "`buildenv simulate` command to resume it"
        )
    try:
        manifest = json.loads(manifest_path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DatasetError(
            f"{manifest_path}: not readable JSON ({exc}); regenerate the dataset: remove {directory} and rerun the "
            "`buildenv simulate` command that made it (campaign.json holds its config)"
        ) from None
    if not isinstance(manifest, dict):
        raise DatasetError(f"{manifest_path}: not a dataset manifest (a JSON {type(manifest).__name__})")
    if not readable_catalogue(manifest.get("catalogue_hash")):
        raise DatasetError(
            f"{directory} was made with catalogue {manifest.get('catalogue_hash')}, this buildenv "
            f"has {cat.catalogue_hash()}: re-simulate it"
        )
    data, regenerate = directory / DATA_FILE, _regenerate(directory, manifest)
    if not data.is_file():
        raise DatasetError(f"{data}: missing; {regenerate}")
    files = manifest.get("files")
    verify_data_file(data, files.get(DATA_FILE) if isinstance(files, dict) else None, regenerate)
    try:
        h5 = h5py.File(data, "r")
    except OSError as exc:
        raise DatasetError(f"{data}: not a readable HDF5 file ({_first_line(exc)}); {regenerate}") from None
    try:
        weather_names = json.loads(h5.attrs["weather_names"])
        missing = [name for name in ARRAYS if name not in h5]
        if missing:
            raise DatasetError(f"{data}: no array {missing[0]!r}; {regenerate}")
        lengths = {name: h5[name].shape[0] for name in ARRAYS}
        if len(set(lengths.values())) > 1:
            raise DatasetError(f"{data}: arrays of different lengths {lengths}; {regenerate}")
    except (OSError, KeyError, ValueError, TypeError) as exc:
        h5.close()
        raise DatasetError(f"{data}: damaged HDF5 structure ({_first_line(exc)}); {regenerate}") from None
    except DatasetError:
        h5.close()
        raise
    return Dataset(directory, manifest, weather_names, h5)


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else type(exc).__name__
