"""TL-AC's collection of a rollout (paper, Algorithm 1, lines 11-23): in every state the high
level picks a teacher or the agent (line 14), the low level samples an action (line 16), the
chosen teacher's action replaces it (line 18), the environments step (line 19) and the
transition is stored with both levels' log-probabilities (line 20); then the advantages (GAE).
Limited advice (tlac.algorithms.advice) and the graduate variant's solo and teacher-led
episodes (tlac.two_level.graduation) decide who may act; ``model.episode_leader``
(:class:`EpisodeLeader`, ``tlac teach``'s take-over) may name the teacher that leads an
episode."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol

import numpy as np
from stable_baselines3.common.vec_env import unwrap_vec_normalize

from tlac.algorithms.advice import (
    AdviceLedger,
    acting_teachers,
    ask_gate,
    away_to_agent,
    corrected_rows,
    mask_logits,
    priced_logits,
)
from tlac.algorithms.common import original_obs, original_rewards, query_teachers
from tlac.algorithms.nets import np_log_softmax
from tlac.algorithms.rollout import Rollout, compute_gae
from tlac.two_level.persistence import schedule_progress

if TYPE_CHECKING:
    from tlac.algorithms.callbacks import LearnCallbacks


class EpisodeLeader(Protocol):
    """``model.episode_leader``: who leads the episodes that start, named from outside the
    run (``tlac teach``: the person takes over, tlac.human.session). None on every model but
    a ``tlac teach`` run's; set on the live model, never saved in a checkpoint or model file.

    :meth:`lead` is called once at every step of :func:`collect`, after the high level's
    choice, with ``episode_starts`` ``(E,)`` bool (the caller's own bookkeeping of episode
    boundaries goes there). It returns ``(E,)`` ints, the teacher that must lead the episode
    starting now in each environment (-1: none; ignored where no episode starts), or None
    (none anywhere). The graduate variant plays such an episode as one of its teacher-led
    episodes (``model.solo``: its return counted as that teacher's own); the paper variant
    forces the high level's choice to that teacher in every state of it. Either way, under
    limited advice a leader that cannot answer (absent, out of budget:
    ``AdviceLedger.can_lead``) stops leading, as any teacher-led episode's does."""

    def lead(self, episode_starts: np.ndarray) -> np.ndarray | None: ...


def collect(model: Any, callbacks: LearnCallbacks | None = None) -> Rollout | None:
    """Collect ``n_steps`` transitions per environment (Algorithm 1, lines 11-23).
    ``callbacks``: ``learn``'s, whose SB3 callbacks see every step as in SB3's
    ``collect_rollouts``; None is returned when one of them stopped the collection."""
    cfg = model.config
    T, E = cfg.n_steps, model.n_envs
    ro = Rollout.empty(T, E, model.nets.obs_dim, model.action_space.shape, model.nets.discrete)
    if model._last_obs is None:
        model._last_obs = model.env.reset()
        model._episode_starts = np.ones(E, dtype=bool)
        model._episode_returns = np.zeros(E)
    sb3 = callbacks if callbacks is not None and callbacks.sb3 else None
    if sb3 is not None:
        sb3.rollout_start()
    if cfg.use_sde:
        model.nets.resample_sde_noise()
    vec_normalize = unwrap_vec_normalize(model.env)  # the user's: teachers get raw observations
    limits = model.advice if model.limited_advice else None
    rule = cfg.advice.ask
    if limits is not None:
        ro.askable = np.zeros((T, E, model.n_teachers), dtype=bool)
        ro.high_mask = np.zeros((T, E, model.n_teachers), dtype=bool)
        if rule == "learned":  # the price of each answer, charged in the high level's logits
            ro.high_shift = np.zeros((T, E, model.n_teachers), dtype=np.float32)
            ro.high_away = np.zeros((T, E, model.n_teachers), dtype=bool)
            steps_left = advice_steps_left(model)
            limits.start_pacing(steps_left)
            pacing = (limits.spent, limits.remaining, steps_left)
        if rule == "mistake":
            ro.corrected = np.zeros((T, E), dtype=bool)
    # ask learned on a budget and mistake: labels come only from the teacher that acted
    # (learned: the high level's ask; mistake: where it disagreed with the student), none from
    # the others; learned without a budget: answers are free, every teacher present labels
    labels_from_gate = rule != "mistake" and not (limits is not None and limits.paced)
    # teachers that answer only when they act (a person: tlac.human) give no other labels, and
    # teachers that say when they are there (a person's open tab, a recording's known states)
    outside = outside_teachers(model.teachers) if limits is not None else None
    labels_from = None if outside is None else ~outside[1]
    mark_outside_leaders(model)  # the audition neither awaits nor picks a person
    for t in range(T):
        if cfg.use_sde and cfg.sde_sample_freq > 0 and t > 0 and t % cfg.sde_sample_freq == 0:
            model.nets.resample_sde_noise()
        obs = model.nets.flat_rows(model._last_obs)
        if (
            model.nets.normalizer is not None
        ):  # statistics of what the networks see, as VecNormalize
            model.nets.normalizer.update_obs(obs)
        net_obs = model.nets.normalized(obs)
        if model.nets.normalizer is not None:
            ro.net_obs[t] = net_obs
        high_logits, low_out, values, latent = model.nets.act_on_input(net_obs)
        if limits is None:
            choices = model.selector.select(high_logits, model._episode_starts)  # line 14
        else:  # only teachers present, affordable and asked can be chosen
            limits.draw_presence(
                model._episode_starts,
                model.num_timesteps,
                schedule_progress(model._schedule, model.num_timesteps),
            )
            if outside is not None:
                limits.outside_presence(outside_presence(outside[0], model, vec_normalize))
            asks = ask_gate(rule, low_out, limits.threshold)
            can = limits.can_answer(asks)
            if ro.high_shift is not None:  # the behaviour policy pays the price of asking
                ro.high_shift[t] = limits.shift()
                high_logits = priced_logits(high_logits, ro.high_shift[t])
                # asking a teacher that is away gets no answer: the student acts
                ro.high_away[t] = limits.away()
                high_logits = away_to_agent(high_logits, ro.high_away[t])
            # UCB1 picks once per episode: the teachers that can answer now, whatever the
            # ask gate says in this first state (where it is shut, the agent acts that row)
            pickable = can if model.selector.trains_high_level else limits.can_lead()
            choices = model.selector.select(
                mask_logits(high_logits, pickable), model._episode_starts
            )
        named = named_leaders(model)  # the episodes that start led from outside (None: none)
        if model.solo is not None:  # graduate variant: some episodes are the student's alone
            solo = start_solo_episodes(model, limits, named)
            choices = np.where(solo, model.n_teachers, choices)
            # ... or one teacher's alone (teacher_episodes): their rows train the high level
            # as its own choices, with their log-probabilities under it
            choices = np.where(model.solo.leader >= 0, model.solo.leader, choices)
            ro.solo[t] = solo
        elif named is not None:  # paper variant: the teacher named acts in every state
            choices = lead_episodes(model, named, limits, choices)
        else:  # no episode_leader (any more: tlac teach's ended): no episode stays led
            model._led_by.fill(-1)
        if limits is not None:  # the acting teachers' answers, paid for
            choices, high_mask = charge_acting(model, limits, choices, can)
            ro.askable[t] = limits.present & (asks & labels_from_gate)[:, None]
            if labels_from is not None:  # nor asked for labels where absent or acting only
                ro.askable[t] &= labels_from
                if limits.outside is not None:
                    ro.askable[t] &= limits.outside.mask
            ro.high_mask[t] = high_mask
            high_logits = mask_logits(high_logits, high_mask)
        actions = model.nets.sample_low(low_out, latent)  # line 16 (kept where the agent acts)
        if model.greedy_solo:
            actions = np.where(ro.solo[t][:, None] > 0, low_out, actions)
        teacher_obs = model._last_obs if vec_normalize is None else original_obs(vec_normalize)
        own = actions.copy() if ro.corrected is not None else None  # the student's intent
        # line 18: the chosen teacher's action in place of the agent's (asked where chosen)
        query_teachers(model.teachers, choices, teacher_obs, model.action_space, actions, True)
        if own is not None:  # mistake correcting: the teacher checked the student's action
            ro.corrected[t] = corrected_rows(choices, own, actions, model.n_teachers)

        clipped_actions = model.nets.to_env_actions(actions)  # (SB3's name, for callbacks)
        new_obs, rewards, dones, infos = model.env.step(clipped_actions)  # line 19
        model.num_timesteps += E
        # SB3's callbacks see the step (the environments' rewards) before tlac's bookkeeping
        stopped = sb3 is not None and not sb3.step(sb3_locals(model, locals(), ro, t))
        rewards = np.asarray(rewards, dtype=np.float32).copy()
        model._episode_returns += (
            rewards if vec_normalize is None else original_rewards(vec_normalize)
        )
        if model.nets.normalizer is not None:  # the training rewards only; returns stay raw
            rewards = model.nets.normalizer.scale_rewards(rewards, dones)
        for i in np.flatnonzero(dones):
            final = infos[i].get("terminal_observation")
            if infos[i].get("TimeLimit.truncated", False) and final is not None:
                # time-limit truncation is not termination: bootstrap from V(final obs)
                rewards[i] += cfg.gamma * float(model.nets.act(final)[2][0])
            model.selector.episode_end(int(i), float(model._episode_returns[i]))
            model.sb3.record_episode_info(infos[i])  # SB3's ep_info_buffer
            if model.solo is not None:
                model._deploy_if_worth(model.solo.end(int(i), float(model._episode_returns[i])))
            model._episode_returns[i] = 0.0

        ro.obs[t] = obs  # line 20: the transition and both levels' log-probabilities
        if vec_normalize is not None:
            ro.teacher_obs[t] = model.nets.flat_rows(teacher_obs)
        ro.actions[t] = actions
        ro.choices[t] = choices
        ro.rewards[t] = rewards
        ro.dones[t] = dones
        ro.values[t] = values
        ro.log_prob_low[t] = model.nets.np_low_log_prob(low_out, latent, actions)
        ro.log_prob_high[t] = np_log_softmax(high_logits)[np.arange(E), choices]
        model._last_obs = new_obs
        model._episode_starts = np.asarray(dones, dtype=bool)
        if stopped:  # as SB3: no update on a rollout that a callback cut short
            return None
    if ro.high_shift is not None:  # the price follows the spending (advice.paced_price)
        spent0, remaining0, steps_left0 = pacing
        limits.repace(limits.spent - spent0, T * E, remaining0, steps_left0)
    last_values = model.nets.act(model._last_obs)[2]
    ro.advantages, ro.returns = compute_gae(
        ro.rewards, ro.values, ro.dones, last_values, cfg.gamma, cfg.gae_lambda
    )
    if model.recorder is not None:
        model.recorder.record_selections(model.num_timesteps, ro.choices, ro.obs)
    if sb3 is not None:
        sb3.rollout_end(sb3_locals(model, locals(), ro, T))
    return ro


def outside_teachers(teachers: list[Any]) -> tuple[list[Any], np.ndarray] | None:
    """The teachers that say themselves when they are there (a ``presence(obs)`` method giving
    ``(n,)`` bool) and those that answer only when they act (``acting_only``: a person is not
    asked to label the states it did not act in): ``([teacher or None per teacher], (K,)
    acting-only flags)``, or None where no teacher does either (the run as before)."""
    inner = [getattr(t, "teacher", t) for t in teachers]
    present = [t if callable(getattr(t, "presence", None)) else None for t in inner]
    acting_only = np.array([bool(getattr(t, "acting_only", False)) for t in inner], dtype=bool)
    if all(p is None for p in present) and not acting_only.any():
        return None
    return present, acting_only


def led_from_outside(outside: tuple[list[Any], np.ndarray] | None) -> np.ndarray | bool:
    """``(K,)``: the teachers of :func:`outside_teachers` that say when they are there or
    answer only when they act (a person, a person's recording): they lead an episode only
    when named from outside (a take-over, :class:`EpisodeLeader`); False where none does."""
    if outside is None:
        return False
    present, acting_only = outside
    return acting_only | np.array([p is not None for p in present], dtype=bool)


def mark_outside_leaders(model: Any) -> None:
    """The graduate variant: tell ``model.solo`` the teachers that lead only when named from
    outside (:func:`led_from_outside`), which its audition neither awaits nor picks."""
    if model.solo is not None:
        model.solo.outside[:] = led_from_outside(outside_teachers(model.teachers))


def outside_presence(present: list[Any], model: Any, vec_normalize: Any) -> np.ndarray | None:
    """``(E, K)``: each teacher's own say on whether it is there in each environment's state
    now (True for the teachers that say nothing); None where none says anything."""
    if all(p is None for p in present):
        return None
    obs = model._last_obs if vec_normalize is None else original_obs(vec_normalize)
    mask = np.ones((model.n_envs, len(present)), dtype=bool)
    for k, teacher in enumerate(present):
        if teacher is not None:
            mask[:, k] = np.asarray(teacher.presence(obs), dtype=bool).reshape(model.n_envs)
    return mask


def advice_steps_left(model: Any) -> int:
    """The steps left in the learn call in progress (its schedules' horizon), to pace the
    price of answers over; 0 outside learn."""
    if model._schedule is None:
        return 0
    origin, horizon = model._schedule
    return max(origin + horizon - model.num_timesteps, 0)


def start_solo_episodes(
    model: Any, limits: AdviceLedger | None, named: np.ndarray | None
) -> np.ndarray:
    """The graduate variant's draw for the episodes that start (``model.solo.start``): solo,
    assisted or led by one teacher; ``named`` (:func:`named_leaders`, None: none) makes an
    episode a teacher-led one of the teacher it names. Under limited advice, a teacher whose
    availability is 0 now, or whose answers the budget left no longer pays for (a budget never
    grows back), is not auditioned, so the audition ends and the labels paid for are copied;
    leaders are limited (:func:`limit_leaders`). Returns the per-environment solo flags."""
    solo = model.solo
    if limits is not None:
        solo.absent[:] = limits.availability == 0
        solo.gone[:] = solo.absent | ~limits.affordable()
    active = solo.start(model._episode_starts, None if limits is None else limits.can_lead())
    if named is not None:
        solo.active[named >= 0] = False
        solo.leader[named >= 0] = named[named >= 0]
    if limits is not None:
        limit_leaders(model, limits)
    return active


def named_leaders(model: Any) -> np.ndarray | None:
    """``(E,)``: the teacher that ``model.episode_leader`` (:class:`EpisodeLeader`) names to
    lead each episode starting now (-1: none, and wherever no episode starts); None without
    an ``episode_leader`` (every run but ``tlac teach``: nothing else is done)."""
    leader = getattr(model, "episode_leader", None)
    if leader is None:
        return None
    starts = np.asarray(model._episode_starts, dtype=bool)
    named = leader.lead(starts)
    if named is None:
        return np.full(model.n_envs, -1, dtype=np.int64)
    named = np.where(starts, np.asarray(named, dtype=np.int64).reshape(model.n_envs), -1)
    if ((named < -1) | (named >= model.n_teachers)).any():
        raise ValueError(
            f"episode_leader named {named.tolist()}: teachers are 0..{model.n_teachers - 1}, "
            "-1 none"
        )
    return named


def lead_episodes(
    model: Any, named: np.ndarray, limits: AdviceLedger | None, choices: np.ndarray
) -> np.ndarray:
    """The paper variant's episodes led from outside (:class:`EpisodeLeader`): the leader of
    each episode that starts now is ``named`` (-1: none), kept in ``model._led_by`` until the
    episode ends or, under limited advice, until it cannot answer; returns ``choices`` with
    the leaders' in their environments."""
    starts = np.asarray(model._episode_starts, dtype=bool)
    model._led_by[starts] = named[starts]
    if limits is not None:
        led = np.flatnonzero(model._led_by >= 0)
        model._led_by[led[~limits.can_lead()[led, model._led_by[led]]]] = -1
    return np.where(model._led_by >= 0, model._led_by, choices)


def episode_leaders(model: Any) -> np.ndarray:
    """``(E,)``: the teacher leading each environment's episode (-1: none): the graduate
    variant's teacher-led episodes, else the paper variant's led from outside."""
    return model.solo.leader if model.solo is not None else model._led_by


def limit_leaders(model: Any, limits: AdviceLedger) -> None:
    """Teacher-led episodes under limited advice: once the budget is spent, every episode
    that starts is the student's alone (it is: no teacher is asked again), and a leader
    whose answers no longer fit in the budget stops leading (its episode's return is then
    counted as an assisted one, not as the teacher's own)."""
    assert model.solo is not None
    if limits.exhausted:
        starting = np.asarray(model._episode_starts, dtype=bool)
        model.solo.active[starting] = True
        model.solo.leader[starting] = -1
    led = np.flatnonzero(model.solo.leader >= 0)
    lost = led[~limits.can_lead()[led, model.solo.leader[led]]]
    model.solo.leader[lost] = -1


def charge_acting(
    model: Any, limits: AdviceLedger, choices: np.ndarray, can: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pay for the answers of the teachers that act now (env by env, while the budget
    holds); a choice the budget no longer covers (spent by an environment before it in
    this step) falls back to the agent, and so does one of a teacher that cannot answer
    (a selector that reads no logits, random or ucb1, may pick it). Returns the choices
    and the teachers each row's high-level choice was made among: those that could answer,
    and a leader (teacher-led episodes, :func:`episode_leaders`, ask their teacher whatever
    the asking rule says)."""
    k = model.n_teachers
    allowed = can.copy()
    leaders = episode_leaders(model)  # a leader still leading (limit_leaders) can answer
    led = np.flatnonzero(leaders >= 0)
    allowed[led, leaders[led]] = True
    rows = np.arange(len(choices))
    choices = np.where((choices < k) & ~allowed[rows, np.minimum(choices, k - 1)], k, choices)
    granted = limits.charge(acting_teachers(choices, k), acting=True)
    refused = (choices < k) & ~granted.any(axis=1)
    if refused.any():
        choices = np.where(refused, k, choices)
        leaders[refused] = -1
    return choices, can | granted


def sb3_locals(model: Any, local_vars: dict[str, Any], ro: Rollout, n_steps: int) -> dict[str, Any]:
    """:func:`collect`'s variables, with the names of SB3's ``collect_rollouts`` that they
    lack, as SB3 callbacks read them in ``self.locals``: ``self`` (the model), ``env``
    (``get_env()``), ``callback``, ``rollout_buffer`` (this rollout, filled so far),
    ``n_rollout_steps`` and ``n_steps`` (the steps collected before this one)."""
    return {
        **local_vars,
        "self": model,
        "env": model.get_env(),
        "callback": local_vars["callbacks"],
        "rollout_buffer": ro,
        "n_rollout_steps": model.config.n_steps,
        "n_steps": n_steps,
    }


def act_with_teachers(model: Any, obs: Any, net_obs: Any, deterministic: bool) -> np.ndarray:
    """``TLAC.predict_with_teachers`` on a raw batch ``obs`` (``net_obs``: as the networks were
    trained on it): the high level picks a teacher or the agent per row (Algorithm 1, line
    14), the chosen teacher's action replaces the agent's (line 18); with ``deterministic``
    the high level and the agent take their most likely choice."""
    nets = model.nets
    high_logits, low_out, _, latent = nets.act(net_obs)
    choices = model.selector.evaluation_choices(high_logits, deterministic)
    if deterministic:
        actions = low_out.argmax(-1) if nets.discrete else low_out.copy()
    else:
        actions = nets.sample_low(low_out, latent)
    query_teachers(model.teachers, choices, obs, model.action_space, actions)
    return nets.to_env_actions(actions)
