"""Callbacks for tlac's own learn loops (TL-AC, DQN-TLQL, AC-Teach), as stable-baselines3 users
pass them: a plain function, an SB3 ``BaseCallback`` (``EvalCallback``, ``CheckpointCallback``,
``CallbackList``, your own subclass), or a list mixing both.

* A plain function ``f(model) -> bool | None`` runs once after every update (a TL-AC rollout
  and its epochs, a DQN-TLQL training step, an AC-Teach cycle); ``False`` stops training.
* An SB3 callback gets SB3's protocol: ``init_callback(model)`` and ``on_training_start`` when
  ``learn`` starts; after each update ``on_rollout_start``, ``on_step`` once per vectorised
  environment step of that update, ``on_rollout_end``; ``on_training_end`` at the end. tlac steps the
  environments inside its own loop, so the ``on_step`` calls of one update come together after
  it (``model.num_timesteps`` is then the step count after the update): an ``EvalCallback``
  with ``eval_freq=1000`` evaluates after the update in which the 1000th step fell.
  ``self.locals`` holds only ``{"self": model}``: callbacks that read the rollout's ``dones`` or
  ``infos`` from it (``StopTrainingOnMaxEpisodes``) are not supported.

For these, the algorithms offer what SB3 callbacks use of a model (:class:`SB3Compat`):
``get_env()``, ``get_vec_normalize_env()``, ``logger`` (an SB3 ``Logger``), ``num_timesteps``, ``predict(observation,
state, episode_start, deterministic)`` and ``save(path)``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger, configure
from stable_baselines3.common.vec_env import VecNormalize, unwrap_vec_normalize

from tlac.errors import ConfigError, require_extra
from tlac.recording import EpisodeRecorder


class SB3Compat:
    """What SB3 callbacks ask of a model, for tlac's own algorithms."""

    env: Any
    _sb3_logger: Logger | None = None
    verbose = 0
    tensorboard_log: str | None = None
    _tb_configured: bool = False
    tb_log_name: str = "TLAC"

    def get_env(self) -> Any:
        """The training environments (SB3's name): the VecEnv the user gave (or tlac made),
        without the episode recorder tlac wraps around it, so that SB3's callbacks find the
        same wrappers as in their evaluation environments (``EvalCallback`` compares the types
        and syncs a ``VecNormalize`` layer by layer)."""
        env = self.env
        return env.venv if isinstance(env, EpisodeRecorder) else env

    def get_vec_normalize_env(self) -> VecNormalize | None:
        """The ``VecNormalize`` in the training environments' wrappers, if the user gave one
        (SB3's name): ``EvalCallback`` syncs its statistics into the evaluation environments
        and ``CheckpointCallback(save_vecnormalize=True)`` saves it."""
        return unwrap_vec_normalize(self.env) if self.env is not None else None

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

    def _sb3_learn_arguments(
        self, log_interval: Any, tb_log_name: Any, reset_num_timesteps: Any
    ) -> None:
        """Check and apply SB3's ``learn`` arguments ``log_interval`` (steps here),
        ``tb_log_name`` and ``reset_num_timesteps`` (its flag only; the caller resets)."""
        if log_interval is not None:
            if (
                isinstance(log_interval, bool)
                or not isinstance(log_interval, int)
                or log_interval < 1
            ):
                raise ConfigError(
                    f"log_interval: expected a positive number of steps, got {log_interval!r}"
                )
            self.log_interval = log_interval
        if not isinstance(tb_log_name, str) or not tb_log_name or "/" in tb_log_name:
            raise ConfigError(f"tb_log_name: expected a folder name, got {tb_log_name!r}")
        if tb_log_name != self.tb_log_name:
            self.tb_log_name, self._tb_configured = tb_log_name, False
        if not isinstance(reset_num_timesteps, bool):
            raise ConfigError(
                f"reset_num_timesteps: expected True or False, got {reset_num_timesteps!r}"
            )

    def _sb3_output(self) -> bool:
        """Whether ``learn`` writes its scalars to the SB3 logger (``verbose`` or
        ``tensorboard_log``); configures that logger on first use, a TensorBoard run in the
        next free ``<tb_log_name>_<n>`` folder (``TLAC_<n>`` by default)."""
        if self.tensorboard_log is not None and not self._tb_configured:
            require_extra("tensorboard", "tensorboard_log", "tensorboard")
            folder = Path(self.tensorboard_log)
            name = self.tb_log_name
            n = 1 + sum(1 for p in folder.glob(f"{name}_*")) if folder.exists() else 1
            formats = ["tensorboard"] + (["stdout"] if self.verbose else [])
            self.set_logger(configure(str(folder / f"{name}_{n}"), formats))
            self._tb_configured = True
        elif self.verbose and self._sb3_logger is None:
            self.set_logger(configure(None, ["stdout"]))
        return bool(self.verbose or self.tensorboard_log is not None)


def check_sb3_arguments(
    verbose: Any, tensorboard_log: Any, device: Any, torch_threads: Any
) -> None:
    """SB3's constructor arguments as tlac accepts them; a bad one raises ConfigError."""
    if verbose not in (0, 1, 2) or isinstance(verbose, bool):
        raise ConfigError(f"verbose must be 0, 1 or 2 (as in SB3), got {verbose!r}")
    if tensorboard_log is not None and not isinstance(tensorboard_log, str | Path):
        raise ConfigError(f"tensorboard_log must be a folder path or None, got {tensorboard_log!r}")
    if device not in ("auto", "cpu"):
        raise ConfigError(
            f"device {device!r}: tlac runs on the CPU ('auto' or 'cpu'); its networks are "
            "small and acting runs in NumPy, where a GPU would only add transfers"
        )
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
    """The callbacks of one ``learn`` call (see the module docstring).

    >>> class Model(SB3Compat):
    ...     env = type("Env", (), {"num_envs": 2})()
    ...     num_timesteps = 0
    >>> seen = []
    >>> callbacks = LearnCallbacks(lambda m: seen.append(m.num_timesteps), Model())
    >>> model = callbacks.model; model.num_timesteps = 16
    >>> callbacks.after_update(), seen
    (True, [16])
    """

    def __init__(self, callback: Any, model: Any):
        self.model = model
        self.functions, self.sb3 = split_callbacks(callback)
        self._steps_seen = model.num_timesteps
        for c in self.sb3:
            c.init_callback(model)
            c.on_training_start({"self": model}, {})

    def after_update(self) -> bool:
        """Run every callback after an update; False when one of them asks to stop."""
        model = self.model
        vec_steps = max(1, (model.num_timesteps - self._steps_seen) // model.env.num_envs)
        self._steps_seen = model.num_timesteps
        go_on = True
        for c in self.sb3:
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
