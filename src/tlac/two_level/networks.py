"""TL-AC's networks and what is computed from them, one object the model holds
(``model.nets``): the stacked high-level actor, low-level actor and critic
(:class:`~tlac.algorithms.nets.StackedMLP`), the Box log-std, the input encoder and
normaliser; their forward passes with autograd (training) and in NumPy (acting); the low
level's log-probabilities, entropies and samples; and the imitation term's likelihood of the
teachers' advice. The algorithm (collect, update, learn) composes them
(:mod:`tlac.two_level.model`)."""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from tlac.algorithms.common import check_observations
from tlac.algorithms.encoding import make_encoder
from tlac.algorithms.nets import (
    CRITIC,
    HIGH,
    LOW,
    StackedMLP,
    categorical_entropy,
    gaussian_entropy,
    gaussian_log_prob,
    gsde_log_std,
    np_gaussian_log_prob,
    np_gsde_log_std,
    np_log_softmax,
    np_sample_categorical,
)
from tlac.algorithms.normalization import Normalizer, declares_unit_scale
from tlac.algorithms.obs_spaces import ObsEncoder, ObsLayout, ObsPolicy, make_layout
from tlac.errors import ConfigError
from tlac.memory import FLOAT_BYTES, check_fits, mlp_params, network_bytes
from tlac.two_level import losses
from tlac.two_level.graduation import StudentSnapshot

IMITATION_STD = 0.1
"""Box actions: the imitation term is the negative log-likelihood of the teachers' actions under
a Gaussian around the low level's mean with this fixed standard deviation, in units of the
action box's half-width (imitation does not touch the exploration noise). 1.0 left Hopper's
student alone at ~150: its imitation gradient was 100x weaker than at 0.1, far below the policy
gradient's (results/graduation-notes.md)."""
SATURATED = 0.05
"""Box actions: a teacher's action within this share of the box's half-width from a bound pushes
at that bound (a squashed actor, as SAC's tanh, comes near it but never reaches it), and any mean
of the low level beyond the bound copies it (losses.scaled_squared_error with ``saturated``): the
environment executes the bound either way. Fitted to the mean alone, the copy of Pendulum's
near-optimal SAC actor fell short of the bound where the actor's push flips sign, and took one
more swing in 8 episodes of 100 (results/teacher-sweep/NOTES.md, "The copy's error at the box's
bounds" and "..., ten seeds on", with its cost on the weak Pendulum suite)."""

if TYPE_CHECKING:
    from tlac.two_level.config import TLACConfig


def _check_memory(
    cfg: TLACConfig,
    net_in: int,
    obs_dim: int,
    n_envs: int,
    n_choices: int,
    low_out: int,
    n_teachers: int,
    advice_width: int,
) -> None:
    """Refuse, before anything is allocated, settings whose networks, rollout or imitation
    buffer would not fit in the memory available (a ConfigError naming the largest)."""
    hidden = [cfg.net_arch_high, cfg.net_arch_low, cfg.net_arch_critic]
    widths = [[net_in, *h, out] for h, out in zip(hidden, [n_choices, low_out, 1], strict=False)]
    depth = min(len(w) for w in widths)  # StackedMLP pads its three members to equal widths
    padded = [max(w[i] for w in widths) for i in range(depth)]
    net = 3 * mlp_params(padded[0], padded[1:-1], padded[-1])
    arch = f"{list(cfg.net_arch_high)}/{list(cfg.net_arch_low)}/{list(cfg.net_arch_critic)}"
    parts = {
        f"the networks (net_arch_high/low/critic {arch})": network_bytes(net) + FLOAT_BYTES * net,
        f"the rollout (n_steps={cfg.n_steps} x {n_envs} environments)": FLOAT_BYTES
        * cfg.n_steps
        * n_envs
        * (3 * obs_dim + 12),
    }
    if n_teachers and cfg.distill_coef != 0:
        rows = cfg.imitation_buffer_size
        parts[f"the imitation buffer (imitation_buffer_size={rows})"] = (
            FLOAT_BYTES * rows * (obs_dim + n_teachers * advice_width)
        )
    check_fits(parts, "lower that setting")


class Networks:
    """The networks of TL-AC and the computations on their outputs (see the module).

    ``n_choices``: the high level's choices (the teachers and the agent, last); ``rng``: the
    model's acting generator (pi_low's samples and the gSDE noise draw from it);
    ``train_high``: whether the high level is trained (its entropy counts).
    ``params``: what the optimiser trains, in its order: the stacked networks' weights and
    biases, the shared CNN's, the Box log-std."""

    def __init__(
        self,
        cfg: TLACConfig,
        obs_space: gym.Space,
        action_space: gym.Space,
        obs_policy: ObsPolicy,
        n_choices: int,
        n_envs: int,
        rng: np.random.Generator,
        train_high: bool,
    ) -> None:
        self.config, self.obs_policy, self.rng, self.train_high = cfg, obs_policy, rng, train_high
        self.n_choices, self.n_teachers, self.n_envs = n_choices, n_choices - 1, n_envs
        self.observation_space, self.action_space = obs_space, action_space
        self.sde_noise: np.ndarray | None = None  # gSDE: one exploration matrix per environment
        # None: a Box read as TL-AC always has; else a Discrete, Dict or image space
        # (tlac.algorithms.obs_spaces), stored as flat float32 rows of obs_dim values
        self.obs_layout: ObsLayout | None = make_layout(
            obs_space, self.obs_policy, cfg.obs_encoding
        )
        self.encoder: Any = None
        # true (NumPy's bool too) asks for normalisation wherever; "auto" only where read raw
        always_normalize = cfg.normalize_obs != "auto" and bool(cfg.normalize_obs)
        if self.obs_layout is None:
            self.obs_dim = int(np.prod(obs_space.shape))
            self.encoder = make_encoder(cfg.obs_encoding, obs_space)
            if always_normalize and self.encoder is not None:
                raise ConfigError(
                    "normalize_obs needs raw observations, but obs_encoding "
                    f"{cfg.obs_encoding!r} one-hot encodes this space; set obs_encoding: raw"
                )
        else:
            self.obs_dim = self.obs_layout.dim
            if any(p.kind != "raw" for p in self.obs_layout.parts):  # else the identity
                self.encoder = ObsEncoder(self.obs_layout, self.obs_policy, cfg.ortho_init_low)
            if always_normalize and self.encoder is not None:
                raise ConfigError(
                    "normalize_obs needs raw observations, but this observation space is read "
                    f"one-hot (Discrete) or as an image: {obs_space}"
                )
        # the shared features extractor's weights (NatureCNN), trained with the networks
        self.extractor_params: list[nn.Parameter] = (
            []
            if self.encoder is None or not hasattr(self.encoder, "parameters")
            else self.encoder.parameters()
        )
        net_in = self.obs_dim if self.encoder is None else self.encoder.out_dim
        # "auto": normalise what the networks read raw, nothing that is encoded, and no Box
        # whose bounds already declare every coordinate on a unit scale (Pendulum's)
        normalize_obs = always_normalize or (
            cfg.normalize_obs == "auto"
            and self.encoder is None
            and not (self.obs_layout is None and declares_unit_scale(obs_space))
        )
        self.normalizer: Normalizer | None = None
        if normalize_obs or cfg.normalize_reward:
            self.normalizer = Normalizer(
                self.obs_dim,
                self.n_envs,
                cfg.gamma,
                normalize_obs,
                cfg.normalize_reward,
            )
        self.discrete = isinstance(action_space, gym.spaces.Discrete)
        if self.discrete:
            low_out = int(action_space.n)
        elif isinstance(action_space, gym.spaces.Box):
            low_out = int(np.prod(action_space.shape))
        else:
            raise ConfigError(f"TL-AC supports Discrete and Box action spaces, got {action_space}")
        if cfg.use_sde and self.discrete:
            raise ConfigError("use_sde applies to Box action spaces only")
        # one teacher's advice in one state: a distribution (discrete), or the action it means
        # and its information (Box; tlac.two_level.labels.advice_on)
        self.advice_width = low_out + (0 if self.discrete else 1)
        _check_memory(
            cfg,
            net_in,
            self.obs_dim,
            self.n_envs,
            self.n_choices,
            low_out,
            self.n_teachers,
            self.advice_width,
        )
        self.net = StackedMLP(
            net_in,
            [list(cfg.net_arch_high), list(cfg.net_arch_low), list(cfg.net_arch_critic)],
            [self.n_choices, low_out, 1],
            ortho_init=[cfg.ortho_init_high, cfg.ortho_init_low, cfg.ortho_init_low],
            out_gains=[0.01, 0.01, 1.0],  # SB3's gains for action and value heads
        )
        params: list[nn.Parameter] = list(self.net.parameters()) + self.extractor_params
        self.log_std: nn.Parameter | None = None
        if not self.discrete:
            shape = (cfg.net_arch_low[-1], low_out) if cfg.use_sde else (low_out,)
            self.log_std = nn.Parameter(torch.full(shape, float(cfg.log_std_init)))
            params.append(self.log_std)
        self.params = params
        # Box actions: the imitation likelihood's standard deviation per action dimension
        self.imitation_scale: torch.Tensor | None = None
        self.saturated: tuple[torch.Tensor, torch.Tensor] | None = None
        if not self.discrete:
            half = (action_space.high - action_space.low).astype(np.float64) / 2.0
            bounded = np.isfinite(half) & (half > 0)
            half[~bounded] = 1.0  # unbounded boxes: unit scale, no bound to push at
            scale = IMITATION_STD * half.reshape(-1)
            self.imitation_scale = torch.as_tensor(scale, dtype=torch.float32)
            margin = SATURATED * half
            low = np.where(bounded, action_space.low + margin, -np.inf).reshape(-1)
            high = np.where(bounded, action_space.high - margin, np.inf).reshape(-1)
            self.saturated = (
                torch.as_tensor(low, dtype=torch.float32),
                torch.as_tensor(high, dtype=torch.float32),
            )

    def update_rows(self, obs: torch.Tensor) -> torch.Tensor:
        """The rollout's rows as :meth:`heads` takes them, for all of an update's minibatches:
        encoded here, once per update, when the encoding has no weights (one-hot, raw parts: a
        fixed function of each row, so every minibatch sees the values its own encoding gave);
        else the rows as they are (a CNN encodes them in every pass, with autograd)."""
        if self.encoder is None or self.extractor_params:
            return obs
        return self.encoder.torch(obs)

    def heads(
        self, x: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Training pass on rows of :meth:`update_rows`: (high logits, low output (logits or
        Gaussian mean), value, low-level last hidden layer), with autograd."""
        out, hidden = self.net(self.encoder.torch(x) if self.extractor_params else x)
        return (
            out[HIGH, :, : self.n_choices],
            out[LOW, :, : self.net.out_dims[LOW]],
            out[CRITIC, :, 0],
            hidden[LOW, :, : self.config.net_arch_low[-1]],
        )

    def replay_rows(self, obs: torch.Tensor) -> torch.Tensor:
        """Replayed raw observations -> rows as :meth:`heads` takes them: normalised with the
        current statistics (as :meth:`net_input` does for acting), then :meth:`update_rows`."""
        if self.normalizer is not None:
            obs = self.normalizer.obs_torch(obs)
        return self.update_rows(obs)

    def act(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Acting pass: the same four heads as :meth:`heads`, in NumPy, without autograd."""
        return self.act_on_input(self.net_input(obs))

    def net_input(self, obs: np.ndarray) -> np.ndarray:
        """Raw observations -> what the networks see: ``(n, obs_dim)`` float32, normalised
        with the current statistics when normalize_obs is on."""
        return self.normalized(self.flat_rows(obs))

    def normalized(self, x: np.ndarray) -> np.ndarray:
        """Flat rows ``(n, obs_dim)`` normalised with the current statistics (normalize_obs)."""
        return x if self.normalizer is None else self.normalizer.obs_numpy(x)

    def flat_rows(self, obs: Any) -> np.ndarray:
        """One raw observation or a batch (an array, a dict of arrays, ints) as the flat
        float32 rows ``(n, obs_dim)`` that the rollout and the advice buffer store."""
        if self.obs_layout is None:
            return np.asarray(obs, dtype=np.float32).reshape(-1, self.obs_dim)
        return self.obs_layout.flatten(obs)

    def teacher_rows(self, rows: np.ndarray) -> Any:
        """Stored flat rows as the raw batch the teachers are given: for a Box, the rows in
        the space's shape (float32, as always); else the environment's own observations (a
        dict of arrays, ints, uint8 images: tlac.algorithms.obs_spaces.ObsLayout.unflatten)."""
        if self.obs_layout is None:
            return rows.reshape(-1, *self.observation_space.shape)
        return self.obs_layout.unflatten(rows)

    def check_obs(self, obs: Any) -> tuple[Any, bool]:
        """``predict``'s observations as a raw batch, and whether it was one observation."""
        if self.obs_layout is None:
            return check_observations(obs, self.observation_space)
        return self.obs_layout.check(obs)

    def act_on_input(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`act` from the networks' input (:meth:`net_input`)."""
        if self.encoder is not None:
            x = self.encoder.numpy(x)
        out, hidden = self.net.forward_numpy(x)
        return (
            out[HIGH, :, : self.n_choices],
            out[LOW, :, : self.net.out_dims[LOW]],
            out[CRITIC, :, 0],
            hidden[LOW, :, : self.config.net_arch_low[-1]],
        )

    def low_log_std(self, latent: torch.Tensor) -> torch.Tensor:
        assert self.log_std is not None
        if self.config.use_sde:
            return gsde_log_std(latent, self.log_std)
        return self.log_std.expand(latent.shape[0], -1)

    def np_low_log_std(self, latent: np.ndarray, log_std: np.ndarray | None = None) -> np.ndarray:
        """The Box log-std per row: of the live low level, or the given (a snapshot's)."""
        if log_std is None:
            log_std = self.log_std.detach().numpy()  # type: ignore[union-attr]
        if self.config.use_sde:
            return np_gsde_log_std(latent, log_std)
        return np.broadcast_to(log_std, (latent.shape[0], log_std.shape[-1]))

    def low_log_prob(
        self, low_out: torch.Tensor, latent: torch.Tensor, actions: torch.Tensor
    ) -> torch.Tensor:
        """log pi_low(actions|s) per row (training pass)."""
        if self.discrete:
            return torch.log_softmax(low_out, dim=-1).gather(1, actions.view(-1, 1)).squeeze(1)
        return gaussian_log_prob(actions, low_out, self.low_log_std(latent))

    def advice_nll(
        self, low_out: torch.Tensor, latent: torch.Tensor, advice: torch.Tensor
    ) -> torch.Tensor:
        """``(n_teachers, B)``: how far pi_low is from each teacher's advice in each row. Discrete:
        the cross-entropy from the teacher's distribution, ``-sum_a pi_k(a|s) log pi_low(a|s)``;
        Box: half the mean squared distance between the low level's mean and the teacher's
        action, in units of :data:`IMITATION_STD` times the action box's half-width: a
        fixed-variance Gaussian likelihood, so that imitation does not shrink the exploration
        noise; an action that pushes at a bound is met by any mean beyond it (:data:`SATURATED`)."""
        if self.discrete:
            return -(advice * torch.log_softmax(low_out, -1).unsqueeze(0)).sum(-1)
        return losses.scaled_squared_error(low_out, advice, self.imitation_scale, self.saturated)

    def advice_information(self, advice: torch.Tensor) -> torch.Tensor:
        """``(n_teachers, n)``: how much each teacher's stored advice (tlac.two_level.labels.
        advice_on) says in each row: discrete actions, losses.advice_information of its
        distribution; Box actions, the information in its last column."""
        return losses.advice_information(advice) if self.discrete else advice[..., -1]

    def imitation_term(
        self,
        high_logits: torch.Tensor,
        low_out: torch.Tensor,
        latent: torch.Tensor,
        advice: torch.Tensor,
        information: torch.Tensor | None = None,
    ) -> torch.Tensor:
        """DAgger on replayed states: each teacher's advice weighted by the high level's trust
        in that teacher (the softmax over the teachers' logits only; no gradient), re-weighted
        by how much its advice says there (losses.informative_trust, losses.reweighted_trust).
        ``advice``: the labels copied (discrete actions: losses.advice_labels of the teachers'
        distributions; Box actions: the actions they mean); ``information``: discrete actions,
        losses.advice_information of those distributions if computed already (else computed
        from ``advice``); Box actions, the teachers' information (None: all 1)."""
        trust = torch.softmax(high_logits.detach()[:, : self.n_teachers], -1)
        if self.discrete:  # advice: (K, B, A) distributions
            trust = losses.informative_trust(trust, advice, information)
        elif information is not None:  # advice: (K, B, act_dim) actions
            trust = losses.reweighted_trust(trust, information)
        return losses.imitation_loss(self.advice_nll(low_out, latent, advice), trust)

    def mean_entropies(
        self,
        high_logits: torch.Tensor,
        low_out: torch.Tensor,
        latent: torch.Tensor,
        cap_high: float | None = None,
    ) -> torch.Tensor:
        """Mean entropy of each trained level: ``[H_low]`` or ``[H_low, H_high]``; with
        ``cap_high``, each state's high-level entropy counts up to that value only."""
        if self.discrete:
            low = categorical_entropy(torch.log_softmax(low_out, -1)).mean()
        else:
            low = gaussian_entropy(self.low_log_std(latent)).mean()
        if not self.train_high:
            return low[None]
        high = categorical_entropy(torch.log_softmax(high_logits, -1))
        if cap_high is not None:
            high = high.clamp(max=cap_high)
        return torch.stack([low, high.mean()])

    def np_low_log_prob(
        self, low_out: np.ndarray, latent: np.ndarray, actions: np.ndarray
    ) -> np.ndarray:
        """log pi_low(actions|s) at collection time (acting pass)."""
        if self.discrete:
            return np_log_softmax(low_out)[np.arange(len(actions)), actions]
        return np_gaussian_log_prob(actions, low_out, self.np_low_log_std(latent))

    def sample_low(self, low_out: np.ndarray, latent: np.ndarray) -> np.ndarray:
        """A sample of pi_low(.|s) per row (Algorithm 1, line 16)."""
        if self.discrete:
            return np_sample_categorical(low_out, self.rng)
        if self.config.use_sde:
            if self.sde_noise is None or len(self.sde_noise) < len(latent):
                self.resample_sde_noise(len(latent))
            # one exploration matrix per environment: noise = latent @ eps_matrix
            return low_out + np.matmul(latent[:, None, :], self.sde_noise[: len(latent)])[:, 0]
        log_std = self.log_std.detach().numpy()  # type: ignore[union-attr]
        return low_out + self.rng.standard_normal(low_out.shape).astype(np.float32) * np.exp(
            log_std
        )

    def student_heads(
        self, obs: np.ndarray, snap: StudentSnapshot | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The deployed student's (low output, last hidden layer, Box log-std or None) on raw
        observations: the kept snapshot ``snap`` (solo episodes) where there is one, else the
        live low level."""
        if snap is None:
            _, low_out, _, latent = self.act(obs)
            return low_out, latent, None
        x = snap.net_input(self.flat_rows(obs))
        encoder = self.encoder if snap.encoder is None else snap.encoder  # its own CNN, if any
        out, hidden = snap.forward(x if encoder is None else encoder.numpy(x))
        return (
            out[:, : self.net.out_dims[LOW]],
            hidden[:, : self.config.net_arch_low[-1]],
            snap.log_std,
        )

    def student_actions(
        self, obs: Any, snap: StudentSnapshot | None, deterministic: bool
    ) -> np.ndarray:
        """``TLAC.predict``'s actions on a raw batch ``obs``: the deployed student's (the kept
        snapshot ``snap``, else the live low level), sampled from ``rng`` unless
        ``deterministic``, as the environments take them."""
        low_out, latent, log_std = self.student_heads(obs, snap)
        if deterministic:
            actions = self.greedy_low(low_out)
        elif self.discrete:
            actions = np_sample_categorical(low_out, self.rng)
        else:
            noise = self.rng.standard_normal(low_out.shape) * np.exp(
                self.np_low_log_std(latent, log_std)
            )
            actions = low_out + noise.astype(np.float32)
        return self.to_env_actions(actions)

    def snapshot_student(self, num_timesteps: int) -> StudentSnapshot:
        """A frozen copy of the live student (what ``TLAC.predict`` deploys), taken at step
        ``num_timesteps``."""
        return StudentSnapshot(
            self.net.member_numpy(LOW),
            None if self.log_std is None else self.log_std.detach().numpy().copy(),
            copy.deepcopy(self.normalizer),
            num_timesteps,
            self.encoder.frozen_copy() if self.extractor_params else None,
        )

    def greedy_low(self, low_out: np.ndarray) -> np.ndarray:
        """pi_low's most likely action per row: the argmax, or the Gaussian's mean."""
        return low_out.argmax(-1) if self.discrete else low_out

    def resample_sde_noise(self, n: int | None = None) -> None:
        """New gSDE exploration matrices, one per environment (or ``n``)."""
        assert self.log_std is not None
        std = np.exp(self.log_std.detach().numpy())
        self.sde_noise = (self.rng.standard_normal((n or self.n_envs, *std.shape)) * std).astype(
            np.float32
        )

    def to_env_actions(self, actions: np.ndarray) -> np.ndarray:
        """Actions as the environments receive them."""
        if self.discrete:
            return actions
        # as SB3 does for unsquashed Gaussians: the stored action keeps its sampled value,
        # the environment receives it clipped to the box
        return np.clip(actions, self.action_space.low, self.action_space.high)
