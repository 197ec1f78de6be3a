"""The partial view computed from the full grid equals MiniGrid's own, and the PPO teacher's
exported actor equals stable-baselines3's greedy policy."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from tlac.domains import get_domain, make_teachers
from tlac.domains.doorkey.env import make_doorkey_env
from tlac.domains.doorkey.planner import DoorKeyOptimalTeacher
from tlac.domains.doorkey.view import partial_view, partial_view_of_grid
from tlac.errors import TeacherError, UnknownNameError


def test_partial_view_equals_minigrid_gen_obs_on_random_and_teacher_states() -> None:
    """States from a mix of optimal and random actions: the key picked up, dropped, the door
    opened, every direction; each compared with MiniGrid's gen_obs_grid + encode."""
    env, optimal = make_doorkey_env(), DoorKeyOptimalTeacher()
    rng = np.random.default_rng(0)
    compared = carrying = 0
    for episode in range(12):
        obs, _ = env.reset(seed=episode)
        for _ in range(120):
            grid, visible = env.unwrapped.gen_obs_grid()
            np.testing.assert_array_equal(
                partial_view(obs[None])[0], grid.encode(visible).reshape(-1)
            )
            compared += 1
            carrying += env.unwrapped.carrying is not None
            use_teacher = rng.random() < 0.6
            action = optimal.predict(obs[None])[0] if use_teacher else rng.integers(6)
            obs, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                break
    assert compared > 300 and carrying > 50


def test_cached_partial_view_equals_a_fresh_computation_and_stays_unshared() -> None:
    """The cache returns what partial_view_of_grid computes, for repeated states too, and the
    caller gets its own writable copy."""
    env, rng = make_doorkey_env(), np.random.default_rng(1)
    obs, _ = env.reset(seed=3)
    batch = [obs]
    for _ in range(40):
        obs, *_ = env.step(int(rng.integers(6)))
        batch.append(obs)
    batch = np.stack(batch + batch[:10])  # ten states seen twice
    fresh = np.stack(
        [partial_view_of_grid(o.reshape(7, 7, 3).astype(np.int64)).reshape(-1) for o in batch]
    )
    first, again = partial_view(batch), partial_view(batch)
    np.testing.assert_array_equal(first, fresh)
    np.testing.assert_array_equal(again, fresh)
    again[:] = 0  # the caller's copy: the cache is unchanged
    np.testing.assert_array_equal(partial_view(batch), fresh)


def test_partial_domain_is_a_valid_env_and_refuses_full_grid_teachers() -> None:
    domain = get_domain("doorkey-partial")
    env = domain.make_env()
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert obs.shape == (147,) and obs.dtype == np.uint8
    with pytest.raises(UnknownNameError, match="doorkey-partial"):
        make_teachers(domain, ["optimal"], env, seed=0)
    (random,) = make_teachers(domain, ["random"], env, seed=0)
    assert random.predict(obs[None]).shape == (1,)


def test_exported_ppo_actor_equals_sb3_greedy_predict(tmp_path) -> None:
    import json

    import torch
    from stable_baselines3 import PPO

    from tlac.teachers.ppo import PPOActor, PPOActorTeacher, ppo_actor_state_dict

    env = get_domain("doorkey-partial").make_env()
    model = PPO("MlpPolicy", env, seed=0, device="cpu", policy_kwargs=dict(net_arch=[16, 16]))
    actor = PPOActor(147, 6, [16, 16])
    actor.load_state_dict(ppo_actor_state_dict(model.policy.state_dict()))
    probe = np.stack([env.observation_space.sample() for _ in range(64)])
    np.testing.assert_array_equal(
        PPOActorTeacher(actor).predict(probe),
        model.predict(probe, deterministic=True)[0],
    )
    # shipped as .pt + .json, loaded back, it advises a full-grid student through its view
    torch.save(actor.state_dict(), tmp_path / "doorkey-ppo.pt")
    meta = {"obs_dim": 147, "n_actions": 6, "net_arch": [16, 16]}
    (tmp_path / "doorkey-ppo.json").write_text(json.dumps(meta))
    teacher = PPOActorTeacher.load("doorkey", transform=partial_view, data_dir=tmp_path)
    full, _ = make_doorkey_env().reset(seed=3)
    view = partial_view(full[None])
    np.testing.assert_array_equal(
        teacher.predict(full[None]), model.predict(view, deterministic=True)[0]
    )
    with pytest.raises(TeacherError, match="tlac teacher train doorkey"):
        PPOActorTeacher.load("doorkey", data_dir=tmp_path / "missing")
