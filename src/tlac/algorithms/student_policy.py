"""``model.policy``: the student that ``TLAC.predict`` deploys as a plain torch module, for
what SB3 users do with ``model.policy``: export it (SB3's ONNX recipe, ``torch.onnx.export``
of a module from observations to actions; ``torch.jit.trace``), or run it without tlac's
``predict``.

:class:`StudentPolicy` holds a copy of the deployed low level (the kept student, or the live
weights where there is none), the observation normalisation it reads (the statistics of the
``VecNormalize`` a loaded model was trained under, ``model.saved_vec_normalize``, and TL-AC's
own ``normalize_obs`` statistics, frozen) and, where the networks read observations through an
encoder, that encoding in torch (:class:`ObsReader`: one-hot for Discrete, MultiDiscrete and
small integer Boxes, each key of a Dict in the space's order, images through a copy of the
student's NatureCNN). ``forward(obs)`` maps a batch of raw observations (a dict of tensors for
a Dict space) to the action logits (Discrete) or the Gaussian's mean (Box, before clipping to
the action box); ``predict`` is SB3's.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from tlac.algorithms.encoding import OneHotEncoder
from tlac.algorithms.nets import LOW, gsde_log_std
from tlac.algorithms.normalization import EPSILON
from tlac.errors import ConfigError


class OneHotPart(nn.Module):
    """One-hot columns as :class:`tlac.algorithms.encoding.OneHotEncoder` makes them, written
    with a comparison instead of a scatter so that a traced or exported module keeps its
    batch size free: output column ``j`` is 1 where its dimension's index equals ``j``."""

    def __init__(self, encoder: OneHotEncoder):
        super().__init__()
        self.register_buffer("low", torch.from_numpy(encoder.low.copy()))
        self.register_buffer("top", torch.from_numpy(encoder._max.copy()))
        self.register_buffer("offsets", torch.from_numpy(encoder.offsets.copy()))
        owner = np.repeat(np.arange(len(encoder.sizes)), encoder.sizes)
        self.register_buffer("owner", torch.from_numpy(owner.astype(np.int64)))
        self.register_buffer("column", torch.arange(encoder.out_dim, dtype=torch.int64))

    def forward(self, columns: torch.Tensor) -> torch.Tensor:
        index = (torch.round(columns).long() - self.low).clamp(min=0)
        index = torch.minimum(index, self.top) + self.offsets
        return (index[:, self.owner] == self.column).float()


class ImagePart(nn.Module):
    """An image's columns through a frozen copy of the student's NatureCNN, as
    :class:`tlac.algorithms.obs_spaces.ObsEncoder` reads them (channel-last images transposed
    to channel-first, pixels divided by 255 with ``normalize_images``)."""

    def __init__(self, cnn: nn.Module, shape: tuple[int, ...], channels_last: bool, scale: float):
        super().__init__()
        self.cnn = copy.deepcopy(cnn).requires_grad_(False)
        self.shape = shape[1:] + shape[:1] if channels_last else shape
        self.channels_last, self.scale = channels_last, scale

    def forward(self, columns: torch.Tensor) -> torch.Tensor:
        images = columns.reshape(-1, *self.shape)
        if self.channels_last:
            images = images.permute(0, 3, 1, 2)
        return self.cnn(images / self.scale)


class ObsReader(nn.Module):
    """Raw observations -> the flat float rows the model stores (:meth:`rows`: a Dict's keys in
    the space's order) -> what the low level reads (:meth:`encode`: each part raw, one-hot or
    through its CNN, concatenated, as the model's encoder does). ``parts``: ``(key, start,
    size)`` per component; ``encoders``: a module per part (None: read raw)."""

    def __init__(self, parts: list[tuple[str | None, int, int]], encoders: list[Any]):
        super().__init__()
        self.parts = parts
        self.encoders = nn.ModuleList([nn.Identity() if e is None else e for e in encoders])
        self.identity = all(e is None for e in encoders)

    def rows(self, obs: Any) -> torch.Tensor:
        if isinstance(obs, Mapping):
            batch = next(iter(obs.values())).shape[0]
            return torch.cat([obs[k].reshape(batch, -1).float() for k, _, _ in self.parts], 1)
        return obs.reshape(obs.shape[0], -1).float()

    def encode(self, x: torch.Tensor) -> torch.Tensor:
        if self.identity:
            return x
        features = [
            encoder(x[:, start : start + size])
            for (_, start, size), encoder in zip(self.parts, self.encoders, strict=True)
        ]
        return features[0] if len(features) == 1 else torch.cat(features, dim=1)


def obs_reader(model: Any) -> ObsReader:
    """The :class:`ObsReader` of ``model``'s deployed student: its observation layout (Dict,
    Discrete, images) or a Box read whole, one-hot under ``obs_encoding``; the CNNs are the
    kept student's own where it has them."""
    layout, encoder = model.nets.obs_layout, model.nets.encoder
    if layout is None:
        return ObsReader(
            [(None, 0, model.nets.obs_dim)], [None if encoder is None else OneHotPart(encoder)]
        )
    snap = model.deployed
    if snap is not None and snap.encoder is not None:
        encoder = snap.encoder  # its own frozen CNNs
    parts, encoders = [], []
    for i, p in enumerate(layout.parts):
        parts.append((p.key, p.start, p.size))
        if p.kind == "onehot":
            encoders.append(OneHotPart(p.onehot))
        elif p.kind == "image":
            cnn = encoder.module[str(i)]
            encoders.append(ImagePart(cnn, p.image_shape, p.channels_last, encoder.scale))
        else:
            encoders.append(None)
    return ObsReader(parts, encoders)


class StudentPolicy(nn.Module):
    """The deployed student as a torch module: raw observations ``(B, *obs_shape)`` (a dict
    of such tensors for a Dict space) -> normalised as in training -> encoded as in training
    -> the low level's tanh MLP -> logits or mean (``forward``).

    ``layers``: the low level's ``(weight (in, out), bias)`` pairs, trimmed to its sizes;
    ``reader``: how observations become its input (:func:`obs_reader`); ``layout``: the
    model's observation layout (None for a Box), which checks ``predict``'s input;
    ``vec_normalize``: the frozen ``VecNormalize`` statistics predict applies (a
    ``FrozenObsNormalization``) or None; ``normalizer``: TL-AC's own (``normalize_obs``) or
    None; ``log_std``: the Box Gaussian's (a gSDE matrix with ``use_sde``)."""

    def __init__(
        self,
        layers: list[tuple[np.ndarray, np.ndarray]],
        observation_space: gym.Space,
        action_space: gym.Space,
        vec_normalize: Any = None,
        normalizer: Any = None,
        log_std: np.ndarray | None = None,
        use_sde: bool = False,
        reader: ObsReader | None = None,
        layout: Any = None,
    ):
        super().__init__()
        self.observation_space, self.action_space = observation_space, action_space
        self.discrete = isinstance(action_space, gym.spaces.Discrete)
        self.use_sde, self.layout = use_sde, layout
        dim = layers[0][0].shape[0] if reader is None else None
        self.reader = reader if reader is not None else ObsReader([(None, 0, dim)], [None])
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

    def _heads(self, obs: Any) -> tuple[torch.Tensor, torch.Tensor]:
        """``(logits or mean, the last hidden layer)`` of a batch of raw observations."""
        x = self.reader.rows(obs)
        if self.vec_normalize:
            x = ((x.double() - self.vec_mean) / self.vec_std).clamp(-self.vec_clip, self.vec_clip)
            x = x.float()
        if self.normalize:
            x = ((x - self.obs_mean) / self.obs_std).clamp(-self.obs_clip, self.obs_clip)
        latent = self.hidden(self.reader.encode(x))
        return self.head(latent), latent

    def forward(self, obs: Any) -> torch.Tensor:
        """The action logits (Discrete) or the Gaussian's mean (Box) of raw observations
        ``(B, *obs_shape)`` (a dict of them for a Dict space): the greedy action is their
        argmax, or the mean clipped to the action box."""
        return self._heads(obs)[0]

    def _batch(self, observation: Any) -> tuple[Any, bool]:
        """``predict``'s input as a batch of tensors, and whether it was one observation."""
        if self.layout is not None:  # Discrete, Dict, images: the model's own checks
            batch, single = self.layout.check(observation)
            if isinstance(batch, Mapping):
                return {k: torch.as_tensor(np.asarray(v)) for k, v in batch.items()}, single
            return torch.as_tensor(np.asarray(batch)), single
        obs = np.asarray(observation)
        single = obs.shape == self.observation_space.shape
        shaped = np.ascontiguousarray(obs.reshape(-1, *self.observation_space.shape))
        return torch.from_numpy(shaped), single

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
        batch, single = self._batch(observation)
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
    kept student, else the live low level), with its observation normalisation and encoding."""
    vec_normalize = model.saved_vec_normalize if model.get_vec_normalize_env() is None else None
    if vec_normalize is not None and model.nets.obs_layout is not None:
        raise NoStudentPolicy(
            f"model.policy applies a saved VecNormalize to Box observations only; this model "
            f"reads {model.observation_space} through its layout: use model.predict"
        )
    snap = model.deployed
    layers = model.nets.net.member_numpy(LOW) if snap is None else snap.layers
    net_in = model.nets.obs_dim if model.nets.encoder is None else model.nets.encoder.out_dim
    widths = [net_in, *model.config.net_arch_low, model.nets.net.out_dims[LOW]]
    trimmed = [
        (w[: widths[i], : widths[i + 1]], np.asarray(b).reshape(-1)[: widths[i + 1]])
        for i, (w, b) in enumerate(layers)
    ]
    if snap is None:
        normalizer = model.nets.normalizer
        log_std = None if model.nets.log_std is None else model.nets.log_std.detach().numpy()
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
        obs_reader(model),
        model.nets.obs_layout,
    )
    return policy.eval()
