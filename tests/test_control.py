"""Hopper and Pick & Place: environments, scripted and shipped teachers, teacher CLI.

Fast checks (well under a minute): ``check_env`` on every continuous-control domain, the
Pick & Place reset distribution, a few teacher episodes against the documented returns
(docs/control.md), region labels, and the shipped SAC Hopper teacher.
"""

from __future__ import annotations

import argparse
import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from tlac.domains import get_domain, make_teachers
from tlac.errors import ConfigError, TeacherError, UnknownNameError
from tlac.teachers.base import check_actions


def _run_episode(env: gym.Env, teacher, seed: int) -> tuple[float, list[np.ndarray], dict]:
    obs, info = env.reset(seed=seed)
    observations, total, done = [obs], 0.0, False
    while not done:
        action = check_actions(teacher.name, teacher.predict(obs[None]), env.action_space, 1)[0]
        obs, reward, terminated, truncated, info = env.step(action)
        observations.append(obs)
        total += float(reward)
        done = terminated or truncated
    return total, observations, info


@pytest.mark.parametrize("name", ["hopper-bullet", "hopper", "pickplace"])
def test_check_env(name: str) -> None:
    domain = get_domain(name)
    env = domain.make_env()
    check_env(env, skip_render_check=True)
    assert env.observation_space.dtype == np.float32
    obs, _ = env.reset(seed=0)
    assert obs.dtype == np.float32 and env.observation_space.contains(obs)
    assert domain.region_of(obs[None]).shape == (1,)
    assert set(domain.presets) == {"tlac", "a2c", "ppo", "ac-teach"}


def test_hopper_spaces() -> None:
    env = get_domain("hopper-bullet").make_env()
    assert env.observation_space.shape == (15,) and env.action_space.shape == (3,)
    assert env.spec is not None and env.spec.max_episode_steps == 1000
    assert get_domain("hopper").make_env().observation_space.shape == (11,)


def test_pickplace_goal_fixed_and_start_ranges() -> None:
    from tlac.domains.pickplace.env import GOAL

    env = get_domain("pickplace").make_env()
    assert env.observation_space.shape == (25,) and env.action_space.shape == (4,)
    grippers, boxes = [], []
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        np.testing.assert_allclose(env.unwrapped.goal, GOAL)
        boxes.append(obs[3:6])
        grippers.append(obs[0:3])
        assert info["is_success"] is False
    boxes, grippers = np.array(boxes), np.array(grippers)
    assert np.all(np.abs(boxes[:, 0] - 1.25) <= 0.05 + 1e-4)
    assert np.all(np.abs(boxes[:, 1] - 0.55) <= 0.05 + 1e-4)
    np.testing.assert_allclose(boxes[:, 2], 0.425, atol=2e-3)  # on the table
    assert boxes[:, :2].std(axis=0).min() > 0.01  # really random
    # Gripper start jitter: +-0.05 (x, y), +-0.025 (z) around Fetch's start (small settling slack).
    spread = grippers.max(axis=0) - grippers.min(axis=0)
    assert np.all(spread > [0.02, 0.02, 0.01]) and np.all(spread < [0.11, 0.11, 0.06])
    # Same seed, same start.
    a, _ = env.reset(seed=3)
    b, _ = env.reset(seed=3)
    np.testing.assert_array_equal(a, b)
    # 100-step episodes with the dense reward -distance(box, goal).
    env.reset(seed=0)
    for t in range(100):
        obs, reward, terminated, truncated, info = env.step(np.zeros(4, dtype=np.float32))
        assert reward == pytest.approx(-np.linalg.norm(obs[3:6] - GOAL), abs=1e-5)
        assert not terminated and truncated == (t == 99)


def test_pickplace_teachers_reach_documented_returns() -> None:
    """docs/control.md, 1000 episodes: optimal about -4.5, random about -21, success 1 / 0."""
    domain = get_domain("pickplace")
    env = domain.make_env()
    names = ["optimal", "good", "noisy", "random"]
    teachers = dict(zip(names, make_teachers(domain, names, env, seed=0), strict=True))
    for name, (low, high) in {
        "optimal": (-6.0, -3.0),
        "good": (-6.0, -3.0),
        "noisy": (-8.0, -3.0),
        "random": (-30.0, -14.0),
    }.items():
        results = [_run_episode(env, teachers[name], seed) for seed in (11, 12)]
        mean = np.mean([r[0] for r in results])
        assert low < mean < high, (name, mean)
        if name != "random":
            assert all(r[2]["is_success"] for r in results), name


def test_pickplace_regions_flip_when_grasping() -> None:
    from tlac.domains.pickplace.env import REGION_NAMES

    domain = get_domain("pickplace")
    assert domain.region_names == REGION_NAMES == ("not_holding", "holding")
    env = domain.make_env()
    (optimal,) = make_teachers(domain, ["optimal"], env, seed=0)
    _, observations, _ = _run_episode(env, optimal, seed=5)
    regions = domain.region_of(np.stack(observations))
    assert regions[0] == 0 and regions.max() == 1 and regions[-1] == 0  # grasp, then release
    first = int(np.argmax(regions == 1))
    obs = np.stack(observations)
    assert np.linalg.norm(obs[first, 6:9]) < 0.03  # grasped: gripper at the box
    assert obs[first, 9] + obs[first, 10] < obs[0, 9] + obs[0, 10] + 0.06


def test_pickplace_region_teachers() -> None:
    """pick-region / place-region follow the optimal teacher in their region only."""
    from tlac.domains.pickplace.teachers import optimal_actions

    domain = get_domain("pickplace")
    env = domain.make_env()
    (optimal,) = make_teachers(domain, ["optimal"], env, seed=0)
    _, observations, _ = _run_episode(env, optimal, seed=7)
    obs = np.stack(observations)
    regions = domain.region_of(obs)
    pick, place = make_teachers(domain, ["pick-region", "place-region"], env, seed=0)
    reference = optimal_actions(obs)
    np.testing.assert_allclose(pick.predict(obs)[regions == 0], reference[regions == 0])
    np.testing.assert_allclose(place.predict(obs)[regions == 1], reference[regions == 1])
    assert not np.allclose(pick.predict(obs)[regions == 1], reference[regions == 1])
    with pytest.raises(UnknownNameError):
        make_teachers(domain, ["nope"], env, seed=0)


def test_pickplace_ac_teach_pick_and_place_teachers() -> None:
    """AC-Teach's partial teachers: pick grasps the box and carries it back to its start (never
    to the goal); place keeps the gripper closed and heads for the goal: alone it never
    grasps, but handed a held box it delivers it."""
    from tlac.domains.pickplace.env import GOAL, OBJECT_START_XY
    from tlac.domains.pickplace.teachers import optimal_actions

    domain = get_domain("pickplace")
    env = domain.make_env()
    pick, place = make_teachers(domain, ["pick", "place"], env, seed=0)
    _total, observations, info = _run_episode(env, pick, seed=3)
    obs = np.stack(observations)
    regions = domain.region_of(obs)
    assert regions.max() == 1 and regions[-1] == 1  # grasps, and keeps holding
    assert np.linalg.norm(obs[-1, 3:5] - OBJECT_START_XY) < 0.03  # back at the start
    assert not info["is_success"]
    # place alone: gripper closed at every step, the box is never held
    _, observations, info = _run_episode(env, place, seed=3)
    obs = np.stack(observations)
    assert (place.predict(obs)[:, 3] == -1.0).all() and domain.region_of(obs).max() == 0
    assert not info["is_success"]
    # optimal until the box is held, then place: the box reaches the goal
    obs, _ = env.reset(seed=4)
    held = False
    for _ in range(100):
        held = held or bool(domain.region_of(obs[None])[0])
        action = place.predict(obs[None])[0] if held else optimal_actions(obs[None])[0]
        obs, _, _, truncated, info = env.step(action)
        if truncated:
            break
    assert held and np.linalg.norm(obs[3:6] - GOAL) < 0.05


def test_sac_actor_matches_sb3() -> None:
    """The exported actor reproduces SB3's deterministic predict (gSDE and plain)."""
    from stable_baselines3 import SAC

    from tlac.teachers.sac import SACActor, SACActorTeacher, actor_state_dict

    env = get_domain("hopper-bullet").make_env()
    obs = np.stack([env.observation_space.sample() for _ in range(16)]).clip(-3, 3)
    for use_sde in (True, False):
        model = SAC("MlpPolicy", env, use_sde=use_sde, policy_kwargs={"net_arch": [32, 32]}, seed=0)
        actor = SACActor(15, 3, [32, 32], clip_mean=2.0 if use_sde else 0.0)
        actor.load_state_dict(actor_state_dict(model.actor))
        teacher = SACActorTeacher(actor, env.action_space.low, env.action_space.high)
        expected, _ = model.predict(obs, deterministic=True)
        np.testing.assert_allclose(teacher.predict(obs), expected, atol=1e-5)


def test_shipped_hopper_bullet_teacher_beats_random() -> None:
    from tlac.teachers.sac import SACActorTeacher, weights_paths

    pt, meta_path = weights_paths("hopper-bullet")
    meta = json.loads(meta_path.read_text())
    assert meta["eval"]["episodes"] >= 100 and meta["steps"] > 0 and meta["command"]
    assert pt.stat().st_size < 2_000_000  # actor only
    domain = get_domain("hopper-bullet")
    env = domain.make_env()
    optimal, random = make_teachers(domain, ["optimal", "random"], env, seed=0)
    actions = optimal.predict(np.stack([env.reset(seed=s)[0] for s in range(4)]))
    check_actions("optimal", actions, env.action_space, 4)
    assert isinstance(SACActorTeacher.load("hopper-bullet"), SACActorTeacher)
    teacher_return = np.mean([_run_episode(env, optimal, s)[0] for s in (1, 2)])
    random_return = np.mean([_run_episode(env, random, s)[0] for s in (1, 2)])
    assert teacher_return > random_return + 100, (teacher_return, random_return)
    good, _noisy = make_teachers(domain, ["good", "noisy"], env, seed=0)
    check_actions("good", good.predict(np.stack([env.reset(seed=0)[0]] * 3)), env.action_space, 3)


def test_missing_weights_error_names_path_and_command(tmp_path) -> None:
    from tlac.teachers.sac import SACActorTeacher

    with pytest.raises(TeacherError, match=r"hopper-sac\.pt.*tlac teacher train hopper"):
        SACActorTeacher.load("hopper", data_dir=tmp_path)
    # The MuJoCo Hopper domain works without an optimal teacher: random needs no weights.
    domain = get_domain("hopper")
    env = domain.make_env()
    (random,) = make_teachers(domain, ["random"], env, seed=0)
    check_actions("random", random.predict(np.zeros((2, 11), np.float32)), env.action_space, 2)


def test_train_teacher_rejects_bad_input(tmp_path) -> None:
    from tlac.teacher_training import train_teacher

    with pytest.raises(UnknownNameError):
        train_teacher("pickplace", 10, 0, tmp_path)
    with pytest.raises(ConfigError):
        train_teacher("hopper-bullet", 0, 0, tmp_path)


def _parser() -> argparse.ArgumentParser:
    from tlac.cli.teacher import register

    parser = argparse.ArgumentParser(prog="tlac")
    register(parser.add_subparsers(dest="command"))
    return parser


def test_cli_eval(capsys) -> None:
    parser = _parser()
    args = parser.parse_args(
        ["teacher", "eval", "pickplace", "--teachers", "random", "--episodes", "2", "--json"]
    )
    assert args.func(args) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["teachers"]["random"]["episodes"] == 2
    args = parser.parse_args(["teacher", "eval", "pickplace", "--teachers", "optimal,bogus"])
    with pytest.raises(UnknownNameError, match="bogus"):
        args.func(args)
    args = parser.parse_args(["teacher", "eval", "nowhere"])
    with pytest.raises(UnknownNameError):
        args.func(args)
    args = parser.parse_args(["teacher", "train", "hopper", "--steps", "5", "--time-limit", "-1"])
    with pytest.raises(ConfigError):
        args.func(args)
    with pytest.raises(SystemExit):
        parser.parse_args(["teacher", "eval", "pickplace", "--episodes", "0"])
