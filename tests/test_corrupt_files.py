"""Damaged files: a checkpoint, a dataset or a result that is not what it should be gives one line naming the
file (or the value) and what is wrong, never a traceback or a silent NaN; JSON output is standard JSON."""

from __future__ import annotations

import json
import os
import pickle
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
import torch

from buildenv.campaign.dataset import DATA_FILE, MANIFEST_FILE, open_dataset, verify_data_file
from buildenv.campaign.runs import CampaignConfig, run_campaign
from buildenv.cli.main import main
from buildenv.errors import DatasetError, NonFiniteError
from buildenv.jsonio import dumps
from buildenv.metamodel import surrogate as sg
from metamodels.checkpoint import Checkpoint, CheckpointFormatError, load_checkpoint
from metamodels.models import build
from metamodels.normalisation import Standardiser

TINY = dict(weeks=4, seed=7, epw=["usa_co_golden"], weeks_per_run=2)


def _strict_loads(text: str):
    """``json.loads`` that refuses the NaN and Infinity tokens standard JSON does not have."""

    def refuse(token: str):
        raise ValueError(f"non-standard JSON token {token}")

    return json.loads(text, parse_constant=refuse)


def _one_line(message: str, *parts: str) -> None:
    assert "\n" not in message.strip(), message
    for part in parts:
        assert part in message, (part, message)


# --- checkpoints -----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def good_checkpoint(tmp_path_factory) -> Path:
    torch.manual_seed(0)
    model = build("lstm", 5, 3, layers=1)
    rng = np.random.default_rng(0)
    ck = Checkpoint(
        "lstm", {"layers": 1}, model, Standardiser.fit(rng.random((10, 5))), Standardiser.fit(rng.random((10, 3)))
    )
    return ck.save(tmp_path_factory.mktemp("ck") / "good.pt")


def _flip(data: bytes, offset: int, n: int = 8) -> bytes:
    out = bytearray(data)
    out[offset : offset + n] = bytes(b ^ 0xFF for b in out[offset : offset + n])
    return bytes(out)


def _bad_checkpoints(good: Path) -> dict[str, tuple[bytes, str]]:
    """name -> (file content, what the message must say)."""
    raw = good.read_bytes()
    import zipfile

    with zipfile.ZipFile(good) as archive:
        weights = next(i for i in archive.infolist() if "/data/" in i.filename and i.file_size > 64)
        pickled = archive.getinfo(next(n for n in archive.namelist() if n.endswith("data.pkl")))
    # where the member's bytes start: after its local header (30 bytes, the name and the extra field)
    header = raw[weights.header_offset : weights.header_offset + 30]
    start = (
        weights.header_offset + 30 + int.from_bytes(header[26:28], "little") + int.from_bytes(header[28:30], "little")
    )
    torch_dict = good.with_name("dict.tmp")
    torch.save({"weights": torch.zeros(2)}, torch_dict)
    tensor = good.with_name("tensor.tmp")
    torch.save(torch.zeros(2), tensor)
    return {
        "empty": (b"", "empty"),
        "truncated": (raw[: len(raw) // 2], "truncated or not a PyTorch checkpoint"),
        "truncated_end": (raw[:-20], "truncated or not a PyTorch checkpoint"),
        "flipped_weights": (_flip(raw, start + weights.file_size // 2), "CRC-32"),
        "flipped_pickle": (_flip(raw, pickled.header_offset + 60), "damaged"),
        "text": (b"not a checkpoint\n", "not a PyTorch checkpoint"),
        "pickled_dict": (pickle.dumps({"format": 1}), "not a PyTorch checkpoint"),
        "torch_dict": (torch_dict.read_bytes(), "missing key 'format': written by another tool?"),
        "torch_tensor": (tensor.read_bytes(), "not a checkpoint dict"),
    }


def test_a_good_checkpoint_loads(good_checkpoint):
    assert load_checkpoint(good_checkpoint).name == "lstm"


def test_every_damaged_or_foreign_checkpoint_is_one_line_naming_the_file(good_checkpoint, tmp_path):
    for name, (content, what) in _bad_checkpoints(good_checkpoint).items():
        path = tmp_path / f"{name}.pt"
        path.write_bytes(content)
        with pytest.raises(CheckpointFormatError) as info:
            load_checkpoint(path)
        _one_line(str(info.value), str(path), what)
        assert isinstance(info.value, ValueError)  # what load_checkpoint raised before for another format
        # buildenv's loader gives its own error type (a BuildenvError the command line prints in one line)
        with pytest.raises(sg.CheckpointError) as info:
            sg.load_metamodel(path)
        _one_line(str(info.value), str(path), what)


def test_weights_that_are_not_finite_are_refused(good_checkpoint, tmp_path):
    ck = load_checkpoint(good_checkpoint)
    with torch.no_grad():
        next(ck.model.parameters()).fill_(float("nan"))
    path = ck.save(tmp_path / "nan.pt")
    with pytest.raises(CheckpointFormatError, match="NaN or infinite"):
        load_checkpoint(path)


def test_the_shipped_checkpoints_still_load():
    for name in sg.SHIPPED_CHECKPOINTS:
        assert sg.load_metamodel(name).checkpoint.outputs == 8


def test_the_command_line_reports_a_damaged_checkpoint_in_one_line(good_checkpoint, tmp_path, capsys):
    bad = tmp_path / "bad.pt"
    bad.write_bytes(good_checkpoint.read_bytes()[:1000])
    assert main(["evaluate", "--checkpoint", str(bad), "--data", str(tmp_path / "nowhere")]) == 2
    err = capsys.readouterr().err.strip()
    _one_line(err, "buildenv evaluate: error:", str(bad), "truncated")
    # a training resumed from a damaged CKPT.last: metamodels' own error, also one line
    (tmp_path / "resumed.pt.last").write_bytes(b"")
    args = ["train", "--model", "lstm", "--data", str(tmp_path), "--out", str(tmp_path / "resumed.pt")]
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    _one_line(err, "buildenv train: error:", str(tmp_path / "resumed.pt.last"), "empty")


# --- datasets --------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("corrupt") / "tiny"
    run_campaign(CampaignConfig(**TINY), out, workers=1, progress=False)
    return out


def _copy(dataset: Path, where: Path) -> Path:
    target = where / "copy"
    shutil.copytree(dataset, target)  # copies keep the modification times (shutil.copy2)
    return target


def _data_offset(path: Path, name: str = "outputs") -> int:
    with h5py.File(path, "r") as h5:
        return int(h5[name].id.get_chunk_info(0).byte_offset)


def test_the_manifest_records_the_checksum_and_the_command(tiny_dataset):
    manifest = json.loads((tiny_dataset / MANIFEST_FILE).read_text())
    record = manifest["files"][DATA_FILE]
    assert record["bytes"] == (tiny_dataset / DATA_FILE).stat().st_size and len(record["sha256"]) == 64
    assert manifest["command"].startswith("buildenv simulate --weeks 4 --seed 7 ")
    verify_data_file(tiny_dataset / DATA_FILE, record, always=True)
    with open_dataset(tiny_dataset) as ds:
        assert len(ds) == 4


def test_flipped_bytes_in_the_data_are_one_line_with_the_command_to_regenerate(tiny_dataset, tmp_path):
    copy = _copy(tiny_dataset, tmp_path)
    data = copy / DATA_FILE
    offset = _data_offset(data) + 1000
    with open(data, "r+b") as handle:
        handle.seek(offset)
        chunk = handle.read(16)
        handle.seek(offset)
        handle.write(bytes(b ^ 0xFF for b in chunk))
    with pytest.raises(DatasetError) as info:
        open_dataset(copy)
    _one_line(str(info.value), str(data), "SHA-256", "regenerate it", "buildenv simulate --weeks 4", str(copy))
    # the same bytes with the modification time put back are caught by a full check
    record = json.loads((copy / MANIFEST_FILE).read_text())["files"][DATA_FILE]
    os.utime(data, ns=(record["mtime_ns"], record["mtime_ns"]))
    open_dataset(copy).close()  # trusted: untouched by its size and time
    with pytest.raises(DatasetError, match="SHA-256"):
        verify_data_file(data, record, always=True)


def test_a_truncated_data_file_is_one_line(tiny_dataset, tmp_path):
    copy = _copy(tiny_dataset, tmp_path)
    data = copy / DATA_FILE
    data.write_bytes(data.read_bytes()[:5000])
    with pytest.raises(DatasetError) as info:
        open_dataset(copy)
    _one_line(str(info.value), str(data), "bytes, the manifest recorded", "regenerate it")


def _forget_checksums(directory: Path) -> None:
    """Make the manifest one written before checksums were recorded."""
    path = directory / MANIFEST_FILE
    manifest = json.loads(path.read_text())
    del manifest["files"], manifest["command"]
    path.write_text(json.dumps(manifest))


def test_a_damaged_header_is_one_line_even_without_a_checksum(tiny_dataset, tmp_path):
    copy = _copy(tiny_dataset, tmp_path)
    data = copy / DATA_FILE
    with open(data, "r+b") as handle:
        handle.write(b"\0" * 64)  # the HDF5 signature and superblock
    with pytest.raises(DatasetError) as info:
        open_dataset(copy)
    _one_line(str(info.value), str(data), "SHA-256")
    _forget_checksums(copy)
    with pytest.raises(DatasetError) as info:
        open_dataset(copy)
    # an old manifest has no command: the message rebuilds it from the campaign's config
    _one_line(str(info.value), str(data), "not a readable HDF5 file", "buildenv simulate --weeks 4", str(copy))


def test_a_damaged_manifest_is_one_line(tiny_dataset, tmp_path):
    copy = _copy(tiny_dataset, tmp_path)
    (copy / MANIFEST_FILE).write_text('{"config": ')
    with pytest.raises(DatasetError) as info:
        open_dataset(copy)
    _one_line(str(info.value), str(copy / MANIFEST_FILE), "not readable JSON")


def test_an_old_manifest_without_checksums_loads(tiny_dataset, tmp_path):
    copy = _copy(tiny_dataset, tmp_path)
    _forget_checksums(copy)
    with open_dataset(copy) as ds:
        assert len(ds) == 4


# --- NaN results and standard JSON ---------------------------------------------------------------------------


def test_json_is_standard_and_non_finite_values_are_refused_or_null():
    record = {"a": np.float32(1.5), "b": [np.int64(2), np.array([1.0, 2.0])], "ok": np.bool_(True)}
    assert _strict_loads(dumps(record, where="x")) == {"a": 1.5, "b": [2, [1.0, 2.0]], "ok": True}
    bad = {"metrics": {"rmse": [0.1, np.float64("nan")]}}
    with pytest.raises(NonFiniteError) as info:
        dumps(bad, where="the evaluation result")
    _one_line(str(info.value), "the evaluation result", "metrics.rmse[1] is nan")
    assert _strict_loads(dumps(bad, where="x", nonfinite="null")) == {"metrics": {"rmse": [0.1, None]}}
    with pytest.raises(NonFiniteError, match="inf"):
        dumps({"q": float("inf")}, where="x")


def test_evaluate_refuses_a_nan_metric_and_writes_standard_json(tiny_dataset, tmp_path, capsys):
    assert main(["evaluate", "--data", str(tiny_dataset), "--subset", "all", "--json"]) == 0
    result = _strict_loads(capsys.readouterr().out)
    assert result["subset"] == "all"
    # NaN outputs that no checksum catches (an old manifest): the result is refused, not printed as NaN
    copy = _copy(tiny_dataset, tmp_path)
    _forget_checksums(copy)
    with h5py.File(copy / DATA_FILE, "r+") as h5:
        h5["outputs"][1, 5] = np.nan
    assert main(["evaluate", "--data", str(copy), "--subset", "all", "--json"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    _one_line(captured.err, "buildenv evaluate: error: the evaluation result:", "is nan", str(copy))
