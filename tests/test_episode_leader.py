"""``model.episode_leader`` (tlac.two_level.collect.EpisodeLeader, ``tlac teach``'s take-over):
a teacher named from outside the run leads the episode that starts, in the paper variant (the
high level's choice forced) and the graduate variant (a teacher-led episode, counted as the
teacher's own); under limited advice a leader that cannot answer stops leading; the hook is
never saved."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from tlac import TLAC


class LeadOnce:
    """Names teacher ``k`` to lead the first episode of environment 0, then nobody."""

    def __init__(self, k: int = 0):
        self.k, self.calls, self.named = k, 0, False

    def lead(self, episode_starts: np.ndarray) -> np.ndarray | None:
        self.calls += 1
        if self.named or not episode_starts[0]:
            return None
        self.named = True
        out = np.full(len(episode_starts), -1)
        out[0] = self.k
        return out


def _model(**settings) -> TLAC:
    # teacher k pushes the cart to side k
    teachers = [lambda obs: 0, lambda obs: 1]
    return TLAC(
        gym.make("CartPole-v1"), teachers=teachers, seed=0, n_steps=128, batch_size=64, **settings
    )


def _first_two_episodes(ro) -> tuple[slice, slice]:
    ends = np.flatnonzero(ro.dones[:, 0])
    assert len(ends) >= 2, "the rollout should hold two episodes"
    return slice(0, ends[0] + 1), slice(ends[0] + 1, ends[1] + 1)


@pytest.mark.parametrize("variant", ["paper", "graduate"])
def test_a_named_teacher_leads_one_episode_then_the_high_level_chooses_again(variant):
    model = _model(variant=variant)
    assert model.episode_leader is None
    leader = model.episode_leader = LeadOnce(0)
    ro = model.collect()
    assert leader.calls == 128  # once a step
    first, second = _first_two_episodes(ro)
    assert (ro.choices[first, 0] == 0).all()
    assert (ro.actions[first, 0] == 0).all()  # teacher 0 acted
    assert (ro.choices[second, 0] != 0).any()  # back to the high level (or the solo draw)
    if variant == "graduate":
        assert not ro.solo[first, 0].any()
        # recorded as teacher 0's led episode, with its return (the first episode's length)
        assert model.solo.led_counts.tolist() == [1, 0]
        assert model.solo.led_sums[0] == first.stop - first.start
    else:
        assert model.solo is None


def test_with_limited_advice_a_leader_out_of_budget_stops_leading():
    model = _model(advice_budget=3)
    model.episode_leader = LeadOnce(0)
    ro = model.collect()
    first, _ = _first_two_episodes(ro)
    assert (ro.choices[:3, 0] == 0).all() and not (ro.choices[3 : first.stop, 0] < 2).any()
    assert model.advice.acted.tolist() == [3, 0]
    # no longer led: the episode counts as an assisted one, not as teacher 0's own
    assert model.solo.led_counts.tolist() == [0, 0]


def test_a_bad_leader_is_refused_and_the_hook_is_never_saved(tmp_path):
    model = _model()
    model.episode_leader = type("Bad", (), {"lead": lambda self, starts: np.array([2])})()
    with pytest.raises(ValueError, match=r"teachers are 0\.\.1"):
        model.collect()
    model.episode_leader = LeadOnce(1)
    model.learn(128, progress_bar=False)
    path = model.save(tmp_path / "m.pt", training_state=True)
    env = gym.make("CartPole-v1")
    loaded = TLAC.load(path, env=env, teachers=[lambda obs: 0, lambda obs: 1], resume=True)
    assert loaded.episode_leader is None


def test_an_episode_leader_gone_mid_episode_leaves_no_episode_led():
    """tlac teach's session ends (``episode_leader = None``) during a take-over: the episode
    it led goes back to the high level at once (``_led_by`` all -1), not led to its end."""
    model = _model(variant="paper")

    class LeadThenGo(LeadOnce):
        def lead(self, episode_starts: np.ndarray) -> np.ndarray | None:
            if self.named:
                model.episode_leader = None  # from the next step on
            return super().lead(episode_starts)

    model.episode_leader = LeadThenGo(0)
    ro = model.collect()
    first, _ = _first_two_episodes(ro)
    assert first.stop > 3 and (ro.choices[:2, 0] == 0).all()
    assert (ro.choices[2 : first.stop, 0] != 0).any()  # the high level chooses again
    assert (model._led_by == -1).all()
