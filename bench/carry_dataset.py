"""Carry the weeks a training run needs to a machine the whole campaign cannot be copied to (a lent GPU).

A 40,000-week campaign is about 450 MB, mostly hourly weather and outputs. A training run reads the inputs of
every week it uses and of the week before each, but the outputs of its training and validation weeks only,
and a campaign's weather has one week per climate and week of year. ``pack`` keeps every week's inputs (the
weather as that table), the outputs of the training and validation weeks of one split, and the manifest;
``unpack`` writes a dataset directory of the same weeks in the same order, so that ``Dataset.split`` and the
``max_weeks`` subset draw the same indices there. The outputs of the other weeks are written as NaN, so
the test scores a run writes there are NaN: ``rescore`` scores its checkpoint again on the full campaign here.

    python bench/carry_dataset.py pack data/campaign-cp-40000-s7 .gpu/pack.npz --max-weeks 3000
    python bench/carry_dataset.py pack data/campaign-cp-160000-r13 .gpu/pack.npz --holdout-climate usa_nj_newark \
        --mantissa-bits 10 --lzma-outputs   # 134,759 weeks' outputs in 80 MB (4.5 min); split it over two calls
    python bench/carry_dataset.py unpack .gpu/pack.npz /tmp/ds        # on the other machine
    python bench/carry_dataset.py rescore data/campaign-cp-40000-s7 RUNS/*.json   # back here
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from buildenv import surrogate as sg
from buildenv.dataset import ARRAYS, open_dataset
from buildenv.training import checkpoint_split, score, training_split

SMALL = ("theta", "settings", "occupancy", "run_id", "week_in_run", "week_of_year", "weather_index")


def pack(data: str | Path, out: str | Path, split: str = "weather_weeks", seed: int = 0,
         max_weeks: int | None = None, holdout_climates: list[str] | None = None,
         mantissa_bits: int = 23, lzma_outputs: bool = False) -> dict:
    """Write ``out`` (compressed ``.npz``) holding what a training run of this split needs; returns a summary
    (weeks whose outputs travel, bytes). ``mantissa_bits`` < 23 rounds the carried outputs to that many bits of
    float32 mantissa (14: a relative error under 3.1e-5, 0.0012 K at 40 degC; 10: under 4.9e-4, 0.016 K at
    32 degC), which compresses them better. ``lzma_outputs`` stores them channel by channel, byte plane by byte
    plane, compressed with LZMA: about 0.6x the size of the default, several minutes to pack 100,000 weeks."""
    with open_dataset(data) as ds:
        parts = training_split(ds, split, seed, holdout_climates, max_weeks)
        carried = np.union1d(parts["train"], parts["val"])
        arrays = {name: ds._h5[name][:] for name in SMALL}
        key = arrays["weather_index"].astype(np.int64) * 100 + arrays["week_of_year"]
        _, first, weather_row = np.unique(key, return_index=True, return_inverse=True)
        weather_table = np.stack([ds.weather[int(i)] for i in first])
        outputs = _rounded(ds.outputs[:][carried], mantissa_bits)
        manifest = (Path(data) / "manifest.json").read_text()
        attrs = {name: str(ds._h5.attrs[name]) for name in ds._h5.attrs}
    stored = {"carried_outputs_lzma": _lzma_planes(outputs), "carried_shape": np.array(outputs.shape)} \
        if lzma_outputs else {"carried_outputs": outputs}
    np.savez_compressed(out, **arrays, weather_table=weather_table, weather_row=weather_row.astype(np.int32),
                        carried=carried, **stored, manifest=np.array(manifest),
                        attrs=np.array(json.dumps(attrs)))
    return {"weeks": int(len(key)), "outputs_carried": int(len(carried)), "bytes": Path(out).stat().st_size}


def _rounded(values: np.ndarray, mantissa_bits: int) -> np.ndarray:
    """float32 ``values`` rounded to the nearest number with ``mantissa_bits`` bits of mantissa."""
    drop = 23 - mantissa_bits
    if drop <= 0:
        return values.astype(np.float32)
    bits = values.astype(np.float32).view(np.uint32)
    return ((bits + np.uint32(1 << (drop - 1))) & ~np.uint32((1 << drop) - 1)).view(np.float32)


def _lzma_planes(values: np.ndarray) -> np.ndarray:
    """float32 ``(weeks, hours, outputs)`` as LZMA-compressed bytes (uint8), output-major and split into the
    four byte planes of the float32s, so that similar bytes sit together."""
    import lzma

    planes = np.ascontiguousarray(values.astype(np.float32).transpose(2, 0, 1)).view(np.uint8).reshape(-1, 4).T
    return np.frombuffer(lzma.compress(np.ascontiguousarray(planes).tobytes(), preset=6), np.uint8)


def _from_lzma_planes(packed: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """The inverse of :func:`_lzma_planes`: float32 of ``shape`` (weeks, hours, outputs)."""
    import lzma

    planes = np.frombuffer(lzma.decompress(packed.tobytes()), np.uint8).reshape(4, -1)
    weeks, hours, outputs = shape
    return np.ascontiguousarray(planes.T).view(np.float32).reshape(outputs, weeks, hours).transpose(1, 2, 0)


def unpack(packed: str | Path, directory: str | Path) -> Path:
    """Write the dataset directory (``dataset.h5`` + ``manifest.json``) a :func:`pack` file holds."""
    import h5py

    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    with np.load(packed) as z:
        weeks = len(z["theta"])
        carried = z["carried_outputs"] if "carried_outputs" in z.files else \
            _from_lzma_planes(z["carried_outputs_lzma"], tuple(int(n) for n in z["carried_shape"]))
        outputs = np.full((weeks, *carried.shape[1:]), np.nan, np.float32)
        outputs[z["carried"]] = carried
        with h5py.File(directory / "dataset.h5", "w") as h5:
            for name in SMALL:
                h5[name] = z[name]
            h5["weather"] = z["weather_table"][z["weather_row"]]
            h5["outputs"] = outputs
            for name, value in json.loads(str(z["attrs"])).items():
                h5.attrs[name] = value
            assert set(h5) == set(ARRAYS)
        (directory / "manifest.json").write_text(str(z["manifest"]))
    return directory


def rescore(data: str | Path, result: str | Path) -> dict:
    """Score again, on the full campaign ``data``, the checkpoint of a run result (``<tag>.json`` beside
    ``<tag>.pt``, as ``bench/_training_runs.trained`` writes them): its ``test`` block (and its
    ``holdout_climate`` block) are replaced, the original kept as ``scored_where_trained``; returns the result."""
    result = Path(result)
    run = json.loads(result.read_text())
    surrogate = sg.load_metamodel(result.with_suffix(".pt"))
    meta = surrogate.checkpoint.metadata
    with open_dataset(data) as ds:
        parts = checkpoint_split(ds, meta)
        encoded = {name: sg.encode_dataset(ds, parts[name], context_hours=surrogate.context_hours,
                                           temperature_before=surrogate.uses_temperature_before)
                   for name in ("test", "holdout_climate") if name in parts}
        scores = {name: score(surrogate, *weeks) for name, weeks in encoded.items()}
    run.setdefault("scored_where_trained", {"test": run["test"], "holdout_climate": run.get("holdout_climate")})
    run["test"] = scores["test"]
    if "holdout_climate" in scores:
        run["holdout_climate"] = {"climates": meta["holdout_climates"], "weeks": int(len(parts["holdout_climate"])),
                                  **scores["holdout_climate"]}
    result.write_text(json.dumps(run) + "\n")
    return run


def main() -> None:
    """Command line: ``pack``, ``unpack`` or ``rescore``."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("pack")
    p.add_argument("data")
    p.add_argument("out")
    p.add_argument("--split", default="weather_weeks")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-weeks", type=int)
    p.add_argument("--holdout-climate", action="append")
    p.add_argument("--mantissa-bits", type=int, default=23, help="bits of float32 mantissa kept in the outputs")
    p.add_argument("--lzma-outputs", action="store_true", help="smaller and slower: the outputs LZMA-compressed")
    u = sub.add_parser("unpack")
    u.add_argument("packed")
    u.add_argument("directory")
    r = sub.add_parser("rescore")
    r.add_argument("data")
    r.add_argument("results", nargs="+")
    args = parser.parse_args()
    if args.command == "rescore":
        for path in args.results:
            print(path, json.dumps({k: round(v, 5) for k, v in rescore(args.data, path)["test"].items()
                                    if k in ("loss", "r2_t_pooled", "rmse_t_celsius")}))
    elif args.command == "pack":
        print(json.dumps(pack(args.data, args.out, args.split, args.seed, args.max_weeks, args.holdout_climate,
                              args.mantissa_bits, args.lzma_outputs)))
    else:
        print(unpack(args.packed, args.directory))


if __name__ == "__main__":
    main()
