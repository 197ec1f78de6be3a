"""Callbacks for tlac's own learn loops (TL-AC, DQN-TLQL, AC-Teach), as stable-baselines3 users
pass them: a plain function, an SB3 ``BaseCallback`` (``EvalCallback``, ``CheckpointCallback``,
``CallbackList``, your own subclass), or a list mixing both.

* A plain function ``f(model) -> bool | None`` runs once after every update (a TL-AC rollout
  and its epochs, a DQN-TLQL training step, an AC-Teach cycle); ``False`` stops training.
* An SB3 callback gets SB3's protocol: ``init_callback(model)`` and ``on_training_start`` when
  ``learn`` starts, with ``self.locals`` holding SB3's names of ``learn`` (``total_timesteps``
  is the step count at which this call ends, as SB3's ``ProgressBarCallback`` reads it), and
  ``on_training_end`` at the end. TL-AC calls the rest as SB3's ``collect_rollouts`` does:
  ``on_rollout_start``; ``on_step`` after every vectorised environment step, with that step's
  ``self.locals`` (``new_obs``, ``rewards``, ``dones``, ``infos``, ``actions``, ``env``,
  ``n_steps``, ``rollout_buffer``...), so that ``StopTrainingOnMaxEpisodes`` counts episodes and
  a callback returning ``False`` stops training at that step, without an update on the rollout
  it cut short; ``on_rollout_end`` before the update. DQN-TLQL and AC-Teach step the
  environments inside their own loop: the ``on_step`` calls of one of their updates come
  together after it (``model.num_timesteps`` is then the step count after the update), and
  ``self.locals`` holds only ``learn``'s names.
* Calling them changes nothing in training: no random draw, no computation of the training's
  own (a callback that itself calls ``predict(deterministic=False)`` draws from the model's
  acting generator, as it does in SB3).

For these, the algorithms offer what SB3 callbacks use of a model: ``get_env()``,
``get_vec_normalize_env()``, ``logger`` (an SB3 ``Logger``), ``num_timesteps``,
``predict(observation, state, episode_start, deterministic)``, ``save(path)`` and (TL-AC, which
keeps them in a composed :class:`SB3Logs`) ``ep_info_buffer`` / ``ep_success_buffer``: the last
100 finished training episodes' ``{"r", "l", "t"}`` and ``is_success``, as SB3 keeps them. The
off-policy baselines have theirs from :class:`SB3Compat`.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger, configure
from stable_baselines3.common.vec_env import VecNormalize, unwrap_vec_normalize

from tlac.errors import ConfigError, require_extra
from tlac.recording import EpisodeRecorder

EPISODE_WINDOW = 100
"""The finished episodes that ``ep_info_buffer`` keeps (SB3's ``stats_window_size``)."""


def training_env(env: Any) -> Any:
    """The training environments as SB3's ``get_env()`` gives them: the VecEnv the user gave
    (or tlac made), without the episode recorder tlac wraps around it, so that SB3's callbacks
    find the same wrappers as in their evaluation environments (``EvalCallback`` compares the
    types and syncs a ``VecNormalize`` layer by layer)."""
    return env.venv if isinstance(env, EpisodeRecorder) else env


def vec_normalize_of(env: Any) -> VecNormalize | None:
    """The ``VecNormalize`` in the training environments' wrappers, if the user gave one
    (SB3's ``get_vec_normalize_env()``): ``EvalCallback`` syncs its statistics into the
    evaluation environments and ``CheckpointCallback(save_vecnormalize=True)`` saves it."""
    return unwrap_vec_normalize(env) if env is not None else None


class SB3Logs:
    """What SB3 callbacks and SB3's logging read of a model that trains in SB3's way (TL-AC
    holds one, ``model.sb3``): the SB3 ``Logger``, the TensorBoard run it writes to, and the
    last 100 finished training episodes (``ep_info_buffer``, ``ep_success_buffer``)."""

    def __init__(self) -> None:
        self.logger: Logger | None = None  # made on first use (:meth:`get_logger`)
        self.tb_log_name = "TLAC"
        self.tb_configured = False
        self.ep_info_buffer: deque[dict[str, Any]] | None = None
        self.ep_success_buffer: deque[Any] | None = None

    def get_logger(self) -> Logger:
        """An SB3 ``Logger`` for callbacks (``EvalCallback`` records its results there); it
        writes nothing unless given output formats (``set_logger``)."""
        if self.logger is None:
            self.logger = Logger(folder=None, output_formats=[])
        return self.logger

    def new_info_buffers(self, reset: bool = True) -> None:
        """SB3's ``ep_info_buffer`` and ``ep_success_buffer`` (the last 100 episodes), new at a
        ``learn`` call that resets the step count, or when there are none yet."""
        if reset or self.ep_info_buffer is None:
            self.ep_info_buffer = deque(maxlen=EPISODE_WINDOW)
            self.ep_success_buffer = deque(maxlen=EPISODE_WINDOW)

    def record_episode_info(self, info: dict[str, Any]) -> None:
        """A finished episode's ``info``, kept as SB3's ``_update_info_buffer`` keeps it: its
        ``"episode"`` record (``{"r", "l", "t"}``: tlac's episode recorder, or a ``Monitor``, puts
        it there) and its ``"is_success"``."""
        if self.ep_info_buffer is None or self.ep_success_buffer is None:
            self.new_info_buffers()
            assert self.ep_info_buffer is not None and self.ep_success_buffer is not None
        episode, success = info.get("episode"), info.get("is_success")
        if episode is not None:
            self.ep_info_buffer.append(episode)
        if success is not None:
            self.ep_success_buffer.append(success)

    def learn_arguments(
        self, log_interval: Any, tb_log_name: Any, reset_num_timesteps: Any
    ) -> int | None:
        """Check and apply SB3's ``learn`` arguments ``tb_log_name`` and
        ``reset_num_timesteps`` (its flag only; the caller resets); returns ``log_interval``
        (steps here), checked."""
        if log_interval is not None and (
            isinstance(log_interval, bool) or not isinstance(log_interval, int) or log_interval < 1
        ):
            raise ConfigError(
                f"log_interval: expected a positive number of steps, got {log_interval!r}"
            )
        if not isinstance(tb_log_name, str) or not tb_log_name or "/" in tb_log_name:
            raise ConfigError(f"tb_log_name: expected a folder name, got {tb_log_name!r}")
        if tb_log_name != self.tb_log_name:
            self.tb_log_name, self.tb_configured = tb_log_name, False
        if not isinstance(reset_num_timesteps, bool):
            raise ConfigError(
                f"reset_num_timesteps: expected True or False, got {reset_num_timesteps!r}"
            )
        return log_interval

    def output(self, verbose: int, tensorboard_log: str | None) -> bool:
        """Whether ``learn`` writes its scalars to the SB3 logger (``verbose`` or
        ``tensorboard_log``); configures that logger on first use, a TensorBoard run in the
        next free ``<tb_log_name>_<n>`` folder (``TLAC_<n>`` by default)."""
        if tensorboard_log is not None and not self.tb_configured:
            require_extra("tensorboard", "tensorboard_log", "tensorboard")
            folder = Path(tensorboard_log)
            name = self.tb_log_name
            n = 1 + sum(1 for p in folder.glob(f"{name}_*")) if folder.exists() else 1
            formats = ["tensorboard"] + (["stdout"] if verbose else [])
            self.logger = configure(str(folder / f"{name}_{n}"), formats)
            self.tb_configured = True
        elif verbose and self.logger is None:
            self.logger = configure(None, ["stdout"])
        return bool(verbose or tensorboard_log is not None)


class SB3Compat:
    """What SB3 callbacks ask of a model, for the off-policy baselines (DQN-TLQL, AC-Teach):
    ``get_env()``, ``get_vec_normalize_env()`` and ``logger``."""

    env: Any
    _sb3_logger: Logger | None = None

    def get_env(self) -> Any:
        """The training environments (SB3's name): :func:`training_env`."""
        return training_env(self.env)

    def get_vec_normalize_env(self) -> VecNormalize | None:
        """The user's ``VecNormalize`` around the training environments, if any (SB3's name):
        :func:`vec_normalize_of`."""
        return vec_normalize_of(self.env)

    @property
    def logger(self) -> Logger:
        """An SB3 ``Logger`` for callbacks (``EvalCallback`` records its results there); it
        writes nothing unless you give it output formats with :meth:`set_logger`. tlac's own
        logs are the run folder's CSVs (``tlac.recording.Recorder``)."""
        if self._sb3_logger is None:
            self._sb3_logger = Logger(folder=None, output_formats=[])
        return self._sb3_logger

    def set_logger(self, logger: Logger) -> None:
        """Use ``logger`` (for example ``stable_baselines3.common.logger.configure(...)``) for
        what SB3 callbacks record."""
        self._sb3_logger = logger


def check_device(device: Any) -> None:
    """SB3's ``device`` as tlac accepts it: ``"auto"`` or ``"cpu"`` (a ``torch.device`` too);
    anything else is a ConfigError saying that tlac runs on the CPU."""
    if str(device) not in ("auto", "cpu"):
        raise ConfigError(
            f"device {device!r}: tlac runs on the CPU ('auto' or 'cpu'); its networks are "
            "small and acting runs in NumPy, where a GPU would only add transfers"
        )


def check_sb3_arguments(
    verbose: Any, tensorboard_log: Any, device: Any, torch_threads: Any
) -> None:
    """SB3's constructor arguments as tlac accepts them; a bad one raises ConfigError."""
    if verbose not in (0, 1, 2) or isinstance(verbose, bool):
        raise ConfigError(f"verbose must be 0, 1 or 2 (as in SB3), got {verbose!r}")
    if tensorboard_log is not None and not isinstance(tensorboard_log, str | Path):
        raise ConfigError(f"tensorboard_log must be a folder path or None, got {tensorboard_log!r}")
    check_device(device)
    if torch_threads is not None and (
        not isinstance(torch_threads, int) or isinstance(torch_threads, bool) or torch_threads < 1
    ):
        raise ConfigError(
            f"torch_threads must be a positive integer or None, got {torch_threads!r}"
        )


def split_callbacks(callback: Any) -> tuple[list[Any], list[BaseCallback]]:
    """``callback`` (None, one callback or a list) as (plain functions, SB3 callbacks);
    anything else is a ConfigError naming its type."""
    items = [] if callback is None else callback
    if not isinstance(items, list | tuple):
        items = [items]
    for item in items:
        if not (isinstance(item, BaseCallback) or callable(item)):
            raise ConfigError(
                "callback must be a function f(model), an SB3 BaseCallback or a list of "
                f"them; got {type(item).__name__}"
            )
    functions = [c for c in items if not isinstance(c, BaseCallback)]
    return functions, [c for c in items if isinstance(c, BaseCallback)]


class LearnCallbacks:
    """The callbacks of one ``learn`` call (see the module docstring). ``learn_locals``: what
    ``on_training_start`` shows of ``learn`` under SB3's names; ``per_step``: the learn loop
    calls :meth:`rollout_start`, :meth:`step` and :meth:`rollout_end` while it collects (TL-AC),
    else :meth:`after_update` makes the SB3 callbacks' calls of the update's steps.

    >>> class Model(SB3Compat):
    ...     env = type("Env", (), {"num_envs": 2})()
    ...     num_timesteps = 0
    >>> seen = []
    >>> callbacks = LearnCallbacks(lambda m: seen.append(m.num_timesteps), Model())
    >>> model = callbacks.model; model.num_timesteps = 16
    >>> callbacks.after_update(), seen
    (True, [16])
    """

    def __init__(
        self,
        callback: Any,
        model: Any,
        learn_locals: dict[str, Any] | None = None,
        per_step: bool = False,
    ):
        self.model = model
        self.functions, self.sb3 = split_callbacks(callback)
        self.per_step = per_step
        self._steps_seen = model.num_timesteps
        for c in self.sb3:
            c.init_callback(model)
            c.on_training_start({"self": model, **(learn_locals or {})}, {})

    def rollout_start(self) -> None:
        """``on_rollout_start`` for the SB3 callbacks (per-step loops)."""
        for c in self.sb3:
            c.on_rollout_start()

    def step(self, step_locals: dict[str, Any]) -> bool:
        """``on_step`` for the SB3 callbacks after one vectorised environment step, which they
        read in ``self.locals`` (per-step loops); False when one of them asks to stop."""
        go_on = True
        for c in self.sb3:
            c.update_locals(step_locals)
            if c.on_step() is False:
                go_on = False
        return go_on

    def rollout_end(self, rollout_locals: dict[str, Any]) -> None:
        """``on_rollout_end`` for the SB3 callbacks, the rollout's end in ``self.locals``
        (per-step loops)."""
        for c in self.sb3:
            c.update_locals(rollout_locals)
            c.on_rollout_end()

    def after_update(self) -> bool:
        """Run every callback after an update (the SB3 ones' rollout and steps, unless the loop
        made them as it collected); False when one of them asks to stop."""
        model = self.model
        vec_steps = max(1, (model.num_timesteps - self._steps_seen) // model.env.num_envs)
        self._steps_seen = model.num_timesteps
        go_on = True
        for c in [] if self.per_step else self.sb3:
            c.on_rollout_start()
            for _ in range(vec_steps):
                if c.on_step() is False:
                    go_on = False
                    break
            c.on_rollout_end()
        for f in self.functions:
            if f(model) is False:
                go_on = False
        return go_on

    def end(self) -> None:
        """``on_training_end`` for the SB3 callbacks."""
        for c in self.sb3:
            c.on_training_end()
