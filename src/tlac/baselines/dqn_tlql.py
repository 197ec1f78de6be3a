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

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import gymnasium as gym
import numpy as np
import torch
import torch.nn.functional as F
from stable_baselines3.common.vec_env import VecEnv
from torch import nn

from tlac.algorithms.callbacks import SB3Compat
from tlac.algorithms.common import (
    check_observations,
    check_seed,
    check_total_timesteps,
    config_from_kwargs,
    flat_obs,
    mlp,
    polyak_update,
    query_teachers,
    real_next_obs,
    stop_if_not_finite,
    td_targets,
)
from tlac.baselines.off_policy import ReplayBuffer, learn_loop, load_model, save_checkpoint
from tlac.errors import ConfigError
from tlac.recording import Recorder
from tlac.validation import Checks

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
        check = Checks("dqn-tlql")
        check.one_of("optimizer", self.optimizer, ["adam"])
        for name in (
            "buffer_size",
            "batch_size",
            "train_freq",
            "gradient_steps",
            "target_update_interval",
        ):
            check.positive_int(name, getattr(self, name))
        check.integer("learning_starts", self.learning_starts, 0)
        check.number("tau", self.tau, 0.0, 1.0, open_low=True)
        for name in ("gamma", "exploration_initial_eps", "exploration_final_eps"):
            check.number(name, getattr(self, name), 0.0, 1.0)
        check.number("exploration_fraction", self.exploration_fraction, 0.0, 1.0)
        check.number("learning_rate", self.learning_rate, 0.0, open_low=True)
        check.number("max_grad_norm", self.max_grad_norm, 0.0, open_low=True)


# --------------------------------------------------------------------------- algorithm
class DQNTLQL(SB3Compat):
    """DQN Two-Level Q-learning over ``teachers + [agent]`` (see the module docstring)."""

    algo = "dqn-tlql"
    loop_state = ("last_obs", "next_target_update", "next_log", "vec_steps", "metrics")
    """The learn loop's attributes (``_<name>``) that a training-state checkpoint holds."""
    exact_resume = True  # save(training_state=True) / load(resume=True)
    samples_actions = False  # predict is greedy whatever ``deterministic`` says

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
        self._start(self.check_hyperparameters(hyperparameters), env, teachers, seed, recorder)

    @classmethod
    def from_config(
        cls,
        config: DQNTLQLConfig,
        env: VecEnv | None,
        teachers: list[Any] | None = None,
        seed: int = 0,
        recorder: Recorder | None = None,
    ) -> DQNTLQL:
        """A model of settings already validated (:meth:`check_hyperparameters`'s, as
        :func:`tlac.run.resolve_run` builds them once)."""
        model = cls.__new__(cls)
        model._start(config, env, teachers, seed, recorder)
        return model

    def _start(
        self,
        config: DQNTLQLConfig,
        env: VecEnv | None,
        teachers: list[Any] | None,
        seed: int,
        recorder: Recorder | None,
    ) -> None:
        self.config = config
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
                "DQN-TLQL does not support continuous control (paper, section 4.1): "
                "use tlac or ac-teach"
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
        self.buffer = self.new_buffer()
        # the learn loop's state, kept across learn calls and saved with the training state
        self._last_obs: np.ndarray | None = None
        self._next_target_update: int | None = None
        self._next_log: int | None = None
        self._vec_steps = 0
        self._metrics: dict[str, float] = {}
        # the exploration schedule's clock: (first step, steps) of the current learn call,
        # or of the interrupted call that a resumed model continues
        self._schedule: tuple[int, int] | None = None
        self._resumed_schedule: tuple[int, int] | None = None

    def new_buffer(self) -> ReplayBuffer:
        """An empty replay buffer of ``buffer_size`` transitions."""
        return ReplayBuffer(
            self.config.buffer_size,
            {
                "obs": ((self.obs_dim,), np.float32),
                "next_obs": ((self.obs_dim,), np.float32),
                "choice": ((), np.int64),
                "action": ((), np.int64),
                "reward": ((), np.float32),
                "terminated": ((), np.float32),
            },
        )

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
            batch = self.buffer.sample(self.rng, cfg.batch_size)
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
        callback: Any = None,
        progress_bar: bool = False,
    ) -> DQNTLQL:
        """Collect and update for ``total_timesteps`` environment steps (over all envs).
        ``callback``: a function ``f(model)`` run after every training step (``False``
        stops), an SB3 ``BaseCallback`` or a list (``tlac.algorithms.callbacks``)."""
        check_total_timesteps(total_timesteps)  # before anything is reset or allocated
        if self.env is None:
            raise ConfigError(
                "dqn-tlql: learn() needs an environment; load(path, env=...) to continue training"
            )
        if len(self.teachers) + 1 != self.n_choices:
            raise ConfigError(
                f"dqn-tlql: the model chooses among {self.n_choices - 1} teachers + agent, "
                f"but {len(self.teachers)} teachers were given"
            )
        if self._last_obs is None:
            self._last_obs = flat_obs(self.env.reset(), self.env.num_envs)
        if self._next_target_update is None:
            self._next_target_update = self.num_timesteps + self.config.target_update_interval
        learn_loop(self, total_timesteps, callback, progress_bar, "DQN-TLQL")
        return self

    # ---- the learn loop's steps (tlac.baselines.off_policy.learn_loop)
    def collect(self, exploration_rate: float) -> None:
        """One epsilon-greedy step in every environment, stored in the replay buffer; the
        target networks' Polyak update when its interval has passed."""
        cfg, env, n = self.config, self.env, self.env.num_envs
        obs = self._last_obs
        assert obs is not None
        choices, actions = self._act(obs, exploration_rate)
        new_obs, rewards, dones, infos = env.step(actions)
        new_obs = flat_obs(new_obs, n)
        real_next, terminated = real_next_obs(new_obs, dones, infos)
        self.buffer.add(
            obs=obs,
            next_obs=real_next.reshape(n, -1),
            choice=choices,
            action=actions,
            reward=np.asarray(rewards, np.float32),
            terminated=terminated,
        )
        if self.recorder is not None:
            self.recorder.record_selections(self.num_timesteps + n, choices, obs)
        self._last_obs = new_obs
        self.num_timesteps += n
        self._vec_steps += 1
        if self.num_timesteps >= self._next_target_update:  # every target_update_interval
            polyak_update(self.q_high, self.q_high_target, cfg.tau)
            polyak_update(self.q_low, self.q_low_target, cfg.tau)
            self._next_target_update += cfg.target_update_interval

    def update_due(self, end: int) -> bool:
        """Every ``train_freq`` vectorised steps."""
        return self._vec_steps % self.config.train_freq == 0

    def update(self) -> None:
        """``gradient_steps`` steps on both Q-networks, once ``learning_starts`` steps are
        taken and a batch is stored."""
        cfg = self.config
        if self.num_timesteps >= cfg.learning_starts and len(self.buffer) >= cfg.batch_size:
            self._metrics = self._train(cfg.gradient_steps)

    def log_metrics(self) -> dict[str, float]:
        """The last update's mean losses of both levels."""
        return dict(self._metrics)

    # ---- inference and persistence
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, None]:
        """The student alone: ``argmax_a Q_L(s, a)`` (no teacher, no exploration; SB3's
        signature, ``deterministic`` has no effect: the student is greedy either way); one
        observation gives one action, a batch gives one per row."""
        batch, single = check_observations(observation, self.observation_space)
        x = torch.as_tensor(flat_obs(batch, len(batch)))
        with torch.no_grad():
            actions = self.q_low(x).argmax(dim=1).numpy()
        return (actions[0] if single else actions), None

    def save(
        self,
        path: str | Path,
        training_state: bool = False,
        run_state: dict[str, Any] | None = None,
    ) -> Path:
        """Write the networks, optimizers, settings and step count to ``path.pt`` and return
        that path. ``training_state``: also the replay buffer, the generators, the teachers'
        generators, the environments and the learn loop's counters, so that
        ``load(..., resume=True)`` continues exactly (``run_state``: plain data for
        ``tlac.run``, in the same file)."""
        return save_checkpoint(
            self,
            path,
            {"n_choices": self.n_choices},
            {
                name: getattr(self, name)
                for name in (
                    "q_high",
                    "q_low",
                    "q_high_target",
                    "q_low_target",
                    "opt_high",
                    "opt_low",
                )
            },
            training_state,
            run_state,
        )

    @classmethod
    def load(
        cls,
        path: str | Path,
        env: VecEnv | None = None,
        teachers: list[Any] | None = None,
        resume: bool = False,
        trust_pickle: bool = False,
    ) -> DQNTLQL:
        """Rebuild a model written by :meth:`save`; pass ``env`` (and the same teachers) to
        continue training. ``resume``: restore the training state of a file saved with
        ``training_state=True`` (the episodes in progress are re-created in ``env``), so that
        ``learn`` continues exactly where the model stopped. No code runs from the file."""
        return load_model(cls, path, env, teachers, resume, "n_choices")
