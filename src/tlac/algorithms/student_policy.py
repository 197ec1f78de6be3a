"""``model.policy``: the student that ``TLAC.predict`` deploys as a plain torch module, for
what SB3 users do with ``model.policy``: export it (SB3's ONNX recipe, ``torch.onnx.export``
of a module from observations to actions; ``torch.jit.trace``), or run it without tlac's
``predict``.

:class:`StudentPolicy` holds a copy of the deployed low level (the kept student, or the live
weights where there is none) and the observation normalisation it reads: the statistics of the
``VecNormalize`` a loaded model was trained under (``model.saved_vec_normalize``) and TL-AC's
own ``normalize_obs`` statistics, frozen. ``forward(obs)`` maps a batch of raw observations to
the action logits (Discrete) or the Gaussian's mean (Box, before clipping to the action box);
``predict`` is SB3's. Observations read through tlac's encoders (one-hot, Dict, images) are
not covered: their flattening runs in NumPy (``model.predict`` takes them).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from tlac.algorithms.nets import LOW, gsde_log_std
from tlac.algorithms.normalization import EPSILON
from tlac.errors import ConfigError


class StudentPolicy(nn.Module):
    """The deployed student as a torch module: raw observations ``(B, *obs_shape)`` ->
    normalised as in training -> the low level's tanh MLP -> logits or mean (``forward``).

    ``layers``: the low level's ``(weight (in, out), bias)`` pairs, trimmed to its sizes;
    ``vec_normalize``: the frozen ``VecNormalize`` statistics predict applies (a
    ``FrozenObsNormalization``) or None; ``normalizer``: TL-AC's own (``normalize_obs``) or
    None; ``log_std``: the Box Gaussian's (a gSDE matrix with ``use_sde``)."""

    def __init__(
        self,
        layers: list[tuple[np.ndarray, np.ndarray]],
        observation_space: gym.spaces.Box,
        action_space: gym.Space,
        vec_normalize: Any = None,
        normalizer: Any = None,
        log_std: np.ndarray | None = None,
        use_sde: bool = False,
    ):
        super().__init__()
        self.observation_space, self.action_space = observation_space, action_space
        self.discrete = isinstance(action_space, gym.spaces.Discrete)
        self.use_sde = use_sde
        hidden: list[nn.Module] = []
        for i, (w, b) in enumerate(layers):
            linear = nn.Linear(*w.shape)
            with torch.no_grad():
                linear.weight.copy_(torch.from_numpy(np.ascontiguousarray(w.T)))
                linear.bias.copy_(torch.from_numpy(np.asarray(b).reshape(-1)))
            hidden += [linear] if i == len(layers) - 1 else [linear, nn.Tanh()]
        self.hidden = nn.Sequential(*hidden[:-1])  # the tanh layers: the latent features
        self.head = hidden[-1]
        self.vec_normalize = vec_normalize is not None and vec_normalize.normalize
        if self.vec_normalize:  # as FrozenObsNormalization: in float64, then float32
            self.register_buffer("vec_mean", torch.from_numpy(vec_normalize.mean.reshape(-1)))
            self.register_buffer("vec_std", torch.from_numpy(vec_normalize.std.reshape(-1)))
            self.vec_clip = vec_normalize.clip
        self.normalize = normalizer is not None and normalizer.normalize_obs
        if self.normalize:  # as Normalizer.obs_numpy, in float32
            rms = normalizer.obs_rms
            self.register_buffer("obs_mean", torch.from_numpy(rms.mean.astype(np.float32)))
            std = np.sqrt(rms.var + EPSILON).astype(np.float32)
            self.register_buffer("obs_std", torch.from_numpy(std))
            self.obs_clip = normalizer.clip
        if log_std is not None:
            self.register_buffer("log_std", torch.from_numpy(np.array(log_std, np.float32)))

    def _heads(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``(logits or mean, the last hidden layer)`` of a batch of raw observations."""
        x = obs.reshape(obs.shape[0], -1).float()
        if self.vec_normalize:
            x = ((x.double() - self.vec_mean) / self.vec_std).clamp(-self.vec_clip, self.vec_clip)
            x = x.float()
        if self.normalize:
            x = ((x - self.obs_mean) / self.obs_std).clamp(-self.obs_clip, self.obs_clip)
        latent = self.hidden(x)
        return self.head(latent), latent

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """The action logits (Discrete) or the Gaussian's mean (Box) of raw observations
        ``(B, *obs_shape)``: the greedy action is their argmax, or the mean clipped to the
        action box."""
        return self._heads(obs)[0]

    @torch.no_grad()
    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, None]:
        """SB3's ``policy.predict``: ``(actions, None)`` for one raw observation or a batch,
        sampled (from torch's generator) unless ``deterministic``; Box actions are clipped to
        the action box, as the environment receives them."""
        obs = np.asarray(observation)
        single = obs.shape == self.observation_space.shape
        batch = torch.from_numpy(
            np.ascontiguousarray(obs.reshape(-1, *self.observation_space.shape))
        )
        out, latent = self._heads(batch)
        if self.discrete:
            if deterministic:
                actions = out.argmax(-1)
            else:
                actions = torch.distributions.Categorical(logits=out).sample()
        else:
            actions = out
            if not deterministic:
                log_std = (
                    gsde_log_std(latent, self.log_std)
                    if self.use_sde
                    else self.log_std.expand_as(out)
                )
                actions = out + torch.randn_like(out) * log_std.exp()
            low, high = self.action_space.low, self.action_space.high
            actions = torch.from_numpy(np.clip(actions.numpy(), low, high))
        result = actions.numpy()
        return (result[0] if single else result), None


class NoStudentPolicy(ConfigError, AttributeError):
    """``model.policy`` where it is not offered: a ConfigError that is also an AttributeError,
    so that ``hasattr(model, "policy")`` stays False there, as for a model without one."""


def student_policy(model: Any) -> StudentPolicy:
    """``model.policy``: a :class:`StudentPolicy` of what ``model.predict`` deploys now (the
    kept student, else the live low level), with its observation normalisation."""
    if model.obs_layout is not None or model.encoder is not None:
        raise NoStudentPolicy(
            f"model.policy covers Box observations read by the MLP as they are; this model "
            f"reads {model.observation_space} through tlac's encoder (one-hot, Dict or image), "
            "whose flattening runs in NumPy: use model.predict"
        )
    snap = model.deployed
    layers = model.net.member_numpy(LOW) if snap is None else snap.layers
    widths = [model.obs_dim, *model.config.net_arch_low, model.net.out_dims[LOW]]
    trimmed = [
        (w[: widths[i], : widths[i + 1]], np.asarray(b).reshape(-1)[: widths[i + 1]])
        for i, (w, b) in enumerate(layers)
    ]
    vec_normalize = model.saved_vec_normalize if model.get_vec_normalize_env() is None else None
    if snap is None:
        normalizer = model.normalizer
        log_std = None if model.log_std is None else model.log_std.detach().numpy()
    else:
        normalizer, log_std = snap.normalizer, snap.log_std
    policy = StudentPolicy(
        trimmed,
        model.observation_space,
        model.action_space,
        vec_normalize,
        normalizer,
        log_std,
        bool(model.config.use_sde),
    )
    return policy.eval()
