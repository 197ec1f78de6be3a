"""TL-AC's networks and what is computed from them (a mixin of
:class:`tlac.algorithms.two_level.TLAC`): the stacked high-level actor, low-level actor and
critic; their forward passes with autograd (training) and in NumPy (acting); the low level's
log-probabilities, entropies and samples; the imitation term's likelihood of every teacher's
advice; and the two ways to act: :meth:`TLACHeads.predict`, the student alone (what a user
deploys), and :meth:`TLACHeads.predict_with_teachers`, the training-time behaviour. The
algorithm itself (collect, update, learn) is in two_level.py."""

from __future__ import annotations

import copy
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from tlac.algorithms import losses
from tlac.algorithms.common import check_observations, query_teachers
from tlac.algorithms.encoding import make_encoder
from tlac.algorithms.graduation import StudentSnapshot
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
from tlac.algorithms.normalization import Normalizer
from tlac.algorithms.obs_spaces import ObsEncoder, ObsLayout, ObsPolicy, make_layout
from tlac.algorithms.optim import ForeachAdam, ForeachRMSpropTFLike
from tlac.algorithms.student_policy import StudentPolicy, student_policy
from tlac.errors import ConfigError
from tlac.memory import FLOAT_BYTES, check_fits, mlp_params, network_bytes
from tlac.presets import make_schedule
from tlac.teachers.base import advice_actions, advice_probabilities, take_rows

IMITATION_STD = 0.1
"""Box actions: the imitation term is the negative log-likelihood of the teachers' actions under
a Gaussian around the low level's mean with this fixed standard deviation, in units of the
action box's half-width (imitation does not touch the exploration noise). 1.0 left Hopper's
student alone at ~150: its imitation gradient was 100x weaker than at 0.1, far below the policy
gradient's (results/graduation-notes.md)."""

if TYPE_CHECKING:
    from tlac.algorithms.tlac_config import TLACConfig
    from tlac.selectors import Selector
    from tlac.teachers.base import Teacher
    from tlac.teachers.sb3 import FrozenObsNormalization


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


class TLACHeads:
    """The networks of TL-AC and the computations on their outputs (see the module)."""

    config: TLACConfig
    teachers: list[Teacher]
    n_teachers: int
    n_choices: int
    n_envs: int
    advice_width: int
    rng: np.random.Generator
    train_high: bool
    selector: Selector
    deployed: StudentSnapshot | None
    saved_vec_normalize: FrozenObsNormalization | None  # TLAC.load's, without a VecNormalize
    _sde_noise: np.ndarray | None
    obs_policy: ObsPolicy = ObsPolicy()  # TLAC(policy=...); a model file's own when loaded

    def _build_networks(self, obs_space: gym.Space, action_space: gym.Space) -> None:
        """The stacked networks (high, low, critic), the Box log-std, the input encoder and
        normaliser, and the imitation likelihood's scale. ``self.params``: what the optimiser
        trains."""
        cfg = self.config
        self.observation_space, self.action_space = obs_space, action_space
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
        self._extractor_params: list[nn.Parameter] = (
            []
            if self.encoder is None or not hasattr(self.encoder, "parameters")
            else self.encoder.parameters()
        )
        net_in = self.obs_dim if self.encoder is None else self.encoder.out_dim
        # "auto": normalise what the networks read raw, nothing that is encoded
        normalize_obs = always_normalize or (cfg.normalize_obs == "auto" and self.encoder is None)
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
        # and its information (Box; _advice_on)
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
        params: list[nn.Parameter] = list(self.net.parameters()) + self._extractor_params
        self.log_std: nn.Parameter | None = None
        if not self.discrete:
            shape = (cfg.net_arch_low[-1], low_out) if cfg.use_sde else (low_out,)
            self.log_std = nn.Parameter(torch.full(shape, float(cfg.log_std_init)))
            params.append(self.log_std)
        self.params = params
        # Box actions: the imitation likelihood's standard deviation per action dimension
        self._imitation_scale: torch.Tensor | None = None
        if not self.discrete:
            half = (action_space.high - action_space.low).astype(np.float64) / 2.0
            half[~np.isfinite(half) | (half <= 0)] = 1.0  # unbounded boxes: unit scale
            scale = IMITATION_STD * half.reshape(-1)
            self._imitation_scale = torch.as_tensor(scale, dtype=torch.float32)

    def _update_rows(self, obs: torch.Tensor) -> torch.Tensor:
        """The rollout's rows as :meth:`_heads` takes them, for all of an update's minibatches:
        encoded here, once per update, when the encoding has no weights (one-hot, raw parts: a
        fixed function of each row, so every minibatch sees the values its own encoding gave);
        else the rows as they are (a CNN encodes them in every pass, with autograd)."""
        if self.encoder is None or self._extractor_params:
            return obs
        return self.encoder.torch(obs)

    def _heads(
        self, x: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Training pass on rows of :meth:`_update_rows`: (high logits, low output (logits or
        Gaussian mean), value, low-level last hidden layer), with autograd."""
        out, hidden = self.net(self.encoder.torch(x) if self._extractor_params else x)
        return (
            out[HIGH, :, : self.n_choices],
            out[LOW, :, : self.net.out_dims[LOW]],
            out[CRITIC, :, 0],
            hidden[LOW, :, : self.config.net_arch_low[-1]],
        )

    def _replay_rows(self, obs: torch.Tensor) -> torch.Tensor:
        """Replayed raw observations -> rows as :meth:`_heads` takes them: normalised with the
        current statistics (as :meth:`_net_input` does for acting), then :meth:`_update_rows`."""
        if self.normalizer is not None:
            obs = self.normalizer.obs_torch(obs)
        return self._update_rows(obs)

    def _act_heads(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Acting pass: the same four heads as :meth:`_heads`, in NumPy, without autograd."""
        return self._act_heads_net(self._net_input(obs))

    def _net_input(self, obs: np.ndarray) -> np.ndarray:
        """Raw observations -> what the networks see: ``(n, obs_dim)`` float32, normalised
        with the current statistics when normalize_obs is on."""
        return self._normalized(self._flat_rows(obs))

    def _normalized(self, x: np.ndarray) -> np.ndarray:
        """Flat rows ``(n, obs_dim)`` normalised with the current statistics (normalize_obs)."""
        return x if self.normalizer is None else self.normalizer.obs_numpy(x)

    def _flat_rows(self, obs: Any) -> np.ndarray:
        """One raw observation or a batch (an array, a dict of arrays, ints) as the flat
        float32 rows ``(n, obs_dim)`` that the rollout and the advice buffer store."""
        if self.obs_layout is None:
            return np.asarray(obs, dtype=np.float32).reshape(-1, self.obs_dim)
        return self.obs_layout.flatten(obs)

    def _teacher_rows(self, rows: np.ndarray) -> Any:
        """Stored flat rows as the raw batch the teachers are given: for a Box, the rows in
        the space's shape (float32, as always); else the environment's own observations (a
        dict of arrays, ints, uint8 images: tlac.algorithms.obs_spaces.ObsLayout.unflatten)."""
        if self.obs_layout is None:
            return rows.reshape(-1, *self.observation_space.shape)
        return self.obs_layout.unflatten(rows)

    def _vec_normalized(self, obs: Any) -> Any:
        """``predict``'s observations as the networks were trained on them: normalised by the
        statistics of the ``VecNormalize`` that the model was trained under, when it was loaded
        without one (TLAC.load sets ``saved_vec_normalize``); else as they are."""
        if self.saved_vec_normalize is None or self.get_vec_normalize_env() is not None:
            return obs
        return self.saved_vec_normalize(obs)

    def _check_obs(self, obs: Any) -> tuple[Any, bool]:
        """``predict``'s observations as a raw batch, and whether it was one observation."""
        if self.obs_layout is None:
            return check_observations(obs, self.observation_space)
        return self.obs_layout.check(obs)

    def _act_heads_net(
        self, x: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`_act_heads` from the networks' input (:meth:`_net_input`)."""
        if self.encoder is not None:
            x = self.encoder.numpy(x)
        out, hidden = self.net.forward_numpy(x)
        return (
            out[HIGH, :, : self.n_choices],
            out[LOW, :, : self.net.out_dims[LOW]],
            out[CRITIC, :, 0],
            hidden[LOW, :, : self.config.net_arch_low[-1]],
        )

    def _low_log_std(self, latent: torch.Tensor) -> torch.Tensor:
        assert self.log_std is not None
        if self.config.use_sde:
            return gsde_log_std(latent, self.log_std)
        return self.log_std.expand(latent.shape[0], -1)

    def _np_low_log_std(self, latent: np.ndarray, log_std: np.ndarray | None = None) -> np.ndarray:
        """The Box log-std per row: of the live low level, or the given (a snapshot's)."""
        if log_std is None:
            log_std = self.log_std.detach().numpy()  # type: ignore[union-attr]
        if self.config.use_sde:
            return np_gsde_log_std(latent, log_std)
        return np.broadcast_to(log_std, (latent.shape[0], log_std.shape[-1]))

    def _low_log_prob(
        self, low_out: torch.Tensor, latent: torch.Tensor, actions: torch.Tensor
    ) -> torch.Tensor:
        """log pi_low(actions|s) per row (training pass)."""
        if self.discrete:
            return torch.log_softmax(low_out, dim=-1).gather(1, actions.view(-1, 1)).squeeze(1)
        return gaussian_log_prob(actions, low_out, self._low_log_std(latent))

    def _advice_on(self, obs: torch.Tensor, asked: torch.Tensor | None = None) -> torch.Tensor:
        """Every teacher's advice in every row of ``obs``, each teacher asked once for the whole
        batch. Discrete actions: its distribution over them, ``(n_teachers, n, n_actions)``
        (tlac.teachers.base.advice_probabilities: a point mass where a teacher cannot tell).
        Box actions: ``(n_teachers, n, act_dim + 1)``, the action it means and, in the last
        column, its information (tlac.teachers.base.advice_actions: its own action and 1 where
        a teacher cannot tell). ``asked`` ``(n, n_teachers)`` (limited advice): each teacher is
        asked on its rows only; elsewhere its advice is a placeholder that says nothing (the
        uniform distribution; a zero action with information 0)."""
        raw = self._teacher_rows(obs.numpy())
        n = obs.shape[0]
        if asked is not None:
            return self._advice_where_asked(raw, n, asked.numpy())
        if self.discrete:
            return torch.from_numpy(
                np.stack(
                    [advice_probabilities(t, raw, self.action_space) for t in self.teachers]
                ).astype(np.float32)
            )
        out = []
        for teacher in self.teachers:
            actions, information = advice_actions(teacher, raw, self.action_space)
            out.append(np.concatenate([actions.reshape(n, -1), information[:, None]], axis=1))
        return torch.from_numpy(np.stack(out).astype(np.float32))

    def _advice_where_asked(self, raw: Any, n: int, asked: np.ndarray) -> torch.Tensor:
        """:meth:`_advice_on` where each teacher is asked on the rows ``asked[:, k]`` only."""
        if self.discrete:
            n_actions = int(self.action_space.n)
            out = np.full((self.n_teachers, n, n_actions), 1.0 / n_actions)
        else:
            out = np.zeros((self.n_teachers, n, self.advice_width))
        for k, teacher in enumerate(self.teachers):
            rows = np.flatnonzero(asked[:, k])
            if not len(rows):
                continue
            batch = take_rows(raw, rows)
            if self.discrete:
                out[k, rows] = advice_probabilities(teacher, batch, self.action_space)
            else:
                actions, information = advice_actions(teacher, batch, self.action_space)
                out[k, rows, :-1] = actions.reshape(len(rows), -1)
                out[k, rows, -1] = information
        return torch.from_numpy(out.astype(np.float32))

    def _advice_nll(
        self, low_out: torch.Tensor, latent: torch.Tensor, advice: torch.Tensor
    ) -> torch.Tensor:
        """``(n_teachers, B)``: how far pi_low is from each teacher's advice in each row. Discrete:
        the cross-entropy from the teacher's distribution, ``-sum_a pi_k(a|s) log pi_low(a|s)``;
        Box: half the mean squared distance between the low level's mean and the teacher's
        action, in units of :data:`IMITATION_STD` times the action box's half-width: a
        fixed-variance Gaussian likelihood, so that imitation does not shrink the exploration
        noise."""
        if self.discrete:
            return -(advice * torch.log_softmax(low_out, -1).unsqueeze(0)).sum(-1)
        return losses.scaled_squared_error(low_out, advice, self._imitation_scale)

    def _imitation_term(
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
        return losses.imitation_loss(self._advice_nll(low_out, latent, advice), trust)

    def _mean_entropies(
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
            low = gaussian_entropy(self._low_log_std(latent)).mean()
        if not self.train_high:
            return low[None]
        high = categorical_entropy(torch.log_softmax(high_logits, -1))
        if cap_high is not None:
            high = high.clamp(max=cap_high)
        return torch.stack([low, high.mean()])

    def _np_low_log_prob(
        self, low_out: np.ndarray, latent: np.ndarray, actions: np.ndarray
    ) -> np.ndarray:
        """log pi_low(actions|s) at collection time (acting pass)."""
        if self.discrete:
            return np_log_softmax(low_out)[np.arange(len(actions)), actions]
        return np_gaussian_log_prob(actions, low_out, self._np_low_log_std(latent))

    def _sample_low(self, low_out: np.ndarray, latent: np.ndarray) -> np.ndarray:
        """A sample of pi_low(.|s) per row (Algorithm 1, line 16)."""
        if self.discrete:
            return np_sample_categorical(low_out, self.rng)
        if self.config.use_sde:
            if self._sde_noise is None or len(self._sde_noise) < len(latent):
                self._resample_sde_noise(len(latent))
            # one exploration matrix per environment: noise = latent @ eps_matrix
            return low_out + np.matmul(latent[:, None, :], self._sde_noise[: len(latent)])[:, 0]
        log_std = self.log_std.detach().numpy()  # type: ignore[union-attr]
        return low_out + self.rng.standard_normal(low_out.shape).astype(np.float32) * np.exp(
            log_std
        )

    def _student_heads(self, obs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """The deployed student's (low output, last hidden layer, Box log-std or None) on raw
        observations: the kept snapshot (solo episodes) where there is one, else the
        live low level."""
        snap = self.deployed
        if snap is None:
            _, low_out, _, latent = self._act_heads(obs)
            return low_out, latent, None
        x = snap.net_input(self._flat_rows(obs))
        encoder = self.encoder if snap.encoder is None else snap.encoder  # its own CNN, if any
        out, hidden = snap.forward(x if encoder is None else encoder.numpy(x))
        return (
            out[:, : self.net.out_dims[LOW]],
            hidden[:, : self.config.net_arch_low[-1]],
            snap.log_std,
        )

    def _snapshot_student(self) -> StudentSnapshot:
        """A frozen copy of the live student (what :meth:`predict` deploys)."""
        return StudentSnapshot(
            self.net.member_numpy(LOW),
            None if self.log_std is None else self.log_std.detach().numpy().copy(),
            copy.deepcopy(self.normalizer),
            self.num_timesteps,
            self.encoder.frozen_copy() if self._extractor_params else None,
        )

    def _greedy_low(self, low_out: np.ndarray) -> np.ndarray:
        """pi_low's most likely action per row: the argmax, or the Gaussian's mean."""
        return low_out.argmax(-1) if self.discrete else low_out

    def _resample_sde_noise(self, n: int | None = None) -> None:
        assert self.log_std is not None
        std = np.exp(self.log_std.detach().numpy())
        self._sde_noise = (self.rng.standard_normal((n or self.n_envs, *std.shape)) * std).astype(
            np.float32
        )

    def _to_env_actions(self, actions: np.ndarray) -> np.ndarray:
        if self.discrete:
            return actions
        # as SB3 does for unsquashed Gaussians: the stored action keeps its sampled value,
        # the environment receives it clipped to the box
        return np.clip(actions, self.action_space.low, self.action_space.high)

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, None]:
        """Actions of the low-level policy alone (no teacher), with SB3's signature and
        defaults: ``(actions, None)``, sampled unless ``deterministic`` (the greedy student,
        which tlac's evaluations and targets use); one observation gives one action, a batch
        ``(n, *obs_shape)`` gives ``n`` actions."""
        obs, single = self._check_obs(observation)
        low_out, latent, log_std = self._student_heads(self._vec_normalized(obs))
        if deterministic:
            actions = self._greedy_low(low_out)
        elif self.discrete:
            actions = np_sample_categorical(low_out, self.rng)
        else:
            noise = self.rng.standard_normal(low_out.shape) * np.exp(
                self._np_low_log_std(latent, log_std)
            )
            actions = low_out + noise.astype(np.float32)
        env_actions = self._to_env_actions(actions)
        return (env_actions[0] if single else env_actions), None

    @property
    def policy(self) -> StudentPolicy:
        """The student that :meth:`predict` deploys now, as a torch module (SB3's
        ``model.policy``, for its ONNX export recipe or ``torch.jit.trace``): raw observations
        -> the normalisation ``predict`` applies -> the low level's logits (Discrete) or mean
        (Box); ``policy.predict`` is SB3's. A copy: take it again after training
        (tlac.algorithms.student_policy)."""
        return student_policy(self)

    def predict_with_teachers(self, obs: np.ndarray, deterministic: bool = False) -> np.ndarray:
        """The training-time behaviour: the high level picks a teacher or the agent per row.
        With ``deterministic`` the high level and the agent take their most likely choice."""
        if not self.teachers:
            return self.predict(obs, deterministic=deterministic)[0]
        obs = self._check_obs(obs)[0]
        high_logits, low_out, _, latent = self._act_heads(self._vec_normalized(obs))
        choices = self.selector.evaluation_choices(high_logits, deterministic)
        if deterministic:
            actions = low_out.argmax(-1) if self.discrete else low_out.copy()
        else:
            actions = self._sample_low(low_out, latent)
        return self._to_env_actions(self._apply_teachers(choices, obs, actions))

    def _apply_teachers(
        self, choices: np.ndarray, obs: np.ndarray, actions: np.ndarray
    ) -> np.ndarray:
        """Replace the agent's action by the chosen teacher's in every row (Algorithm 1, line 18).
        A teacher is queried only for the rows where it was chosen."""
        query_teachers(self.teachers, choices, obs, self.action_space, actions)
        return actions


def make_optimizer(cfg: TLACConfig, params: list[nn.Parameter]) -> torch.optim.Optimizer:
    """The optimiser of all three networks: SB3's RMSpropTFLike (the paper's Table 5) or Adam,
    at the learning rate's starting value (``learn`` sets it per update from its schedule),
    each stepped with one call per operation (tlac.algorithms.optim)."""
    lr0 = make_schedule(cfg.learning_rate, "learning_rate")(1.0)
    if cfg.optimizer == "adam":
        return ForeachAdam(params, lr=lr0, eps=cfg.optimizer_eps, foreach=True)
    return ForeachRMSpropTFLike(params, lr=lr0, alpha=0.99, eps=cfg.optimizer_eps)  # A2C's alpha
