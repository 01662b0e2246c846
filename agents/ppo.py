"""PPO (stable-baselines3) trained across the training weeks of BuildingWeek-v0, evaluated on held-out weeks.

One PPO policy maps a week's observation (weather forecast summary, occupancy, week of the year, calibrated
building) to the week's settings: after training, choosing a week's settings is one small forward pass
instead of a per-week optimisation (:func:`agents.cmaes.optimise_week`, thousands of scored weeks).

- :class:`BuildingVecEnv`: a stable-baselines3 ``VecEnv`` over the native batched
  :class:`buildenv.env.building_week.BuildingWeekVectorEnv`, so that one PPO step of N environments is one
  metamodel call (SB3's ``DummyVecEnv`` would call the metamodel once per environment).
- :func:`train_ppo`: PPO with hyper-parameters for a one-step contextual bandit (:data:`PPO_DEFAULTS`), the
  policy's mean started at the site's historical settings.
- :func:`evaluate_policy_weeks`: the deterministic action of each held-out week, scored with the
  environment's batched ``evaluate``, with the policy's inference time.
- :func:`save_policy` / :func:`load_policy`: the trained model as one SB3 ``.zip`` file.

Only the environment is used (``gymnasium.make``/``make_vec`` of ``BuildingWeek-v0`` and
``env.unwrapped.evaluate``); never the metamodel or EnergyPlus directly.
"""

from __future__ import annotations

import time
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper, VecMonitor

import buildenv  # noqa: F401  (registers BuildingWeek-v0)
from agents.cmaes import WeekResult, scalar_scores
from buildenv.env.building_week import split_weeks
from buildenv.errors import BuildingEnvError

ENV_ID = "BuildingWeek-v0"

#: PPO hyper-parameters for one-week episodes, a contextual bandit (``gamma`` and ``gae_lambda`` play no role);
#: initial exploration noise exp(-1.2) = 0.3 action units, CMA-ES's initial step. Tuned on training weeks only;
#: any of them can be overridden in :func:`train_ppo`.
PPO_DEFAULTS: dict[str, Any] = {
    "n_steps": 4,
    "batch_size": 256,
    "n_epochs": 10,
    "learning_rate": 1e-3,
    "gamma": 0.0,
    "gae_lambda": 1.0,
    "clip_range": 0.2,
    "ent_coef": 0.0,
    "vf_coef": 0.5,
    "max_grad_norm": 0.5,
    "policy_kwargs": {"net_arch": {"pi": [256, 256], "vf": [256, 256]}, "log_std_init": -1.2},
}


# ---------------------------------------------------------------------------------------------- the VecEnv
class BuildingVecEnv(VecEnv):
    """A stable-baselines3 ``VecEnv`` over :class:`buildenv.env.building_week.BuildingWeekVectorEnv` (one
    metamodel call a step).

    The gymnasium vector environment resets finished sub-environments in the same step
    (``AutoresetMode.SAME_STEP``), which is what SB3 expects: the returned observation is the new episode's,
    the finished episode's last observation goes to ``infos[i]["terminal_observation"]`` and
    ``infos[i]["TimeLimit.truncated"]`` says whether it was cut by a time limit (``max_episode_steps``). The vector
    info dict of arrays is split into one dict per environment (reward terms, ``week``, ...).

    The N environments share one batched simulator, so ``get_attr``/``set_attr``/``env_method`` act on the
    vector environment (a method is called once and its result repeated for each index asked for). Seeds
    given with ``seed(s)`` are used at the next ``reset`` (the first one seeds the vector environment).

    Args:
        env: a ``BuildingWeekVectorEnv`` (``gymnasium.make_vec("BuildingWeek-v0", num_envs=N, ...)``), or
            None to make one from ``num_envs`` and ``env_kwargs``.
        num_envs: environments, when ``env`` is None.
        **env_kwargs: arguments of ``BuildingWeek-v0`` (``weeks``, ``comfort_weight``, ...), when ``env`` is
            None.
    """

    def __init__(self, env: gym.vector.VectorEnv | None = None, num_envs: int = 64, **env_kwargs: Any) -> None:
        if env is None:
            if num_envs < 1:
                raise BuildingEnvError(f"num_envs={num_envs}: give 1 or more environments")
            env = gym.make_vec(
                ENV_ID, num_envs=int(num_envs), autoreset_mode=gym.vector.AutoresetMode.SAME_STEP, **env_kwargs
            )
        elif env_kwargs:
            raise BuildingEnvError(
                f"BuildingVecEnv: give either env or environment arguments, not both ({', '.join(env_kwargs)})"
            )
        if not hasattr(env.unwrapped, "evaluate") or not hasattr(env, "single_action_space"):
            raise BuildingEnvError(
                "BuildingVecEnv wraps the native BuildingWeek-v0 vector env: "
                "gymnasium.make_vec('BuildingWeek-v0', num_envs=N)"
            )
        if env.metadata.get("autoreset_mode") != gym.vector.AutoresetMode.SAME_STEP:
            raise BuildingEnvError(
                "BuildingVecEnv needs same-step autoreset, as SB3 expects: "
                "gymnasium.make_vec('BuildingWeek-v0', num_envs=N, autoreset_mode=AutoresetMode.SAME_STEP)"
            )
        self.venv = env
        self._actions: np.ndarray | None = None
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)

    # ----------------------------------------------------------------------------- stepping
    def reset(self) -> np.ndarray:
        """Reset every environment; returns observations ``(N, obs)``."""
        seed = self._seeds[0]
        options = self._options[0] or None
        obs, info = self.venv.reset(seed=seed, options=options)
        self.reset_infos = self._split_info(info)
        self._reset_seeds()
        self._reset_options()
        return np.asarray(obs, dtype=np.float32)

    def step_async(self, actions: np.ndarray) -> None:
        """Store the actions ``(N, A)`` of the next :meth:`step_wait`."""
        self._actions = np.asarray(actions, dtype=np.float32)

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        """Step all environments in one batched call; returns ``(obs, rewards, dones, infos)`` (SB3's API)."""
        if self._actions is None:
            raise BuildingEnvError("BuildingVecEnv: call step_async(actions) before step_wait()")
        obs, rewards, terminated, truncated, info = self.venv.step(self._actions)
        self._actions = None
        dones = np.logical_or(terminated, truncated)
        infos = self._split_info(info)
        if dones.any():  # gymnasium puts the finished episodes' step info in final_info, SB3 in infos
            finished = self._split_info(info["final_info"])
            for i in np.flatnonzero(dones):
                self.reset_infos[i] = infos[i]
                infos[i] = finished[i]
                infos[i]["terminal_observation"] = np.asarray(info["final_obs"][i], dtype=np.float32)
        for i in range(self.num_envs):
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return np.asarray(obs, dtype=np.float32), np.asarray(rewards, dtype=np.float32), dones, infos

    def _split_info(self, info: dict) -> list[dict[str, Any]]:
        """One dict per environment from a gymnasium vector info (arrays with ``_key`` masks)."""
        out: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for key, value in info.items():
            if key.startswith("_") or key in ("final_obs", "final_info"):
                continue
            mask = info.get(f"_{key}", np.ones(self.num_envs, bool))
            for i in np.flatnonzero(mask):
                out[i][key] = value[i]
        return out

    def close(self) -> None:
        """Close the vector environment."""
        self.venv.close()

    # ----------------------------------------------------------------------------- attributes and methods
    def _count(self, indices: Any) -> int:
        return len(list(self._get_indices(indices)))

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        """The vector environment's attribute, once per index (the environments share it)."""
        return [getattr(self.venv.unwrapped, attr_name)] * self._count(indices)

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        """Set an attribute of the (shared) vector environment."""
        setattr(self.venv.unwrapped, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any) -> list[Any]:
        """Call a method of the (shared) vector environment once; its result repeated per index."""
        result = getattr(self.venv.unwrapped, method_name)(*method_args, **method_kwargs)
        return [result] * self._count(indices)

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: Any = None) -> list[bool]:
        """Never wrapped (the environments are rows of one batched simulator)."""
        return [False] * self._count(indices)

    def get_images(self) -> Sequence[np.ndarray | None]:
        """The last week of each environment as a picture with ``render_mode="rgb_array"``, else None each."""
        if getattr(self.venv, "render_mode", None) == "rgb_array":
            return list(self.venv.render())
        return [None] * self.num_envs

    def evaluate(self, actions: np.ndarray, week: int) -> dict[str, np.ndarray]:
        """Score actions ``(N, A)`` on one week (the vector environment's batched ``evaluate``)."""
        return self.venv.unwrapped.evaluate(actions, week=week)


class ObservationNoise(VecEnvWrapper):
    """Training-time augmentation: Gaussian noise of standard deviation ``std`` (observation units) added to
    every observation the agent sees, so that the policy varies smoothly between the few training contexts
    (a site's year has 51 weeks, 39 of them for training) instead of keying on details of each week.

    The environment itself (rewards, terminal observations) is unchanged.

    Args:
        venv: the SB3 vector environment.
        std: noise standard deviation (the compact observation's values are of order one).
        seed: seed of the noise.
    """

    def __init__(self, venv: VecEnv, std: float, seed: int = 0) -> None:
        super().__init__(venv)
        if std < 0:
            raise BuildingEnvError(f"observation noise std={std}: give 0 or more")
        self.std = float(std)
        self.rng = np.random.default_rng(seed)

    def _noisy(self, obs: np.ndarray) -> np.ndarray:
        return (obs + self.rng.normal(0.0, self.std, obs.shape)).astype(np.float32)

    def reset(self) -> np.ndarray:
        """Reset, noisy observations."""
        return self._noisy(self.venv.reset())

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict]]:
        """Step, noisy observations."""
        obs, rewards, dones, infos = self.venv.step_wait()
        return self._noisy(obs), rewards, dones, infos


# ---------------------------------------------------------------------------------------------- training
class _TqdmProgress(BaseCallback):
    """A tqdm bar of environment steps (SB3's own bar needs ``rich``)."""

    def __init__(self, total: int) -> None:
        super().__init__()
        self.total = total
        self.bar = None

    def _on_training_start(self) -> None:
        from tqdm.auto import tqdm

        self.bar = tqdm(total=self.total, unit="week", desc="PPO")

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        return True

    def _on_training_end(self) -> None:
        self.bar.close()


def train_ppo(
    env_kwargs: dict | None = None,
    timesteps: int = 300_000,
    num_envs: int = 64,
    seed: int = 0,
    save: Path | str | None = None,
    progress: bool = False,
    historical_start: bool = True,
    observation_noise: float = 0.0,
    callback: BaseCallback | list[BaseCallback] | None = None,
    **ppo_kwargs: Any,
) -> PPO:
    """Train PPO on BuildingWeek-v0 (by default on the training weeks), stepping ``num_envs`` weeks a call.

    Args:
        env_kwargs: arguments of ``BuildingWeek-v0``; ``weeks`` defaults to ``"train"`` (the held-out test
            weeks 12-15, 28-31 and 44-47 are never seen).
        timesteps: simulated weeks to train on (rounded up to whole rollouts of ``n_steps * num_envs``).
        num_envs: environments stepped together (one metamodel call of ``num_envs`` weeks per PPO step).
        seed: seed of PPO (network initialisation, action noise, minibatches) and of the week draws.
            SB3 also seeds Python's, numpy's and torch's global generators with it.
        save: write the trained model there (an SB3 ``.zip``, see :func:`save_policy`).
        progress: show a tqdm bar of simulated weeks.
        historical_start: start the policy's mean at the site's historical settings (the action layer's
            bias set to ``historical_action``; with several sites, the mean of theirs), as CMA-ES starts from
            them; the saved model needs nothing extra to act.
        observation_noise: standard deviation of the Gaussian noise added to training observations
            (:class:`ObservationNoise`; 0: none). Acting and evaluation use clean observations.
        callback: SB3 callback(s) called during training (e.g. to record a learning curve).
        **ppo_kwargs: override :data:`PPO_DEFAULTS` or pass other ``stable_baselines3.PPO`` arguments
            (``policy_kwargs`` are merged with the defaults').
    Returns:
        The trained ``stable_baselines3.PPO`` model (CPU). ``model.predict(obs, deterministic=True)`` gives
        actions ``(N, A)``; :func:`policy_actions` does the same.
    Raises:
        BuildingEnvError: ``timesteps`` < 1.
    """
    if timesteps < 1:
        raise BuildingEnvError(f"timesteps={timesteps}: give 1 or more simulated weeks")
    env_kwargs = {"weeks": "train", **(env_kwargs or {})}
    params = {**PPO_DEFAULTS, **ppo_kwargs}
    params["policy_kwargs"] = {**PPO_DEFAULTS["policy_kwargs"], **ppo_kwargs.get("policy_kwargs", {})}
    venv: VecEnv = VecMonitor(BuildingVecEnv(num_envs=num_envs, **env_kwargs))
    if observation_noise > 0:
        venv = ObservationNoise(venv, observation_noise, seed=seed)
    model = PPO("MlpPolicy", venv, seed=seed, device="cpu", verbose=0, **params)
    if historical_start:
        import torch

        historical = np.asarray(venv.unwrapped.venv.unwrapped.site_historical_actions.mean(axis=0), dtype=np.float32)
        with torch.no_grad():
            model.policy.action_net.bias.copy_(torch.from_numpy(historical))
    callbacks = [] if callback is None else list(callback) if isinstance(callback, list) else [callback]
    if progress:
        callbacks.append(_TqdmProgress(int(timesteps)))
    model.learn(total_timesteps=int(timesteps), callback=callbacks or None)
    if save is not None:
        save_policy(model, save)
    return model


# ---------------------------------------------------------------------------------------------- acting
def policy_actions(model: PPO, observations: np.ndarray) -> np.ndarray:
    """Deterministic actions ``(N, A)`` in [-1, 1] (the policy's mean, clipped) of observations ``(N, obs)``."""
    actions, _ = model.predict(np.asarray(observations, dtype=np.float32), deterministic=True)
    return np.asarray(actions, dtype=np.float32)


def evaluate_policy_weeks(
    model: PPO, env_kwargs: dict | None = None, weeks: Iterable[int] | str = "test", env: gym.Env | None = None
) -> list[WeekResult]:
    """Score the policy's deterministic settings on each of ``weeks`` (default: the held-out test weeks).

    For each week: the observation of the week's start (``reset(options={"week": k})``), the policy's
    action (timed: ``seconds`` is this inference time alone, one forward pass, after one untimed warm-up),
    then the action scored with ``env.unwrapped.evaluate`` (not timed).

    Args:
        model: a trained PPO model (:func:`train_ppo`, :func:`load_policy`).
        env_kwargs: arguments of ``BuildingWeek-v0`` the model was trained with; ``weeks`` is set from
            ``weeks``.
        weeks: ``"test"``, ``"train"``, ``"all"`` or week indices.
        env: an existing ``BuildingWeek-v0`` environment to use instead of making one (its ``weeks`` must
            allow starting on each week asked for).
    Returns:
        One :class:`agents.cmaes.WeekResult` per week (``evaluations=1``; ``scores``: reward, energy_term,
        comfort_k, savings_percent, ...; ``seconds``: inference time of the action, s).
    """
    if not isinstance(weeks, str):
        weeks = [int(w) for w in weeks]  # once: an iterator is read only once
    own = env is None
    if own:
        env = gym.make(ENV_ID, **{**(env_kwargs or {}), "weeks": weeks})
    try:
        base = env.unwrapped
        if isinstance(weeks, str):  # the split's weeks the environment can start on
            split = split_weeks(base.site_model.weeks, weeks)
            week_list = [w for w in base.weeks if w in split]
        else:
            week_list = weeks
        obs, _ = env.reset(options={"week": int(week_list[0])})
        policy_actions(model, obs[None])  # warm-up (first call builds torch kernels)
        results = []
        for week in week_list:
            obs, _ = env.reset(options={"week": int(week)})
            started = time.perf_counter()
            action = policy_actions(model, obs[None])[0]
            seconds = time.perf_counter() - started
            scores = base.evaluate(action[None], week=int(week))
            results.append(WeekResult(int(week), action, scalar_scores(scores, 0), 1, seconds))
        return results
    finally:
        if own:
            env.close()


# ---------------------------------------------------------------------------------------------- files
def save_policy(model: PPO, path: Path | str) -> Path:
    """Write a trained model to ``path`` (an SB3 ``.zip``: weights, hyper-parameters, spaces); returns the path."""
    path = Path(path)
    if path.suffix != ".zip":
        path = path.with_suffix(".zip")
    path.parent.mkdir(parents=True, exist_ok=True)
    model.save(path)
    return path


def load_policy(path: Path | str) -> PPO:
    """A model written by :func:`save_policy` (CPU, no environment attached: use it with :func:`policy_actions`).

    Raises:
        BuildingEnvError: no such file.
    """
    path = Path(path)
    if not path.is_file() and path.with_suffix(".zip").is_file():
        path = path.with_suffix(".zip")
    if not path.is_file():
        raise BuildingEnvError(f"PPO policy not found: {path} (write one with agents.ppo.save_policy)")
    return PPO.load(path, device="cpu")
