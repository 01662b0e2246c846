"""Sequence metamodels: one contract, ``(batch, hours, inputs) -> (batch, hours, outputs)``.

``MODELS`` maps a name to its class; :func:`build` makes one from a plain config dict (what checkpoints
store). All models see the whole input sequence of a week (its inputs are known in advance: weather,
settings, occupancy), so the bidirectional ones may look ahead.

- ``transformer``: the paper's encoder-decoder Transformer with local attention (:class:`Transformer`), with
  optional hour patches and a per-hour read-out head (our additions, off by default);
- ``bigru``: bidirectional GRU, linear read-out.
- ``lstm``: (forward) LSTM, linear read-out.
- ``convgru``: two 1-D convolutions (kernel 5, ReLU) then a bidirectional GRU.
- ``ffn``: a per-hour multilayer perceptron with ReLU on the hour's inputs and those of the ``lags``
  preceding hours (the feed-forward baseline of earlier work; unlike the authors' code, it has activations).
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

DENSE_MATMUL_MAX_TOKENS = 64  # up to this many tokens attention runs as explicit matmuls (faster on CPU)


def band_mask(hours: int, window: int, device: torch.device | None = None) -> torch.Tensor:
    """``(hours, hours)`` boolean mask, True where ``|i - j| <= window`` (the attention band)."""
    idx = torch.arange(hours, device=device)
    return (idx[:, None] - idx[None, :]).abs() <= window


def band_bias(hours: int, window: int, device: torch.device | None = None) -> torch.Tensor:
    """``(hours, hours)`` additive attention mask: 0 inside the band of :func:`band_mask`, -inf outside."""
    inside = band_mask(hours, window, device)
    return torch.zeros(inside.shape, device=device).masked_fill(~inside, float("-inf"))


def sinusoidal_positions(hours: int, dim: int) -> torch.Tensor:
    """Fixed sinusoidal position encoding, ``(hours, dim)``."""
    pos = torch.arange(hours, dtype=torch.float32)[:, None]
    freq = torch.exp(torch.arange(0, dim, 2, dtype=torch.float32) * (-math.log(10000.0) / dim))
    pe = torch.zeros(hours, dim)
    pe[:, 0::2] = torch.sin(pos * freq)
    pe[:, 1::2] = torch.cos(pos * freq[: dim // 2])
    return pe


class LocalAttention(nn.Module):
    """Multi-head attention restricted to a band of ``window`` hours either side."""

    def __init__(self, d_model: int, heads: int, head_dim: int, dropout: float):
        super().__init__()
        self.heads, self.head_dim = heads, head_dim
        self.q = nn.Linear(d_model, heads * head_dim)
        self.kv = nn.Linear(d_model, 2 * heads * head_dim)
        self.out = nn.Linear(heads * head_dim, d_model)
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor, memory: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
        """``bias``: ``(tokens, tokens)`` additive mask, 0 inside the band and -inf outside."""
        b, t, _ = x.shape
        s, h, d = memory.shape[1], self.heads, self.head_dim
        q = self.q(x).view(b, t, h, d).transpose(1, 2).reshape(b * h, t, d)
        k, v = self.kv(memory).view(b, s, 2, h, d).permute(2, 0, 3, 1, 4).reshape(2, b * h, s, d)
        if t > DENSE_MATMUL_MAX_TOKENS:  # long sequences (the paper's hourly tokens): the fused kernel wins
            z = F.scaled_dot_product_attention(
                q.view(b, h, t, d), k.view(b, h, s, d), v.view(b, h, s, d), attn_mask=bias
            )
            return self.drop(self.out(z.transpose(1, 2).reshape(b, t, h * d)))
        # Explicit batched matmuls: with head size 8 and a few dozen tokens they run 2-3x faster on CPU
        # than scaled_dot_product_attention's flash kernel, and give the same result.
        scores = torch.baddbmm(bias.expand(b * h, t, s), q, k.transpose(1, 2), alpha=d**-0.5)
        z = torch.bmm(scores.softmax(-1), v).view(b, h, t, d)
        return self.drop(self.out(z.transpose(1, 2).reshape(b, t, h * d)))


class _Block(nn.Module):
    """Post-norm residual block: attention(s) then a ReLU feed-forward network."""

    def __init__(self, d_model: int, heads: int, head_dim: int, d_ff: int, dropout: float, cross: bool):
        super().__init__()
        self.self_attn = LocalAttention(d_model, heads, head_dim, dropout)
        self.cross_attn = LocalAttention(d_model, heads, head_dim, dropout) if cross else None
        self.ff = nn.Sequential(nn.Linear(d_model, d_ff), nn.ReLU(), nn.Linear(d_ff, d_model))
        self.norms = nn.ModuleList(nn.LayerNorm(d_model) for _ in range(3 if cross else 2))
        self.drop = nn.Dropout(dropout)

    def forward(self, x: torch.Tensor, mask: torch.Tensor, memory: torch.Tensor | None = None) -> torch.Tensor:
        x = self.norms[0](x + self.self_attn(x, x, mask))
        if self.cross_attn is not None:
            x = self.norms[1](x + self.cross_attn(x, memory, mask))
        return self.norms[-1](x + self.drop(self.ff(x)))


class Transformer(nn.Module):
    """The paper's encoder-decoder Transformer with local attention.

    A linear embedding to ``d_model``, sinusoidal positions, ``layers`` encoder layers of local self-attention,
    then ``layers`` decoder layers of local self-attention and local attention onto the encoder's latent
    vectors, and a linear read-out; ``heads`` heads of size ``head_dim``. "Local" is the paper's attention size
    Delta = ``window``: hour k attends to hours k - window .. k + window. The defaults are the paper's model.

    Args (our additions):
        patch_hours: > 1 makes each token a block of that many consecutive hours (embedded together, read out
            hour by hour); the window then spans ``ceil(window / patch_hours)`` tokens.
        hourly_head: > 0 replaces the linear read-out by a per-hour network of that many hidden units
            (:class:`HourlyHead`) on the hour's inputs, its token's latent vector and its place in the token.
        hourly_gru: > 0 (with ``hourly_head``) runs a bidirectional GRU of that many units per direction over
            the head's hourly features (about 2x slower).
        hourly_state: > 0 (with ``hourly_head``) gives each hour that many :class:`ThermalStates` per direction
            instead, clamped by a ReLU layer; linear filters, so they run at matrix speed, unlike a GRU.
        hourly_state_layers: > 1 stacks further such stages (residual), so that a response to a state can
            itself drive slower states.
    """

    #: a patch's inputs are flattened hour by hour (all channels of its first hour, then of the next)
    hour_major_inputs = True

    def __init__(
        self,
        inputs: int,
        outputs: int,
        d_model: int = 64,
        heads: int = 8,
        head_dim: int = 8,
        layers: int = 4,
        window: int = 12,
        d_ff: int = 256,
        dropout: float = 0.0,
        patch_hours: int = 1,
        hourly_head: int = 0,
        hourly_gru: int = 0,
        hourly_state: int = 0,
        hourly_state_layers: int = 1,
        max_hours: int = 512,
    ):
        super().__init__()
        self.patch, self.outputs = patch_hours, outputs
        self.token_window = math.ceil(window / patch_hours)
        self.embed = nn.Linear(inputs * patch_hours, d_model)
        self.register_buffer("positions", sinusoidal_positions(max_hours, d_model), persistent=False)
        self.encoder = nn.ModuleList(_Block(d_model, heads, head_dim, d_ff, dropout, False) for _ in range(layers))
        self.decoder = nn.ModuleList(_Block(d_model, heads, head_dim, d_ff, dropout, True) for _ in range(layers))
        if hourly_head:
            self.head = HourlyHead(
                inputs, d_model, patch_hours, hourly_head, outputs, hourly_gru, hourly_state, hourly_state_layers
            )
        else:
            self.readout = nn.Linear(d_model, outputs * patch_hours)

    def forward(self, x: torch.Tensor, skip_hours: int = 0) -> torch.Tensor:
        """``(batch, hours, inputs)`` -> ``(batch, hours - skip_hours, outputs)``: the outputs of the hours
        from ``skip_hours`` on (the first hours, a context, are still read); with the hourly head the
        skipped hours' read-out is not computed, and the outputs are those of the full pass."""
        batch, hours, _ = x.shape
        if hours % self.patch:
            raise ValueError(f"{hours} hours do not split into patches of {self.patch}")
        tokens = hours // self.patch
        mask = band_bias(tokens, self.token_window, x.device).to(x.dtype)  # built once, shared by every attention
        memory = self.embed(x.reshape(batch, tokens, -1)) + self.positions[:tokens]
        for layer in self.encoder:
            memory = layer(memory, mask)
        y = memory + self.positions[:tokens]
        for layer in self.decoder:
            y = layer(y, mask, memory)
        if hasattr(self, "head"):
            return self.head(x, y, skip_hours)
        return self.readout(y).reshape(batch, hours, self.outputs)[:, skip_hours:]


class ThermalStates(nn.Module):
    """Exponentially weighted means of ``channels`` hourly drives, forward or backward in time.

    Channel ``c`` with time constant ``tau_c`` (hours, learnt as its logarithm) holds, at hour ``t``, the mean of
    the drive over hours ``s <= t`` (``s >= t`` backward) weighted by ``exp(-|t - s| / tau_c)``, normalised
    by the weights present, so that the first hours of a sequence are not biased towards zero:
    ``num_t = a num_{t-1} + u_t``, ``den_t = a den_{t-1} + 1``, state ``num_t / den_t`` with ``a = exp(-1 / tau)``.
    The time constants start log-spaced from ``tau_min_h`` to ``tau_max_h``. A building's temperature is, to
    first order, such a filtered heat balance, clamped by the thermostat.

    The recurrence is evaluated in blocks of ``block`` hours, with no loop over hours: one small matrix product
    within each block, one across the blocks' end values, ``(batch, hours, channels) -> (batch, hours, channels)``.
    (A full ``hours x hours`` filter matrix gives the same numbers at about ten times the cost on a CPU.)
    """

    def __init__(
        self, channels: int, backward: bool = False, tau_min_h: float = 1.0, tau_max_h: float = 96.0, block: int = 8
    ):
        super().__init__()
        self.backward, self.block = backward, block
        self.log_tau = nn.Parameter(torch.linspace(math.log(tau_min_h), math.log(tau_max_h), channels))

    def forward(self, drive: torch.Tensor) -> torch.Tensor:
        if self.backward:
            drive = drive.flip(1)
        batch, hours, channels = drive.shape
        blocks = -(-hours // self.block)
        padded = F.pad(drive, (0, 0, 0, blocks * self.block - hours))  # zeros after the end change nothing before
        # (channels,); kept above 0, where 0 ** 0 would have no gradient
        decay = torch.exp(-torch.exp(-self.log_tau)).clamp(min=1e-6)
        k = torch.arange(self.block, device=drive.device, dtype=drive.dtype)
        within = self._powers(decay, k[:, None] - k[None, :])  # (channels, block, block), lower triangular
        u = padded.view(batch, blocks, self.block, channels).permute(3, 0, 1, 2)  # (channels, batch, blocks, block)
        local = torch.matmul(u, within.transpose(1, 2)[:, None])  # sums within each block
        b = torch.arange(blocks, device=drive.device, dtype=drive.dtype)
        across = self._powers(decay**self.block, b[:, None] - b[None, :])  # (channels, blocks, blocks)
        carried = torch.matmul(local[..., -1], across.transpose(1, 2))  # num at each block's last hour
        before = F.pad(carried[..., :-1], (1, 0))  # num at the hour before each block
        num = local + before[..., None] * decay[:, None, None, None] ** (k + 1)
        t = torch.arange(blocks * self.block, device=drive.device, dtype=drive.dtype)
        den = (1 - decay[:, None] ** (t + 1)) / (1 - decay[:, None])  # (channels, hours)
        states = (num.reshape(channels, batch, -1) / den[:, None]).permute(1, 2, 0)[:, :hours]
        return states.flip(1) if self.backward else states

    @staticmethod
    def _powers(decay: torch.Tensor, lag: torch.Tensor) -> torch.Tensor:
        """``decay ** lag`` where ``lag >= 0``, else 0: ``(channels,)``, ``(n, n)`` -> ``(channels, n, n)``."""
        return decay[:, None, None] ** lag.clamp(min=0) * (lag >= 0)


class HourlyHead(nn.Module):
    """Per-hour read-out of a patched Transformer: ``ReLU(A latent + B inputs + c_position) -> outputs``.

    The first layer acts on the concatenation (token latent, hour's inputs, hour's place in the token); it is
    computed as a sum so that the token's term is evaluated once per token, not once per hour. With ``gru``
    a bidirectional GRU runs over these hourly features; with ``state``, forward and backward
    :class:`ThermalStates` of linear drives of them feed a second ReLU layer (see the module docstring).
    """

    def __init__(
        self,
        inputs: int,
        d_model: int,
        patch_hours: int,
        hidden: int,
        outputs: int,
        gru: int = 0,
        state: int = 0,
        state_layers: int = 1,
    ):
        super().__init__()
        if gru and state:
            raise ValueError("choose hourly_gru or hourly_state, not both")
        if state_layers < 1:
            raise ValueError(f"hourly_state_layers must be at least 1, got {state_layers}")
        self.patch = patch_hours
        self.from_latent = nn.Linear(d_model, hidden)
        self.from_inputs = nn.Linear(inputs, hidden, bias=False)
        self.position = nn.Parameter(torch.zeros(patch_hours, hidden))
        self.rnn = nn.GRU(hidden, gru, batch_first=True, bidirectional=True) if gru else None
        if state:
            self.drive = nn.Linear(hidden, 2 * state)
            self.past, self.future = ThermalStates(state), ThermalStates(state, backward=True)
            self.mix = nn.Linear(hidden + 2 * state, hidden)
            # further stages filter the first stage's nonlinear features again (a thermostat's response to
            # a state is itself a drive of later states)
            self.stages = nn.ModuleList(_StateStage(hidden, state) for _ in range(state_layers - 1))
        self.state = state
        self.out = nn.Linear(2 * gru if gru else hidden, outputs)

    def forward(self, x: torch.Tensor, latent: torch.Tensor, skip_hours: int = 0) -> torch.Tensor:
        """``x`` ``(batch, hours, inputs)``, ``latent`` ``(batch, tokens, d_model)`` -> ``(batch, hours -
        skip_hours, outputs)``. The skipped first hours feed the forward states; their read-out, and the
        backward states and mix of the last stage there, are not computed (later hours do not depend on them)."""
        batch, tokens, _ = latent.shape
        h = self.from_inputs(x).view(batch, tokens, self.patch, -1)
        h = torch.relu(h + self.from_latent(latent)[:, :, None, :] + self.position)
        h = h.reshape(batch, tokens * self.patch, -1)
        if self.rnn is not None:
            h = self.rnn(h)[0][:, skip_hours:]
        elif self.state:
            h = _filtered_features(self, h, 0 if self.stages else skip_hours)  # only the last stage skips
            for i, stage in enumerate(self.stages):
                skip = skip_hours if i == len(self.stages) - 1 else 0
                h = h[:, skip:] + _filtered_features(stage, h, skip)
        else:
            h = h[:, skip_hours:]
        return self.out(h)


def _filtered_features(stage: nn.Module, h: torch.Tensor, skip_hours: int = 0) -> torch.Tensor:
    """``ReLU(mix(h, past states, future states))`` of one thermal-state stage (its ``drive``, ``past``,
    ``future``, ``mix`` and ``state``), ``(batch, hours, hidden) -> (batch, hours - skip_hours, hidden)``.

    The past states need every hour; the future states of the kept hours only the kept hours (they look
    forward), so they are filtered from ``skip_hours`` on: the same values as over the whole sequence."""
    past, future = stage.drive(h).split(stage.state, dim=-1)
    past = stage.past(past)[:, skip_hours:]
    future = stage.future(future[:, skip_hours:])
    return torch.relu(stage.mix(torch.cat([h[:, skip_hours:], past, future], dim=-1)))


class _StateStage(nn.Module):
    """One more stage of thermal states (the parameters :func:`_filtered_features` uses); the hourly head adds
    its features to the previous stage's (residual)."""

    def __init__(self, hidden: int, state: int):
        super().__init__()
        self.state = state
        self.drive = nn.Linear(hidden, 2 * state)
        self.past, self.future = ThermalStates(state), ThermalStates(state, backward=True)
        self.mix = nn.Linear(hidden + 2 * state, hidden)


class BiGRU(nn.Module):
    """Bidirectional GRU."""

    def __init__(self, inputs: int, outputs: int, hidden: int = 64, layers: int = 4, dropout: float = 0.0):
        super().__init__()
        self.rnn = nn.GRU(
            inputs,
            hidden,
            num_layers=layers,
            batch_first=True,
            bidirectional=True,
            dropout=dropout if layers > 1 else 0.0,
        )
        self.readout = nn.Linear(2 * hidden, outputs)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.readout(self.rnn(x)[0])


class LSTM(nn.Module):
    """Forward LSTM."""

    def __init__(self, inputs: int, outputs: int, hidden: int = 64, layers: int = 4, dropout: float = 0.0):
        super().__init__()
        self.rnn = nn.LSTM(inputs, hidden, num_layers=layers, batch_first=True, dropout=dropout if layers > 1 else 0.0)
        self.readout = nn.Linear(hidden, outputs)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.readout(self.rnn(x)[0])


class ConvGRU(nn.Module):
    """Two temporal convolutions (kernel 5, ReLU) feeding a bidirectional GRU."""

    def __init__(
        self, inputs: int, outputs: int, hidden: int = 64, layers: int = 2, kernel: int = 5, dropout: float = 0.0
    ):
        super().__init__()
        self.conv = nn.Sequential(
            nn.Conv1d(inputs, hidden, kernel, padding=kernel // 2),
            nn.ReLU(),
            nn.Conv1d(hidden, hidden, kernel, padding=kernel // 2),
            nn.ReLU(),
        )
        self.rnn = nn.GRU(
            hidden,
            hidden,
            num_layers=layers,
            batch_first=True,
            bidirectional=True,
            dropout=dropout if layers > 1 else 0.0,
        )
        self.readout = nn.Linear(2 * hidden, outputs)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.conv(x.transpose(1, 2)).transpose(1, 2)
        return self.readout(self.rnn(h)[0])


class FFN(nn.Module):
    """Per-hour MLP (ReLU) on the inputs of the hour and of the ``lags`` hours before it."""

    def __init__(self, inputs: int, outputs: int, hidden: int = 256, layers: int = 3, lags: int = 6):
        super().__init__()
        self.lags = lags
        widths = [inputs * (lags + 1)] + [hidden] * layers
        body: list[nn.Module] = []
        for a, b in zip(widths[:-1], widths[1:]):
            body += [nn.Linear(a, b), nn.ReLU()]
        self.mlp = nn.Sequential(*body, nn.Linear(widths[-1], outputs))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        padded = F.pad(x, (0, 0, self.lags, 0), mode="replicate") if self.lags else x
        window = padded.unfold(1, self.lags + 1, 1)  # (B, H, C, lags+1)
        return self.mlp(window.flatten(2))


MODELS: dict[str, type[nn.Module]] = {
    "transformer": Transformer,
    "bigru": BiGRU,
    "lstm": LSTM,
    "convgru": ConvGRU,
    "ffn": FFN,
}


def build(name: str, inputs: int, outputs: int, **config) -> nn.Module:
    """Instantiate a registered model; ``config`` holds its keyword arguments (see each class)."""
    if name not in MODELS:
        raise ValueError(f"unknown model {name!r}; choose one of {', '.join(MODELS)}")
    return MODELS[name](inputs, outputs, **config)


def with_more_inputs(model: nn.Module, name: str, config: dict, inputs: int, outputs: int, extra: int) -> nn.Module:
    """A copy of ``model`` (``build(name, inputs, outputs, **config)``) that takes ``extra`` more input channels,
    appended after the others, with zero weights: it computes what ``model`` did whatever they hold, and
    training then learns their use (fine-tuning a trained model with a new input)."""
    return with_inputs(model, name, config, inputs, outputs, [*range(inputs), *([-1] * extra)])


def with_inputs(model: nn.Module, name: str, config: dict, inputs: int, outputs: int, sources: list[int]) -> nn.Module:
    """A copy of ``model`` (``build(name, inputs, outputs, **config)``) whose input channel ``j`` is the
    model's channel ``sources[j]``, or a new channel with zero weights where ``sources[j]`` is -1: fed the same
    values on the channels it had, it computes what ``model`` did, and training then learns the new ones.

    Every weight whose second axis reads the inputs is rebuilt: ``k x inputs`` columns (``k`` hours of a patch
    or lags, flattened hour by hour where the class sets ``hour_major_inputs``, channel by channel otherwise).
    """
    old = model.state_dict()
    try:
        build(name, inputs, outputs, **config).load_state_dict(old)
    except RuntimeError as exc:
        raise ValueError(
            f"{name}: cannot widen a model that is not build({name!r}, {inputs}, {outputs}, "
            f"**config): {str(exc).splitlines()[0]}"
        ) from None
    n = len(sources)
    if n == inputs and list(sources) != list(range(inputs)):
        raise ValueError(f"{name}: reordering inputs needs a different number of them ({inputs} given)")
    src = torch.tensor(sources)
    kept = src >= 0
    wide = build(name, n, outputs, **config)
    state = wide.state_dict()
    hour_major = getattr(type(model), "hour_major_inputs", False)
    for key, target in state.items():
        source = old[key]
        if source.shape == target.shape:
            state[key] = source.clone()
            continue
        k = source.shape[1] // inputs
        fits = source.shape[1] == k * inputs and target.shape[1] == k * n
        if source.shape[0] != target.shape[0] or not fits:
            raise ValueError(f"{name}: cannot widen {key} from {tuple(source.shape)} to {tuple(target.shape)}")
        rest = tuple(source.shape[2:])
        grown = torch.zeros_like(target)
        if hour_major:
            view, old_view = grown.view(target.shape[0], k, n, *rest), source.view(source.shape[0], k, inputs, *rest)
            view[:, :, kept] = old_view[:, :, src[kept]]
        else:
            view, old_view = grown.view(target.shape[0], n, k, *rest), source.view(source.shape[0], inputs, k, *rest)
            view[:, kept] = old_view[:, src[kept]]
        state[key] = grown
    wide.load_state_dict(state)
    return wide.train(model.training)
