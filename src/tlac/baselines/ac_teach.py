"""AC-Teach (Kurenkov, Mandlekar, Martin-Martin, Savarese and Garg, CoRL 2019).

Rebuilt from the public implementation (github.com/StanfordVL/ac-teach, files
``src/rl_with_teachers/learners.py`` and ``behavior_policies.py``) and the facts gathered in
``baselines-and-domains.md``; decisions where the sources were unclear are listed in
``docs/baselines/ac-teach.md``.

Continuous actions (``Box``; the original method):

* learner: DDPG. Actor MLP [64, 64, 64] with LayerNorm and ReLU, ``tanh`` output, loss
  ``-mean_k Q_k(s, pi(s)) + action_l2 * mean(pi(s)^2)`` (the mean over ``mc_samples`` dropout
  samples, as the code's ``critic_with_actor_tf_mc_avg``);
* Bayesian critic: MLP [64, 64, 64], LayerNorm, ReLU, dropout after every hidden activation
  (keep probability 0.9), the action concatenated after the first hidden layer; trained with
  the black-box alpha-divergence loss (alpha 0.5, precision ``dropout_tau`` 10) over 50
  dropout samples (:func:`alpha_divergence_loss`) plus the dropout weight decay
  (:func:`dropout_weight_decay`); its target uses the deterministic (no dropout) pass;
* behaviour policy: Thompson sampling over the learner's noisy action and each teacher's
  action, one dropout sample of ``Q`` each, with commitment (:func:`switch_probability`,
  :func:`commitment_decision`);
* "meta target": ``y = r + gamma * Q_target(s', a*)``, ``a*`` the best of ``{actor(s'),
  teachers(s')}`` under the online critic's deterministic pass.

Discrete actions (DoorKey): an ADAPTATION (AC-Teach is continuous-only; the TL-AC paper does
not say how it ran it on DoorKey). The critic outputs ``Q(s, .)`` over the actions (same
body, same dropout and loss), the learner is the epsilon-greedy policy of the critic's
deterministic pass, the "target actor" is the greedy policy of the target critic, and the
behaviour policy and meta target are unchanged.

Choices are numbered like every tlac algorithm: teachers ``0..N-1``, the learner ``N``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
    polyak_update,
    real_next_obs,
    stop_if_not_finite,
)
from tlac.baselines.off_policy import ReplayBuffer, learn_loop, load_model, save_checkpoint
from tlac.errors import ConfigError
from tlac.recording import Recorder
from tlac.teachers.base import ask_teacher
from tlac.validation import Checks

SWITCH_SIGNS = ("paper", "code")


# --------------------------------------------------------------------------- pure math
def switch_probability(
    mean_current: float,
    var_current: float,
    mean_new: float,
    var_new: float,
    dropout_tau: float,
    sign: str = "paper",
) -> float:
    """Probability used to decide a switch from the followed policy to the Thompson argmax.

    Both Q estimates are treated as independent Gaussians (MC-dropout mean and variance), the
    variance of their difference being ``var_current + var_new + 1 / dropout_tau`` (the
    model's observation noise, AC-Teach ``behavior_policies.py``). ``sign="paper"`` returns
    ``P(Q_new > Q_current) = Phi((mean_new - mean_current) / sd)``, what the paper and the
    code's comment describe; ``sign="code"`` reproduces the public code's formula, which
    computes ``P(Q_current > Q_new)`` (including its ``1e-12`` offset).

    >>> round(switch_probability(1.0, 0.0, 1.0, 0.0, 10.0), 6)
    0.5
    >>> p = switch_probability(0.0, 0.05, 1.0, 0.05, 10.0)   # sd = sqrt(0.2)
    >>> round(p, 4), round(switch_probability(0.0, 0.05, 1.0, 0.05, 10.0, "code"), 4)
    (0.9873, 0.0127)
    """
    if sign not in SWITCH_SIGNS:
        raise ConfigError(f"switch_sign: expected one of {', '.join(SWITCH_SIGNS)}, got {sign!r}")
    var = var_current + var_new + 1.0 / dropout_tau
    if sign == "paper":
        return 0.5 * (1.0 + math.erf((mean_new - mean_current) / math.sqrt(2.0 * var)))
    # the code: diff_mean = current - new; 1 - (1 + erf((0 - diff_mean + 1e-12) / sqrt(2 var))) / 2
    diff_mean = mean_current - mean_new
    return 1.0 - (1.0 + math.erf((0.0 - diff_mean + 1e-12) / math.sqrt(2.0 * var))) / 2.0


def commitment_threshold(threshold: float, decay: float, n_declined: int) -> float:
    """Confidence needed to switch after ``n_declined`` declined switches: ``threshold *
    decay ** n`` (AC-Teach: 0.6 and 0.99; ``decay = 1`` is the "no commitment decay" ablation).

    >>> commitment_threshold(0.6, 0.99, 0), round(commitment_threshold(0.6, 0.99, 10), 6)
    (0.6, 0.542629)
    """
    return threshold * decay**n_declined


def commitment_decision(
    current: int,
    proposed: int,
    prob_better: float,
    threshold: float,
    decay: float,
    n_declined: int,
    commitment: bool = True,
) -> tuple[int, int]:
    """One step of "Thompson sampling with commitment". Returns ``(choice, n_declined)``.

    ``current`` is the policy followed at the previous step (``-1`` at an episode start),
    ``proposed`` the argmax of the Thompson samples. As in the public code: at an episode
    start, without commitment, or when ``proposed == current`` the proposal is taken and the
    counter is unchanged; otherwise the switch happens iff ``prob_better`` exceeds
    :func:`commitment_threshold` (counter reset to 0), else the followed policy is kept and
    the counter grows by one. So ``n`` counts declined switches since the last switch.

    >>> commitment_decision(-1, 2, 0.0, 0.6, 0.99, 0)      # episode start
    (2, 0)
    >>> commitment_decision(0, 2, 0.55, 0.6, 0.99, 0)     # not confident enough: stay
    (0, 1)
    >>> commitment_decision(0, 2, 0.55, 0.6, 0.99, 10)    # 0.55 > 0.6 * 0.99**10: switch
    (2, 0)
    """
    if current < 0 or not commitment or proposed == current:
        return proposed, n_declined
    if prob_better > commitment_threshold(threshold, decay, n_declined):
        return proposed, 0
    return current, n_declined + 1


def alpha_divergence_loss(
    q_samples: torch.Tensor, target: torch.Tensor, alpha: float, tau: float
) -> torch.Tensor:
    """Black-box alpha-divergence loss with MC dropout (Li and Gal 2017, eq. 10), AC-Teach's
    critic loss: per transition ``-1/alpha * (logsumexp_k(-alpha * tau / 2 * (y - q_k)^2) -
    log K)``, averaged over the batch. ``q_samples``: ``(K, B)``; ``target``: ``(B,)``.
    (The code omits the constant ``log K`` and sums over the batch; see the docs page.)
    When all ``K`` samples agree it equals ``tau / 2 * (y - q)^2``.
    """
    k = q_samples.shape[0]
    scaled = -0.5 * alpha * tau * (target.unsqueeze(0) - q_samples) ** 2
    return (-(torch.logsumexp(scaled, dim=0) - math.log(k)) / alpha).mean()


def dropout_weight_decay(
    keep_prob: float, length_scale: float, dataset_size: float, tau: float
) -> float:
    """L2 coefficient of the critic's weights for MC dropout (Gal and Ghahramani 2016, eq. 7):
    ``keep_prob * length_scale^2 / (2 * N * tau)`` (AC-Teach: N = total training steps).

    >>> round(dropout_weight_decay(0.9, 0.01, 1e6, 10.0), 18)
    4.5e-12
    """
    return keep_prob * length_scale**2 / (2.0 * dataset_size * tau)


# --------------------------------------------------------------------------- networks
def dropout_mask(
    rng: np.random.Generator, shape: tuple[int, ...], keep_prob: float
) -> torch.Tensor:
    """An inverted-dropout mask of ``shape``: each element ``1 / keep_prob`` with probability
    ``keep_prob`` (32 random bits from ``rng`` compared with ``keep_prob * 2**32``), else 0.

    The same masks as ``F.dropout(h, 1 - keep_prob)`` in distribution, about 5x faster on one
    CPU core than torch's per-element Bernoulli draws, which took a third of AC-Teach's time.

    >>> m = dropout_mask(np.random.default_rng(0), (1000, 100), 0.9)
    >>> m.shape, torch.unique(m).tolist() == [0.0, np.float32(1 / 0.9)]
    (torch.Size([1000, 100]), True)
    >>> round(float((m > 0).float().mean()), 2)
    0.9
    """
    n = math.prod(shape)
    if keep_prob >= 1.0:
        return torch.ones(shape)
    bits = rng.bit_generator.random_raw((n + 1) // 2).view(np.uint32)[:n]
    keep = bits < np.uint32(min(round(keep_prob * 2**32), 2**32 - 1))
    return torch.from_numpy(np.multiply(keep, np.float32(1.0 / keep_prob))).view(shape)


class BayesianCritic(nn.Module):
    """AC-Teach's critic: Linear + LayerNorm + ReLU per hidden layer, dropout after every
    hidden activation in the MC passes only, the action (if any) concatenated after the first
    hidden layer, a final linear layer initialised in ``U(-3e-3, 3e-3)``.

    ``forward(obs, action, samples=0)`` is the deterministic pass ``(B, out)``;
    ``samples=K`` gives ``K`` dropout samples ``(K, B, out)`` with independent masks, drawn
    from ``rng`` (:func:`dropout_mask`; AC-Teach passes its own generator, so that a seed
    fixes them and a checkpoint resumes them)."""

    def __init__(
        self,
        obs_dim: int,
        action_dim: int,
        out_dim: int,
        hidden: list[int],
        keep_prob: float,
        layer_norm: bool = True,
        rng: np.random.Generator | None = None,
    ):
        super().__init__()
        self.keep_prob = keep_prob
        self.rng = np.random.default_rng() if rng is None else rng
        self.linears = nn.ModuleList()
        self.norms = nn.ModuleList()
        last = obs_dim
        for i, h in enumerate(hidden):
            self.linears.append(nn.Linear(last, h))
            self.norms.append(nn.LayerNorm(h) if layer_norm else nn.Identity())
            last = h + (action_dim if i == 0 else 0)
        self.out = nn.Linear(last, out_dim)
        nn.init.uniform_(self.out.weight, -3e-3, 3e-3)
        nn.init.uniform_(self.out.bias, -3e-3, 3e-3)

    def forward(
        self, obs: torch.Tensor, action: torch.Tensor | None = None, samples: int = 0
    ) -> torch.Tensor:
        h = obs
        for i, (lin, norm) in enumerate(zip(self.linears, self.norms, strict=True)):
            h = F.relu(norm(lin(h)))
            if samples:
                if i == 0:  # the first layer is shared by all samples; masks differ from here on
                    h = h.unsqueeze(0).expand(samples, *h.shape)
                h = h * dropout_mask(self.rng, tuple(h.shape), self.keep_prob)
            if i == 0 and action is not None:
                a = action if not samples else action.unsqueeze(0).expand(samples, *action.shape)
                h = torch.cat([h, a], dim=-1)
        return self.out(h)

    def kernels(self) -> list[torch.Tensor]:
        """The hidden layers' weight matrices (the output layer is not regularised)."""
        return [lin.weight for lin in self.linears]


class Actor(nn.Module):
    """DDPG actor: Linear + LayerNorm + ReLU per hidden layer, ``tanh`` output in [-1, 1]."""

    def __init__(self, obs_dim: int, action_dim: int, hidden: list[int], layer_norm: bool = True):
        super().__init__()
        layers: list[nn.Module] = []
        last = obs_dim
        for h in hidden:
            layers += [
                nn.Linear(last, h),
                nn.LayerNorm(h) if layer_norm else nn.Identity(),
                nn.ReLU(),
            ]
            last = h
        out = nn.Linear(last, action_dim)
        nn.init.uniform_(out.weight, -3e-3, 3e-3)
        nn.init.uniform_(out.bias, -3e-3, 3e-3)
        self.net = nn.Sequential(*layers, out, nn.Tanh())

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.net(obs)


# --------------------------------------------------------------------------- configuration
@dataclass(frozen=True)
class ACTeachConfig:
    """AC-Teach settings: the public code's pick-and-place defaults unless noted."""

    actor_lr: float = 1e-4
    """Adam step size of the actor (continuous only)."""
    critic_lr: float = 1e-3
    """Adam step size of the critic."""
    tau: float = 0.001
    """Soft target update per gradient step."""
    gamma: float = 0.99
    """Discount."""
    batch_size: int = 128
    """Minibatch size of each gradient step."""
    buffer_size: int = 1_000_000
    """Replay buffer size (transitions)."""
    cycle_env_steps: int = 200
    """Environment steps collected per cycle ("nb_rollout_steps")."""
    cycle_grad_steps: int = 50
    """Gradient steps after each cycle ("nb_train_steps")."""
    action_noise_sigma: float = 0.2
    """Gaussian exploration noise on the learner's action, in [-1, 1] units (continuous)."""
    actor_arch: list[int] = field(default_factory=lambda: [64, 64, 64])
    """Hidden layers of the actor (continuous)."""
    critic_arch: list[int] = field(default_factory=lambda: [64, 64, 64])
    """Hidden layers of the Bayesian critic."""
    layer_norm: bool = True
    """LayerNorm after every hidden linear layer of both networks."""
    dropout_keep_prob: float = 0.9
    """Keep probability of the critic's MC dropout."""
    mc_samples: int = 50
    """Monte-Carlo dropout samples for the loss, the actor loss and the switch statistics."""
    alpha: float = 0.5
    """Alpha of the black-box alpha-divergence loss."""
    dropout_tau: float = 10.0
    """Model precision tau of the dropout critic (loss and switch variance)."""
    length_scale: float = 0.01
    """Prior length scale of the dropout weight decay."""
    dataset_size: float = 1e6
    """N of the dropout weight decay (the code: ``num_timesteps_final``)."""
    action_l2: float = 0.1
    """Penalty on the actor's squared actions (continuous)."""
    obs_clip: float | None = 5.0
    """Observations are clipped to [-obs_clip, obs_clip] (``None``: no clipping)."""
    commitment: bool = True
    """Thompson sampling with commitment; ``False`` is the "no commitment" ablation."""
    commitment_threshold: float = 0.6
    """Confidence needed to switch policy right after a switch (:func:`commitment_threshold`)."""
    commitment_decay: float = 0.99
    """Threshold decay per declined switch; 1.0 is the "no commitment decay" ablation."""
    meta_target: bool = True
    """The meta target; ``False`` is the "no meta target" ablation (plain DDPG target)."""
    switch_sign: str = "paper"
    """``paper``: switch on P(Q_new > Q_cur); ``code``: the public code's P(Q_cur > Q_new)."""
    exploration_initial_eps: float = 1.0
    """Discrete adaptation: epsilon of the learner's epsilon-greedy action at the start."""
    exploration_final_eps: float = 0.01
    """Discrete adaptation: epsilon after ``exploration_fraction`` of training."""
    exploration_fraction: float = 0.1
    """Discrete adaptation: fraction of training over which epsilon decays linearly."""

    def __post_init__(self) -> None:
        check = Checks("ac-teach")
        for name in (
            "batch_size",
            "buffer_size",
            "cycle_env_steps",
            "cycle_grad_steps",
            "mc_samples",
        ):
            check.positive_int(name, getattr(self, name))
        check.one_of("switch_sign", self.switch_sign, SWITCH_SIGNS)
        for name in ("dropout_keep_prob", "tau", "commitment_decay"):
            check.number(name, getattr(self, name), 0.0, 1.0, open_low=True)
        check.number("gamma", self.gamma, 0.0, 1.0)
        for name in ("actor_lr", "critic_lr", "alpha", "dropout_tau", "dataset_size"):
            check.number(name, getattr(self, name), 0.0, open_low=True)
        if self.obs_clip is not None:
            check.number("obs_clip", self.obs_clip, 0.0, open_low=True)


# --------------------------------------------------------------------------- algorithm
class ACTeach(SB3Compat):
    """AC-Teach: DDPG (or, for Discrete actions, a Q-learning adaptation) with a Bayesian
    critic and Thompson sampling with commitment over the learner and the teachers."""

    algo = "ac-teach"
    loop_state = (
        "last_obs",
        "teacher_acts",
        "current",
        "declined",
        "switches",
        "cycle_start",
        "next_log",
        "losses",
    )
    """The learn loop's attributes (``_<name>``) that a training-state checkpoint holds."""
    exact_resume = True  # save(training_state=True) / load(resume=True)
    samples_actions = False  # predict is greedy whatever ``deterministic`` says

    @classmethod
    def check_hyperparameters(cls, hyperparameters: dict[str, Any]) -> ACTeachConfig:
        """The validated settings; a bad one raises ConfigError naming it."""
        return config_from_kwargs(ACTeachConfig, "ac-teach", hyperparameters)

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
        config: ACTeachConfig,
        env: VecEnv | None,
        teachers: list[Any] | None = None,
        seed: int = 0,
        recorder: Recorder | None = None,
    ) -> ACTeach:
        """A model of settings already validated (:meth:`check_hyperparameters`'s, as
        :func:`tlac.run.resolve_run` builds them once)."""
        model = cls.__new__(cls)
        model._start(config, env, teachers, seed, recorder)
        return model

    def _start(
        self,
        config: ACTeachConfig,
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
            self._setup(env.observation_space, env.action_space, len(self.teachers))

    # ---- construction
    def _setup(self, obs_space: gym.Space, action_space: gym.Space, n_teachers: int) -> None:
        cfg = self.config
        self.observation_space, self.action_space = obs_space, action_space
        self.obs_dim = int(np.prod(obs_space.shape))
        self.n_teachers = int(n_teachers)
        self.discrete = isinstance(action_space, gym.spaces.Discrete)
        torch.manual_seed(self.seed)
        self.rng = np.random.default_rng(self.seed)
        if self.discrete:
            self.action_dim, self.n_actions = 0, int(action_space.n)
            out_dim = self.n_actions
        elif isinstance(action_space, gym.spaces.Box) and len(action_space.shape) == 1:
            if not (
                np.all(np.isfinite(action_space.low)) and np.all(np.isfinite(action_space.high))
            ):
                raise ConfigError(f"ac-teach needs a bounded action box, got {action_space}")
            self.action_dim, self.n_actions = int(action_space.shape[0]), 0
            self._low = action_space.low.astype(np.float32)
            self._high = action_space.high.astype(np.float32)
            out_dim = 1
        else:
            raise ConfigError(
                f"ac-teach supports Discrete and 1-d Box action spaces, got {action_space}"
            )
        arch = [int(h) for h in cfg.critic_arch]
        self.critic = BayesianCritic(
            self.obs_dim,
            self.action_dim,
            out_dim,
            arch,
            cfg.dropout_keep_prob,
            cfg.layer_norm,
            rng=self.rng,  # its dropout masks come from the model's generator (saved, resumed)
        )
        self.critic_target = BayesianCritic(
            self.obs_dim, self.action_dim, out_dim, arch, cfg.dropout_keep_prob, cfg.layer_norm
        )
        self.critic_target.load_state_dict(self.critic.state_dict())
        self.critic_opt = torch.optim.Adam(self.critic.parameters(), lr=cfg.critic_lr)
        self.actor: Actor | None = None
        if not self.discrete:
            actor_arch = [int(h) for h in cfg.actor_arch]
            self.actor = Actor(self.obs_dim, self.action_dim, actor_arch, cfg.layer_norm)
            self.actor_target = Actor(self.obs_dim, self.action_dim, actor_arch, cfg.layer_norm)
            self.actor_target.load_state_dict(self.actor.state_dict())
            self.actor_opt = torch.optim.Adam(self.actor.parameters(), lr=cfg.actor_lr)
        self.weight_decay = dropout_weight_decay(
            cfg.dropout_keep_prob, cfg.length_scale, cfg.dataset_size, cfg.dropout_tau
        )
        self.buffer: ReplayBuffer | None = None  # allocated by the first learn call
        # the learn loop's state, kept across learn calls and saved with the training state
        self._last_obs: np.ndarray | None = None
        self._teacher_acts: np.ndarray | None = None  # the teachers' advice at _last_obs
        self._current: np.ndarray | None = None  # per env: the followed policy, -1 at a start
        self._declined: np.ndarray | None = None  # per env: switches declined in a row
        self._switches = 0
        self._cycle_start: int | None = None
        self._next_log: int | None = None
        self._losses: dict[str, float] = {}
        # the exploration schedule's clock (see tlac.baselines.off_policy.schedule_progress)
        self._schedule: tuple[int, int] | None = None
        self._resumed_schedule: tuple[int, int] | None = None

    # ---- action scaling (continuous): the networks work in [-1, 1]
    def _to_unit(self, actions: np.ndarray) -> np.ndarray:
        return (2.0 * (actions - self._low) / (self._high - self._low) - 1.0).astype(np.float32)

    def _to_env(self, unit: np.ndarray) -> np.ndarray:
        return (
            self._low + (np.clip(unit, -1.0, 1.0) + 1.0) * 0.5 * (self._high - self._low)
        ).astype(np.float32)

    def _clip_obs(self, obs: torch.Tensor) -> torch.Tensor:
        c = self.config.obs_clip
        return obs if c is None else obs.clamp(-c, c)

    # ---- replay buffer
    def new_buffer(self) -> ReplayBuffer:
        """An empty replay buffer of ``buffer_size`` transitions, with the teachers' advice at
        the next state (for the meta target), asked once at collection time."""
        n_t = self.n_teachers
        act_shape: tuple[int, ...] = () if self.discrete else (self.action_dim,)
        act_dtype = np.int64 if self.discrete else np.float32
        return ReplayBuffer(
            self.config.buffer_size,
            {
                "obs": ((self.obs_dim,), np.float32),
                "next_obs": ((self.obs_dim,), np.float32),
                "action": (act_shape, act_dtype),
                "reward": ((), np.float32),
                "terminated": ((), np.float32),
                "teacher_next": ((n_t, *act_shape), act_dtype),
            },
        )

    # ---- acting
    def _teacher_actions(self, obs: np.ndarray) -> np.ndarray:
        """Every teacher's advice for every row: ``(n, N)`` ints or ``(n, N, act_dim)`` in
        [-1, 1] units."""
        n = len(obs)
        if self.discrete:
            out = np.zeros((n, self.n_teachers), np.int64)
        else:
            out = np.zeros((n, self.n_teachers, self.action_dim), np.float32)
        for k, t in enumerate(self.teachers):
            a = ask_teacher(t, obs, self.action_space)
            out[:, k] = a if self.discrete else self._to_unit(a)
        return out

    def _learner_actions(self, obs_t: torch.Tensor, eps: float) -> np.ndarray:
        """The learner's exploratory actions: Gaussian noise on the actor (continuous, as the
        code's ``normal_0.2``) or epsilon-greedy on the critic (discrete adaptation)."""
        n = obs_t.shape[0]
        with torch.no_grad():
            if self.discrete:
                greedy = self.critic(obs_t).argmax(dim=1).numpy()
                rand = self.rng.integers(0, self.n_actions, size=n)
                return np.where(self.rng.random(n) < eps, rand, greedy)
            assert self.actor is not None
            a = self.actor(obs_t).numpy()
        noise = self.rng.normal(0.0, self.config.action_noise_sigma, size=a.shape)
        return np.clip(a + noise, -1.0, 1.0).astype(np.float32)

    def _candidate_samples(self, obs_t: torch.Tensor, candidates: np.ndarray) -> torch.Tensor:
        """Dropout samples of Q for every candidate: ``(K + C, n, C)``. Rows ``0..K-1`` give
        the switch statistics; row ``K + c`` is candidate ``c``'s Thompson sample, drawn with
        its own masks (the code draws each candidate's sample separately)."""
        k = self.config.mc_samples
        n, c = candidates.shape[:2]
        with torch.no_grad():
            if self.discrete:
                q = self.critic(obs_t, samples=k + c)  # (K + C, n, A)
                idx = torch.as_tensor(candidates).unsqueeze(0).expand(k + c, n, c)
                return q.gather(2, idx)
            obs_rep = obs_t.unsqueeze(1).expand(n, c, obs_t.shape[1]).reshape(n * c, -1)
            acts = torch.as_tensor(candidates).reshape(n * c, -1)
            return self.critic(obs_rep, acts, samples=k + c).reshape(k + c, n, c)

    def _behaviour(
        self, obs: np.ndarray, teacher_acts: np.ndarray, eps: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Thompson sampling with commitment (AC-Teach ``ACTeachBehaviorPolicy``) for every
        environment; returns the choices and the candidates' actions."""
        cfg = self.config
        obs_t = self._clip_obs(torch.as_tensor(obs))
        learner = self._learner_actions(obs_t, eps)
        n, c = len(obs), self.n_teachers + 1
        if self.discrete:
            candidates = np.concatenate([teacher_acts, learner[:, None]], axis=1)
        else:
            candidates = np.concatenate([teacher_acts, learner[:, None, :]], axis=1)
        if self.n_teachers == 0:
            return np.full(n, self.n_teachers), candidates
        q = self._candidate_samples(obs_t, candidates).numpy()
        k = cfg.mc_samples
        thompson = q[k + np.arange(c), :, np.arange(c)].T  # (n, C): candidate c's own sample
        means, variances = q[:k].mean(axis=0), q[:k].var(axis=0)  # (n, C)
        choices = np.zeros(n, dtype=np.int64)
        for i in range(n):
            proposed = int(np.argmax(thompson[i]))
            current = int(self._current[i])
            prob = 0.0
            if current >= 0 and proposed != current and cfg.commitment:
                prob = switch_probability(
                    float(means[i, current]),
                    float(variances[i, current]),
                    float(means[i, proposed]),
                    float(variances[i, proposed]),
                    cfg.dropout_tau,
                    cfg.switch_sign,
                )
            choice, self._declined[i] = commitment_decision(
                current,
                proposed,
                prob,
                cfg.commitment_threshold,
                cfg.commitment_decay,
                int(self._declined[i]),
                cfg.commitment,
            )
            choices[i] = choice
            self._switches += int(current >= 0 and choice != current)
        self._current[:] = choices
        return choices, candidates

    # ---- learning
    def _critic_target(self, batch: dict[str, torch.Tensor]) -> torch.Tensor:
        """``y = r + gamma * (1 - terminated) * Q_target(s', a*)`` (deterministic passes)."""
        cfg = self.config
        nxt = batch["next_obs"]
        with torch.no_grad():
            if self.discrete:
                if cfg.meta_target and self.n_teachers:
                    q_online = self.critic(nxt)  # (B, A)
                    cands = torch.cat(
                        [q_online.argmax(dim=1, keepdim=True), batch["teacher_next"]], dim=1
                    )
                    best = q_online.gather(1, cands).argmax(dim=1, keepdim=True)
                    a_star = cands.gather(1, best)
                else:  # the greedy policy of the target critic plays DDPG's target actor
                    a_star = self.critic_target(nxt).argmax(dim=1, keepdim=True)
                q_next = self.critic_target(nxt).gather(1, a_star).squeeze(1)
            else:
                assert self.actor is not None
                if cfg.meta_target and self.n_teachers:
                    cands = torch.cat(
                        [self.actor(nxt).unsqueeze(1), batch["teacher_next"]], dim=1
                    )  # (B, C, d)
                    b, c, d = cands.shape
                    q_c = self.critic(
                        nxt.unsqueeze(1).expand(b, c, nxt.shape[1]).reshape(b * c, -1),
                        cands.reshape(b * c, d),
                    ).reshape(b, c)
                    a_star = cands[torch.arange(b), q_c.argmax(dim=1)]
                else:
                    a_star = self.actor_target(nxt)
                q_next = self.critic_target(nxt, a_star).squeeze(1)
            return batch["reward"] + cfg.gamma * (1.0 - batch["terminated"]) * q_next

    def _train_step(self) -> dict[str, float]:
        cfg = self.config
        assert self.buffer is not None
        batch = self.buffer.sample(self.rng, cfg.batch_size)
        batch["obs"] = self._clip_obs(batch["obs"])
        batch["next_obs"] = self._clip_obs(batch["next_obs"])
        y = self._critic_target(batch)
        out: dict[str, float] = {}
        if self.actor is not None:
            # actor and critic gradients from the same parameters (as the code's single sess.run)
            pi = self.actor(batch["obs"])
            q_pi = self.critic(batch["obs"], pi, samples=cfg.mc_samples).mean(dim=0)
            actor_loss = -q_pi.mean() + cfg.action_l2 * (pi**2).mean()
            self.actor_opt.zero_grad()
            actor_loss.backward()
            out["train/actor_loss"] = float(actor_loss.detach())
        if self.discrete:
            q = self.critic(batch["obs"], samples=cfg.mc_samples)  # (K, B, A)
            a = batch["action"].view(1, -1, 1).expand(cfg.mc_samples, -1, 1)
            q_taken = q.gather(2, a).squeeze(2)
        else:
            q_taken = self.critic(batch["obs"], batch["action"], samples=cfg.mc_samples).squeeze(2)
        critic_loss = alpha_divergence_loss(q_taken, y, cfg.alpha, cfg.dropout_tau)
        critic_loss = critic_loss + self.weight_decay * sum(
            (w**2).sum() for w in self.critic.kernels()
        )
        self.critic_opt.zero_grad()
        critic_loss.backward()
        stop_if_not_finite(critic_loss.detach(), "ac-teach", self.num_timesteps, "critic loss")
        if self.actor is not None:
            stop_if_not_finite(actor_loss.detach(), "ac-teach", self.num_timesteps, "actor loss")
        self.critic_opt.step()
        if self.actor is not None:
            self.actor_opt.step()
            polyak_update(self.actor, self.actor_target, cfg.tau)
        polyak_update(self.critic, self.critic_target, cfg.tau)
        out["train/critic_loss"] = float(critic_loss.detach())
        return out

    def learn(
        self,
        total_timesteps: int,
        callback: Any = None,
        progress_bar: bool = False,
    ) -> ACTeach:
        """Cycles of ``cycle_env_steps`` environment steps with the behaviour policy, then
        ``cycle_grad_steps`` gradient steps, for ``total_timesteps`` steps over all envs.
        ``callback``: a function ``f(model)`` run after every cycle (``False`` stops), an SB3
        ``BaseCallback`` or a list (``tlac.algorithms.callbacks``)."""
        check_total_timesteps(total_timesteps)  # before anything is reset or allocated
        if self.env is None:
            raise ConfigError(
                "ac-teach: learn() needs an environment; load(path, env=...) to continue training"
            )
        if len(self.teachers) != self.n_teachers:
            raise ConfigError(
                f"ac-teach: the model was built for {self.n_teachers} teachers, "
                f"got {len(self.teachers)}"
            )
        if self.buffer is None:
            self.buffer = self.new_buffer()
        if self._last_obs is None:
            n = self.env.num_envs
            self._current = np.full(n, -1, dtype=np.int64)
            self._declined = np.zeros(n, dtype=np.int64)
            self._last_obs = flat_obs(self.env.reset(), n)
            self._teacher_acts = self._teacher_actions(self._last_obs)
        if self._cycle_start is None:
            self._cycle_start = self.num_timesteps
        learn_loop(self, total_timesteps, callback, progress_bar, "AC-Teach")
        return self

    # ---- the learn loop's steps (tlac.baselines.off_policy.learn_loop)
    def collect(self, exploration_rate: float) -> None:
        """One step of the behaviour policy in every environment, stored in the replay buffer
        with the teachers' advice at the next state."""
        cfg, env, n = self.config, self.env, self.env.num_envs
        obs, teacher_acts = self._last_obs, self._teacher_acts
        assert obs is not None and teacher_acts is not None and self.buffer is not None
        choices, candidates = self._behaviour(obs, teacher_acts, exploration_rate)
        unit_actions = candidates[np.arange(n), choices]
        env_actions = unit_actions if self.discrete else self._to_env(unit_actions)
        new_obs, rewards, dones, infos = env.step(env_actions)
        new_obs = flat_obs(new_obs, n)
        real_next, terminated = real_next_obs(new_obs, dones, infos)
        real_next = real_next.reshape(n, -1)
        new_teacher_acts = self._teacher_actions(new_obs)
        teacher_next = new_teacher_acts.copy()
        if dones.any() and self.n_teachers and cfg.meta_target:
            d = np.flatnonzero(dones)
            teacher_next[d] = self._teacher_actions(real_next[d])
        self.buffer.add(
            obs=obs,
            next_obs=real_next,
            action=unit_actions,
            reward=np.asarray(rewards, np.float32),
            terminated=terminated,
            teacher_next=teacher_next,
        )
        if self.recorder is not None:
            self.recorder.record_selections(self.num_timesteps + n, choices, obs)
        assert self._current is not None and self._declined is not None
        self._current[dones] = -1  # AC-Teach resets the followed policy at each episode start
        self._declined[dones] = 0
        self._last_obs, self._teacher_acts = new_obs, new_teacher_acts
        self.num_timesteps += n

    def update_due(self, end: int) -> bool:
        """At the end of every cycle of ``cycle_env_steps`` steps, and of the ``learn`` call."""
        assert self._cycle_start is not None
        if (
            self.num_timesteps - self._cycle_start >= self.config.cycle_env_steps
            or self.num_timesteps >= end
        ):
            self._cycle_start = self.num_timesteps
            return True
        return False

    def update(self) -> None:
        """``cycle_grad_steps`` gradient steps, once a batch is stored."""
        cfg = self.config
        assert self.buffer is not None
        if len(self.buffer) >= cfg.batch_size:
            step_losses = [self._train_step() for _ in range(cfg.cycle_grad_steps)]
            self._losses = {k: float(np.mean([s[k] for s in step_losses])) for k in step_losses[0]}

    def log_metrics(self) -> dict[str, float]:
        """The last update's mean losses and the switches since the last log (the counter
        starts again)."""
        metrics = {**self._losses, "rollout/switches": float(self._switches)}
        self._switches = 0
        return metrics

    # ---- inference and persistence
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, None]:
        """The student alone: the actor's action (continuous) or the critic's greedy action
        (discrete), without teachers or exploration noise (SB3's signature; ``deterministic``
        has no effect, as for SB3's TD3)."""
        batch, single = check_observations(observation, self.observation_space)
        x = self._clip_obs(torch.as_tensor(flat_obs(batch, len(batch))))
        with torch.no_grad():
            if self.discrete:
                actions = self.critic(x).argmax(dim=1).numpy()
            else:
                assert self.actor is not None
                actions = self._to_env(self.actor(x).numpy())
        return (actions[0] if single else actions), None

    def save(
        self,
        path: str | Path,
        training_state: bool = False,
        run_state: dict[str, Any] | None = None,
    ) -> Path:
        """Write networks, optimizers, settings and step count to ``path.pt`` and return that
        path. ``training_state``: also the replay buffer, the generators, the teachers'
        generators, the environments and the learn loop's state (the followed policies, the
        commitment counters, the cycle), so that ``load(..., resume=True)`` continues exactly
        (``run_state``: plain data for ``tlac.run``, in the same file)."""
        modules: dict[str, Any] = {
            "critic": self.critic,
            "critic_target": self.critic_target,
            "critic_opt": self.critic_opt,
        }
        if self.actor is not None:
            modules.update(
                actor=self.actor, actor_target=self.actor_target, actor_opt=self.actor_opt
            )
        fields = {"n_teachers": self.n_teachers}
        return save_checkpoint(self, path, fields, modules, training_state, run_state)

    @classmethod
    def load(
        cls,
        path: str | Path,
        env: VecEnv | None = None,
        teachers: list[Any] | None = None,
        resume: bool = False,
        trust_pickle: bool = False,
    ) -> ACTeach:
        """Rebuild a model written by :meth:`save`; pass ``env`` and the same teachers to
        continue training (the replay buffer starts empty). ``resume``: restore the training
        state of a file saved with ``training_state=True``, replay buffer included (the
        episodes in progress are re-created in ``env``; no code runs from the file)."""
        return load_model(cls, path, env, teachers, resume, "n_teachers")
