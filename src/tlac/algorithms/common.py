"""Pieces shared by the algorithms: config building, teacher queries, progress bars,
target networks, and the truncation-aware next observation."""

from __future__ import annotations

import contextlib
import os
import sys
import warnings
from collections import OrderedDict
from pathlib import Path
from typing import Any, TypeVar

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from tlac.errors import ConfigError, StorageError
from tlac.teachers.base import ask_teacher, take_rows
from tlac.validation import from_mapping

C = TypeVar("C")


def config_from_kwargs(cls: type[C], algo: str, kwargs: dict[str, Any]) -> C:
    """Build the frozen config dataclass ``cls`` from preset keys (``n_envs``, the run's, is
    dropped); unknown keys raise :class:`ConfigError` naming the key and listing the accepted
    ones (:func:`tlac.validation.from_mapping`)."""
    kwargs = {k: v for k, v in kwargs.items() if k != "n_envs"}
    return from_mapping(cls, algo, kwargs, noun="hyperparameter", sort_names=True)


def mlp(in_dim: int, hidden: list[int] | tuple[int, ...], out_dim: int) -> nn.Sequential:
    """A ReLU MLP ``in_dim -> hidden... -> out_dim`` (SB3's DQN ``MlpPolicy`` shape)."""
    layers: list[nn.Module] = []
    last = in_dim
    for h in hidden:
        layers += [nn.Linear(last, int(h)), nn.ReLU()]
        last = int(h)
    layers.append(nn.Linear(last, out_dim))
    return nn.Sequential(*layers)


def linear_epsilon(progress: float, initial: float, final: float, fraction: float) -> float:
    """Exploration rate after ``progress`` (0 -> 1) of training: linear from ``initial`` to
    ``final`` over the first ``fraction`` of training, then constant (SB3's DQN schedule).

    >>> (linear_epsilon(0.0, 1.0, 0.01, 0.1), linear_epsilon(0.05, 1.0, 0.01, 0.1),
    ...  linear_epsilon(0.5, 1.0, 0.01, 0.1))
    (1.0, 0.505, 0.01)
    """
    if fraction <= 0 or progress >= fraction:
        return final
    return initial + (final - initial) * progress / fraction


def td_targets(
    rewards: torch.Tensor, terminated: torch.Tensor, next_q: torch.Tensor, gamma: float
) -> torch.Tensor:
    """One-step Q-learning targets ``r + gamma * (1 - terminated) * max_j next_q[:, j]``.
    Truncated (time-limit) transitions are not ``terminated``: they bootstrap."""
    return rewards + gamma * (1.0 - terminated) * next_q.max(dim=1).values


def polyak_update(online: nn.Module, target: nn.Module, tau: float) -> None:
    """``target <- tau * online + (1 - tau) * target`` (SB3's ``polyak_update``)."""
    with torch.no_grad():
        for p, tp in zip(online.parameters(), target.parameters(), strict=True):
            tp.mul_(1.0 - tau).add_(p, alpha=tau)


def real_next_obs(
    next_obs: np.ndarray, dones: np.ndarray, infos: list[dict[str, Any]]
) -> tuple[np.ndarray, np.ndarray]:
    """The true next observations (``terminal_observation`` for finished episodes, not the
    reset observation a VecEnv returns) and the ``terminated`` flags (done and not a
    time-limit truncation)."""
    real = np.array(next_obs, copy=True)
    terminated = np.zeros(len(dones), dtype=np.float32)
    for i in np.flatnonzero(dones):
        real[i] = infos[i]["terminal_observation"]
        terminated[i] = 0.0 if infos[i].get("TimeLimit.truncated", False) else 1.0
    return real, terminated


def flat_obs(obs: np.ndarray, n: int) -> np.ndarray:
    """Observations as a float32 ``(n, obs_dim)`` array."""
    return np.asarray(obs, dtype=np.float32).reshape(n, -1)


def checkpoint_path(path: str | Path) -> Path:
    """Where ``save(path)`` writes: ``path`` itself when it has a suffix (``model.pt``, or
    ``rl_model_3008_steps.zip`` as SB3's CheckpointCallback names it: a torch file is a zip
    archive), else ``path`` + ``.pt`` (as SB3 adds ``.zip``).

    >>> checkpoint_path("runs/model"), checkpoint_path("m.zip"), checkpoint_path("m.pt")
    (PosixPath('runs/model.pt'), PosixPath('m.zip'), PosixPath('m.pt'))
    """
    if not isinstance(path, str | os.PathLike) or not str(path).strip():
        raise ConfigError(f"expected a file path (a str or pathlib.Path), got {path!r}")
    p = Path(path)
    return p if p.suffix else p.with_name(p.name + ".pt")


def check_total_timesteps(total_timesteps: Any) -> int:
    """``learn``'s step budget as an int; anything but a positive integer is a ConfigError.

    >>> check_total_timesteps(np.int64(64))
    64
    """
    if (
        not isinstance(total_timesteps, int | np.integer)
        or isinstance(total_timesteps, bool)
        or total_timesteps <= 0
    ):
        raise ConfigError(f"total_timesteps must be a positive integer, got {total_timesteps!r}")
    return int(total_timesteps)


def make_progress_bar(total: int, desc: str, enabled: bool) -> Any:
    """A tqdm bar over environment steps (live in a terminal, a line every 10 s in a log
    file), or ``None`` when ``enabled`` is false."""
    if not enabled:
        return None
    import sys

    from tqdm.auto import tqdm

    interval = 0.2 if sys.stderr.isatty() else 10.0
    return tqdm(total=int(total), unit="step", dynamic_ncols=True, desc=desc, mininterval=interval)


def query_teachers(
    teachers: list[Any],
    choices: np.ndarray,
    obs: np.ndarray,
    action_space: gym.Space,
    out: np.ndarray,
    envs: bool = False,
) -> None:
    """Write into ``out[i]`` the advice of teacher ``choices[i]`` for every row whose choice
    is a teacher (``< len(teachers)``); each teacher is asked once, on its rows only.
    ``envs``: row ``i`` is the training environment ``i`` (TL-AC's collection); a teacher
    with an ``env_rows`` attribute (a person: tlac.teachers.human) is told, before it is
    asked, the environments its rows are (None where they are not training environments)."""
    for k in set(choices.tolist()):
        if k >= len(teachers):
            continue  # the agent's own action stays
        rows = np.flatnonzero(choices == k)
        teacher = teachers[k]
        inner = getattr(teacher, "teacher", teacher)
        if hasattr(inner, "env_rows"):
            inner.env_rows = rows if envs else None
        out[rows] = ask_teacher(teacher, take_rows(obs, rows), action_space)


def original_obs(vec_normalize: Any) -> np.ndarray:
    """The observations of the environments' last reset or step as they produced them, before
    the user's SB3 ``VecNormalize`` normalised them: what teachers (trained on raw observations,
    or carrying their own statistics) are given, while the networks see the normalised ones
    (a Dict space's: a dict of arrays)."""
    obs = vec_normalize.get_original_obs()
    if isinstance(obs, dict):
        return {key: np.asarray(value) for key, value in obs.items()}  # type: ignore[return-value]
    return np.asarray(obs, dtype=np.float32)


def original_rewards(vec_normalize: Any) -> np.ndarray:
    """The last step's rewards before the user's ``VecNormalize`` scaled them (episode returns
    are counted in the environment's own units)."""
    return np.asarray(vec_normalize.get_original_reward(), dtype=np.float64)


def space_to_data(space: gym.Space) -> dict[str, Any]:
    """A Box, Discrete, MultiDiscrete, MultiBinary or Dict space as plain data (lists, numbers,
    strings), so that checkpoints load with ``torch.load(weights_only=True)``: nothing in them
    is unpickled as code.

    >>> space_to_data(gym.spaces.Discrete(3))
    {'type': 'Discrete', 'n': 3, 'start': 0}
    >>> box = gym.spaces.Box(-1.0, 1.0, (2,))
    >>> space_from_data(space_to_data(box)) == box
    True
    >>> d = gym.spaces.Dict({"a": gym.spaces.MultiDiscrete([2, 3]), "b": gym.spaces.MultiBinary(2)})
    >>> space_to_data(d)["spaces"][0]
    ['a', {'type': 'MultiDiscrete', 'nvec': [2, 3], 'start': [0, 0], 'dtype': 'int64'}]
    >>> spaces_match(space_from_data(space_to_data(d)), d)
    True
    """
    if isinstance(space, gym.spaces.Discrete):
        return {"type": "Discrete", "n": int(space.n), "start": int(space.start)}
    if isinstance(space, gym.spaces.MultiDiscrete):
        return {
            "type": "MultiDiscrete",
            "nvec": space.nvec.tolist(),
            "start": np.asarray(space.start).tolist(),
            "dtype": str(space.dtype),
        }
    if isinstance(space, gym.spaces.MultiBinary):
        return {"type": "MultiBinary", "n": np.asarray(space.n).tolist()}
    if isinstance(space, gym.spaces.Dict):
        return {
            "type": "Dict",
            "spaces": [[str(k), space_to_data(v)] for k, v in space.spaces.items()],
        }
    if isinstance(space, gym.spaces.Box):
        return {
            "type": "Box",
            "low": space.low.tolist(),
            "high": space.high.tolist(),
            "shape": list(space.shape),
            "dtype": str(space.dtype),
        }
    raise ConfigError(
        f"cannot save a model for a {type(space).__name__} space; expected Box, Discrete, "
        "MultiDiscrete, MultiBinary or Dict"
    )


def space_from_data(data: Any) -> gym.Space:
    """The inverse of :func:`space_to_data`; a malformed entry raises ConfigError."""
    try:
        if data["type"] == "Discrete":
            return gym.spaces.Discrete(int(data["n"]), start=int(data["start"]))
        if data["type"] == "Box":
            dtype = np.dtype(data["dtype"])
            low = np.asarray(data["low"], dtype=dtype).reshape(data["shape"])
            high = np.asarray(data["high"], dtype=dtype).reshape(data["shape"])
            return gym.spaces.Box(low, high, dtype=dtype)
        if data["type"] == "MultiDiscrete":
            return gym.spaces.MultiDiscrete(
                np.asarray(data["nvec"]),
                dtype=np.dtype(data["dtype"]),
                start=np.asarray(data["start"]),
            )
        if data["type"] == "MultiBinary":
            return gym.spaces.MultiBinary(data["n"])
        if data["type"] == "Dict":  # an OrderedDict's key order is kept as it is
            return gym.spaces.Dict(
                OrderedDict((str(k), space_from_data(v)) for k, v in data["spaces"])
            )
    except (KeyError, TypeError, ValueError) as exc:
        raise ConfigError(f"malformed space in the checkpoint: {exc}") from None
    raise ConfigError(f"malformed space in the checkpoint: {data!r:.80}")


def spaces_match(a: gym.Space, b: gym.Space) -> bool:
    """Same kind, shape, dtype and bounds (Box) or size (Discrete, MultiDiscrete,
    MultiBinary); a Dict: the same keys in the same order, each matching."""
    if isinstance(a, gym.spaces.Discrete) and isinstance(b, gym.spaces.Discrete):
        return int(a.n) == int(b.n) and int(a.start) == int(b.start)
    if isinstance(a, gym.spaces.MultiDiscrete) and isinstance(b, gym.spaces.MultiDiscrete):
        return np.array_equal(a.nvec, b.nvec) and np.array_equal(a.start, b.start)
    if isinstance(a, gym.spaces.MultiBinary) and isinstance(b, gym.spaces.MultiBinary):
        return a.shape == b.shape
    if isinstance(a, gym.spaces.Dict) and isinstance(b, gym.spaces.Dict):
        return list(a.spaces) == list(b.spaces) and all(spaces_match(a[k], b[k]) for k in a.spaces)
    if isinstance(a, gym.spaces.Box) and isinstance(b, gym.spaces.Box):
        return (
            a.shape == b.shape
            and a.dtype == b.dtype
            and np.array_equal(a.low, b.low)
            and np.array_equal(a.high, b.high)
        )
    return False


class CheckedEnv(gym.Wrapper):
    """A user's environment with its first ``reset`` and first ``step`` checked against
    Gymnasium's API (``(obs, info)``; ``(obs, reward, terminated, truncated, info)``) and a Box
    observation against its space's shape: the old 4-tuple API or a wrong shape is one
    ConfigError saying what was returned and what is expected, not an unpacking error deep
    inside SB3's DummyVecEnv. Later calls pass through unchecked."""

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self._checked = {"reset": False, "step": False}

    def _check(self, call: str, result: Any, arity: int, expected: str) -> None:
        if self._checked[call]:
            return
        if not isinstance(result, tuple) or len(result) != arity:
            got = f"a {len(result)}-tuple" if isinstance(result, tuple) else type(result).__name__
            raise ConfigError(
                f"the environment's {call}() returned {got}; expected {expected} (Gymnasium's "
                "API; an old gym environment needs gymnasium's compatibility wrapper)"
            )
        space = self.observation_space
        if isinstance(space, gym.spaces.Box) and np.shape(result[0]) != space.shape:
            raise ConfigError(
                f"the environment's {call}() returned an observation of shape "
                f"{np.shape(result[0])}; its observation_space is {space}"
            )
        self._checked[call] = True

    def reset(self, **kwargs: Any) -> Any:
        result = self.env.reset(**kwargs)
        self._check("reset", result, 2, "(observation, info)")
        return result

    def step(self, action: Any) -> Any:
        result = self.env.step(action)
        self._check("step", result, 5, "(observation, reward, terminated, truncated, info)")
        return result


def check_finite_weights(tensors: dict[str, torch.Tensor], path: Any) -> None:
    """A model file whose weights hold NaN or infinity (its training diverged) is refused with a
    ConfigError naming the file and the tensor: it would act on garbage without a word."""
    for key, tensor in tensors.items():
        if (
            isinstance(tensor, torch.Tensor)
            and tensor.is_floating_point()
            and not bool(torch.isfinite(tensor).all())
        ):
            raise ConfigError(
                f"{str(path)!r}: the model's weights hold NaN or infinity ({key}): its training "
                "diverged; load an earlier checkpoint or train it again"
            )


def check_env_spaces(env: Any, observation_space: gym.Space, action_space: gym.Space) -> None:
    """The environment given to ``load`` has the checkpoint's spaces (:func:`spaces_match`);
    ConfigError naming the one that differs. ``env=None`` passes."""
    if env is None:
        return
    for kind, saved, given in (
        ("observation", observation_space, env.observation_space),
        ("action", action_space, env.action_space),
    ):
        if not spaces_match(saved, given):
            raise ConfigError(
                f"the environment's {kind} space {one_line(given)} does not match the model's "
                f"{one_line(saved)}"
            )


def one_line(value: Any, width: int = 100) -> str:
    """``str(value)`` on one line, at most ``width`` characters (a Box's bounds print as
    arrays over several lines).

    >>> one_line(gym.spaces.Box(0, np.arange(40), (40,), np.uint8), 30)
    'Box(0, [ 0 1 2 3 4 5 6 7 8...'
    """
    text = " ".join(str(value).split())
    return text if len(text) <= width else text[: width - 3].rstrip() + "..."


def canonical_data(data: Any) -> Any:
    """``data`` with fresh containers and interned strings, so that its pickle (``torch.save``)
    depends on its values only: pickle writes an object seen before as a reference to it, so
    the same values read back from a checkpoint (other string objects) would otherwise give
    other bytes than those of the run that never stopped. Tensors are kept as they are.

    >>> a, b = canonical_data({"k": ["x" * 3]}), canonical_data({"k": ["".join("xxx")]})
    >>> a["k"][0] is b["k"][0]
    True
    """
    if type(data) is str:
        return sys.intern(data)
    if isinstance(data, dict):
        out = type(data)((canonical_data(k), canonical_data(v)) for k, v in data.items())
        metadata = getattr(data, "_metadata", None)  # a state_dict's module versions
        if metadata is not None:
            out._metadata = canonical_data(metadata)  # type: ignore[attr-defined]
        return out
    if type(data) in (list, tuple):
        return type(data)(canonical_data(v) for v in data)
    return data


def atomic_torch_save(data: Any, path: Path) -> Path:
    """``torch.save`` of :func:`canonical_data` to a temporary file, then rename it to
    ``path``: a crash while writing leaves the previous file whole, and the same values give
    the same bytes. Returns ``path``."""
    tmp = path.with_name(path.name + ".tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            torch.save(canonical_data(data), tmp)
        except RuntimeError:  # torch's zip writer hides the file system's reason: ask it again
            _raise_write_error(tmp)
            raise
        tmp.replace(path)
    except OSError as exc:  # a full disk, a read-only folder, no such place
        raise StorageError(f"cannot write {str(exc.filename or path)!r}: {exc.strerror}") from None
    return path


def _raise_write_error(tmp: Path) -> None:
    """After torch failed to write ``tmp``: raise the OSError the file system gives for a
    write there (disk full, a file size limit, a read-only folder), the partial file removed;
    return when a write succeeds (then the failure was not the file system's)."""
    try:
        with open(tmp, "ab") as f:
            f.write(b"\0")
            f.flush()
            os.fsync(f.fileno())
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise OSError(exc.errno, exc.strerror, str(tmp)) from None


def safe_torch_load(path: Path, what: str) -> Any:
    """``torch.load(weights_only=True)`` (no code runs, whatever the file holds), with any
    failure (not a checkpoint, truncated, empty, a pickle that needs code) as one ConfigError."""
    try:
        with warnings.catch_warnings():  # a plain pickle's protocol warning says nothing useful
            warnings.simplefilter("ignore", UserWarning)
            return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - every failure of an untrusted file is the same error
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ConfigError(f"{str(path)!r} is not a loadable {what} file ({reason[:160]})") from None


def check_observations(obs: Any, space: gym.Space) -> tuple[np.ndarray, bool]:
    """``(batch, single)``: ``obs`` as a batch ``(n, *space.shape)`` and whether it was one
    observation. Anything else (a wrong shape, text, NaN or infinite values) raises
    :class:`ConfigError` saying what was expected.

    >>> box = gym.spaces.Box(0.0, 1.0, (2,))
    >>> check_observations([0.5, 0.5], box)[0].shape, check_observations(np.zeros((3, 2)), box)[1]
    ((1, 2), False)
    >>> check_observations(np.zeros(4), box)
    Traceback (most recent call last):
    tlac.errors.ConfigError: predict: expected one observation of shape (2,) or a batch (n, 2),
    got shape (4,)
    """
    try:
        array = np.asarray(obs)  # the caller's dtype is kept: teachers get what they expect
    except (TypeError, ValueError):  # ragged nested lists
        array = None
    if array is None or array.dtype.kind not in "biuf":
        raise ConfigError(
            f"predict: expected numeric observations of shape {space.shape}, "
            f"got {type(obs).__name__}"
        )
    shape = tuple(space.shape or ())
    if array.shape == shape:
        single, array = True, array[None]
    elif array.ndim == len(shape) + 1 and array.shape[1:] == shape and len(array) > 0:
        single = False
    else:
        batch = f"({', '.join(['n', *map(str, shape)])})"
        raise ConfigError(
            f"predict: expected one observation of shape {shape} or a batch {batch}, "
            f"got shape {array.shape}"
        )
    if array.dtype.kind == "f" and not np.isfinite(array).all():
        raise ConfigError("predict: the observations contain NaN or infinite values")
    return array, single


def stop_if_not_finite(value: torch.Tensor, algo: str, step: int, what: str = "loss") -> None:
    """Raise :class:`TrainingError` when ``value`` (a loss or a gradient norm) is NaN or
    infinite: the update is not applied, the run stops, and nothing is marked finished."""
    if not bool(torch.isfinite(value).all()):
        from tlac.errors import TrainingError

        flat = value.detach().reshape(-1)
        bad = float(flat[~torch.isfinite(flat)][0])
        raise TrainingError(
            f"{algo}: non-finite {what} ({bad}) at step {step}; "
            "training stopped (a learning rate too high, or NaN in observations or rewards?)"
        )


MAX_SEED = 2**31 - 1
"""The largest seed: the environments and generators are seeded with the seed plus small
offsets, and NumPy's legacy seeding (Gymnasium's spaces) takes at most 2**32 - 1."""


def random_seed() -> int:
    """A seed drawn from the operating system's entropy (``seed=None``, as SB3 takes it); the
    model records it (``model.seed``), so the run can be repeated."""
    return int(np.random.SeedSequence().entropy % (MAX_SEED + 1))


def check_seed(seed: Any) -> int:
    """A seed is an integer from 0 to MAX_SEED; else ConfigError.

    >>> check_seed(3)
    3
    """
    if (
        isinstance(seed, bool)
        or not isinstance(seed, int | np.integer)
        or not 0 <= seed <= MAX_SEED
    ):
        raise ConfigError(f"seed must be an integer from 0 to {MAX_SEED}, got {seed!r}")
    return int(seed)
