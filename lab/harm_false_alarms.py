"""How often the harm gate (tlac.two_level.graduation.shows_harm) reads a teacher as harm on
CartPole, where an untrained student plays about as a random policy: the episode returns of a
uniformly random policy and of one that always pushes left (an idle teacher), then draws of 5
"untrained" episodes and 3 led ones, as the audition judges them (results/teacher-sweep/
NOTES.md, "A teacher that harms is left out of the copy"):

    .venv/bin/python lab/harm_false_alarms.py
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from tlac.two_level.graduation import MIN_LED_EPISODES, shows_harm

EPISODES, DRAWS, UNTRAINED_EPISODES = 1000, 4000, 5


def returns(policy, seed: int) -> np.ndarray:
    """The returns of ``EPISODES`` CartPole episodes of ``policy`` (a function of a generator)."""
    env, rng = gym.make("CartPole-v1"), np.random.default_rng(seed)
    out = []
    for episode in range(EPISODES):
        env.reset(seed=seed * EPISODES + episode)
        total, done = 0.0, False
        while not done:
            _, reward, terminated, truncated, _ = env.step(policy(rng))
            total, done = total + reward, terminated or truncated
        out.append(total)
    return np.array(out)


def harm_rate(untrained: np.ndarray, led: np.ndarray, n_led: int, seed: int) -> float:
    """The share of draws in which ``n_led`` led returns show harm against 5 untrained ones."""
    rng, hits = np.random.default_rng(seed), 0
    for _ in range(DRAWS):
        first = rng.choice(untrained, UNTRAINED_EPISODES)
        episodes = rng.choice(led, n_led)
        floor_se = float(np.std(first)) / np.sqrt(UNTRAINED_EPISODES)
        hits += shows_harm(
            episodes.sum(), (episodes**2).sum(), n_led, float(first.mean()), floor_se
        )
    return hits / DRAWS


def main() -> None:
    random_policy = returns(lambda rng: int(rng.integers(2)), seed=1)
    idle = returns(lambda rng: 0, seed=2)
    print(f"random policy {random_policy.mean():.1f} +- {random_policy.std():.1f}; ", end="")
    print(f"idle (always left) {idle.mean():.1f} +- {idle.std():.1f}")
    for n_led in (MIN_LED_EPISODES, 10, 30):
        rate = harm_rate(random_policy, random_policy, n_led, seed=n_led)
        print(f"a random teacher, {n_led} led episodes: read as harm in {rate:.1%} of draws")
    rate = harm_rate(random_policy, idle, MIN_LED_EPISODES, seed=0)
    print(f"the idle teacher, {MIN_LED_EPISODES} led episodes: read as harm in {rate:.1%}")


if __name__ == "__main__":
    main()
