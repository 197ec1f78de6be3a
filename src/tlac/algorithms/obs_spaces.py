"""Observation spaces as SB3 takes them (issue 43, point 4): ``Discrete`` and ``MultiDiscrete``
one-hot, ``Dict`` through a combined extractor, and images through SB3's ``NatureCNN``.

A plain ``Box`` keeps TL-AC's own path (its observations flattened, ``obs_encoding`` for integer
Boxes; tlac.algorithms.encoding), and no :class:`ObsLayout` is made for it. Every other space
gets one: how a raw observation (an int, a dict, an image) becomes one flat float32 row, which
the rollout and the advice buffer store; how such a row becomes the raw observation again,
which the teachers are given; and (:class:`ObsEncoder`) what the networks see of a row.

>>> import gymnasium as gym
>>> space = gym.spaces.Dict(
...     {"pos": gym.spaces.Box(-1.0, 1.0, (2,)), "room": gym.spaces.Discrete(3)}
... )
>>> layout = make_layout(space, ObsPolicy(), "auto")
>>> rows = layout.flatten({"pos": np.array([0.5, -0.5]), "room": 2})
>>> rows.tolist()                                  # keys in the space's order: pos, room
[[0.5, -0.5, 2.0]]
>>> ObsEncoder(layout, ObsPolicy(), ortho_init=True).numpy(rows).tolist()   # room one-hot
[[0.5, -0.5, 0.0, 0.0, 1.0]]
>>> layout.unflatten(rows)                         # what a teacher is given
{'pos': array([[ 0.5, -0.5]], dtype=float32), 'room': array([2])}
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from functools import partial
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common import torch_layers
from stable_baselines3.common.policies import BasePolicy
from stable_baselines3.common.preprocessing import is_image_space, is_image_space_channels_first
from torch import nn

from tlac.algorithms.common import check_observations
from tlac.algorithms.encoding import OneHotEncoder, make_encoder
from tlac.errors import ConfigError

POLICIES = ("MlpPolicy", "CnnPolicy", "MultiInputPolicy")
"""SB3's policy names that TLAC takes (``TLAC(env, policy=...)``)."""

EXTRACTORS = {"FlattenExtractor": "MlpPolicy", "NatureCNN": "CnnPolicy"}
EXTRACTORS["CombinedExtractor"] = "MultiInputPolicy"
"""SB3's features extractors that ``policy_kwargs=dict(features_extractor_class=...)`` may
name, and the policy each one amounts to."""

POLICY_KWARGS = ("features_extractor_class", "features_extractor_kwargs", "normalize_images")
"""The keys of SB3's ``policy_kwargs`` that :class:`ObsPolicy` takes (TL-AC's settings take
the others: tlac.two_level.config.settings_from_policy_kwargs)."""

MIN_IMAGE_SIDE = 36
"""The smallest height and width NatureCNN's convolutions (8 stride 4, 4 stride 2, 3 stride 1)
accept."""


@dataclass(frozen=True)
class ObsPolicy:
    """How the networks read observations: SB3's ``policy`` name and the features-extractor
    part of its ``policy_kwargs``. Saved with a model (:meth:`to_data`)."""

    policy: str = "MlpPolicy"
    """MlpPolicy (observations flattened; Discrete one-hot), CnnPolicy (an image through SB3's
    NatureCNN) or MultiInputPolicy (a Dict: image keys through NatureCNN, the others as
    MlpPolicy reads them)."""
    features_dim: int | None = None
    """NatureCNN's output size: None: SB3's (512 for CnnPolicy, 256 per image key for
    MultiInputPolicy)."""
    normalize_images: bool = True
    """SB3's: divide image pixels by 255. False: the images are already normalised (CnnPolicy),
    or (MlpPolicy) a uint8 image is flattened into the MLP on purpose."""

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise ConfigError(f"policy must be one of {', '.join(POLICIES)}, got {self.policy!r}")
        dim = self.features_dim
        if dim is not None and (isinstance(dim, bool) or not isinstance(dim, int) or dim < 1):
            raise ConfigError(f"features_dim must be a positive integer, got {dim!r}")
        if not isinstance(self.normalize_images, bool):
            raise ConfigError(
                f"normalize_images must be True or False, got {self.normalize_images!r}"
            )

    @classmethod
    def from_arguments(cls, policy: Any, settings: dict[str, Any]) -> tuple[ObsPolicy, dict]:
        """``TLAC(policy=..., policy_kwargs=...)``: the ObsPolicy, and the settings without the
        keys it took from ``policy_kwargs`` (:data:`POLICY_KWARGS`).

        >>> from stable_baselines3.common.torch_layers import NatureCNN
        >>> kwargs = dict(features_extractor_class=NatureCNN, net_arch=[32, 32])
        >>> ObsPolicy.from_arguments("MlpPolicy", {"policy_kwargs": kwargs})
        (ObsPolicy(policy='CnnPolicy', features_dim=None, normalize_images=True),
         {'policy_kwargs': {'net_arch': [32, 32]}})
        """
        if not isinstance(policy, str):
            raise ConfigError(
                f"policy must be one of {', '.join(POLICIES)} (SB3's names), got {policy!r}; "
                "a features extractor goes in policy_kwargs=dict(features_extractor_class=...)"
            )
        settings = dict(settings)
        kwargs = settings.get("policy_kwargs")
        if not isinstance(kwargs, dict):
            return cls(policy), settings
        taken = {k: kwargs[k] for k in POLICY_KWARGS if k in kwargs}
        settings["policy_kwargs"] = {k: v for k, v in kwargs.items() if k not in POLICY_KWARGS}
        extractor = taken.get("features_extractor_class")
        if extractor is not None:
            name = extractor if isinstance(extractor, str) else getattr(extractor, "__name__", "")
            implied = EXTRACTORS.get(name)
            if implied is None or not (
                isinstance(extractor, str) or extractor is getattr(torch_layers, name)
            ):
                raise ConfigError(
                    f"features_extractor_class {extractor!r} is not supported: TL-AC takes SB3's "
                    f"{', '.join(EXTRACTORS)} (a model file holds no code, so no custom class)"
                )
            if policy != "MlpPolicy" and policy != implied:
                raise ConfigError(
                    f"policy {policy!r} and features_extractor_class {name} disagree; "
                    f"{name} is policy={implied!r}"
                )
            policy = implied
        extractor_kwargs = taken.get("features_extractor_kwargs") or {}
        if not isinstance(extractor_kwargs, dict) or set(extractor_kwargs) - {
            "features_dim",
            "cnn_output_dim",
        }:
            raise ConfigError(
                "features_extractor_kwargs takes features_dim (NatureCNN) or cnn_output_dim "
                f"(CombinedExtractor), got {extractor_kwargs!r}"
            )
        dim = extractor_kwargs.get("features_dim", extractor_kwargs.get("cnn_output_dim"))
        return cls(policy, dim, taken.get("normalize_images", True)), settings

    def to_data(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_data(cls, data: Any) -> ObsPolicy:
        """From :meth:`to_data`; None (a file saved before policies): MlpPolicy."""
        return cls() if data is None else cls(**data)


def is_image(space: gym.Space, policy: ObsPolicy) -> bool:
    """SB3's test for an image (``is_image_space``: a 3-dimensional uint8 Box of bounds 0 and
    255, channels first or last; with ``normalize_images=False`` any 3-dimensional Box)."""
    return is_image_space(space, check_channels=False, normalized_image=not policy.normalize_images)


@dataclass
class Part:
    """One component of an observation: a Dict key's space, or the whole space (key None),
    and its columns ``[start, start + size)`` in a flat row."""

    key: str | None
    space: gym.Space
    start: int
    size: int
    kind: str  # "raw" (its values as they are), "onehot" or "image"
    onehot: OneHotEncoder | None = None
    image_shape: tuple[int, ...] = ()  # (C, H, W), as NatureCNN takes it
    channels_last: bool = False  # the environment's images are (H, W, C)

    def where(self) -> str:
        return "the observation" if self.key is None else f"key {self.key!r}"

    def to_raw(self, columns: np.ndarray) -> np.ndarray:
        """A batch of this part's raw observations from its float32 columns."""
        space, n = self.space, len(columns)
        if isinstance(space, gym.spaces.Discrete):
            return np.rint(columns[:, 0]).astype(np.int64)
        values = columns.reshape(n, *space.shape)
        if np.issubdtype(space.dtype, np.integer):
            values = np.rint(values)
        return values.astype(space.dtype)


def _integer_part(key: str | None, space: gym.Space, start: int) -> Part:
    """Discrete / MultiDiscrete: one-hot, as SB3's preprocessing does."""
    if isinstance(space, gym.spaces.Discrete):
        low, sizes = np.array([space.start]), np.array([space.n])
    else:
        low, sizes = np.asarray(space.start).reshape(-1), np.asarray(space.nvec).reshape(-1)
    return Part(key, space, start, len(sizes), "onehot", OneHotEncoder(low, sizes.astype(np.int64)))


def _image_part(key: str | None, space: gym.spaces.Box, start: int) -> Part:
    channels_last = not is_image_space_channels_first(space)
    shape = tuple(int(d) for d in space.shape)
    chw = (shape[2], shape[0], shape[1]) if channels_last else shape
    if min(chw[1:]) < MIN_IMAGE_SIDE:
        where = "the observation" if key is None else f"key {key!r}"
        raise ConfigError(
            f"{where} is an image of {chw[1]}x{chw[2]} pixels ({space}); SB3's NatureCNN needs "
            f"at least {MIN_IMAGE_SIDE}x{MIN_IMAGE_SIDE}. To flatten it into the MLP instead, "
            "pass policy='MlpPolicy' (the default) with policy_kwargs=dict(normalize_images=False)"
        )
    return Part(key, space, start, int(np.prod(shape)), "image", None, chw, channels_last)


def _image_meets_mlp(where: str, space: gym.spaces.Box, whole: bool) -> str:
    """The error for an image under MlpPolicy: what to pass instead."""
    pixels = "x".join(str(d) for d in space.shape)
    flatten = "policy_kwargs=dict(normalize_images=False)"
    if sorted(space.shape)[1] < MIN_IMAGE_SIDE:  # too small for NatureCNN
        fix = f"it is too small for SB3's NatureCNN; to flatten it into the MLP, pass {flatten}"
    else:
        cnn = "policy='CnnPolicy'" if whole else "policy='MultiInputPolicy'"
        fix = f"pass {cnn} (SB3's NatureCNN), or, to flatten it into the MLP on purpose, {flatten}"
    return (
        f"{where} is an image ({space}: SB3's is_image_space), and an MLP would read its "
        f"{pixels} raw pixels as unrelated inputs: {fix}"
    )


def _part(key: str | None, space: gym.Space, start: int, policy: ObsPolicy, encoding: str) -> Part:
    where = "the observation" if key is None else f"key {key!r}"
    if isinstance(space, gym.spaces.Discrete | gym.spaces.MultiDiscrete):
        return _integer_part(key, space, start)
    if isinstance(space, gym.spaces.MultiBinary):
        return Part(key, space, start, int(np.prod(space.shape)), "raw")
    if isinstance(space, gym.spaces.Box):
        if policy.policy != "MlpPolicy" and is_image(space, policy):
            return _image_part(key, space, start)
        if policy.policy == "MlpPolicy" and policy.normalize_images and is_image(space, policy):
            raise ConfigError(_image_meets_mlp(where, space, key is None))
        size = int(np.prod(space.shape))
        encoder = make_encoder("auto" if encoding == "onehot" else encoding, space)
        return Part(key, space, start, size, "raw" if encoder is None else "onehot", encoder)
    raise _unsupported(key, space)


FLAT_SPACES = (
    gym.spaces.Box,
    gym.spaces.Discrete,
    gym.spaces.MultiDiscrete,
    gym.spaces.MultiBinary,
)


def _unsupported(key: str | None, space: gym.Space) -> ConfigError:
    if key is None:
        return ConfigError(
            "TL-AC takes Box, Discrete, MultiDiscrete, MultiBinary and Dict observation "
            f"spaces (as SB3 does), got {space}"
        )
    kind = type(space).__name__
    nested = isinstance(space, gym.spaces.Dict | gym.spaces.Tuple)
    return ConfigError(
        f"key {key!r} of the Dict observation space is a {'nested ' * nested}{kind}, which "
        "TL-AC cannot read (nor can SB3: Box, Discrete, MultiDiscrete and MultiBinary keys "
        + (
            "only); flatten it into the top-level Dict"
            if nested
            else "only); drop it, e.g. gymnasium.wrappers.FilterObservation(env, [the other keys])"
        )
    )


def check_space_kinds(space: gym.Space) -> None:
    """ConfigError unless ``space`` is of a kind TL-AC reads (whatever the policy): checked
    before an environment is wrapped (SB3's DummyVecEnv fails on a text key with a TypeError).

    >>> check_space_kinds(gym.spaces.Dict({"note": gym.spaces.Text(8)}))
    Traceback (most recent call last):
    tlac.errors.ConfigError: key 'note' of the Dict observation space is a Text, which TL-AC
    cannot read (nor can SB3: Box, Discrete, MultiDiscrete and MultiBinary keys only); drop it,
    e.g. gymnasium.wrappers.FilterObservation(env, [the other keys])
    """
    if isinstance(space, gym.spaces.Dict):
        for key, sub in space.spaces.items():
            if not isinstance(sub, FLAT_SPACES):
                raise _unsupported(str(key), sub)
    elif not isinstance(space, FLAT_SPACES):
        raise _unsupported(None, space)


def _bytes(space: gym.Space) -> bool:
    """Whether every value of ``space`` is an integer from 0 to 255."""
    if isinstance(space, gym.spaces.Discrete):
        low, high = int(space.start), int(space.start + space.n - 1)
    elif isinstance(space, gym.spaces.MultiDiscrete):
        low, high = int(np.min(space.start)), int(np.max(space.start + space.nvec - 1))
    elif isinstance(space, gym.spaces.MultiBinary):
        return True
    elif isinstance(space, gym.spaces.Box) and np.issubdtype(space.dtype, np.integer):
        low, high = int(space.low.min()), int(space.high.max())
    else:
        return False
    return low >= 0 and high <= 255


class ObsLayout:
    """Raw observations <-> flat float32 rows, for one non-Box (or image) observation space."""

    def __init__(self, space: gym.Space, parts: list[Part]):
        self.space, self.parts = space, parts
        self.dim = sum(p.size for p in parts)
        self.is_dict = isinstance(space, gym.spaces.Dict)
        self.has_images = any(p.kind == "image" for p in parts)

    @property
    def storage_dtype(self) -> torch.dtype:
        """The advice buffer's dtype: uint8 for images (a (64, 64, 3) one is 12,288 values a
        row) where every stored value is an integer from 0 to 255 (with small Discrete keys,
        say), float32 otherwise.

        >>> image = gym.spaces.Box(0, 255, (36, 36, 3), dtype=np.uint8)
        >>> space = gym.spaces.Dict({"image": image, "direction": gym.spaces.Discrete(4)})
        >>> make_layout(space, ObsPolicy("MultiInputPolicy"), "auto").storage_dtype
        torch.uint8
        """
        as_bytes = self.has_images and all(_bytes(p.space) for p in self.parts)
        return torch.uint8 if as_bytes else torch.float32

    def flatten(self, obs: Any) -> np.ndarray:
        """One raw observation or a batch (as the VecEnv gives it) as ``(n, dim)`` float32."""
        if not self.is_dict:
            return np.asarray(obs, dtype=np.float32).reshape(-1, self.dim)
        columns = [np.asarray(obs[p.key], dtype=np.float32).reshape(-1, p.size) for p in self.parts]
        return np.concatenate(columns, axis=1)

    def unflatten(self, rows: np.ndarray) -> Any:
        """Flat rows as the environment's raw batch (a dict of arrays for a Dict space), in its
        dtypes: what the teachers are given."""
        rows = np.asarray(rows, dtype=np.float32).reshape(-1, self.dim)
        raw = {p.key: p.to_raw(rows[:, p.start : p.start + p.size]) for p in self.parts}
        return raw if self.is_dict else raw[None]

    def check(self, obs: Any) -> tuple[Any, bool]:
        """``predict``'s input: ``(batch, single)``, the observation(s) as a raw batch and
        whether it was one observation; anything else is a ConfigError saying what was
        expected (:func:`tlac.algorithms.common.check_observations` per component)."""
        if not self.is_dict:
            return _check_part(obs, self.parts[0])
        if not isinstance(obs, Mapping):
            raise ConfigError(
                f"predict: expected a dict with the keys {list(self.space.spaces)}, got "
                f"{type(obs).__name__}"
            )
        missing = [p.key for p in self.parts if p.key not in obs]
        if missing:
            raise ConfigError(f"predict: the observation has no key {missing[0]!r}")
        batch, kinds = {}, set()
        for p in self.parts:
            batch[p.key], single = _check_part(obs[p.key], p)
            kinds.add((single, len(batch[p.key])))
        if len(kinds) != 1:
            raise ConfigError(
                "predict: the dict's values must all be one observation, or all batches of the "
                "same length"
            )
        return batch, kinds.pop()[0]


def _check_part(value: Any, part: Part) -> tuple[np.ndarray, bool]:
    try:
        array, single = check_observations(value, part.space)
    except ConfigError as exc:
        if part.key is None:
            raise
        raise ConfigError(f"{exc} (key {part.key!r})") from None
    space = part.space
    if isinstance(space, gym.spaces.Discrete | gym.spaces.MultiDiscrete | gym.spaces.MultiBinary):
        if isinstance(space, gym.spaces.Discrete):
            low, high = space.start, space.start + space.n - 1
        elif isinstance(space, gym.spaces.MultiDiscrete):
            low, high = space.start, space.start + space.nvec - 1
        else:
            low, high = 0, 1
        if not (
            np.all(array == np.round(array)) and np.all(array >= low) and np.all(array <= high)
        ):
            raise ConfigError(
                f"predict: {part.where()} must hold integers of {space}, got {array.tolist()!r:.80}"
            )
    return array, single


def make_layout(space: gym.Space, policy: ObsPolicy, encoding: str) -> ObsLayout | None:
    """The layout of ``space`` under ``policy``; None for a Box that TL-AC reads as it always
    has (flattened, ``obs_encoding`` for integers). An image meeting an MLP, a non-image with
    CnnPolicy, a Dict with CnnPolicy (or MultiInputPolicy without one), a nested Dict and a key
    of another space (text) are ConfigErrors saying what to do."""
    if isinstance(space, gym.spaces.Dict):
        if policy.policy == "CnnPolicy":
            raise ConfigError(
                "a Dict observation space needs policy='MultiInputPolicy' (as in SB3), not "
                "'CnnPolicy'"
            )
        check_space_kinds(space)
        parts, start = [], 0
        for key, sub in space.spaces.items():
            parts.append(_part(str(key), sub, start, policy, encoding))
            start += parts[-1].size
        return ObsLayout(space, parts)
    if policy.policy == "MultiInputPolicy":
        raise ConfigError(
            f"policy='MultiInputPolicy' needs a Dict observation space, got {space}; use "
            "'MlpPolicy', or 'CnnPolicy' for an image"
        )
    part = _part(None, space, 0, policy, encoding)
    if policy.policy == "CnnPolicy" and part.kind != "image":
        raise ConfigError(
            "policy='CnnPolicy' needs an image observation space (SB3's is_image_space: a "
            f"uint8 Box of shape (H, W, C) or (C, H, W) with bounds 0 and 255), got {space}; "
            "use policy='MlpPolicy'"
        )
    if isinstance(space, gym.spaces.Box) and part.kind != "image":
        return None  # TL-AC's own Box path, exactly as before
    return ObsLayout(space, [part])


class ObsEncoder:
    """A layout's flat rows -> what the three networks see: each component in order, raw,
    one-hot (Discrete, MultiDiscrete, small integer Boxes under obs_encoding auto) or through
    its own NatureCNN (images: channel-last transposed to channel-first, as SB3's
    VecTransposeImage does, and divided by 255 with normalize_images), concatenated, as SB3's
    CombinedExtractor does. The CNNs are shared by the high level, the low level and the
    critic (SB3's share_features_extractor) and trained with them. ``numpy`` for acting,
    ``torch`` (with autograd) for training, as :class:`tlac.algorithms.encoding.OneHotEncoder`."""

    def __init__(self, layout: ObsLayout, policy: ObsPolicy, ortho_init: bool):
        self.layout, self.scale = layout, 255.0 if policy.normalize_images else 1.0
        cnns: dict[str, nn.Module] = {}
        self.out_dim = 0
        for i, p in enumerate(layout.parts):
            if p.kind != "image":
                self.out_dim += p.size if p.onehot is None else p.onehot.out_dim
                continue
            dim = policy.features_dim or (512 if p.key is None else 256)  # SB3's defaults
            box = p.space
            if p.channels_last:
                box = gym.spaces.Box(
                    box.low.transpose(2, 0, 1), box.high.transpose(2, 0, 1), dtype=box.dtype
                )
            cnn = torch_layers.NatureCNN(
                box, features_dim=dim, normalized_image=not policy.normalize_images
            )
            if ortho_init:  # SB3's ActorCriticPolicy: its features extractor, gain sqrt(2)
                cnn.apply(partial(BasePolicy.init_weights, gain=np.sqrt(2)))
            cnns[str(i)] = cnn
            self.out_dim += dim
        self.module: nn.ModuleDict | None = nn.ModuleDict(cnns) if cnns else None

    def parameters(self) -> list[nn.Parameter]:
        return [] if self.module is None else list(self.module.parameters())

    def frozen_copy(self) -> ObsEncoder:
        """A copy whose CNNs no training changes (a kept student's), or itself when it has none."""
        if self.module is None:
            return self
        clone = copy.copy(self)
        clone.module = copy.deepcopy(self.module).requires_grad_(False)
        return clone

    def torch(self, x: torch.Tensor) -> torch.Tensor:
        x = x if x.is_floating_point() else x.float()
        features = []
        for i, p in enumerate(self.layout.parts):
            columns = x[:, p.start : p.start + p.size]
            if p.kind == "raw":
                features.append(columns)
            elif p.kind == "onehot":
                features.append(p.onehot.torch(columns))  # type: ignore[union-attr]
            else:
                shape = p.image_shape
                images = columns.reshape(
                    len(x), *(shape[1:] + shape[:1] if p.channels_last else shape)
                )
                if p.channels_last:
                    images = images.permute(0, 3, 1, 2)
                features.append(self.module[str(i)](images / self.scale))  # type: ignore[index]
        return features[0] if len(features) == 1 else torch.cat(features, dim=1)

    def numpy(self, x: np.ndarray) -> np.ndarray:
        if self.module is not None:
            with torch.no_grad():
                return self.torch(torch.from_numpy(np.asarray(x, dtype=np.float32))).numpy()
        features = []
        for p in self.layout.parts:
            columns = x[:, p.start : p.start + p.size]
            features.append(columns if p.onehot is None else p.onehot.numpy(columns))
        return np.concatenate(features, axis=1, dtype=np.float32)
