"""Time-major rollout storage and GAE with time-limit bootstrap.

:class:`Rollout` is a dataclass of tensors of shape ``(n_steps, n_envs, ...)``: adding a field is
one line. The teacher index ``choices`` and both levels' log-probabilities of what happened
are stored at collection time (Algorithm 1, line 19), so the clipped ratios of the update
compare against the behaviour that produced the data.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import torch


@dataclass
class Rollout:
    """Filled as NumPy arrays while acting (cheap per-step writes); :meth:`flat` hands the
    update zero-copy PyTorch tensors."""

    obs: np.ndarray  # (T, E, obs_dim) float32
    actions: np.ndarray  # (T, E) int64 or (T, E, act_dim) float32: the EXECUTED actions
    choices: np.ndarray  # (T, E) int64: teacher index, n_teachers = the agent itself
    rewards: np.ndarray  # (T, E) float32, with gamma * V(final obs) added on truncation
    dones: np.ndarray  # (T, E) float32: the episode ended after this step
    values: np.ndarray  # (T, E) float32: V(s_t) at collection time
    log_prob_low: np.ndarray  # (T, E): log pi_low(a_t | s_t) at collection time
    log_prob_high: np.ndarray  # (T, E): log pi_high(e_t | s_t) at collection time
    advantages: np.ndarray  # (T, E), filled by compute_gae
    returns: np.ndarray  # (T, E), filled by compute_gae
    solo: np.ndarray  # (T, E) float32: 1 in an episode the student plays alone (graduation)
    net_obs: np.ndarray  # (T, E, obs_dim) float32: what the networks saw (normalised), if not obs
    teacher_obs: np.ndarray  # (T, E, obs_dim) float32: what the teachers saw, under a VecNormalize
    # advice limited (tlac.algorithms.advice; None otherwise): (T, E, K) bool
    askable: np.ndarray | None = None  # the teachers present where the student asked
    high_mask: np.ndarray | None = None  # the teachers the high level could choose from
    high_shift: np.ndarray | None = None  # ask learned, (T, E, K): the price in the logits
    high_away: np.ndarray | None = None  # ask learned: the teachers away (advice.away_to_agent)
    corrected: np.ndarray | None = None  # ask mistake, (T, E) bool: the teacher disagreed

    @classmethod
    def empty(
        cls, n_steps: int, n_envs: int, obs_dim: int, action_shape: tuple[int, ...], discrete: bool
    ) -> Rollout:
        te = (n_steps, n_envs)
        z = lambda *shape, dtype=np.float32: np.zeros(shape, dtype=dtype)  # noqa: E731
        return cls(
            obs=z(*te, obs_dim),
            actions=z(*te, dtype=np.int64) if discrete else z(*te, *action_shape),
            choices=z(*te, dtype=np.int64),
            rewards=z(*te),
            dones=z(*te),
            values=z(*te),
            log_prob_low=z(*te),
            log_prob_high=z(*te),
            advantages=z(*te),
            returns=z(*te),
            solo=z(*te),
            net_obs=z(*te, obs_dim),
            teacher_obs=z(*te, obs_dim),
        )

    def flat(self) -> dict[str, torch.Tensor]:
        """Every field with time and env axes merged: ``(T * E, ...)``."""
        out = {}
        for f in fields(self):
            a = getattr(self, f.name)
            if a is None:
                continue
            out[f.name] = torch.from_numpy(
                np.ascontiguousarray(a.reshape(a.shape[0] * a.shape[1], *a.shape[2:]))
            )
        return out


def compute_gae(
    rewards: np.ndarray,
    values: np.ndarray,
    dones: np.ndarray,
    last_values: np.ndarray,
    gamma: float,
    gae_lambda: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Generalized advantage estimation over time-major arrays ``(T, E)``.

    ``dones[t]`` marks that the episode ended after step ``t`` (the value of ``s_{t+1}`` is not
    bootstrapped; a time-limit truncation has already added ``gamma * V(final obs)`` to the
    reward). ``last_values`` is ``V(s_T)`` for the state after the rollout.
    With ``gae_lambda = 0`` the advantage is exactly the paper's Eq. 2:
    ``A = r_t + gamma V(s_{t+1}) - V(s_t)``.

    >>> one = lambda x: np.array([[x]])
    >>> adv, ret = compute_gae(one(1.0), one(0.5), one(0.0), np.array([2.0]), 0.9, 0.0)
    >>> round(float(adv[0, 0]), 6)   # 1 + 0.9 * 2 - 0.5
    2.3
    """
    n_steps = rewards.shape[0]
    advantages = np.zeros_like(rewards, dtype=np.float64)
    last_gae = np.zeros_like(last_values, dtype=np.float64)
    for t in reversed(range(n_steps)):
        next_values = last_values if t == n_steps - 1 else values[t + 1]
        not_done = 1.0 - dones[t]
        delta = rewards[t] + gamma * next_values * not_done - values[t]
        last_gae = delta + gamma * gae_lambda * not_done * last_gae
        advantages[t] = last_gae
    returns = advantages + values
    return advantages.astype(np.float32), returns.astype(np.float32)
