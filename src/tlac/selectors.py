"""The high level of TL-AC as a swappable component (paper, section 3.2 and Figure 11).

A selector picks, for each environment, which of the K = N teachers + 1 (the agent, index N)
acts. ``learned`` is TL-AC's trained high-level actor pi_high(e|s); ``random`` and ``ucb1`` are
the paper's ablations (Figure 11): uniform selection at every step, and a multi-armed bandit
that picks one teacher per EPISODE from the returns obtained so far (Auer et al. 2002).

>>> sel = UCB1Selector(n_choices=2, n_envs=1, seed=0)
>>> first = int(sel.select(None, np.array([True]))[0]); sel.episode_end(0, 1.0)
>>> int(sel.select(None, np.array([True]))[0]) == 1 - first   # untried arms are played first
True
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np

from tlac.algorithms.advice import MASKED_LOGIT
from tlac.algorithms.nets import np_sample_categorical


def ucb1_scores(sums: np.ndarray, counts: np.ndarray, c: float, value_range: float) -> np.ndarray:
    """UCB1 index per arm: mean return + c * range * sqrt(2 ln n / n_a); untried arms get +inf.

    UCB1 assumes rewards in [0, 1]; episode returns are on any scale, so the exploration term
    is multiplied by the range of returns seen so far (1 before two distinct returns exist).

    >>> ucb1_scores(np.array([3.0, 1.0]), np.array([3, 1]), 1.0, 1.0).round(4).tolist()
    [1.9614, 2.6651]
    """
    total = counts.sum()
    scores = np.full(len(counts), np.inf)
    tried = counts > 0
    if tried.any():
        means = sums[tried] / counts[tried]
        bonus = c * value_range * np.sqrt(2.0 * math.log(max(total, 1)) / counts[tried])
        scores[tried] = means + bonus
    return scores


class Selector(Protocol):
    """What TL-AC asks of its high level. ``select`` is called at every step of training with
    the high-level actor's logits (ignored by the ablations) and which environments start an
    episode; ``episode_end`` reports each finished episode's return; ``evaluation_choices``
    is the choice outside training (``TLAC.predict_with_teachers``)."""

    name: str
    trains_high_level: bool
    """True when the high-level actor's loss (Eq. 7) is trained."""

    def select(self, high_logits: np.ndarray, episode_starts: np.ndarray) -> np.ndarray: ...

    def episode_end(self, env_index: int, episode_return: float) -> None: ...

    def evaluation_choices(self, high_logits: np.ndarray, deterministic: bool) -> np.ndarray: ...


class LearnedSelector:
    """pi_high(e|s): sample the high-level actor's categorical distribution."""

    name = "learned"
    trains_high_level = True

    def __init__(self, rng: np.random.Generator):
        self.rng = rng

    def select(self, high_logits: np.ndarray, episode_starts: np.ndarray) -> np.ndarray:
        return np_sample_categorical(high_logits, self.rng)

    def episode_end(self, env_index: int, episode_return: float) -> None:
        pass

    def evaluation_choices(self, high_logits: np.ndarray, deterministic: bool) -> np.ndarray:
        """The most likely choice, or a sample of pi_high."""
        if deterministic:
            return high_logits.argmax(-1)
        return np_sample_categorical(high_logits, self.rng)


class RandomSelector:
    """Uniform choice among teachers and agent at every step (Figure 11, 'Random')."""

    name = "random"
    trains_high_level = False

    def __init__(self, n_choices: int, seed: int):
        self.n_choices = n_choices
        self.rng = np.random.default_rng(seed)

    def select(self, high_logits: np.ndarray | None, episode_starts: np.ndarray) -> np.ndarray:
        return self.rng.integers(self.n_choices, size=len(episode_starts))

    def episode_end(self, env_index: int, episode_return: float) -> None:
        pass

    def evaluation_choices(self, high_logits: np.ndarray, deterministic: bool) -> np.ndarray:
        """Uniform, as in training (there is no most likely choice)."""
        return self.rng.integers(self.n_choices, size=len(high_logits))


class UCB1Selector:
    """One choice per episode by UCB1 over the returns of earlier episodes (Figure 11, 'UCB1')."""

    name = "ucb1"
    trains_high_level = False

    def __init__(self, n_choices: int, n_envs: int, seed: int, c: float = 1.0):
        self.sums = np.zeros(n_choices)
        self.counts = np.zeros(n_choices, dtype=np.int64)
        self.c = c
        self.current = np.zeros(n_envs, dtype=np.int64)
        self.rng = np.random.default_rng(seed)
        self.low = math.inf
        self.high = -math.inf

    def select(self, high_logits: np.ndarray | None, episode_starts: np.ndarray) -> np.ndarray:
        """At each episode start, the arm of the best UCB1 score among those that can answer
        (under limited advice, a teacher absent or unaffordable has its logit at
        ``MASKED_LOGIT``: it is not picked, so its arm is never credited with an episode the
        agent played)."""
        for i in np.flatnonzero(episode_starts):
            value_range = self.high - self.low if self.high > self.low else 1.0
            scores = ucb1_scores(self.sums, self.counts, self.c, value_range)
            if high_logits is not None:
                scores = np.where(high_logits[i] > MASKED_LOGIT / 2, scores, -np.inf)
            best = np.flatnonzero(scores == scores.max())
            self.current[i] = int(self.rng.choice(best))  # ties (e.g. untried arms): at random
        return self.current.copy()

    def episode_end(self, env_index: int, episode_return: float) -> None:
        arm = int(self.current[env_index])
        self.sums[arm] += episode_return
        self.counts[arm] += 1
        self.low = min(self.low, episode_return)
        self.high = max(self.high, episode_return)

    def evaluation_choices(self, high_logits: np.ndarray, deterministic: bool) -> np.ndarray:
        """The arm with the best mean return so far, for every row."""
        best = int(np.argmax(self.sums / np.maximum(self.counts, 1)))
        return np.full(len(high_logits), best)


SELECTORS: dict[str, Callable[..., Selector]] = {
    "learned": lambda n_choices, n_envs, seed, rng: LearnedSelector(rng),
    "random": lambda n_choices, n_envs, seed, rng: RandomSelector(n_choices, seed),
    "ucb1": lambda n_choices, n_envs, seed, rng: UCB1Selector(n_choices, n_envs, seed),
}
"""The one list of high levels: name -> factory ``(n_choices, n_envs, seed, rng)``."""
SELECTOR_NAMES = tuple(SELECTORS)


def make_selector(
    name: str, n_choices: int, n_envs: int, seed: int, rng: np.random.Generator
) -> Selector:
    """The named selector; ``rng`` is TL-AC's acting generator (the learned one samples from it)."""
    return SELECTORS[name](n_choices, n_envs, seed, rng)
