"""Run-folder writers shared by every algorithm (file formats: ``docs/architecture.md``).

* :class:`EpisodeRecorder` wraps a stable-baselines3 ``VecEnv`` and writes one row per finished
  training episode to ``episodes.csv`` (``timestep,return,length``); it also fills
  ``info["episode"]`` like SB3's ``Monitor`` so SB3 baselines log their own returns.
* :class:`Recorder` accumulates the high level's selections per region and writes
  ``teacher_usage.csv`` once per logging window, and training scalars to ``progress.csv``
  (long format ``timestep,key,value``) and optionally TensorBoard.
* :class:`EpisodeLog` wraps each environment under it and keeps what re-creates its episode in
  progress (how it was reset, the actions since), which checkpoints store instead of the
  environment itself (:mod:`tlac.algorithms.resume`).
* :func:`platform_record` says where a run was made (result.json's ``platform``).
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import json
import platform
import time
from collections import deque
from collections.abc import Callable, Iterable
from importlib import metadata
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3.common.vec_env import (
    DummyVecEnv,
    VecEnv,
    VecEnvWrapper,
    unwrap_vec_normalize,
)

from tlac.errors import require_extra

MONITOR_FILE = "monitor.csv"
"""Written beside episodes.csv in stable-baselines3's Monitor format (a JSON header line, then
``r,l,t``: return, length, seconds since the start), so that SB3 / rl-zoo tools
(``stable_baselines3.common.monitor.load_results``) read a run folder."""


PLATFORM_PACKAGES = ("torch", "numpy", "gymnasium", "minigrid", "stable-baselines3")


def installed_versions(packages: Iterable[str]) -> dict[str, str]:
    """Name -> installed version of each of ``packages`` that is installed, in their order."""
    versions = {}
    for package in packages:
        with contextlib.suppress(metadata.PackageNotFoundError):
            versions[package] = metadata.version(package)
    return versions


def platform_record() -> dict[str, str]:
    """The machine and package versions a run was made with, for result.json: runs on two
    machine types can differ in their bytes (docs/architecture.md, "Golden hashes across
    machines"), so each run says where it was made."""
    record = {"python": platform.python_version(), "machine": platform.machine()}
    with contextlib.suppress(OSError):  # not Linux: no /proc/cpuinfo, the CPU stays unnamed
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = (part.strip() for part in line.partition(":"))
            if key == "model name":
                record["cpu"] = value
            elif key == "flags":  # a model name can be generic ("Intel(R) Xeon(R) Processor")
                record["avx512"] = "yes" if "avx512f" in value.split() else "no"
            if "cpu" in record and "avx512" in record:
                break
    versions = installed_versions(PLATFORM_PACKAGES)
    record.update(
        {package: versions.get(package, "not installed") for package in PLATFORM_PACKAGES}
    )
    return record


def next_log_step(timestep: int, interval: int) -> int:
    """The logging clock of every algorithm: the first multiple of ``interval`` after
    ``timestep``. A learn loop logs its metrics at the first update that reaches this step,
    then sets the clock again from the step it logged at, so that every algorithm writes
    ``progress.csv`` on the same grid as the teacher-usage windows, whatever step it starts or
    resumes from.

    >>> (next_log_step(0, 500), next_log_step(499, 500), next_log_step(500, 500),
    ...  next_log_step(1234, 500))
    (500, 500, 1000, 1500)
    """
    return (timestep // interval + 1) * interval


class MetricWindow:
    """The statistics of the updates between two logging steps (:func:`next_log_step`); at a
    logging step, :meth:`flush` gives each one's mean over the window, or its last value for a
    count such as ``train/n_updates``.

    >>> window = MetricWindow(counts=("train/n_updates",))
    >>> window.add({"train/value_loss": 1.0, "train/n_updates": 5})
    >>> window.add({"train/value_loss": 3.0, "train/n_updates": 10})
    >>> window.flush()
    {'train/value_loss': 2.0, 'train/n_updates': 10.0}
    >>> window.flush()
    {}
    """

    def __init__(self, counts: tuple[str, ...] = ()):
        self.counts = counts
        self._values: dict[str, list[float]] = {}

    def add(self, stats: dict[str, float]) -> None:
        for key, value in stats.items():
            self._values.setdefault(key, []).append(value)

    def state(self) -> dict[str, np.ndarray]:
        """The statistics so far, each an array as NumPy makes it of the values (its mean is
        the same), for checkpoints."""
        return {key: np.asarray(values) for key, values in self._values.items()}

    def restore(self, state: dict[str, np.ndarray]) -> None:
        self._values = {key: list(np.asarray(values)) for key, values in state.items()}

    def flush(self) -> dict[str, float]:
        out = {k: float(v[-1] if k in self.counts else np.mean(v)) for k, v in self._values.items()}
        self._values.clear()
        return out


REPLAY_LIMIT = 100_000
"""The longest episode in progress that :class:`EpisodeLog` keeps the actions of; a longer one
cannot be re-created (a resume starts new episodes instead)."""


def observation_digest(obs: Any) -> str:
    """A sha256 of an observation (an array, or a dict of arrays), its dtypes and shapes
    included: how a re-created episode is checked against the original."""
    digest = hashlib.sha256()
    items = sorted(obs.items()) if isinstance(obs, dict) else [("", obs)]
    for key, value in items:
        array = np.ascontiguousarray(value)
        digest.update(f"{key}|{array.dtype.str}|{array.shape}|".encode())
        digest.update(array.tobytes())
    return digest.hexdigest()


class EpisodeLog(gym.Wrapper):
    """What re-creates the episode in progress of one environment, as plain data: the seed of
    the reset that began it or, for a reset without one, the state of the environment's
    generator just before it, and every action since. A checkpoint stores this
    (:meth:`state`) rather than the environment itself, whose objects can only be pickled, and
    :meth:`replay` redoes the episode in a fresh copy: a Gymnasium environment draws its
    randomness from ``np_random``, so the same reset and the same actions give the same
    episode (checked against the digest of its last observation). This holds for PyBullet's
    and MuJoCo's simulations too, which no pickle can carry.

    >>> env = EpisodeLog(gym.make("CartPole-v1"))
    >>> _ = env.reset(seed=3); _ = [env.step(a) for a in (0, 1, 1)]
    >>> again = EpisodeLog(gym.make("CartPole-v1"))
    >>> again.replay(env.state()), again.state()["obs_sha256"] == env.state()["obs_sha256"]
    (True, True)
    """

    def __init__(self, env: gym.Env):
        super().__init__(env)
        self._seed: int | None = None
        self._rng: dict[str, Any] | None = None
        self._actions: list[np.ndarray] | None = None  # None: nothing to re-create
        self._last_obs: Any = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        rng = None if seed is not None else self.env.np_random.bit_generator.state
        obs, info = self.env.reset(seed=seed, options=options)
        self._seed, self._rng = (None if seed is None else int(seed)), rng
        self._actions = [] if options is None else None  # reset options are not kept
        self._last_obs = obs
        return obs, info

    def step(self, action: Any) -> Any:
        if self._actions is not None:
            if len(self._actions) < REPLAY_LIMIT:
                self._actions.append(np.array(action))  # a copy, as the environment got it
            else:
                self._actions = None
        result = self.env.step(action)
        self._last_obs = result[0]
        return result

    def state(self) -> dict[str, Any] | None:
        """The episode in progress as plain data and a tensor (None where it cannot be
        re-created: never reset, reset with options, or longer than :data:`REPLAY_LIMIT`)."""
        import torch

        if self._actions is None:
            return None
        actions = np.stack(self._actions) if self._actions else np.zeros(0)
        return {
            "seed": self._seed,
            "rng": self._rng,
            "actions": torch.from_numpy(actions),
            "steps": len(self._actions),
            "obs_sha256": observation_digest(self._last_obs),
        }

    def replay(self, state: dict[str, Any] | None) -> bool:
        """Re-create the episode that :meth:`state` described, in this environment; whether
        it came out the same (same length, same last observation)."""
        if not isinstance(state, dict) or state.get("actions") is None:
            return False
        try:
            if state["seed"] is None:
                self.env.np_random.bit_generator.state = state["rng"]
            self.reset(seed=state["seed"])
            actions = state["actions"].numpy()[: int(state["steps"])]
            for action in actions:
                _, _, terminated, truncated, _ = self.step(action)
                if terminated or truncated:
                    return False  # the original episode went on
        except Exception:  # noqa: BLE001 - any failure means the episode is not re-created
            return False
        return observation_digest(self._last_obs) == state["obs_sha256"]


def episode_logs(venv: VecEnv) -> DummyVecEnv | None:
    """The DummyVecEnv under ``venv``'s wrappers, its environments wrapped in
    :class:`EpisodeLog` (done once); None for a VecEnv whose environments are not in this
    process (SubprocVecEnv)."""
    while not isinstance(venv, DummyVecEnv):
        venv = getattr(venv, "venv", None)
        if venv is None:
            return None
    venv.envs = [
        EpisodeLog(env) if isinstance(env, gym.Env) and not isinstance(env, EpisodeLog) else env
        for env in venv.envs
    ]
    return venv


class EpisodeRecorder(VecEnvWrapper):
    """Counts environment steps over all sub-environments and records finished episodes:
    ``path`` (episodes.csv: ``timestep,return,length``) and, beside it, ``monitor.csv``."""

    domain_name: str | None = None
    """The tlac domain whose environments these are (``tlac.domains.make_vec_env`` sets it):
    the name a model trained on them records (``TLAC.save``)."""

    def __init__(self, venv: VecEnv, path: str | Path | None = None, window: int = 20):
        super().__init__(venv)
        episode_logs(venv)  # what a checkpoint keeps of the episodes in progress
        # returns in the environment's own units even under a user's VecNormalize
        self._vec_normalize = unwrap_vec_normalize(venv)
        self.num_timesteps = 0
        self.episode_returns: deque[float] = deque(maxlen=window)
        self.episode_lengths: deque[int] = deque(maxlen=window)
        self.episodes_done = 0
        # per environment: its last finished episode's return, its number among all the
        # episodes (1-based: its row in episodes.csv) and the step it ended at (0, NaN: none)
        self.last_return = np.full(self.num_envs, np.nan)
        self.last_episode = np.zeros(self.num_envs, dtype=np.int64)
        self.last_end = np.zeros(self.num_envs, dtype=np.int64)
        self._returns = np.zeros(self.num_envs)
        self._lengths = np.zeros(self.num_envs, dtype=np.int64)
        self._files: list[Any] = []
        self._writer: Any = None
        self._monitor: Any = None
        self._t_start = time.time()
        if path is not None:
            path = Path(path)
            new = not path.exists()
            self._files.append(open(path, "a", newline=""))  # noqa: SIM115 - closed in close()
            self._writer = csv.writer(self._files[0])
            if new:  # on disk at once: a run killed before its first episode keeps it
                self._writer.writerow(["timestep", "return", "length"])
                self._files[0].flush()
            self._monitor = self._open_monitor(path.with_name(MONITOR_FILE))

    def _open_monitor(self, path: Path) -> Any:
        """Open (or continue, keeping its start time) the SB3 Monitor-format file."""
        if path.exists():
            try:
                with path.open() as f:
                    self._t_start = float(json.loads(f.readline()[1:])["t_start"])
            except (ValueError, KeyError, IndexError):
                pass  # a damaged header: the times restart from now
        else:
            with path.open("w") as f:
                f.write("#" + json.dumps({"t_start": self._t_start, "env_id": "tlac"}) + "\n")
                f.write("r,l,t\n")
        self._files.append(open(path, "a", newline=""))  # noqa: SIM115 - closed in close()
        return csv.writer(self._files[-1])

    def reset(self) -> Any:
        self._returns[:] = 0
        self._lengths[:] = 0
        return self.venv.reset()

    def step_wait(self) -> Any:
        obs, rewards, dones, infos = self.venv.step_wait()
        infos = list(infos)  # SubprocVecEnv returns a tuple
        self.num_timesteps += self.num_envs
        vec_normalize = self._vec_normalize
        self._returns += rewards if vec_normalize is None else vec_normalize.get_original_reward()
        self._lengths += 1
        for i in np.flatnonzero(dones):
            ret, length = float(self._returns[i]), int(self._lengths[i])
            self.episode_returns.append(ret)
            self.episode_lengths.append(length)
            self.episodes_done += 1
            end = self.num_timesteps - self.num_envs + i + 1
            self.last_return[i], self.last_episode[i], self.last_end[i] = (
                ret,
                self.episodes_done,
                end,
            )
            infos[i] = dict(infos[i])
            elapsed = round(time.time() - self._t_start, 6)  # as SB3's Monitor
            infos[i]["episode"] = {"r": ret, "l": length, "t": elapsed}
            if self._writer is not None:
                # the step at which this episode ended, counted over all environments
                self._writer.writerow([end, ret, length])
                self._monitor.writerow([ret, length, elapsed])
            self._returns[i] = 0.0
            self._lengths[i] = 0
        if dones.any():
            for f in self._files:
                f.flush()
        return obs, rewards, dones, infos

    def mean_recent_return(self) -> float:
        return float(np.mean(self.episode_returns)) if self.episode_returns else float("nan")

    def mean_recent_length(self) -> float:
        return float(np.mean(self.episode_lengths)) if self.episode_lengths else float("nan")

    def close(self) -> None:
        for f in self._files:
            f.close()
        self._files = []
        self.venv.close()


def find_episode_recorder(env: Any) -> EpisodeRecorder | None:
    """The :class:`EpisodeRecorder` inside a stack of VecEnv wrappers, if any."""
    while env is not None:
        if isinstance(env, EpisodeRecorder):
            return env
        env = getattr(env, "venv", None)
    return None


class Recorder:
    """Teacher-usage statistics per region, and training scalars, for one run folder.

    ``choice_names`` lists the high level's options: the teachers in order, then ``agent``
    (index ``len(teachers)``, the paper's E = E_0 U {Agent}, section 3.2).
    """

    def __init__(
        self,
        out_dir: str | Path | None,
        choice_names: list[str],
        region_names: tuple[str, ...] = ("all",),
        region_of: Callable[[np.ndarray], np.ndarray] | None = None,
        log_interval: int = 2000,
        tensorboard: bool = False,
    ):
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.choice_names = list(choice_names)
        self.region_names = tuple(region_names)
        self.region_of = region_of
        self.log_interval = int(log_interval)
        self._counts = np.zeros((len(self.region_names), len(self.choice_names)), dtype=np.int64)
        self._next_flush = self.log_interval
        self.last_usage: dict[str, float] = {}
        self.last_metrics: dict[str, float] = {}
        self._tb: Any = None
        self._usage_file = self._progress_file = None
        if self.out_dir is not None:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            self._usage_file, self._usage = self._open(
                "teacher_usage.csv", ["timestep", "region", "choice", "count", "fraction"]
            )
            self._progress_file, self._progress = self._open(
                "progress.csv", ["timestep", "key", "value"]
            )
            if tensorboard:
                require_extra("tensorboard", "TensorBoard logs", "tensorboard")
                from torch.utils.tensorboard import SummaryWriter

                self._tb = SummaryWriter(str(self.out_dir / "tb"))

    def _open(self, name: str, header: list[str]) -> tuple[Any, Any]:
        assert self.out_dir is not None
        path = self.out_dir / name
        new = not path.exists()
        f = open(path, "a", newline="")  # noqa: SIM115 - closed in close()
        w = csv.writer(f)
        if new:  # on disk at once: a run killed before its first log keeps it
            w.writerow(header)
            f.flush()
        return f, w

    def window_end_after(self, timestep: int) -> int:
        """The first multiple of ``log_interval`` after ``timestep``: where the logging window
        that contains ``timestep`` ends (:func:`next_log_step`; the algorithms log their
        metrics on the same grid)."""
        return next_log_step(timestep, self.log_interval)

    def record_selections(self, timestep: int, choices: np.ndarray, obs: np.ndarray) -> None:
        """Count the high level's choices (ints into ``choice_names``) made in states ``obs``
        (first axis aligned with ``choices``); flushes a window when ``timestep`` passes it."""
        choices = np.asarray(choices).reshape(-1)
        if self.region_of is not None and len(self.region_names) > 1:
            flat_obs = np.asarray(obs).reshape(len(choices), -1) if np.ndim(obs) > 1 else obs
            regions = np.asarray(self.region_of(flat_obs), dtype=np.int64).reshape(-1)
        else:
            regions = np.zeros(len(choices), dtype=np.int64)
        np.add.at(self._counts, (regions, choices), 1)
        if timestep >= self._next_flush:
            self.flush(timestep)

    def window_state(self) -> dict[str, Any]:
        """The logging window in progress, as JSON data (for checkpoints)."""
        return {"counts": self._counts.tolist(), "next_flush": int(self._next_flush)}

    def load_window_state(self, state: dict[str, Any]) -> None:
        self._counts[...] = np.asarray(state["counts"], dtype=np.int64)
        self._next_flush = int(state["next_flush"])

    def flush(self, timestep: int) -> None:
        """Write the current window's usage rows (overall and per region) and start a new one."""
        if self._counts.sum() == 0:
            self._next_flush = self.window_end_after(timestep)
            return
        rows = [("all", self._counts.sum(axis=0))]
        if len(self.region_names) > 1:
            rows += list(zip(self.region_names, self._counts, strict=True))
        for region, counts in rows:
            total = counts.sum()
            if total == 0:
                continue
            for name, c in zip(self.choice_names, counts, strict=True):
                frac = float(c) / float(total)
                if region == "all":
                    self.last_usage[name] = frac
                if self._usage_file is not None:
                    self._usage.writerow([timestep, region, name, int(c), f"{frac:.6g}"])
                if self._progress_file is not None:
                    self._progress.writerow([timestep, f"teacher/{region}/{name}", f"{frac:.6g}"])
                if self._tb is not None:
                    self._tb.add_scalar(f"teacher/{region}/{name}", frac, timestep)
        for f in (self._usage_file, self._progress_file):
            if f is not None:
                f.flush()
        self._counts[:] = 0
        self._next_flush = self.window_end_after(timestep)

    def record_metrics(self, timestep: int, metrics: dict[str, float]) -> None:
        """Write scalars under the fixed namespaces (``train/``, ``rollout/``, ``time/``)."""
        self.last_metrics.update(metrics)
        for key, value in metrics.items():
            if self._progress_file is not None:
                self._progress.writerow([timestep, key, f"{float(value):.8g}"])
            if self._tb is not None:
                self._tb.add_scalar(key, float(value), timestep)
        if self._progress_file is not None:
            self._progress_file.flush()

    def close(self, timestep: int | None = None) -> None:
        if timestep is not None:
            self.flush(timestep)
        for f in (self._usage_file, self._progress_file):
            if f is not None:
                f.close()
        self._usage_file = self._progress_file = None
        if self._tb is not None:
            self._tb.close()
            self._tb = None
