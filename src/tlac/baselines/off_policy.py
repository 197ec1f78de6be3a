"""Plumbing shared by the off-policy baselines (DQN-TLQL and AC-Teach): one replay buffer, one
learn loop (:func:`learn_loop`) with the clock of the exploration schedule and the logging
clock, and one checkpoint format with an optional training state for exact resume.

The learn loop is composed, not inherited: each algorithm keeps its own ``learn`` (its checks
and the start of its loop state) and its own explicit steps, which the loop calls in a fixed
order (:class:`OffPolicySteps`)::

    while num_timesteps < end:
        collect(exploration_rate)      # one vectorised step, stored in the replay buffer
        if update_due(end):
            update()                   # gradient steps, when enough data is stored
            log on the clock           # log_metrics() at tlac.recording.next_log_step
            progress bar, callbacks    # evaluation and checkpoints of tlac.run are callbacks

A checkpoint is ``torch.save`` of plain data and tensors (``torch.load(weights_only=True)``
reads it; see :func:`tlac.algorithms.common.safe_torch_load`)::

    {"algo", "config", "num_timesteps", "seed", "teacher_names", "state": {module: state_dict},
     "observation_space", "action_space" (tlac.algorithms.common.space_to_data),
     ...the algorithm's own fields...,
     "training": {...}   # only with save(training_state=True): see training_state()
     "run": {...}}       # only when tlac.run passes its writers' state

The training state holds what :mod:`tlac.algorithms.resume` lists for TL-AC (generators, the
teachers' generators, the environments with their episodes in progress) plus the replay
buffer and the learn loop's counters, so that a run stopped and resumed from a checkpoint
continues byte-identically (``tests/test_off_policy.py``).
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch

from tlac.algorithms.callbacks import LearnCallbacks
from tlac.algorithms.common import (
    atomic_torch_save,
    check_env_spaces,
    check_finite_weights,
    checkpoint_path,
    linear_epsilon,
    make_progress_bar,
    safe_torch_load,
    space_from_data,
    space_to_data,
)
from tlac.algorithms.resume import (
    generator_states,
    restore_generator_states,
    restore_vec_env,
    vec_env_state,
)
from tlac.errors import ConfigError, TlacError
from tlac.memory import check_fits
from tlac.recording import Recorder, next_log_step


class ReplayBuffer:
    """A ring buffer of named arrays with ``capacity`` rows.

    >>> buf = ReplayBuffer(3, {"obs": ((2,), np.float32), "reward": ((), np.float32)})
    >>> buf.add(obs=np.ones((2, 2)), reward=np.array([1.0, 2.0]))
    >>> buf.add(obs=np.zeros((2, 2)), reward=np.array([3.0, 4.0]))  # wraps: overwrites row 0
    >>> len(buf), buf.arrays["reward"].tolist()
    (3, [4.0, 2.0, 3.0])
    >>> batch = buf.sample(np.random.default_rng(0), 4)
    >>> sorted(batch), tuple(batch["obs"].shape)
    (['obs', 'reward'], (4, 2))
    """

    def __init__(self, capacity: int, fields: dict[str, tuple[tuple[int, ...], Any]]):
        self.capacity = int(capacity)
        row = sum(
            int(np.prod(shape)) * np.dtype(dtype).itemsize for shape, dtype in fields.values()
        )
        check_fits(
            {f"the replay buffer (buffer_size={self.capacity})": row * self.capacity},
            "lower buffer_size",
        )
        self.arrays = {
            name: np.zeros((self.capacity, *shape), dtype)
            for name, (shape, dtype) in fields.items()
        }
        self.pos, self.full = 0, False

    def add(self, **rows: np.ndarray) -> None:
        """Append a batch of rows (every field, first axis the batch)."""
        n = len(next(iter(rows.values())))
        idx = (self.pos + np.arange(n)) % self.capacity
        for name, value in rows.items():
            self.arrays[name][idx] = value
        self.full |= self.pos + n >= self.capacity
        self.pos = int((self.pos + n) % self.capacity)

    def __len__(self) -> int:
        return self.capacity if self.full else self.pos

    def sample(self, rng: np.random.Generator, batch_size: int) -> dict[str, torch.Tensor]:
        """``batch_size`` rows drawn uniformly with replacement by ``rng``."""
        idx = rng.integers(0, len(self), size=batch_size)
        return {name: torch.as_tensor(a[idx]) for name, a in self.arrays.items()}

    def state(self) -> dict[str, Any]:
        """The filled rows as tensors, and the write position."""
        n = len(self)
        return {
            "arrays": {name: torch.from_numpy(a[:n].copy()) for name, a in self.arrays.items()},
            "pos": self.pos,
            "full": self.full,
        }

    def restore(self, state: dict[str, Any]) -> None:
        """Put back what :meth:`state` saved (the same fields and capacity)."""
        for name, value in state["arrays"].items():
            if name not in self.arrays or len(value) > self.capacity:
                raise ConfigError(
                    f"the checkpoint's replay buffer does not fit this model (field {name!r}, "
                    f"{len(value)} rows for a capacity of {self.capacity})"
                )
            self.arrays[name][: len(value)] = value.numpy()
        self.pos, self.full = int(state["pos"]), bool(state["full"])


def schedule_progress(num_timesteps: int, schedule: tuple[int, int]) -> float:
    """The share of the schedule's steps done: ``(t - origin) / horizon``, for the linear
    exploration rate. ``schedule``: (first step, number of steps) of the ``learn`` call that
    set it, or of the interrupted call that a resumed model continues.

    >>> schedule_progress(1500, (1000, 2000))
    0.25
    """
    origin, horizon = schedule
    return (num_timesteps - origin) / max(1, horizon)


class OffPolicySteps(Protocol):
    """What :func:`learn_loop` asks of an algorithm: its explicit steps, and the loop's clocks
    as attributes (they are part of the training state, :func:`training_state`)."""

    config: Any  # exploration_initial_eps, exploration_final_eps, exploration_fraction
    recorder: Recorder | None
    num_timesteps: int
    _next_log: int | None  # the logging clock: the step at or after which the next log falls
    _schedule: tuple[int, int] | None  # the exploration schedule's clock
    _resumed_schedule: tuple[int, int] | None

    def collect(self, exploration_rate: float) -> None:
        """Act in every environment once, store the transitions, advance ``num_timesteps``."""

    def update_due(self, end: int) -> bool:
        """Whether an update follows the step just collected (``end``: the call's last step)."""

    def update(self) -> None:
        """The gradient steps of one update (none while too little data is stored)."""

    def log_metrics(self) -> dict[str, float]:
        """The algorithm's own metrics for ``progress.csv`` at a logging step."""


def exploration_rate(model: OffPolicySteps) -> float:
    """Epsilon of the linear exploration schedule at ``model.num_timesteps`` (SB3's DQN
    schedule, over the steps of the ``learn`` call that set the schedule's clock)."""
    cfg = model.config
    assert model._schedule is not None
    return linear_epsilon(
        schedule_progress(model.num_timesteps, model._schedule),
        cfg.exploration_initial_eps,
        cfg.exploration_final_eps,
        cfg.exploration_fraction,
    )


def learn_loop(
    model: OffPolicySteps, total_timesteps: int, callback: Any, progress_bar: bool, desc: str
) -> None:
    """Run ``total_timesteps`` environment steps (over all environments; the caller's
    ``learn`` has checked the number) of ``model``'s collect / update steps (see the module
    docstring). The exploration schedule spans this
    call, or the interrupted call that a resumed model continues; metrics are logged at the
    first update at or after :func:`tlac.recording.next_log_step` of the last log (of the
    first step, for the first log), with the exploration rate and the steps per second;
    ``callback`` runs after every update (:class:`tlac.algorithms.callbacks.LearnCallbacks`)."""
    start, end = model.num_timesteps, model.num_timesteps + int(total_timesteps)
    model._schedule = model._resumed_schedule or (start, int(total_timesteps))
    model._resumed_schedule = None
    recorder = model.recorder
    if recorder is not None and model._next_log is None:
        model._next_log = next_log_step(start, recorder.log_interval)
    t0 = time.time()
    bar = make_progress_bar(total_timesteps, desc, progress_bar)
    learn_locals = {"total_timesteps": end, "callback": callback, "progress_bar": progress_bar}
    callbacks = LearnCallbacks(callback, model, learn_locals)  # (SB3's names of learn)
    while model.num_timesteps < end:
        eps = exploration_rate(model)
        model.collect(eps)
        if not model.update_due(end):
            continue
        model.update()
        if recorder is not None and model.num_timesteps >= (model._next_log or 0):
            fps = (model.num_timesteps - start) / max(time.time() - t0, 1e-9)
            metrics = {**model.log_metrics(), "rollout/exploration_rate": eps, "time/fps": fps}
            recorder.record_metrics(model.num_timesteps, metrics)
            model._next_log = next_log_step(model.num_timesteps, recorder.log_interval)
        if bar is not None:
            bar.update(min(model.num_timesteps, end) - start - bar.n)
        if not callbacks.after_update():
            break
    callbacks.end()
    if bar is not None:
        bar.close()


def _tensor(a: np.ndarray | None) -> torch.Tensor | None:
    return None if a is None else torch.from_numpy(np.array(a))


def _array(t: torch.Tensor | None) -> np.ndarray | None:
    return None if t is None else t.numpy().copy()


def training_state(model: Any) -> dict[str, Any]:
    """What exact resume needs of an off-policy model: its NumPy generator, torch's global
    generator (dropout, initialisation), the teachers' generators, the environments, the
    replay buffer, the exploration schedule's clock and the learn loop's own state (the
    attributes ``_<name>`` for each name in ``model.loop_state``; plain data, arrays as
    tensors)."""
    loop = {name: getattr(model, f"_{name}") for name in model.loop_state}
    return {
        "rng": model.rng.bit_generator.state,
        "torch_rng": torch.get_rng_state(),
        "teachers": [generator_states(t) for t in model.teachers],
        "env": vec_env_state(model.env),
        "buffer": None if model.buffer is None else model.buffer.state(),
        "schedule": None if model._schedule is None else list(model._schedule),
        "loop": {k: _tensor(v) if isinstance(v, np.ndarray) else v for k, v in loop.items()},
    }


def restore_training_state(model: Any, state: dict[str, Any]) -> None:
    """Put back what :func:`training_state` saved."""
    if len(state["teachers"]) != len(model.teachers):
        raise ConfigError(
            f"the checkpoint was saved with {len(state['teachers'])} teachers, "
            f"got {len(model.teachers)}"
        )
    model.rng.bit_generator.state = state["rng"]
    torch.set_rng_state(state["torch_rng"])
    for teacher, states in zip(model.teachers, state["teachers"], strict=True):
        restore_generator_states(teacher, states)
    exact_envs = restore_vec_env(model.env, state["env"])
    if state["buffer"] is not None:
        model.buffer = model.new_buffer()
        model.buffer.restore(state["buffer"])
    schedule = state["schedule"]
    model._resumed_schedule = None if schedule is None else (int(schedule[0]), int(schedule[1]))
    for name, value in state["loop"].items():
        setattr(model, f"_{name}", _array(value) if isinstance(value, torch.Tensor) else value)
    if not exact_envs:
        model._last_obs = None  # new episodes: learn() resets the environments


def save_checkpoint(
    model: Any,
    path: str | Path,
    fields: dict[str, Any],
    modules: dict[str, Any],
    training_state_too: bool,
    run_state: dict[str, Any] | None,
) -> Path:
    """Write ``path.pt``: the common fields, the algorithm's own ``fields``, the state dicts
    of ``modules``, and, with ``training_state_too`` (``save(training_state=True)``), the
    training state. Returns the file's path."""
    data: dict[str, Any] = {
        "algo": model.algo,
        "config": dataclasses.asdict(model.config),
        "teacher_names": [t.name for t in model.teachers],
        "num_timesteps": model.num_timesteps,
        "seed": model.seed,
        "observation_space": space_to_data(model.observation_space),
        "action_space": space_to_data(model.action_space),
        **fields,
        "state": {name: m.state_dict() for name, m in modules.items()},
    }
    if training_state_too:
        data["training"] = training_state(model)
    if run_state is not None:
        data["run"] = run_state
    return atomic_torch_save(data, checkpoint_path(path))


def load_model(
    cls: Any,
    path: str | Path,
    env: Any,
    teachers: list[Any] | None,
    resume: bool,
    setup_count: str,
) -> Any:
    """Rebuild a model of ``cls`` from its checkpoint: the settings, the spaces (checked
    against ``env``'s), the networks and optimizers, the step count, and with ``resume`` the
    training state. ``setup_count``: the checkpoint field that ``cls._setup`` takes third
    (the number of choices or of teachers)."""
    data = load_checkpoint(path, cls.algo, resume, env)
    try:
        model = cls(
            env=None, teachers=teachers, seed=int(data["seed"]), recorder=None, **data["config"]
        )
        obs_space = space_from_data(data["observation_space"])
        action_space = space_from_data(data["action_space"])
        check_env_spaces(env, obs_space, action_space)
        model._setup(obs_space, action_space, int(data[setup_count]))
        for name, state_dict in data["state"].items():
            getattr(model, name).load_state_dict(state_dict)
            check_finite_weights(state_dict, checkpoint_path(path))
        model.num_timesteps, model.env = int(data["num_timesteps"]), env
        if resume:
            restore_training_state(model, data["training"])
    except TlacError:
        raise
    except (KeyError, TypeError, ValueError, RuntimeError, IndexError, AttributeError) as exc:
        problem = " ".join(str(exc).split())
        raise ConfigError(
            f"{str(checkpoint_path(path))!r} is not a loadable {cls.algo} model file: "
            f"{type(exc).__name__} {problem[:200]} (missing keys, wrong tensor shapes or a "
            "broken optimizer state)"
        ) from None
    return model


def load_checkpoint(path: str | Path, algo: str, resume: bool, env: Any) -> dict[str, Any]:
    """Read a checkpoint written by :func:`save_checkpoint` for ``algo`` (no code runs);
    one-line ConfigError when it is missing, of another algorithm, or lacks the training
    state that ``resume`` asks for."""
    p = checkpoint_path(path)
    if not p.exists():
        raise ConfigError(f"no {algo} model at {str(p)!r}")
    data = safe_torch_load(p, f"{algo} model")
    if not isinstance(data, dict) or data.get("algo") != algo:
        found = data.get("algo") if isinstance(data, dict) else None
        raise ConfigError(f"{str(p)!r} is not a {algo} model file (it holds {found!r})")
    if resume:
        if "training" not in data:
            raise ConfigError(
                f"{str(p)!r} holds no training state; save it with training_state=True"
            )
        if env is None:
            raise ConfigError("resume=True needs env (the environments are restored into it)")
    return data
