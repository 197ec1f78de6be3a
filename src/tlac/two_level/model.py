"""TL-AC: the Two-Level Actor-Critic using multiple teachers (paper, section 3, Algorithm 1).

A high-level actor pi_high(e|s) picks, in every state, which of the N teachers or the agent
itself acts; a low-level actor pi_low(a|s) is the student's control policy; ONE critic V(s) is
shared by both levels (Eq. 5-6), so both are trained with the same advantage (Eq. 3, 7).

Reading guide: :class:`~tlac.two_level.config.TLACConfig` (the settings, the paper's Tables
5, 8 and 10), :func:`tlac.two_level.collect.collect` (Algorithm 1, lines 11-23),
:func:`tlac.two_level.update.update` (lines 5-9), :meth:`TLAC.learn` (the outer loop). The
model holds plain parts: its networks (``model.nets``), optimiser, selector, advice ledger and
buffer, solo episodes, and what SB3's callbacks read (``model.sb3``); ``model.episode_leader``
(None but in ``tlac teach``) names teachers to lead episodes from outside the run.

>>> from tlac import TLAC
>>> model = TLAC("doorkey", teachers=["optimal", "random"], seed=0, n_steps=8, batch_size=8)
>>> model = model.learn(64, progress_bar=False)
>>> model.num_timesteps
64
"""

from __future__ import annotations

import copy
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import VecNormalize

from tlac.algorithms import callbacks as sb3_callbacks
from tlac.algorithms.callbacks import LearnCallbacks, SB3Logs, check_device
from tlac.algorithms.common import check_finite_weights, check_total_timesteps
from tlac.algorithms.obs_spaces import POLICIES, ObsPolicy
from tlac.algorithms.rollout import Rollout
from tlac.algorithms.student_policy import StudentPolicy, student_policy
from tlac.errors import ConfigError
from tlac.recording import MetricWindow, Recorder
from tlac.selectors import make_selector
from tlac.teachers.sb3 import FrozenObsNormalization
from tlac.two_level import collect, graduation, inputs, labels, persistence, steps, update
from tlac.two_level.config import TLACConfig, resolve_settings
from tlac.two_level.graduation import StudentSnapshot
from tlac.two_level.networks import Networks
from tlac.two_level.summary import LearnProgress


class TLAC:
    """Two-Level Actor-Critic. ``TLAC(env, teachers, **settings).learn(steps)``.

    ``env``: a domain name (``"doorkey"``), a Gymnasium env or an SB3 ``VecEnv``.
    ``teachers``: objects with a batched ``predict``, SB3 models or policies (``model.policy``),
    plain functions of one observation, or -- when ``env`` is a domain name -- that domain's
    teacher names; one teacher may come alone, without a list.
    ``predict`` uses the low-level policy ALONE: the student a user deploys.
    ``seed``: as SB3's, None (the default) draws one at random, recorded in ``model.seed``
    (``TLAC(..., seed=model.seed)`` repeats the run); ``tlac train`` and experiments pass theirs.
    ``preset``: the settings that ``settings`` override. ``"auto"``: a domain name's own preset
    (as ``tlac train`` uses it), else ``presets/default.yaml`` (measured on users'
    environments, docs/graduation.md; the graduate variant's: ``variant="paper"`` takes
    TLACConfig's defaults there, Algorithm 1 with Table 5's settings); a preset name; or
    ``None``: TLACConfig's defaults only (what ``tlac train`` passes, having resolved the
    preset already).
    SB3-style arguments: ``verbose`` (1: print the logged scalars every ``log_interval``
    steps, as SB3 does), ``tensorboard_log`` (a folder: the same scalars for TensorBoard, in
    ``TLAC_<n>`` under it), ``device`` (``"auto"`` or ``"cpu"``: tlac's networks are small and
    it acts in NumPy, so it runs on the CPU; ``"cuda"`` is refused), ``torch_threads`` (the
    torch threads ``learn`` sets: 1, fastest for [64, 64] networks and right for parallel runs;
    None leaves torch's setting alone), ``policy`` (SB3's name: ``"MlpPolicy"``, the default;
    ``"CnnPolicy"`` for an image observation space, read by SB3's NatureCNN;
    ``"MultiInputPolicy"`` for a Dict with image keys; an image never meets an MLP silently:
    tlac.algorithms.obs_spaces, docs/algorithm.md "Observation spaces"). Discrete and
    MultiDiscrete observations are one-hot encoded, Dict ones read key by key, and the
    teachers always get the environment's own observations (an int, a dict, an image).
    """

    exact_resume = True  # save(training_state=True) / load(resume=True)
    # SB3-style arguments (class defaults, so that TLAC.load has them too)
    verbose = 0
    tensorboard_log: str | None = None
    torch_threads: int | None = 1
    log_interval = 2000

    def __new__(cls, *args: Any, **kwargs: Any) -> TLAC:
        """SB3's order, ``TLAC("MlpPolicy", env=...)``, is one clear error (not Python's
        TypeError about ``env`` given twice)."""
        if args and "env" in kwargs:
            raise ConfigError(inputs.policy_first_error(args[0]))
        return super().__new__(cls)

    def __init__(
        self,
        env: Any,
        teachers: Sequence[Any] = (),
        seed: int | None = None,
        recorder: Recorder | None = None,
        preset: str | None = "auto",
        verbose: int = 0,
        tensorboard_log: str | None = None,
        device: str = "auto",
        torch_threads: int | None = 1,
        policy: str = "MlpPolicy",
        **settings: Any,
    ):
        sb3_callbacks.check_sb3_arguments(verbose, tensorboard_log, device, torch_threads)
        if isinstance(env, str) and env in POLICIES:
            raise ConfigError(inputs.policy_first_error(env))
        inputs.check_made_env_settings(env, settings)
        obs_policy, settings = ObsPolicy.from_arguments(policy, settings)
        self.verbose, self.tensorboard_log = int(verbose), tensorboard_log
        self.torch_threads = torch_threads
        config = TLACConfig.from_settings(resolve_settings(env, preset, settings))
        seed = inputs.seed_torch(seed, torch_threads)
        self._build(config, seed, env, teachers, recorder, obs_policy)

    @classmethod
    def from_config(
        cls,
        config: TLACConfig,
        env: Any,
        teachers: Sequence[Any] = (),
        seed: int | None = None,
        recorder: Recorder | None = None,
    ) -> TLAC:
        """A model of settings already worked out and validated: ``tlac train`` builds a
        run's TLACConfig once (:func:`tlac.run.resolve_run`) and hands it here. SB3's
        arguments keep their defaults; ``config.n_envs`` must be ``env``'s number of
        environments where ``env`` is already made."""
        inputs.check_made_env_settings(env, {"n_envs": config.n_envs, "vec_env": config.vec_env})
        model = cls.__new__(cls)
        seed = inputs.seed_torch(seed, model.torch_threads)
        model._build(config, seed, env, teachers, recorder, ObsPolicy())
        return model

    def _build(
        self,
        config: TLACConfig,
        seed: int,
        env: Any,
        teachers: Sequence[Any] | None,
        recorder: Recorder | None,
        obs_policy: ObsPolicy,
        saved: dict[str, Any] | None = None,
    ) -> None:
        """The model's parts, for a new model or (``saved``: a model file's contents) a loaded
        one (:func:`tlac.two_level.inputs.resolve_inputs`)."""
        made = inputs.resolve_inputs(config, seed, env, teachers, saved)
        self.config = cfg = made.config
        self.seed, self.recorder, self.obs_policy = seed, recorder, obs_policy
        self.env, self.n_envs, self.env_name = made.env, made.n_envs, made.env_name
        self.observation_space, self.action_space = made.observation_space, made.action_space
        self.teachers, self.teacher_names = made.teachers, made.teacher_names
        self.n_teachers = len(self.teacher_names)
        self.n_choices = self.n_teachers + 1  # E = E_0 U {Agent}; the agent is the last index
        self.num_timesteps = 0 if saved is None else int(saved["num_timesteps"])
        self.saved_vec_normalize: FrozenObsNormalization | None = None  # load sets it
        self.sb3 = SB3Logs()  # what SB3's callbacks and logging read
        self.rng = np.random.default_rng(seed)  # acting
        self.selector = make_selector(cfg.selector, self.n_choices, self.n_envs, seed, self.rng)
        self.train_high = self.selector.trains_high_level and self.n_choices > 1
        spaces = (self.observation_space, self.action_space)
        self.nets = Networks(
            cfg, *spaces, obs_policy, self.n_choices, self.n_envs, self.rng, self.train_high
        )
        self.optimizer = steps.make_optimizer(cfg, self.nets.params)
        self.lr_schedule, self.clip_schedule, self.distill_schedule, self.kl_schedule = (
            steps.make_schedules(cfg)
        )
        self.generator = torch.Generator().manual_seed(seed)  # minibatch order
        self._replay_generator = torch.Generator().manual_seed(seed + 1)  # replayed rows
        self.limited_advice = cfg.advice.limits and self.n_teachers > 0
        self.advice = labels.make_advice_ledger(
            cfg.advice, self.teacher_names, self.n_envs, seed, self.nets.discrete
        )
        self.advice_buffer = labels.make_advice_buffer(cfg, self.nets, self.limited_advice)
        self.greedy_solo = graduation.plays_solo_greedily(cfg, self.nets.discrete)
        self.solo = graduation.make_solo(cfg, self.n_envs, seed, self.n_teachers)
        self.deployed: StudentSnapshot | None = None  # None: predict uses the live weights
        # the student that collected the last rollout (the live weights before the last
        # update), which a renewal of the kept student deploys; None where those were the
        # weights the model started from, and after a change of weights from outside: then
        # the live weights
        self.collector: StudentSnapshot | None = None
        # who leads the episodes that start, named from outside the run (tlac teach's
        # take-over: collect.EpisodeLeader); None but in tlac teach, and never saved. The
        # paper variant keeps the episodes it leads in _led_by (-1: none)
        self.episode_leader: collect.EpisodeLeader | None = None
        self._led_by = np.full(self.n_envs, -1, dtype=np.int64)
        self._ent_coefs = torch.tensor(cfg.entropy_coefs)  # [low, high]
        self._handover = graduation.hands_over(cfg, self.nets.discrete, self.solo)
        self._use_entropy = bool(self._ent_coefs.any()) or self._handover
        # the training state: the episodes in progress; (origin, horizon) of the schedules of
        # the learn call in progress or last made, and of an interrupted call (a resume's);
        # epochs begun (SB3's train/n_updates); the logging window in progress
        self._last_obs: Any = None
        self._episode_starts: np.ndarray | None = None
        self._episode_returns: np.ndarray | None = None
        self._schedule: tuple[int, int] | None = None
        self._resumed_schedule: tuple[int, int] | None = None
        self._n_updates = 0
        self._log_window: tuple[MetricWindow, np.ndarray] | None = None

    @classmethod
    def check_hyperparameters(cls, hyperparameters: dict[str, Any]) -> TLACConfig:
        """The validated settings (``preset`` aside); a bad one raises ConfigError naming it."""
        return TLACConfig.from_settings({k: v for k, v in hyperparameters.items() if k != "preset"})

    # ----------------------------------------------------------------- Algorithm 1
    def collect(self, callbacks: LearnCallbacks | None = None) -> Rollout | None:
        """Collect ``n_steps`` transitions per environment (Algorithm 1, lines 11-23;
        :func:`tlac.two_level.collect.collect`)."""
        return collect.collect(self, callbacks)

    def update(self, ro: Rollout, progress_remaining: float) -> dict[str, float]:
        """Epochs of minibatch updates of both levels and the shared critic (lines 5-9;
        :func:`tlac.two_level.update.update`)."""
        return update.update(self, ro, progress_remaining)

    def learn(
        self,
        total_timesteps: int,
        callback: Any = None,
        log_interval: int | None = None,
        tb_log_name: str = "TLAC",
        reset_num_timesteps: bool = True,
        progress_bar: bool = False,
    ) -> TLAC:
        """Train for ``total_timesteps`` environment steps (over all environments), with
        SB3's signature and defaults.

        ``callback``: a function ``f(model)`` run after every collect/update iteration
        (returning ``False`` stops), an SB3 ``BaseCallback`` (``EvalCallback``,
        ``CheckpointCallback``...) or a list of them (``tlac.algorithms.callbacks``).
        ``log_interval``: environment steps per logged window of ``verbose`` /
        ``tensorboard_log`` output (tlac logs by steps, where SB3 counts iterations); None:
        the model's ``log_interval`` (2000). ``tb_log_name``: the TensorBoard run's folder
        prefix (``<tb_log_name>_<n>``). ``reset_num_timesteps``: as SB3, True starts the step
        count (and the schedules) at 0 with new episodes; False continues from the current
        count, as chunked training does. A model loaded with ``resume=True`` always continues.
        ``progress_bar``: off by default, as SB3 (``tlac train`` shows one).
        """
        total_timesteps = check_total_timesteps(total_timesteps)
        inputs.check_can_learn(self.env, self.teachers, self.teacher_names)
        checked = self.sb3.learn_arguments(log_interval, tb_log_name, reset_num_timesteps)
        self.log_interval = checked or self.log_interval  # steps per logged window
        if reset_num_timesteps and self._resumed_schedule is None and self.num_timesteps:
            self.num_timesteps, self._last_obs = 0, None  # SB3: a new count, new episodes
            self.collector = None  # labelled with the old count
        start_steps = self.num_timesteps
        end_steps = start_steps + total_timesteps
        # the schedules' clock: this call's steps, or, right after a resume, the interrupted
        # call's (so that a resumed run follows the same linear schedules as an uninterrupted one)
        origin, horizon = self._resumed_schedule or (start_steps, total_timesteps)
        self._resumed_schedule = None
        self._schedule = (origin, horizon)
        progress = LearnProgress(self, start_steps, total_timesteps, progress_bar)
        if self.torch_threads is not None:
            torch.set_num_threads(self.torch_threads)
        self.sb3.new_info_buffers(reset_num_timesteps)
        learn_locals = {  # SB3's names, as its callbacks read them at on_training_start
            "total_timesteps": end_steps,
            "callback": callback,
            "log_interval": log_interval,
            "tb_log_name": tb_log_name,
            "reset_num_timesteps": reset_num_timesteps,
            "progress_bar": progress_bar,
        }
        callbacks = LearnCallbacks(callback, self, learn_locals, per_step=True)
        while self.num_timesteps < end_steps:
            ro = self.collect(callbacks)
            if ro is None:  # an SB3 callback stopped training
                break
            progress_remaining = 1.0 - (self.num_timesteps - origin) / horizon
            if self.solo is not None:  # the weights the model started from are never kept
                trained = self._n_updates > 0
                self.collector = self.nets.snapshot_student(self.num_timesteps) if trained else None
            progress.add(ro.choices, self.update(ro, max(progress_remaining, 0.0)))
            progress.show(end_steps)
            if self.num_timesteps >= end_steps:  # before the callbacks' last evaluation
                self._deploy_if_worth(
                    self.solo is not None and self.solo.latest_is_worth_deploying()
                )
            if not callbacks.after_update():
                break
        callbacks.end()
        progress.close()
        return self

    def _deploy_if_worth(self, worth: bool) -> None:
        """The kept student: when the recent solo episodes say it is worth it (after each solo
        episode, and at the end of ``learn``: tlac.two_level.graduation.worth_deploying),
        ``predict`` deploys the student that collected the last rollout, one update behind the
        live weights: the window's episodes were played by it and the students before it, and
        by the live weights only since the last update, which can be the one that collapses (a
        collapse shows in the returns of episodes that end a rollout or more later:
        docs/graduation.md, "The kept student"). The weights the model started from (before
        its first update) are never kept: a window of their solo returns says nothing of what
        the updates make, and while they collect, a renewal takes the live weights."""
        if not worth or self._n_updates == 0:
            return
        if self.collector is not None:
            self.deployed = self.collector
        else:  # the collecting student was the starting one: the live weights, since updated
            self.deployed = self.nets.snapshot_student(self.num_timesteps)

    # ----------------------------------------------------------------- acting
    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, None]:
        """Actions of the low-level policy alone (no teacher), with SB3's signature and
        defaults: ``(actions, None)``, sampled unless ``deterministic`` (the greedy student,
        which tlac's targets use, and its evaluations unless a run deploys the sampled one:
        ``tlac train --deploy``); one observation gives one action, a batch
        ``(n, *obs_shape)`` gives ``n`` actions."""
        obs, single = self.nets.check_obs(observation)
        actions = self.nets.student_actions(self._vec_normalized(obs), self.deployed, deterministic)
        return (actions[0] if single else actions), None

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
        obs = self.nets.check_obs(obs)[0]
        return collect.act_with_teachers(self, obs, self._vec_normalized(obs), deterministic)

    def _vec_normalized(self, obs: Any) -> Any:
        """``predict``'s observations as the networks were trained on them: normalised by the
        statistics of the ``VecNormalize`` that the model was trained under, when it was loaded
        without one (TLAC.load sets ``saved_vec_normalize``); else as they are."""
        if self.saved_vec_normalize is None or self.get_vec_normalize_env() is not None:
            return obs
        return self.saved_vec_normalize(obs)

    # ----------------------------------------------------------------- files
    def save(
        self,
        path: str | Path,
        training_state: bool = False,
        run_state: dict[str, Any] | None = None,
    ) -> Path:
        """Save the networks, optimizer and settings (never the teachers) to ``path`` (.pt).
        A schedule given as a function (SB3's ``Schedule``) is saved as its value at this step:
        a model file holds plain data, and :meth:`load` runs no code from it; ``load`` warns,
        and takes the function again as ``custom_objects``.

        ``training_state``: also everything that training needs to continue exactly as if it
        had never stopped (random-number generators, the teachers' generators, the advice
        buffer, the solo statistics and the environments with their episodes in progress);
        ``load(..., resume=True)`` restores it. Such a file is larger (the advice buffer).
        ``run_state``: plain data saved alongside under ``"run"`` (``tlac.run``: what the run
        folder's writers need to continue), in the same file so that both change together."""
        return persistence.save(self, path, training_state, run_state)

    @classmethod
    def load(
        cls,
        path: str | Path,
        env: Any = None,
        teachers: Sequence[Any] | None = None,
        resume: bool = False,
        trust_pickle: bool = False,
        device: str = "auto",
        custom_objects: dict[str, Any] | None = None,
    ) -> TLAC:
        """Load a saved model. Pass ``env`` (and, to train on with advice, the same number of
        ``teachers`` as at save time) to continue training; ``predict`` needs neither.
        ``device``: as SB3's, ``"auto"`` or ``"cpu"``, where tlac runs. ``custom_objects``: as
        SB3's, settings by name that replace the saved ones (``{"learning_rate": 1e-4}``; a
        schedule function, which a model file keeps only the value of; SB3's ``lr_schedule``
        is ``learning_rate``). A model saved by SB3 (its .zip) is refused in one line: it is
        loaded with its SB3 class, and TL-AC takes it as a teacher.

        A model trained under a ``VecNormalize`` holds its statistics: loaded with
        ``env=VecNormalize(...)`` they are put in it (as SB3's ``VecNormalize.load`` would),
        and ``predict`` takes the observations it gives; loaded without one (no env, or a raw
        one), ``predict`` takes RAW observations and normalises them with those statistics,
        frozen (``model.saved_vec_normalize``; set it to None to pass observations you
        normalise yourself).

        ``resume``: restore the training state of a file saved with ``training_state=True``
        (needs ``env`` and the same ``teachers``), so that ``learn`` continues exactly where
        the saved model stopped; the next ``learn`` call keeps the schedules (learning rate,
        clip range...) of the call that was interrupted, so a run resumed with its remaining
        steps follows the same schedules as an uninterrupted one. The episodes in progress are
        re-created in ``env``'s environments (:mod:`tlac.algorithms.resume`). Loading, with or
        without ``resume``, runs no code from the file (``torch.load(weights_only=True)``), so
        ``trust_pickle`` (the contract's, for SB3's zips) changes nothing."""
        check_device(device)
        path, state = persistence.open_model_file(path)
        with persistence.load_errors(path):
            config = persistence.loaded_config(state, custom_objects, repr(str(path)), resume)
            model = cls.__new__(cls)
            policy = ObsPolicy.from_data(state.get("policy"))
            model._build(config, state["seed"], env, teachers, None, policy, state)
            persistence.restore(model, state, path, resume)
        check_finite_weights(model.nets.net.state_dict(), path)
        return model

    def get_parameters(self) -> dict[str, Any]:
        """SB3's ``get_parameters``: a copy of the model's parameters by name, each a state dict
        (plain data and tensors, as a model file holds them): ``"net"`` (the three networks,
        stacked), ``"optimizer"``, and, None where the model has none, ``"extractor"`` (the
        shared CNN), ``"log_std"`` (the Gaussian's, a tensor), ``"normalizer"`` (tlac's
        observation and reward statistics) and ``"deployed"`` (the kept student that
        ``predict`` deploys). :meth:`set_parameters` loads them back."""
        return copy.deepcopy(persistence.parameters(self))

    def set_parameters(
        self,
        load_path_or_dict: str | Path | dict[str, Any],
        exact_match: bool = True,
        device: str = "auto",
    ) -> None:
        """SB3's ``set_parameters``: load parameters from :meth:`get_parameters`' dict or from
        a TL-AC model file, into a model of the same spaces and networks. ``exact_match``:
        every name of :meth:`get_parameters` must be given (False: those given only).
        ``device``: ``"auto"`` or ``"cpu"``, where tlac runs."""
        check_device(device)
        persistence.set_parameters(self, load_path_or_dict, exact_match)

    # ----------------------------------------------------------------- SB3's surface
    def set_env(self, env: Any, force_reset: bool = True) -> None:
        """Train on other environments from now on (SB3's ``set_env``): a VecEnv, a Gymnasium
        env or id, with the model's spaces and number of environments. ``force_reset``: start
        new episodes at the next ``learn`` (SB3's default); False continues the current ones,
        which only makes sense for the same environments."""
        spaces = (self.observation_space, self.action_space)
        self.env = inputs.other_vec_env(env, self.n_envs, self.seed, *spaces)
        if force_reset:
            self._last_obs = None

    def get_env(self) -> Any:
        """SB3's: the training VecEnv, without tlac's episode recorder."""
        return sb3_callbacks.training_env(self.env)

    def get_vec_normalize_env(self) -> VecNormalize | None:
        """SB3's: the user's ``VecNormalize`` around the training environments, if any."""
        return sb3_callbacks.vec_normalize_of(self.env)

    @property
    def logger(self) -> Logger:
        """SB3's ``Logger`` for callbacks (``EvalCallback`` records there); it writes nothing
        unless given output formats (:meth:`set_logger`); tlac's own logs are the run's CSVs."""
        return self.sb3.get_logger()

    def set_logger(self, logger: Logger) -> None:
        """Use ``logger`` (SB3's ``configure(...)``) for what SB3 callbacks record."""
        self.sb3.logger = logger

    @property
    def ep_info_buffer(self) -> Any:
        """SB3's: the last 100 finished training episodes' ``{"r", "l", "t"}``."""
        return self.sb3.ep_info_buffer

    @property
    def ep_success_buffer(self) -> Any:
        """SB3's: the last 100 finished training episodes' ``is_success``."""
        return self.sb3.ep_success_buffer
