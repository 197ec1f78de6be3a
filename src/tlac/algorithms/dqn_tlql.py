"""DQN-TLQL: a DQN version of Two-Level Q-Learning (Li, Wei and Kudenko, KER 2019).

The TL-AC paper compares against "the DQN version of the Two-level Q-learning algorithm as
described in (Li et al., 2019b)", re-implemented by its authors after Stable-Baselines3's DQN
(paper, section 4.1; settings in its Table 6). Neither that code nor the exact update rules
were available, so this module implements the rules below; every choice is listed in
``docs/baselines/dqn-tlql.md``.

Two Q-networks, trained from ONE replay buffer on the environment's reward:

* high level ``Q_H(s, e)`` over the choices ``e`` in ``teachers + [agent]`` (index ``N`` =
  the agent, as in :class:`tlac.recording.Recorder`), chosen epsilon-greedily;
* low level ``Q_L(s, a)`` over the actions. The executed action is the chosen teacher's
  advice, or, when the agent is chosen, the epsilon-greedy action of ``Q_L``.

Both are updated like SB3's DQN (Huber loss, Adam, gradient-norm clipping, Polyak target
update every ``target_update_interval`` steps) with the targets of :func:`td_targets`::

    Q_H(s, e) <- r + gamma * (1 - terminated) * max_e' Q_H_target(s', e')
    Q_L(s, a) <- r + gamma * (1 - terminated) * max_a' Q_L_target(s', a')

``Q_L`` learns off-policy from every transition (teacher actions included): that is how the
student learns from advice. ``predict`` (the student alone) is ``argmax_a Q_L(s, a)``.
Discrete action spaces only; the paper notes DQN-TLQL "does not support continuous control".
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import gymnasium as gym
import numpy as np
import torch
import torch.nn.functional as F
from stable_baselines3.common.vec_env import VecEnv
from torch import nn

from tlac.algorithms.common import (
    check_observations,
    check_seed,
    checkpoint_path,
    config_from_kwargs,
    flat_obs,
    linear_epsilon,
    make_progress_bar,
    mlp,
    polyak_update,
    query_teachers,
    real_next_obs,
    safe_torch_load,
    stop_if_not_finite,
    td_targets,
)
from tlac.errors import ConfigError
from tlac.recording import Recorder

ContractCallback = Callable[[Any], "bool | None"]
C = TypeVar("C")


# --------------------------------------------------------------------------- configuration
@dataclass(frozen=True)
class DQNTLQLConfig:
    """DQN-TLQL settings (paper, Table 6; keys not in the table are documented choices)."""

    learning_rate: float = 1e-4
    """Adam step size for both Q-networks (Table 6)."""
    optimizer: str = "adam"
    """Only ``adam`` (Table 6)."""
    buffer_size: int = 10_000
    """Replay memory size (Table 6)."""
    learning_starts: int = 100
    """Environment steps before the first update (not in Table 6: SB3's DQN default)."""
    batch_size: int = 32
    """Minibatch size (not in Table 6: SB3's DQN default)."""
    train_freq: int = 100
    """Vec-env steps between updates ("number of steps per update", Table 6)."""
    gradient_steps: int = 1
    """Gradient steps per update (not in Table 6; SB3's default 1; see the docs page)."""
    target_update_interval: int = 100
    """Environment steps between Polyak target updates (Table 6)."""
    tau: float = 0.2
    """Polyak coefficient of the target update (Table 6)."""
    exploration_initial_eps: float = 1.0
    """Epsilon at the start (Table 6: 1 -> 0.01)."""
    exploration_final_eps: float = 0.01
    """Epsilon after ``exploration_fraction`` of training (Table 6)."""
    exploration_fraction: float = 0.1
    """Fraction of training over which epsilon decays (Table 6)."""
    low_level_epsilon: bool = True
    """Apply the same epsilon to the agent's own action when the agent is chosen."""
    max_grad_norm: float = 10.0
    """Gradient-norm clipping per network (Table 6)."""
    gamma: float = 0.99
    """Discount (Table 6)."""
    net_arch: list[int] = field(default_factory=lambda: [64, 64])
    """Hidden layers of each Q-network (Table 6: [64, 64] for each level)."""

    def __post_init__(self) -> None:
        if self.optimizer != "adam":
            raise ConfigError(
                f"dqn-tlql optimizer: only 'adam' is supported, got {self.optimizer!r}"
            )
        for name in (
            "buffer_size",
            "batch_size",
            "train_freq",
            "gradient_steps",
            "target_update_interval",
        ):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v <= 0:
                raise ConfigError(f"dqn-tlql {name} must be a positive integer, got {v!r}")
        if self.learning_starts < 0:
            raise ConfigError(
                f"dqn-tlql learning_starts must be >= 0, got {self.learning_starts!r}"
            )
        if not 0.0 < self.tau <= 1.0:
            raise ConfigError(f"dqn-tlql tau must be in (0, 1], got {self.tau!r}")
        if not 0.0 <= self.gamma <= 1.0:
            raise ConfigError(f"dqn-tlql gamma must be in [0, 1], got {self.gamma!r}")
        for name in ("exploration_initial_eps", "exploration_final_eps", "exploration_fraction"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ConfigError(f"dqn-tlql {name} must be in [0, 1], got {v!r}")
        if self.learning_rate <= 0 or self.max_grad_norm <= 0:
            raise ConfigError("dqn-tlql learning_rate and max_grad_norm must be positive")


# --------------------------------------------------------------------------- algorithm
class DQNTLQL:
    """DQN Two-Level Q-learning over ``teachers + [agent]`` (see the module docstring)."""

    @classmethod
    def check_hyperparameters(cls, hyperparameters: dict[str, Any]) -> DQNTLQLConfig:
        """The validated settings; a bad one raises ConfigError naming it."""
        return config_from_kwargs(DQNTLQLConfig, "dqn-tlql", hyperparameters)

    def __init__(
        self,
        env: VecEnv | None,
        teachers: list[Any] | None = None,
        seed: int = 0,
        recorder: Recorder | None = None,
        **hyperparameters: Any,
    ):
        self.config = self.check_hyperparameters(hyperparameters)
        seed = check_seed(seed)
        self.teachers = list(teachers or [])
        self.seed, self.recorder, self.env = seed, recorder, env
        self.num_timesteps = 0
        if env is not None:
            self._setup(env.observation_space, env.action_space, len(self.teachers) + 1)

    # ---- construction
    def _setup(self, obs_space: gym.Space, action_space: gym.Space, n_choices: int) -> None:
        if not isinstance(action_space, gym.spaces.Discrete):
            raise ConfigError(
                f"dqn-tlql needs a Discrete action space, got {action_space}; "
                "DQN-TLQL does not support continuous control (paper, section 4.1): use tlac or ac-teach"
            )
        self.observation_space, self.action_space = obs_space, action_space
        self.obs_dim = int(np.prod(obs_space.shape))
        self.n_actions, self.n_choices = int(action_space.n), int(n_choices)
        torch.manual_seed(self.seed)
        self.rng = np.random.default_rng(self.seed)
        arch = list(self.config.net_arch)
        self.q_high, self.q_low = (
            mlp(self.obs_dim, arch, n_choices),
            mlp(self.obs_dim, arch, self.n_actions),
        )
        self.q_high_target, self.q_low_target = (
            mlp(self.obs_dim, arch, n_choices),
            mlp(self.obs_dim, arch, self.n_actions),
        )
        self.q_high_target.load_state_dict(self.q_high.state_dict())
        self.q_low_target.load_state_dict(self.q_low.state_dict())
        lr = self.config.learning_rate
        self.opt_high = torch.optim.Adam(self.q_high.parameters(), lr=lr)
        self.opt_low = torch.optim.Adam(self.q_low.parameters(), lr=lr)
        cap = self.config.buffer_size
        self._buf = {
            "obs": np.zeros((cap, self.obs_dim), np.float32),
            "next_obs": np.zeros((cap, self.obs_dim), np.float32),
            "choice": np.zeros(cap, np.int64),
            "action": np.zeros(cap, np.int64),
            "reward": np.zeros(cap, np.float32),
            "terminated": np.zeros(cap, np.float32),
        }
        self._buf_pos, self._buf_full = 0, False

    # ---- replay buffer
    def _store(self, **rows: np.ndarray) -> None:
        n = len(rows["reward"])
        idx = (self._buf_pos + np.arange(n)) % self.config.buffer_size
        for k, v in rows.items():
            self._buf[k][idx] = v
        self._buf_full |= self._buf_pos + n >= self.config.buffer_size
        self._buf_pos = int((self._buf_pos + n) % self.config.buffer_size)

    def _buffer_len(self) -> int:
        return self.config.buffer_size if self._buf_full else self._buf_pos

    def _sample(self, batch_size: int) -> dict[str, torch.Tensor]:
        idx = self.rng.integers(0, self._buffer_len(), size=batch_size)
        return {k: torch.as_tensor(v[idx]) for k, v in self._buf.items()}

    # ---- acting
    def _act(self, obs: np.ndarray, eps: float) -> tuple[np.ndarray, np.ndarray]:
        """High-level choices and executed actions for a batch of observations."""
        n = len(obs)
        with torch.no_grad():
            x = torch.as_tensor(obs)
            greedy_high = self.q_high(x).argmax(dim=1).numpy()
        explore = self.rng.random(n) < eps
        choices = np.where(explore, self.rng.integers(0, self.n_choices, size=n), greedy_high)
        actions = np.zeros(n, dtype=np.int64)
        query_teachers(self.teachers, choices, obs, self.action_space, actions)
        agent_rows = np.flatnonzero(choices == self.n_choices - 1)
        if len(agent_rows):
            with torch.no_grad():
                greedy_low = self.q_low(torch.as_tensor(obs[agent_rows])).argmax(dim=1).numpy()
            low_eps = eps if self.config.low_level_epsilon else 0.0
            random_low = self.rng.integers(0, self.n_actions, size=len(agent_rows))
            actions[agent_rows] = np.where(
                self.rng.random(len(agent_rows)) < low_eps, random_low, greedy_low
            )
        return choices, actions

    # ---- learning
    def _q_loss(
        self,
        net: nn.Module,
        target: nn.Module,
        x: torch.Tensor,
        idx: torch.Tensor,
        batch: dict[str, torch.Tensor],
    ) -> torch.Tensor:
        with torch.no_grad():
            y = td_targets(
                batch["reward"], batch["terminated"], target(batch["next_obs"]), self.config.gamma
            )
        q = net(x).gather(1, idx[:, None]).squeeze(1)
        return F.smooth_l1_loss(q, y)

    def _train(self, gradient_steps: int) -> dict[str, float]:
        cfg = self.config
        losses_h, losses_l = [], []
        for _ in range(gradient_steps):
            batch = self._sample(cfg.batch_size)
            for net, target, opt, key, out in (
                (self.q_high, self.q_high_target, self.opt_high, "choice", losses_h),
                (self.q_low, self.q_low_target, self.opt_low, "action", losses_l),
            ):
                loss = self._q_loss(net, target, batch["obs"], batch[key], batch)
                opt.zero_grad()
                loss.backward()
                norm = nn.utils.clip_grad_norm_(net.parameters(), cfg.max_grad_norm)
                stop_if_not_finite(norm, "dqn-tlql", self.num_timesteps, "gradient norm")
                opt.step()
                out.append(float(loss.detach()))
        return {
            "train/loss_high": float(np.mean(losses_h)),
            "train/loss_low": float(np.mean(losses_l)),
        }

    def learn(
        self,
        total_timesteps: int,
        callback: ContractCallback | None = None,
        progress_bar: bool = False,
    ) -> DQNTLQL:
        """Collect and update for ``total_timesteps`` environment steps (over all envs)."""
        if self.env is None:
            raise ConfigError(
                "dqn-tlql: learn() needs an environment; load(path, env=...) to continue training"
            )
        if len(self.teachers) + 1 != self.n_choices:
            raise ConfigError(
                f"dqn-tlql: the model chooses among {self.n_choices - 1} teachers + agent, "
                f"but {len(self.teachers)} teachers were given"
            )
        cfg, env, n = self.config, self.env, self.env.num_envs
        start_steps, end_steps = self.num_timesteps, self.num_timesteps + int(total_timesteps)
        obs = flat_obs(env.reset(), n)
        next_target_update = self.num_timesteps + cfg.target_update_interval
        vec_steps, metrics, t0 = 0, {}, time.time()
        next_log = self.num_timesteps + (self.recorder.log_interval if self.recorder else 0)
        bar = make_progress_bar(total_timesteps, "DQN-TLQL", progress_bar)
        while self.num_timesteps < end_steps:
            progress = (self.num_timesteps - start_steps) / max(1, end_steps - start_steps)
            eps = linear_epsilon(
                progress,
                cfg.exploration_initial_eps,
                cfg.exploration_final_eps,
                cfg.exploration_fraction,
            )
            choices, actions = self._act(obs, eps)
            new_obs, rewards, dones, infos = env.step(actions)
            new_obs = flat_obs(new_obs, n)
            real_next, terminated = real_next_obs(new_obs, dones, infos)
            self._store(
                obs=obs,
                next_obs=real_next.reshape(n, -1),
                choice=choices,
                action=actions,
                reward=np.asarray(rewards, np.float32),
                terminated=terminated,
            )
            if self.recorder is not None:
                self.recorder.record_selections(self.num_timesteps + n, choices, obs)
            obs = new_obs
            self.num_timesteps += n
            vec_steps += 1
            if self.num_timesteps >= next_target_update:  # every target_update_interval env steps
                polyak_update(self.q_high, self.q_high_target, cfg.tau)
                polyak_update(self.q_low, self.q_low_target, cfg.tau)
                next_target_update += cfg.target_update_interval
            if vec_steps % cfg.train_freq == 0:
                if (
                    self.num_timesteps >= cfg.learning_starts
                    and self._buffer_len() >= cfg.batch_size
                ):
                    metrics = self._train(cfg.gradient_steps)
                if self.recorder is not None and self.num_timesteps >= next_log:
                    fps = (self.num_timesteps - start_steps) / max(time.time() - t0, 1e-9)
                    self.recorder.record_metrics(
                        self.num_timesteps,
                        {**metrics, "rollout/exploration_rate": eps, "time/fps": fps},
                    )
                    next_log = self.recorder.window_end_after(self.num_timesteps)
                if bar is not None:
                    bar.update(min(self.num_timesteps, end_steps) - start_steps - bar.n)
                if callback is not None and callback(self) is False:
                    break
        if bar is not None:
            bar.close()
        return self

    # ---- inference and persistence
    def predict(self, obs: np.ndarray, deterministic: bool = True) -> tuple[np.ndarray, None]:
        """The student alone: ``argmax_a Q_L(s, a)`` (no teacher, no exploration); one
        observation gives one action, a batch gives one per row."""
        batch, single = check_observations(obs, self.observation_space)
        x = torch.as_tensor(flat_obs(batch, len(batch)))
        with torch.no_grad():
            actions = self.q_low(x).argmax(dim=1).numpy()
        return (actions[0] if single else actions), None

    def save(self, path: str | Path) -> None:
        """``torch.save`` of the networks, optimizers, settings and step count to ``path.pt``
        (teachers and the replay buffer are not saved)."""
        torch.save(
            {
                "algo": "dqn-tlql",
                "config": dataclasses.asdict(self.config),
                "obs_shape": list(self.observation_space.shape),
                "n_actions": self.n_actions,
                "n_choices": self.n_choices,
                "teacher_names": [t.name for t in self.teachers],
                "num_timesteps": self.num_timesteps,
                "seed": self.seed,
                "state": {
                    "q_high": self.q_high.state_dict(),
                    "q_low": self.q_low.state_dict(),
                    "q_high_target": self.q_high_target.state_dict(),
                    "q_low_target": self.q_low_target.state_dict(),
                    "opt_high": self.opt_high.state_dict(),
                    "opt_low": self.opt_low.state_dict(),
                },
            },
            checkpoint_path(path),
        )

    @classmethod
    def load(
        cls, path: str | Path, env: VecEnv | None = None, teachers: list[Any] | None = None
    ) -> DQNTLQL:
        """Rebuild a model written by :meth:`save`; pass ``env`` (and the same teachers) to
        continue training."""
        p = checkpoint_path(path)
        if not p.exists():
            raise ConfigError(f"no dqn-tlql model at {str(p)!r}")
        data = safe_torch_load(p, "dqn-tlql model")
        obj = cls(
            env=None, teachers=teachers, seed=int(data["seed"]), recorder=None, **data["config"]
        )
        obs_space = gym.spaces.Box(
            -np.inf, np.inf, shape=tuple(data["obs_shape"]), dtype=np.float32
        )
        obj._setup(obs_space, gym.spaces.Discrete(int(data["n_actions"])), int(data["n_choices"]))
        for name, sd in data["state"].items():
            getattr(obj, name).load_state_dict(sd)
        obj.num_timesteps, obj.env = int(data["num_timesteps"]), env
        return obj
