"""Training loop: Adam on the paper's loss, early stopping on validation, a checkpoint every epoch.

Read it top to bottom in :func:`fit`. Data are already-normalised tensors; the loss counts only the hours
where ``hour_mask`` is True (the week, not the context hours that precede it). Every epoch writes
``<out>.last`` (weights, optimiser, epoch, history) so that a killed run continues where it stopped, and
``<out>`` itself whenever validation improves. A CSV log line is written per epoch.
"""

from __future__ import annotations

import csv
import logging
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import torch

from metamodels.checkpoint import Checkpoint, load_checkpoint
from metamodels.loss import paper_loss, response_loss

log = logging.getLogger(__name__)


@dataclass
class TrainConfig:
    """Hyper-parameters of a training run (CLI flags of ``buildenv train`` map onto these)."""

    epochs: int = 100
    batch_size: int = 64
    lr: float = 1e-3
    weight_decay: float = 0.0
    schedule: str = "cosine"  # "cosine": lr decays to 0 over `epochs` (half a cosine); "constant"
    patience: int = 10  # epochs without validation improvement before stopping
    minutes: float | None = None  # a training-time budget: see :func:`budget_progress`
    alpha: float = 1.0
    beta: float = 0.3
    seed: int = 0
    device: str = "auto"  # "auto": CUDA when present, else CPU
    temperature_channels: list[int] = field(default_factory=list)
    consumption_channels: list[int] = field(default_factory=list)
    response_weight: float = 0.0  # weight of :func:`metamodels.loss.response_loss` on weeks that have a partner
    energy_channels: list[int] = field(default_factory=list)  # outputs summed into the energy the response compares
    energy_floor: float = 0.0  # smallest partner energy a difference is divided by (units of those outputs)


def learning_rate(cfg: TrainConfig, epoch: int) -> float:
    """Learning rate of epoch ``epoch`` (0-based): constant, or half a cosine from ``lr`` towards 0."""
    return cosine_rate(cfg, epoch / max(cfg.epochs, 1))


def cosine_rate(cfg: TrainConfig, share: float) -> float:
    """Learning rate once ``share`` (0-1) of the schedule has passed: ``cfg.lr`` when constant, else half a
    cosine from ``cfg.lr`` at 0 to 0 at 1."""
    if cfg.schedule == "constant":
        return cfg.lr
    return 0.5 * cfg.lr * (1.0 + math.cos(math.pi * share))


def budget_progress(cfg: TrainConfig, seconds: float) -> float | None:
    """Share of a run's time budget (``cfg.minutes``) spent after ``seconds`` of training, validation included;
    ``None`` when the run has no budget.

    With a budget the run stops once it is spent, in the middle of an epoch if need be (that epoch is then
    validated and logged as the last), and the cosine schedule decays over the budget's time, step by step,
    instead of over ``epochs``: a model whose epoch is slow gets fewer epochs, not a truncated schedule.
    """
    if cfg.minutes is None:
        return None
    return seconds / (60.0 * cfg.minutes)


def pick_device(name: str) -> torch.device:
    """``auto`` -> CUDA if available else CPU; otherwise the named device."""
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    return torch.device(name)


def _resident(tensor: torch.Tensor, device: torch.device) -> torch.Tensor:
    """``tensor`` moved to a GPU ``device`` once for the whole training when it fits in a third of the free
    memory (batches are then gathered there, not copied from host memory each step); left where it is otherwise."""
    if device.type != "cuda":
        return tensor
    free, _ = torch.cuda.mem_get_info(device)
    size = tensor.element_size() * tensor.nelement()
    return tensor.to(device) if size < free / 3 else tensor


@torch.no_grad()
def evaluate_loss(
    model: torch.nn.Module,
    x: torch.Tensor,
    y: torch.Tensor,
    hour_mask: torch.Tensor,
    cfg: TrainConfig,
    device: torch.device,
    batch_size: int = 512,
) -> float:
    """Mean paper loss over a dataset (batched, eval mode, no gradients)."""
    model.eval()
    total = 0.0
    for start in range(0, len(x), batch_size):
        xb, yb = x[start : start + batch_size].to(device), y[start : start + batch_size].to(device)
        mask = hour_mask.to(device).expand(len(xb), -1)
        loss = paper_loss(model(xb), yb, cfg.temperature_channels, cfg.consumption_channels, cfg.alpha, cfg.beta, mask)
        total += float(loss) * len(xb)
    return total / max(len(x), 1)


def fit(
    checkpoint: Checkpoint,
    x_train: torch.Tensor,
    y_train: torch.Tensor,
    x_val: torch.Tensor,
    y_val: torch.Tensor,
    hour_mask: torch.Tensor,
    cfg: TrainConfig,
    out: Path,
    progress: bool = True,
    partner: torch.Tensor | None = None,
) -> dict:
    """Train ``checkpoint.model`` in place and save the best model to ``out``.

    Args:
        checkpoint: model + normalisation + metadata (the model's initial weights are used unless ``out.last``
            exists, in which case training resumes from it).
        x_train, y_train, x_val, y_val: normalised ``(weeks, hours, channels)`` float tensors.
        hour_mask: ``(hours,)`` boolean, hours counted by the loss.
        cfg: hyper-parameters.
        out: path of the best checkpoint; ``out.last`` and ``out.csv`` sit beside it.
        progress: show a progress bar per epoch.
        partner: ``(weeks,)`` long, for each training week the index of its partner (the same building and weather
            under other settings) or -1; with ``cfg.response_weight`` > 0 a batch runs its weeks' partners too and
            adds ``response_weight`` x :func:`metamodels.loss.response_loss` over the pairs.
    Returns:
        ``{"best_val_loss", "best_epoch", "epochs_run", "weeks_seen", "seconds", "history": [...]}``
        (``weeks_seen``: training weeks drawn, summed over epochs; a budget's last epoch may be partial).
    """
    from tqdm import tqdm

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    last = out.with_name(out.name + ".last")
    log_path = out.with_name(out.name + ".csv")
    device = pick_device(cfg.device)
    torch.manual_seed(cfg.seed)
    model = checkpoint.model.to(device)
    optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    if cfg.schedule not in ("cosine", "constant"):
        raise ValueError(f"unknown learning-rate schedule {cfg.schedule!r}; choose cosine or constant")
    if cfg.minutes is not None and cfg.minutes <= 0:
        raise ValueError(f"a training-time budget must be positive minutes, not {cfg.minutes}")
    state = {
        "epoch": 0,
        "best_val_loss": float("inf"),
        "best_epoch": -1,
        "history": [],
        "seconds": 0.0,
        "weeks_seen": 0,
    }
    if last.exists():
        resumed = load_checkpoint(last)
        model.load_state_dict(resumed.model.state_dict())
        optimiser.load_state_dict(resumed.training["optimiser"])
        # a run saved before "weeks_seen" was recorded drew every training week in each of its epochs
        state = {k: resumed.training[k] for k in state if k != "weeks_seen"}
        state["weeks_seen"] = resumed.training.get("weeks_seen", state["epoch"] * len(x_train))
        log.info("resuming %s from epoch %d", out, state["epoch"])
    generator = torch.Generator().manual_seed(cfg.seed)
    for _ in range(state["epoch"]):  # replay the shuffles so a resumed run sees the same batches
        torch.randperm(len(x_train), generator=generator)
    mask = hour_mask.to(device)
    x_train, y_train = _resident(x_train, device), _resident(y_train, device)
    respond = partner is not None and cfg.response_weight > 0 and bool((partner >= 0).any())
    if respond:
        partner = partner.to(x_train.device)
        energy_norm = [
            torch.as_tensor(getattr(checkpoint.output_norm, k)[cfg.energy_channels], dtype=torch.float32).to(device)
            for k in ("mean", "std")
        ]
    with open(log_path, "a", newline="") as handle:
        writer = csv.writer(handle)
        if state["epoch"] == 0:
            writer.writerow(["epoch", "train_loss", "val_loss", "seconds"])
        while (
            state["epoch"] < cfg.epochs
            and state["epoch"] - state["best_epoch"] <= cfg.patience
            and (budget_progress(cfg, state["seconds"]) or 0.0) < 1.0
        ):
            started = time.perf_counter()
            model.train()
            for group in optimiser.param_groups:
                group["lr"] = learning_rate(cfg, state["epoch"])
            order = torch.randperm(len(x_train), generator=generator).to(x_train.device)
            running, seen = torch.zeros((), device=device), 0
            bar = tqdm(
                range(0, len(order), cfg.batch_size),
                desc=f"epoch {state['epoch'] + 1}",
                leave=False,
                disable=not progress,
            )
            for start in bar:
                spent = budget_progress(cfg, state["seconds"] + time.perf_counter() - started)
                if spent is not None:
                    if spent >= 1.0:
                        break
                    for group in optimiser.param_groups:
                        group["lr"] = cosine_rate(cfg, spent)
                idx = order[start : start + cfg.batch_size]
                mates = partner[idx][partner[idx] >= 0] if respond else idx[:0]
                rows = torch.cat([idx, mates]) if len(mates) else idx
                xb, yb = x_train[rows].to(device), y_train[rows].to(device)
                pred = model(xb)
                n = len(idx)
                loss = paper_loss(
                    pred[:n],
                    yb[:n],
                    cfg.temperature_channels,
                    cfg.consumption_channels,
                    cfg.alpha,
                    cfg.beta,
                    mask.expand(n, -1),
                )
                if len(mates):
                    paired = (partner[idx] >= 0).to(device)
                    loss = loss + cfg.response_weight * response_loss(
                        pred[:n][paired],
                        pred[n:],
                        yb[:n][paired],
                        yb[n:],
                        cfg.energy_channels,
                        *energy_norm,
                        cfg.energy_floor,
                        mask,
                    )
                optimiser.zero_grad(set_to_none=True)
                loss.backward()
                optimiser.step()
                running += loss.detach() * len(idx)  # summed on the device: no synchronisation per step
                seen += len(idx)
                if progress and bar.n % 50 == 0:
                    bar.set_postfix(loss=f"{running.item() / seen:.4f}")
            running = running.item()
            val_loss = evaluate_loss(model, x_val, y_val, hour_mask, cfg, device)
            seconds = time.perf_counter() - started
            state["epoch"] += 1
            state["seconds"] += seconds
            state["weeks_seen"] += seen
            state["history"].append(
                {
                    "epoch": state["epoch"],
                    "train_loss": running / max(seen, 1),
                    "val_loss": val_loss,
                    "seconds": seconds,
                }
            )
            writer.writerow([state["epoch"], f"{running / max(seen, 1):.6f}", f"{val_loss:.6f}", f"{seconds:.1f}"])
            handle.flush()
            model.cpu()
            if val_loss < state["best_val_loss"]:
                state["best_val_loss"], state["best_epoch"] = val_loss, state["epoch"]
                checkpoint.training = {"config": asdict(cfg), **state}
                checkpoint.save(out)
            checkpoint.training = {"config": asdict(cfg), **state, "optimiser": optimiser.state_dict()}
            checkpoint.save(last)
            model.to(device)
            log.info("epoch %d train %.5f val %.5f (%.1fs)", state["epoch"], running / max(seen, 1), val_loss, seconds)
    model.cpu().eval()
    best = load_checkpoint(out)
    checkpoint.model.load_state_dict(best.model.state_dict())
    checkpoint.training = best.training
    return {
        "best_val_loss": state["best_val_loss"],
        "best_epoch": state["best_epoch"],
        "epochs_run": state["epoch"],
        "weeks_seen": state["weeks_seen"],
        "seconds": state["seconds"],
        "history": state["history"],
    }
