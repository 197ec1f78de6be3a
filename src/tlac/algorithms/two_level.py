"""TL-AC: the Two-Level Actor-Critic using multiple teachers (paper, section 3, Algorithm 1).

A high-level actor pi_high(e|s) picks, in every state, which of the N teachers or the agent
itself acts; a low-level actor pi_low(a|s) is the student's control policy; ONE critic V(s) is
shared by both levels (Eq. 5-6), so both are trained with the same advantage (Eq. 3, 7).

Reading guide: :class:`~tlac.algorithms.tlac_config.TLACConfig` (every setting of the paper's
Tables 5, 8 and 10, in :mod:`tlac.algorithms.tlac_config`),
:meth:`TLAC.collect` (Algorithm 1, lines 11-23), :meth:`TLAC.update` (lines 5-9, with the
clipped surrogate the paper's tables imply), :meth:`TLAC.learn` (the outer loop).

>>> from tlac import TLAC
>>> model = TLAC("doorkey", teachers=["optimal", "random"], seed=0, n_steps=8, batch_size=8)
>>> model = model.learn(64, progress_bar=False)
>>> model.num_timesteps
64
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3.common.vec_env import unwrap_vec_normalize
from torch import nn

from tlac.algorithms import losses
from tlac.algorithms.advice import (
    AdviceLedger,
    acting_teachers,
    ask_gate,
    corrected_rows,
    mask_logits,
    per_teacher,
    priced_logits,
)
from tlac.algorithms.callbacks import LearnCallbacks, SB3Compat, check_sb3_arguments
from tlac.algorithms.common import (
    check_seed,
    check_total_timesteps,
    make_progress_bar,
    original_obs,
    original_rewards,
    random_seed,
    stop_if_not_finite,
)
from tlac.algorithms.graduation import (
    AdviceBuffer,
    SoloEpisodes,
    StudentSnapshot,
    handover_entropy_coef,
)
from tlac.algorithms.nets import (
    HIGH,
    LOW,
    clip_coefficients,
    member_grad_norms,
    np_log_softmax,
)
from tlac.algorithms.obs_spaces import POLICIES, ObsPolicy
from tlac.algorithms.optim import (
    ForeachAdam,
    ForeachRMSpropTFLike,
    clip_grad_norm,
    stepping_rows,
)
from tlac.algorithms.rollout import Rollout, compute_gae
from tlac.algorithms.tlac_config import VARIANT_DEFAULTS, TLACConfig, resolve_settings  # noqa: F401  (VARIANT_DEFAULTS: re-exported)
from tlac.algorithms.tlac_heads import TLACHeads, make_optimizer
from tlac.algorithms.tlac_io import (
    TLACPersistence,
    check_made_env_settings,
    log_metrics,
    progress_text,
)
from tlac.algorithms.tlac_update import (
    ReplayDraws,
    ReplayPlan,
    RowWeights,
    UpdateLog,
    active_columns,
    row_weights,
    summarize_update,
)
from tlac.errors import ConfigError
from tlac.presets import make_schedule
from tlac.recording import MetricWindow, Recorder, find_episode_recorder, next_log_step
from tlac.selectors import Selector, make_selector

MAX_PLANNED_REPLAY_VALUES = 1 << 23
"""An update holds the replayed rows of all its minibatches, as the networks take them, when
they have at most this many values (32 MB of float32; DoorKey's preset: 320 x 1029); larger
(images, or SB3-sized rollouts of wide one-hot rows) each minibatch makes its own, and the
first layer is not narrowed (TLAC._narrowed_columns)."""


def policy_first_error(first: Any) -> str:
    """The error for SB3's argument order, ``TLAC(policy, env)``: ``first`` came before env
    (given by name, or as the teachers)."""
    if not isinstance(first, str):
        return "TLAC got env twice: as its first argument and as env=; pass it once"
    return (
        "TLAC takes the environment first and builds its own networks: TLAC(env, "
        f"teachers=[...]), not SB3's TLAC(policy, env); got {first!r:.60} before env (to "
        "choose the networks' kind, pass policy='MlpPolicy' or 'CnnPolicy' by name)"
    )


class TLAC(TLACHeads, SB3Compat, TLACPersistence):
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
            raise ConfigError(policy_first_error(args[0]))
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
        check_sb3_arguments(verbose, tensorboard_log, device, torch_threads)
        if isinstance(env, str) and env in POLICIES:
            raise ConfigError(policy_first_error(env))
        check_made_env_settings(env, settings)
        self.obs_policy, settings = ObsPolicy.from_arguments(policy, settings)
        self.verbose, self.tensorboard_log, self.torch_threads = (
            int(verbose),
            tensorboard_log,
            torch_threads,
        )
        config = TLACConfig.from_settings(resolve_settings(env, preset, settings))
        self._start(config, env, teachers, seed, recorder)

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
        check_made_env_settings(env, {"n_envs": config.n_envs, "vec_env": config.vec_env})
        model = cls.__new__(cls)
        model.obs_policy = ObsPolicy()
        model._start(config, env, teachers, seed, recorder)
        return model

    def _start(
        self,
        config: TLACConfig,
        env: Any,
        teachers: Sequence[Any],
        seed: int | None,
        recorder: Recorder | None,
    ) -> None:
        seed = random_seed() if seed is None else check_seed(seed)  # None: as SB3, a random one
        if self.torch_threads is not None:  # before the initialisation: its orthogonal
            torch.set_num_threads(self.torch_threads)  # matrices (QR) differ with the threads
        torch.manual_seed(seed)  # the networks' initialisation
        self._setup(config, seed, env, teachers, recorder)

    # ----------------------------------------------------------------- construction
    def _build(
        self, obs_space: gym.Space, action_space: gym.Space, teacher_names: list[str]
    ) -> None:
        cfg = self.config
        self.teacher_names = list(teacher_names)
        self.n_teachers = len(teacher_names)
        self.n_choices = self.n_teachers + 1  # E = E_0 U {Agent}; the agent is the last index
        self._build_networks(obs_space, action_space)
        self.optimizer = make_optimizer(cfg, self.params)
        self.lr_schedule = make_schedule(cfg.learning_rate, "learning_rate")
        self.clip_schedule = make_schedule(cfg.clip_range, "clip_range")
        self.distill_schedule = make_schedule(cfg.distill_coef, "distill_coef")
        self.kl_schedule = (
            None if cfg.target_kl is None else make_schedule(cfg.target_kl, "target_kl")
        )
        self.generator = torch.Generator().manual_seed(self.seed)  # minibatch order
        self.rng = np.random.default_rng(self.seed)  # acting
        self.selector: Selector = make_selector(
            cfg.selector, self.n_choices, self.n_envs, self.seed, self.rng
        )
        self.train_high = self.selector.trains_high_level and self.n_choices > 1
        # advice as it costs (tlac.algorithms.advice): answers are counted whenever there are
        # teachers; limited (a budget, availability, an asking rule) only where the settings say
        self.advice: AdviceLedger | None = None
        terms = cfg.advice
        self.limited_advice = terms.limits and self.n_teachers > 0
        if self.n_teachers or terms.teacher_cost or terms.availability:
            if terms.ask in ("importance", "uncertainty", "mistake") and not self.discrete:
                raise ConfigError(
                    f"TL-AC setting ask {terms.ask!r} reads the student's action logits and "
                    "needs discrete actions; use always or early with Box actions"
                )
            self.advice = AdviceLedger(
                per_teacher(terms.teacher_cost, self.teacher_names, "teacher_cost", 1.0),
                per_teacher(terms.availability, self.teacher_names, "availability", 1.0),
                terms.advice_budget,
                self.n_envs,
                self.seed,
                terms.ask,
                terms.ask_threshold,
            )
        self.advice_buffer: AdviceBuffer | None = None
        if self.n_teachers and cfg.distill_coef != 0:
            self.advice_buffer = AdviceBuffer(  # per state, every teacher's advice
                cfg.imitation_buffer_size,
                self.obs_dim,
                (self.n_teachers, self.advice_width),
                torch.float32,
                None if self.obs_layout is None else self.obs_layout.storage_dtype,
                track_labels=self.limited_advice,
            )
        self._replay_generator = torch.Generator().manual_seed(self.seed + 1)
        self.solo: SoloEpisodes | None = None
        # Box actions, where the low level learns by imitation (low_level_data "silent"):
        # the student plays its solo episodes greedily. Imitation fits its Gaussian's mean and
        # leaves its noise untrained (a fixed-variance likelihood), so a sampled solo episode
        # measures that noise rather than the student a user deploys (hopper, seed 0: the live
        # student 593 greedy against 100 sampled; the kept student, chosen on sampled solo
        # returns, stayed at 190 while the live one reached 2170)
        self.greedy_solo = (
            not self.discrete and bool(cfg.solo_budget) and cfg.low_level_data == "silent"
        )
        # ask learned on a budget: the high level's choices are the only asks. A teacher-led
        # episode asks in every state whatever the price (on CartPole, 500 answers an episode:
        # the audition's first two would spend a budget of 1e3), so there is none
        teacher_share = cfg.teacher_episodes
        if terms.ask == "learned" and terms.advice_budget is not None:
            teacher_share = 0.0
        if cfg.solo_budget and self.n_teachers:
            self.solo = SoloEpisodes(
                self.n_envs,
                cfg.solo_budget,
                self.seed,
                n_teachers=self.n_teachers,
                teacher_share=teacher_share,
            )
        self.deployed: StudentSnapshot | None = None  # None: predict uses the live weights
        self._sde_noise: np.ndarray | None = None
        # (origin, horizon) of the schedules: of the learn call in progress or last made
        # (None before any), and of an interrupted call, set by a resume
        self._schedule: tuple[int, int] | None = None
        self._resumed_schedule: tuple[int, int] | None = None
        self._n_updates = 0  # epochs begun over all updates (SB3's train/n_updates)
        # the logging window in progress (learn): its statistics and the high level's choices
        self._log_window: tuple[MetricWindow, np.ndarray] | None = None
        self._ent_coefs = torch.tensor(cfg.entropy_coefs)  # [low, high]
        # weaned imitation hands a discrete student over to its own policy gradient with an
        # entropy bonus that grows with its competence (graduation.handover_entropy_coef)
        self._handover = self.discrete and cfg.wean_imitation and self.solo is not None
        self._use_entropy = bool(self._ent_coefs.any()) or self._handover

    @classmethod
    def check_hyperparameters(cls, hyperparameters: dict[str, Any]) -> TLACConfig:
        """The validated settings (``preset`` aside); a bad one raises ConfigError naming it."""
        return TLACConfig.from_settings({k: v for k, v in hyperparameters.items() if k != "preset"})

    # ----------------------------------------------------------------- Algorithm 1
    def collect(self, callbacks: LearnCallbacks | None = None) -> Rollout | None:
        """Collect ``n_steps`` transitions per environment (Algorithm 1, lines 11-23).
        ``callbacks``: ``learn``'s, whose SB3 callbacks see every step as in SB3's
        ``collect_rollouts``; None is returned when one of them stopped the collection."""
        cfg = self.config
        T, E = cfg.n_steps, self.n_envs
        ro = Rollout.empty(T, E, self.obs_dim, self.action_space.shape, self.discrete)
        if self._last_obs is None:
            self._last_obs = self.env.reset()
            self._episode_starts = np.ones(E, dtype=bool)
            self._episode_returns = np.zeros(E)
        sb3 = callbacks if callbacks is not None and callbacks.sb3 else None
        if sb3 is not None:
            sb3.rollout_start()
        if cfg.use_sde:
            self._resample_sde_noise()
        vec_normalize = unwrap_vec_normalize(self.env)  # the user's: teachers get raw observations
        limits = self.advice if self.limited_advice else None
        rule = cfg.advice.ask
        if limits is not None:
            ro.askable = np.zeros((T, E, self.n_teachers), dtype=bool)
            ro.high_mask = np.zeros((T, E, self.n_teachers), dtype=bool)
            if rule == "learned":  # the price of each answer, charged in the high level's logits
                ro.high_shift = np.zeros((T, E, self.n_teachers), dtype=np.float32)
                steps_left = self._advice_steps_left()
                limits.start_pacing(steps_left)
                pacing = (limits.spent, limits.remaining, steps_left)
            if rule == "mistake":
                ro.corrected = np.zeros((T, E), dtype=bool)
        # ask learned and mistake: labels come only from the teacher that acted (learned: the
        # high level's ask; mistake: where it disagreed with the student), none from the others
        labels_from_gate = rule not in ("learned", "mistake")
        for t in range(T):
            if cfg.use_sde and cfg.sde_sample_freq > 0 and t > 0 and t % cfg.sde_sample_freq == 0:
                self._resample_sde_noise()
            obs = self._flat_rows(self._last_obs)
            if self.normalizer is not None:  # statistics of what the networks see, as VecNormalize
                self.normalizer.update_obs(obs)
            net_obs = self._normalized(obs)
            if self.normalizer is not None:
                ro.net_obs[t] = net_obs
            high_logits, low_out, values, latent = self._act_heads_net(net_obs)
            if limits is None:
                choices = self.selector.select(high_logits, self._episode_starts)  # line 14
            else:  # only teachers present, affordable and asked can be chosen
                limits.draw_presence(self._episode_starts)
                asks = ask_gate(rule, low_out, cfg.advice.ask_threshold)
                can = limits.can_answer(asks)
                if ro.high_shift is not None:  # the behaviour policy pays the price of asking
                    ro.high_shift[t] = limits.shift()
                    high_logits = priced_logits(high_logits, ro.high_shift[t])
                choices = self.selector.select(mask_logits(high_logits, can), self._episode_starts)
            if self.solo is not None:  # graduate variant: some episodes are the student's alone
                solo = self.solo.start(
                    self._episode_starts, None if limits is None else limits.can_lead()
                )
                if limits is not None:
                    self._limit_leaders(limits)
                choices = np.where(solo, self.n_teachers, choices)
                # ... or one teacher's alone (teacher_episodes): their rows train the high level
                # as its own choices, with their log-probabilities under it
                choices = np.where(self.solo.leader >= 0, self.solo.leader, choices)
                ro.solo[t] = solo
            if limits is not None:  # the acting teachers' answers, paid for
                choices, high_mask = self._charge_acting(limits, choices, can)
                ro.askable[t] = limits.present & (asks & labels_from_gate)[:, None]
                ro.high_mask[t] = high_mask
                high_logits = mask_logits(high_logits, high_mask)
            actions = self._sample_low(low_out, latent)  # line 16 (kept where the agent acts)
            if self.greedy_solo:
                actions = np.where(ro.solo[t][:, None] > 0, low_out, actions)
            teacher_obs = self._last_obs if vec_normalize is None else original_obs(vec_normalize)
            own = actions.copy() if ro.corrected is not None else None  # the student's intent
            actions = self._apply_teachers(choices, teacher_obs, actions)  # line 18
            if own is not None:  # mistake correcting: the teacher checked the student's action
                ro.corrected[t] = corrected_rows(choices, own, actions, self.n_teachers)

            clipped_actions = self._to_env_actions(actions)  # (SB3's name, for callbacks)
            new_obs, rewards, dones, infos = self.env.step(clipped_actions)  # line 19
            self.num_timesteps += E
            # SB3's callbacks see the step (the environments' rewards) before tlac's bookkeeping
            stopped = sb3 is not None and not sb3.step(self._sb3_locals(locals(), ro, t))
            rewards = np.asarray(rewards, dtype=np.float32).copy()
            self._episode_returns += (
                rewards if vec_normalize is None else original_rewards(vec_normalize)
            )
            if self.normalizer is not None:  # the training rewards only; returns stay raw
                rewards = self.normalizer.scale_rewards(rewards, dones)
            for i in np.flatnonzero(dones):
                final = infos[i].get("terminal_observation")
                if infos[i].get("TimeLimit.truncated", False) and final is not None:
                    # time-limit truncation is not termination: bootstrap from V(final obs)
                    rewards[i] += cfg.gamma * float(self._act_heads(final)[2][0])
                self.selector.episode_end(int(i), float(self._episode_returns[i]))
                self._record_episode_info(infos[i])  # SB3's ep_info_buffer
                if self.solo is not None:
                    self._deploy_if_worth(self.solo.end(int(i), float(self._episode_returns[i])))
                self._episode_returns[i] = 0.0

            ro.obs[t] = obs  # line 20: the transition and both levels' log-probabilities
            if vec_normalize is not None:
                ro.teacher_obs[t] = self._flat_rows(teacher_obs)
            ro.actions[t] = actions
            ro.choices[t] = choices
            ro.rewards[t] = rewards
            ro.dones[t] = dones
            ro.values[t] = values
            ro.log_prob_low[t] = self._np_low_log_prob(low_out, latent, actions)
            ro.log_prob_high[t] = np_log_softmax(high_logits)[np.arange(E), choices]
            self._last_obs = new_obs
            self._episode_starts = np.asarray(dones, dtype=bool)
            if stopped:  # as SB3: no update on a rollout that a callback cut short
                return None
        if ro.high_shift is not None:  # the price follows the spending (advice.paced_price)
            spent0, remaining0, steps_left0 = pacing
            limits.repace(limits.spent - spent0, T * E, remaining0, steps_left0)
        last_values = self._act_heads(self._last_obs)[2]
        ro.advantages, ro.returns = compute_gae(
            ro.rewards, ro.values, ro.dones, last_values, cfg.gamma, cfg.gae_lambda
        )
        if self.recorder is not None:
            self.recorder.record_selections(self.num_timesteps, ro.choices, ro.obs)
        if sb3 is not None:
            sb3.rollout_end(self._sb3_locals(locals(), ro, T))
        return ro

    def _advice_steps_left(self) -> int:
        """The steps left in the learn call in progress (its schedules' horizon), to pace the
        price of answers over; 0 outside learn."""
        if self._schedule is None:
            return 0
        origin, horizon = self._schedule
        return max(origin + horizon - self.num_timesteps, 0)

    def _limit_leaders(self, limits: AdviceLedger) -> None:
        """Teacher-led episodes under limited advice: once the budget is spent, every episode
        that starts is the student's alone (it is: no teacher is asked again), and a leader
        whose answers no longer fit in the budget stops leading (its episode's return is then
        counted as an assisted one, not as the teacher's own)."""
        assert self.solo is not None
        if limits.exhausted:
            starting = np.asarray(self._episode_starts, dtype=bool)
            self.solo.active[starting] = True
            self.solo.leader[starting] = -1
        led = np.flatnonzero(self.solo.leader >= 0)
        lost = led[~limits.can_lead()[led, self.solo.leader[led]]]
        self.solo.leader[lost] = -1

    def _charge_acting(
        self, limits: AdviceLedger, choices: np.ndarray, can: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Pay for the answers of the teachers that act now (env by env, while the budget
        holds); a choice the budget no longer covers (spent by an environment before it in
        this step) falls back to the agent, and so does one of a teacher that cannot answer
        (a selector that reads no logits, random or ucb1, may pick it). Returns the choices
        and the teachers each row's high-level choice was made among: those that could answer,
        and a leader (teacher-led episodes ask their teacher whatever the asking rule says)."""
        k = self.n_teachers
        allowed = can.copy()
        if self.solo is not None:  # a leader still leading (_limit_leaders) can answer
            led = np.flatnonzero(self.solo.leader >= 0)
            allowed[led, self.solo.leader[led]] = True
        rows = np.arange(len(choices))
        choices = np.where((choices < k) & ~allowed[rows, np.minimum(choices, k - 1)], k, choices)
        granted = limits.charge(acting_teachers(choices, k), acting=True)
        refused = (choices < k) & ~granted.any(axis=1)
        if refused.any():
            choices = np.where(refused, k, choices)
            if self.solo is not None:
                self.solo.leader[refused] = -1
        return choices, can | granted

    def _charge_labels(
        self, data: dict[str, torch.Tensor], paid_only: bool = False
    ) -> torch.Tensor:
        """``(n, K)`` bool: the teachers asked for a label in each row of the rollout: those
        present where the student asked, while the budget holds (rollout order); a teacher that
        acted in a row labels it with the answer already paid for. ``paid_only``: only those."""
        assert self.advice is not None
        paid = acting_teachers(data["choices"].numpy(), self.n_teachers)
        if "corrected" in data:  # mistake correcting: a label only where the teacher disagreed
            paid &= data["corrected"].numpy()[:, None]
        wanted = paid if paid_only else data["askable"].numpy() | paid
        return torch.from_numpy(self.advice.charge(wanted, paid))

    def _store_labels(
        self,
        data: dict[str, torch.Tensor],
        labelled: torch.Tensor,
        advice: torch.Tensor | None = None,
    ) -> None:
        """Add to the advice buffer the rollout's states that some teacher labelled, with their
        labels (``advice``: asked here where None). Only those: a state no teacher was asked in
        would dilute the imitation term's mean (it weighs 0) and push asked states out of the
        ring (under a budget of 1e3 answers over 1e5 steps, 99% of it)."""
        assert self.advice_buffer is not None
        keep = labelled.any(dim=1)
        if not bool(keep.any()):
            return
        if advice is None:
            obs = data["obs"] if unwrap_vec_normalize(self.env) is None else data["teacher_obs"]
            advice = self._advice_on(obs[keep], labelled[keep])
            self.advice_buffer.add(data["obs"][keep], advice, labelled[keep])
            return
        self.advice_buffer.add(data["obs"][keep], advice[:, keep], labelled[keep])

    def _sb3_locals(self, local_vars: dict[str, Any], ro: Rollout, n_steps: int) -> dict[str, Any]:
        """:meth:`collect`'s variables, with the names of SB3's ``collect_rollouts`` that they
        lack, as SB3 callbacks read them in ``self.locals``: ``env`` (``get_env()``),
        ``callback``, ``rollout_buffer`` (this rollout, filled so far), ``n_rollout_steps`` and
        ``n_steps`` (the steps collected before this one)."""
        return {
            **local_vars,
            "env": self.get_env(),
            "callback": local_vars["callbacks"],
            "rollout_buffer": ro,
            "n_rollout_steps": self.config.n_steps,
            "n_steps": n_steps,
        }

    def update(self, ro: Rollout, progress_remaining: float) -> dict[str, float]:
        """Epochs of minibatch updates of both levels and the shared critic (lines 5-9)."""
        cfg = self.config
        clip, lr = self.clip_schedule(progress_remaining), self.lr_schedule(progress_remaining)
        target_kl = None if self.kl_schedule is None else self.kl_schedule(progress_remaining)
        for group in self.optimizer.param_groups:
            group["lr"] = lr
        data = ro.flat()
        n = data["obs"].shape[0]
        has_advice = bool(self.advice_buffer)
        # graduation (docs/graduation.md): what every teacher advises in every collected state,
        # imitated by the low level in proportion to the high level's trust in that teacher
        distill = self.distill_schedule(progress_remaining)
        if cfg.wean_imitation and self.solo is not None:
            distill *= 1.0 - self.solo.weaning
        imitates = self.advice_buffer is not None and distill > 0
        silent = None
        if self.advice is not None and not self.limited_advice:  # counted only
            self.advice.count_unlimited(data["choices"].numpy(), imitates)
        if self.advice_buffer is not None and self.limited_advice and not imitates:
            # nothing is copied now (the audition, a weaned copy): no label is asked, but the
            # answers already paid for (the teachers that acted) are kept, at no cost
            self._store_labels(data, self._charge_labels(data, paid_only=True))
        if imitates and self.limited_advice:
            labelled = self._charge_labels(data)
            advice = self._advice_on(
                data["obs"] if unwrap_vec_normalize(self.env) is None else data["teacher_obs"],
                labelled,
            )
            self._store_labels(data, labelled, advice)  # only the states some teacher labelled
            if cfg.low_level_data == "silent":  # where no teacher asked says anything
                information = (
                    losses.advice_information(advice) if self.discrete else advice[..., -1]
                )
                silent = losses.silent_information(information * labelled.T)
        elif imitates:
            advice = self._advice_on(
                data["obs"] if unwrap_vec_normalize(self.env) is None else data["teacher_obs"]
            )
            self.advice_buffer.add(data["obs"], advice)
            if cfg.low_level_data == "silent":
                silent = (
                    losses.silent_states(advice)  # advice: distributions
                    if self.discrete
                    else losses.silent_information(advice[..., -1])
                )
        rows = row_weights(
            cfg,
            data,
            self.n_teachers,
            self.train_high,
            self.solo is not None,
            has_advice,
            silent,
            self.greedy_solo,
        )
        # what every minibatch reads, prepared once: the rollout's rows as the networks see
        # them, and the replayed rows (states, advice) of every minibatch the update may take
        x = self._update_rows(data["obs"] if self.normalizer is None else data["net_obs"])
        replay = None
        imitates = imitates and len(self.advice_buffer) > 0  # limited advice: none asked yet
        if imitates:
            replay = self._replay_plan(cfg.n_epochs * -(-n // cfg.batch_size))
        cols = self._narrowed_columns(x, replay)
        if cols is not None:  # the first layer on the input columns this update activates
            x = x[:, cols]
            if replay is not None and replay.x is not None:
                replay = dataclasses.replace(replay, x=replay.x[:, cols])
        with self._first_layer_on(cols):
            log, running, heads = self._epochs(
                data, rows, clip, target_kl, distill if imitates else None, x, replay
            )
        if replay is not None:
            replay.draws.finish()  # the generator as if each minibatch had drawn its own rows
        per_level = cfg.update_rule == "per_level"
        out = summarize_update(log, rows.old_log_probs.shape[0])
        out["train/explained_variance"] = losses.explained_variance(data["values"], data["returns"])
        out["train/n_updates"] = self._n_updates
        with torch.no_grad():  # entropies of the last minibatch, for the logs
            for lv, h in zip(["low", "high"], self._mean_entropies(*heads).tolist(), strict=False):
                out[f"train/entropy_{lv}"] = h
        if self.solo is not None:
            out["train/solo_probability"] = self.solo.probability
            out["train/competence"] = self.solo.competence
            if cfg.wean_imitation:  # the competence the imitation is weaned by
                out["train/weaning"] = self.solo.weaning
        if log.imitation:
            out["train/imitation_loss"] = float(torch.stack(log.imitation).mean())
            out["train/distill_coef"] = distill
        out.update(
            {
                "train/learning_rate": lr,
                "train/clip_range": clip,
                "train/stopped_early": float(log.stopped_early),
            }
        )
        if per_level:  # which levels the KL stop ended before the last epoch's end
            for lv, run in zip(["low", "high"], running.tolist(), strict=False):
                out[f"train/stopped_{lv}"] = float(not run)
        return out

    def _epochs(
        self,
        data: dict[str, torch.Tensor],
        rows: RowWeights,
        clip: float,
        target_kl: float | None,
        distill: float | None,
        x: torch.Tensor,
        replay: ReplayPlan | None,
    ) -> tuple[UpdateLog, torch.Tensor, tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """The update's epochs of minibatch gradient steps, until the target-KL stop: what
        they logged, which levels still ran at the end (``[low, high]``; update_rule
        per_level) and the heads of the last minibatch."""
        cfg = self.config
        n = x.shape[0]
        log = UpdateLog()
        per_level = cfg.update_rule == "per_level"
        running = torch.ones(rows.old_log_probs.shape[0], dtype=torch.bool)  # [low, high]
        heads: Any = None
        for _epoch in range(cfg.n_epochs):
            self._n_updates += 1  # epochs begun, as SB3's train/n_updates counts them
            perm = torch.randperm(n, generator=self.generator)
            for start in range(0, n, cfg.batch_size):
                idx = perm[start : start + cfg.batch_size]
                loss, kls, heads = self._minibatch_loss(
                    data, idx, rows, clip, distill, log, x, replay
                )
                # SB3's rule: stop before a step that moves too far (per level, or all at once)
                too_far = (
                    kls > 1.5 * target_kl if target_kl is not None else torch.zeros_like(running)
                )
                if per_level:
                    running &= ~too_far
                    log.stopped_early = log.stopped_early or bool(too_far.any())
                    if not running.any():
                        break
                    self._gradient_step_per_level(loss, running)
                    continue
                if bool(too_far.any()):
                    log.stopped_early = True
                    break
                self._gradient_step(loss)
            if (not running.any()) if per_level else log.stopped_early:
                break
        return log, running, heads

    def _narrowed_columns(self, x: torch.Tensor, replay: ReplayPlan | None) -> torch.Tensor | None:
        """The input columns that the update's rows (the rollout's ``x``, the replayed rows)
        activate, where its first layer can step on those alone (:meth:`_first_layer_on`):
        inputs read by the stacked networks' first layer (no CNN), the joint update rule, and
        an optimiser that leaves weights without gradient as they are (RMSprop without
        momentum). None where that does not hold or every column is active."""
        if (
            self._extractor_params
            or self.config.update_rule != "joint"
            or not isinstance(self.optimizer, ForeachRMSpropTFLike)
            or not self.optimizer.zero_gradient_keeps_weights()
        ):
            return None
        if replay is not None and replay.x is None:  # the replayed rows are not all known
            return None
        cols = active_columns(x) if replay is None else active_columns(x, replay.x)
        return None if len(cols) == x.shape[1] else cols

    @contextmanager
    def _first_layer_on(self, cols: torch.Tensor | None) -> Iterator[None]:
        """While open, the update's passes and gradient steps use only the rows ``cols`` of
        the first layer's weight (None: all of it). One-hot observations activate a third of
        DoorKey's 1029 input columns in an update; the other rows' weights get no gradient, so
        the first layer's forward, weight gradient, clipping and optimiser arithmetic can skip
        them, and their optimiser statistics decay as a zero gradient's step decays them
        (tlac.algorithms.optim.stepping_rows). The same steps as on the whole layer, up to
        floating-point rounding (a matmul over fewer columns sums its terms in another order)."""
        if cols is None:
            yield
            return
        first = self.net.weights[0]
        with (
            stepping_rows(self.optimizer, first, cols, dim=1) as part,
            self.net.first_layer_as(part, cols),
        ):
            yield

    def _minibatch_loss(
        self,
        data: dict[str, torch.Tensor],
        idx: torch.Tensor,
        rows: RowWeights,
        clip: float,
        distill: float | None,
        log: UpdateLog,
        x: torch.Tensor | None = None,
        replay: ReplayPlan | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor, tuple[torch.Tensor, torch.Tensor, torch.Tensor]]:
        """One minibatch's loss (both levels' clipped surrogates, the critic's error, and the
        graduate variant's terms), each level's approximate KL ``[low, high]``, and the heads
        it used. ``x``: the rollout's rows as :meth:`_heads` takes them (_update_rows; None:
        made here); ``replay``: the update's replayed rows (None: planned here, for one
        minibatch)."""
        cfg = self.config
        if x is None:
            x = self._update_rows(data["obs"] if self.normalizer is None else data["net_obs"])
        adv = data["advantages"][idx]  # one advantage for both levels (Eq. 6)
        adv = losses.normalize(adv) if cfg.normalize_advantage else adv
        replayed = None  # this minibatch's replayed rows, in the same pass as its own
        if distill is not None:
            one_off = replay is None  # planned here, for this minibatch alone
            replay = self._replay_plan(1) if replay is None else replay
            replayed = replay.draws.next()
            if one_off:
                replay.draws.finish()
        b = len(idx)
        heads = self._heads(
            x[idx] if replayed is None else torch.cat([x[idx], self._replayed_x(replay, replayed)])
        )
        high_logits, low_out, values, latent = (h[:b] for h in heads)
        # ask learned: the high level acted with the price each answer had in this row; its
        # entropy bonus reads its preferences without the price (below)
        acting_logits = None
        if "high_shift" in data:
            acting_logits = priced_logits(high_logits, data["high_shift"][idx])
        if "high_mask" in data:  # limited advice: the choices the high level had in each row
            high_logits = mask_logits(high_logits, data["high_mask"][idx])
            if acting_logits is not None:
                acting_logits = mask_logits(acting_logits, data["high_mask"][idx])
        if acting_logits is None:
            acting_logits = high_logits
        # low level, Eq. 3: log pi_low(a|s) A(s, a) on the EXECUTED actions
        lp_low = self._low_log_prob(low_out, latent, data["actions"][idx])
        log_probs = lp_low[None]
        if self.train_high:  # high level, Eq. 7: log pi_high(e|s) A(s, a), the SAME advantage
            lp_high = torch.log_softmax(acting_logits, -1)
            lp_high = lp_high.gather(1, data["choices"][idx].view(-1, 1))
            log_probs = torch.stack([lp_low, lp_high.squeeze(1)])
        old = rows.old_log_probs[:, idx]
        weights = None if rows.loss is None else rows.loss[:, idx]
        policy_losses, kls = losses.clipped_policy_losses(
            log_probs, old, adv, clip, weights, rows.kl[:, idx]
        )
        vf_loss = losses.value_loss(values, data["returns"][idx])  # Eq. 5
        loss = policy_losses.sum() + cfg.vf_coef * vf_loss
        if replayed is not None:  # the imitation term on the replayed rows
            imitation = self._imitation_term(
                heads[0][b:],
                heads[1][b:],
                heads[3][b:],
                replay.advice[:, replayed],
                replay.information[:, replayed],
            )
            loss = loss + distill * imitation
            log.imitation.append(imitation.detach())
        if self._use_entropy:  # skipped when both coefficients are 0 (Table 5)
            # (ask learned: on the logits without the price. On the priced ones, nearly all on
            # the agent, the bonus pushed the teachers' logits up against the price, which
            # chased them (278 after 3e5 DoorKey steps), and its gradient, p_k |log p_k| for a
            # rare teacher, favoured the likeliest one: 960 of 1,000 answers to one random
            # teacher, results/advice-budget/NOTES.md)
            entropies = self._mean_entropies(high_logits, low_out, latent, cfg.ent_cap_high or None)
            loss = loss - (self._entropy_coefs()[: len(entropies)] * entropies).sum()
        log.losses_and_kls.append(torch.cat([policy_losses.detach(), vf_loss.detach()[None], kls]))
        log.clip_fractions.append(losses.clip_fractions(log_probs, old, clip, weights))
        return loss, kls.detach(), (high_logits, low_out, latent)

    def _replayed_x(self, replay: ReplayPlan, replayed: slice) -> torch.Tensor:
        """A minibatch's replayed rows as :meth:`_heads` takes them: planned, or made here."""
        if replay.x is not None:
            return replay.x[replayed]
        assert self.advice_buffer is not None
        assert self.net.weights[0] is self.net._layers[0][0], "a narrowed layer needs planned rows"
        return self._replay_rows(self.advice_buffer.obs[replay.draws.idx[replayed]])

    def _gradient_step(self, loss: torch.Tensor) -> None:
        # what the optimiser steps: self.params, with the first layer's active rows in place
        # of the whole weight while _first_layer_on is open
        params = [p for group in self.optimizer.param_groups for p in group["params"]]
        for p in params:  # the optimiser's zero_grad(set_to_none=True), without its hooks
            p.grad = None
        loss.backward()
        grads = [p.grad for p in params if p.grad is not None]
        norm = clip_grad_norm(grads, self.config.max_grad_norm)  # clip_grad_norm_'s arithmetic
        stop_if_not_finite(norm, "TL-AC", self.num_timesteps, "gradient norm")
        self._optimizer_step()

    def _optimizer_step(self) -> None:
        """The optimiser's step; ours without torch's profiler range and hooks."""
        if isinstance(self.optimizer, (ForeachRMSpropTFLike, ForeachAdam)):
            self.optimizer.step_unhooked()
        else:
            self.optimizer.step()

    def _gradient_step_per_level(self, loss: torch.Tensor, running: torch.Tensor) -> None:
        """update_rule per_level: each network's gradient clipped to max_grad_norm on its own,
        then one optimiser step that leaves a stopped level's weights and optimiser statistics
        as they were (``running``: ``[low, high]``; the critic steps while either runs). The
        optimiser is element-wise, so this is the step of separate optimisers per network
        (Adam's step count aside, which its state shares over the stack)."""
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        stacked = [p for p in self.net.parameters() if p.grad is not None]
        log_std_grad = None if self.log_std is None else self.log_std.grad
        own = {} if log_std_grad is None else {LOW: [log_std_grad]}  # the low level's own
        norms = member_grad_norms([p.grad for p in stacked], self.net.members, own)
        stop_if_not_finite(norms, "TL-AC", self.num_timesteps, "gradient norm")
        coefs = clip_coefficients(norms, self.config.max_grad_norm)
        stopped = [m for m, run in zip((LOW, HIGH), running.tolist(), strict=False) if not run]
        coefs[stopped] = 0.0  # no gradient reaches a stopped level's optimiser statistics
        for p in stacked:
            p.grad.mul_(coefs.view(-1, *[1] * (p.grad.dim() - 1)))
        for m, grads in own.items():
            for g in grads:
                g.mul_(coefs[m])
        if self._extractor_params:  # the shared CNN: its own clip; it steps while a level runs
            norm = nn.utils.clip_grad_norm_(self._extractor_params, self.config.max_grad_norm)
            stop_if_not_finite(norm, "TL-AC", self.num_timesteps, "gradient norm")
        kept = self._member_state(stopped)
        self._optimizer_step()
        for live, saved in kept:
            live.copy_(saved)

    @torch.no_grad()
    def _member_state(self, members: list[int]) -> list[tuple[torch.Tensor, torch.Tensor]]:
        """(live tensor, copy) pairs of the given members' weights and optimiser statistics, to
        put back after a step: a slice of each stacked tensor, the whole log std for LOW."""
        pairs: list[tuple[torch.Tensor, torch.Tensor]] = []
        for m in members:
            for p in self.net.parameters():
                pairs += [(t[m], t[m].clone()) for t in [p.data, *self._moments(p)]]
            if m == LOW and self.log_std is not None:
                p = self.log_std
                pairs += [(t, t.clone()) for t in [p.data, *self._moments(p)]]
        return pairs

    def _moments(self, p: torch.Tensor) -> list[torch.Tensor]:
        """The optimiser's per-element statistics of ``p`` (square averages, momenta)."""
        state = self.optimizer.state[p].values()
        return [v for v in state if isinstance(v, torch.Tensor) and v.shape == p.shape]

    def _deploy_if_worth(self, worth: bool) -> None:
        """The kept student: make the live student the one ``predict`` deploys when its recent
        solo episodes say it is worth it (after each solo episode, and at the end of ``learn``:
        tlac.algorithms.graduation.worth_deploying)."""
        if worth:
            self.deployed = self._snapshot_student()

    def _entropy_coefs(self) -> torch.Tensor:
        """``[low, high]`` entropy coefficients of this gradient step: the settings', plus the
        hand-over bonus on the low level under weaned imitation (discrete actions)."""
        if not self._handover:
            return self._ent_coefs
        assert self.solo is not None
        bonus = handover_entropy_coef(self.solo.weaning)
        return self._ent_coefs + torch.tensor([bonus, 0.0])

    def _replay_plan(self, max_batches: int) -> ReplayPlan:
        """The states the imitation term replays in each of up to ``max_batches`` minibatches,
        drawn from the advice buffer at once (the same rows, and the same generator state after
        the update, as one draw per minibatch: tlac_update.ReplayDraws), with their advice and
        (discrete actions) its information, computed once."""
        assert self.advice_buffer is not None
        buffer = self.advice_buffer
        draws = ReplayDraws(
            len(buffer), self.config.imitation_batch_size, max_batches, self._replay_generator
        )
        width = max(self.obs_dim, self.net.weights[0].shape[1])  # of a row, stored or encoded
        x = None  # too large to hold (images; wide rows over SB3-sized rollouts): per minibatch
        if draws.idx.numel() * width <= MAX_PLANNED_REPLAY_VALUES:
            x = self._replay_rows(buffer.obs[draws.idx])
        advice = buffer.advice[draws.idx].transpose(0, 1)  # (n_teachers, rows, ...)
        if buffer.labelled is not None:  # limited advice: a teacher not asked says nothing
            asked = buffer.labelled[draws.idx].T.float()
            if not self.discrete:
                return ReplayPlan(draws, x, advice[..., :-1], advice[..., -1] * asked)
            information = losses.advice_information(advice) * asked
            return ReplayPlan(draws, x, losses.advice_labels(advice), information)
        if not self.discrete:  # the actions meant, and their information
            return ReplayPlan(draws, x, advice[..., :-1], advice[..., -1])
        return ReplayPlan(draws, x, losses.advice_labels(advice), losses.advice_information(advice))

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
        self._check_can_learn()
        self._sb3_learn_arguments(log_interval, tb_log_name, reset_num_timesteps)
        if reset_num_timesteps and self._resumed_schedule is None and self.num_timesteps:
            self.num_timesteps, self._last_obs = 0, None  # SB3: a new count, new episodes
        start_steps = self.num_timesteps
        end_steps = start_steps + total_timesteps
        # the schedules' clock: this call's steps, or, right after a resume, the interrupted
        # call's (so that a resumed run follows the same linear schedules as an uninterrupted one)
        origin, horizon = self._resumed_schedule or (start_steps, total_timesteps)
        self._resumed_schedule = None
        self._schedule = (origin, horizon)
        episodes = find_episode_recorder(self.env)
        bar = make_progress_bar(total_timesteps, "TL-AC", progress_bar)
        usage = np.zeros(self.n_choices)  # the high level's choices since the bar's last text
        call_usage = np.zeros(self.n_choices)  # ... and in this call, for the bar's final text
        # the window since the last log, kept on the model (and in its checkpoints): a
        # continued or resumed run logs the same means as an uninterrupted one
        if self._log_window is None or start_steps == 0:
            self._log_window = (MetricWindow(counts=("train/n_updates",)), np.zeros(self.n_choices))
        window, logged_usage = self._log_window  # the choices since the last logged window
        sb3_output = self._sb3_output()
        interval = self.recorder.log_interval if self.recorder else self.log_interval
        next_log = next_log_step(start_steps, interval)
        if self.torch_threads is not None:
            torch.set_num_threads(self.torch_threads)
        t0, last_bar = time.time(), 0.0
        self._new_info_buffers(reset_num_timesteps)
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
            counts = np.bincount(ro.choices.reshape(-1), minlength=self.n_choices)
            usage += counts
            call_usage += counts
            logged_usage += counts
            progress_remaining = 1.0 - (self.num_timesteps - origin) / horizon
            window.add(self.update(ro, max(progress_remaining, 0.0)))
            if (self.recorder is not None or sb3_output) and self.num_timesteps >= next_log:
                fps = (self.num_timesteps - start_steps) / max(time.time() - t0, 1e-9)
                shares = logged_usage / max(logged_usage.sum(), 1.0)
                names = [*self.teacher_names, "agent"]
                usage_metrics = {
                    f"teacher/{n}": float(v) for n, v in zip(names, shares, strict=True)
                }
                metrics = window.flush()
                if self.advice is not None:  # the answers asked so far, per teacher
                    metrics.update(self.advice.metrics(self.teacher_names))
                log_metrics(self, metrics, fps, episodes, sb3_output, usage_metrics)
                logged_usage[:] = 0
                next_log = next_log_step(self.num_timesteps, interval)
            if bar is not None:
                bar.update(min(self.num_timesteps, end_steps) - bar.n - start_steps)
                if time.time() - last_bar > 0.5:
                    last_bar = time.time()
                    bar.set_postfix_str(self._bar_text(episodes, usage), refresh=False)
                    usage[:] = 0
            if self.num_timesteps >= end_steps:  # before the callbacks' last evaluation
                self._deploy_if_worth(
                    self.solo is not None and self.solo.latest_is_worth_deploying()
                )
            if not callbacks.after_update():
                break
        callbacks.end()
        if bar is not None:  # the whole call's shares, as the bar's final text says
            span = f"all {self.num_timesteps - start_steps} steps:"
            bar.set_postfix_str(self._bar_text(episodes, call_usage, span), refresh=False)
            bar.close()
        return self

    def _bar_text(self, episodes: Any, usage: np.ndarray, span: str = "recent:") -> str:
        """The progress bar's text: the training return, the high level's choices and, where
        advice is limited (a budget, costs, availability, an asking rule), the answers asked so
        far and the budget spent (without limits they are in progress.csv and result.json)."""
        text = progress_text(episodes, usage, self.teacher_names, span)
        if self.advice is None or not self.limited_advice:
            return text
        return f"{text} | {self.advice.progress(self.teacher_names)}"

    def _check_can_learn(self) -> None:
        if self.env is None:
            raise ConfigError("this model has no environment: pass env= to TLAC.load to train it")
        if len(self.teachers) != self.n_teachers:
            raise ConfigError(
                f"this model was trained with {self.n_teachers} teachers "
                f"({', '.join(self.teacher_names)}); "
                "pass the same number as teachers= to TLAC.load to train it further"
            )
