"""Observation spaces as SB3 takes them (issue 43, point 4): Discrete / MultiDiscrete one-hot,
Dict key by key, images through SB3's NatureCNN (policy="CnnPolicy"), and a clear error, never
a silent flatten, when an image meets an MLP. The teachers always get the environment's own
observations (an int, a dict, a uint8 image)."""

from __future__ import annotations

import gymnasium as gym
import minigrid  # noqa: F401  (registers the MiniGrid ids)
import numpy as np
import pytest
import torch
from gymnasium.wrappers import FilterObservation
from minigrid.wrappers import ImgObsWrapper, RGBImgPartialObsWrapper
from stable_baselines3.common.torch_layers import NatureCNN

from tlac import TLAC
from tlac.algorithms.obs_spaces import ObsEncoder, ObsPolicy, make_layout
from tlac.errors import ConfigError

# ----------------------------------------------------------------- the encodings, by hand


def test_discrete_and_multidiscrete_are_one_hot() -> None:
    space = gym.spaces.Discrete(4, start=1)
    layout = make_layout(space, ObsPolicy(), "raw")  # one-hot whatever obs_encoding says
    rows = layout.flatten(3)
    encoder = ObsEncoder(layout, ObsPolicy(), ortho_init=True)
    assert rows.tolist() == [[3.0]]
    assert encoder.numpy(rows).tolist() == [[0.0, 0.0, 1.0, 0.0]]
    assert encoder.torch(torch.from_numpy(rows)).tolist() == [[0.0, 0.0, 1.0, 0.0]]
    assert layout.unflatten(rows).tolist() == [3]  # what a teacher gets: the int

    multi = make_layout(gym.spaces.MultiDiscrete([2, 3]), ObsPolicy(), "auto")
    rows = multi.flatten(np.array([[1, 2], [0, 0]]))
    assert ObsEncoder(multi, ObsPolicy(), True).numpy(rows).tolist() == [
        [0.0, 1.0, 0.0, 0.0, 1.0],
        [1.0, 0.0, 1.0, 0.0, 0.0],
    ]
    assert multi.unflatten(rows).tolist() == [[1, 2], [0, 0]]


def test_a_dict_is_flattened_key_by_key() -> None:
    space = gym.spaces.Dict(
        {
            "pos": gym.spaces.Box(-1.0, 1.0, (2,)),
            "room": gym.spaces.Discrete(3),
            "cell": gym.spaces.Box(0, 2, (1,), dtype=np.uint8),  # small integers
            "flags": gym.spaces.MultiBinary(2),
        }
    )
    obs = {"pos": np.array([0.5, -0.25]), "room": 2, "cell": np.array([1]), "flags": [1, 0]}
    assert list(space.spaces) == ["cell", "flags", "pos", "room"]  # gymnasium sorts the keys
    layout = make_layout(space, ObsPolicy(), "auto")
    rows = layout.flatten(obs)
    assert rows.tolist() == [[1.0, 1.0, 0.0, 0.5, -0.25, 2.0]]
    encoder = ObsEncoder(layout, ObsPolicy(), ortho_init=True)
    #                cell one-hot (auto)  flags     pos          room one-hot
    expected = [[0.0, 1.0, 0.0, 1.0, 0.0, 0.5, -0.25, 0.0, 0.0, 1.0]]
    assert encoder.numpy(rows).tolist() == expected
    assert encoder.torch(torch.from_numpy(rows)).tolist() == expected
    raw = make_layout(space, ObsPolicy(), "raw")  # the integer Box raw, the Discrete one-hot
    assert ObsEncoder(raw, ObsPolicy(), True).numpy(rows).tolist() == [
        [1.0, 1.0, 0.0, 0.5, -0.25, 0.0, 0.0, 1.0]
    ]
    back = layout.unflatten(rows)  # the teachers' dict, in the space's dtypes
    assert back["room"].tolist() == [2] and back["cell"].dtype == np.uint8
    assert back["flags"].tolist() == [[1, 0]] and back["pos"].tolist() == [[0.5, -0.25]]
    assert layout.check(obs)[1] and not layout.check(back)[1]  # one observation / a batch


def test_an_image_is_transposed_scaled_and_read_by_nature_cnn() -> None:
    space = gym.spaces.Box(0, 255, (36, 40, 3), dtype=np.uint8)  # channel last, as MiniGrid's
    policy = ObsPolicy("CnnPolicy")
    layout = make_layout(space, policy, "auto")
    encoder = ObsEncoder(layout, policy, ortho_init=True)
    cnn = encoder.module["0"]
    assert isinstance(cnn, NatureCNN) and encoder.out_dim == 512  # SB3's features_dim
    image = np.random.default_rng(0).integers(0, 256, (36, 40, 3), dtype=np.uint8)
    chw = torch.from_numpy(image.transpose(2, 0, 1).copy())[None].float() / 255.0
    with torch.no_grad():
        features = encoder.torch(torch.from_numpy(layout.flatten(image)))
        assert torch.allclose(features, cnn(chw), rtol=0, atol=1e-6)
    assert np.array_equal(layout.unflatten(layout.flatten(image))[0], image)  # uint8 again

    first = make_layout(gym.spaces.Box(0, 255, (3, 36, 40), dtype=np.uint8), policy, "auto")
    encoder = ObsEncoder(first, policy, ortho_init=False)  # channel first: as it is
    with torch.no_grad():
        features = encoder.torch(torch.from_numpy(first.flatten(image.transpose(2, 0, 1))))
        assert torch.allclose(features, encoder.module["0"](chw), rtol=0, atol=1e-6)


# ----------------------------------------------------------------- clear errors


def rgb_view_env() -> gym.Env:
    """MiniGrid's RGB partial view: a (56, 56, 3) uint8 image."""
    return ImgObsWrapper(RGBImgPartialObsWrapper(gym.make("MiniGrid-Empty-5x5-v0")))


def test_an_image_never_meets_an_mlp_silently() -> None:
    with pytest.raises(ConfigError, match=r"is an image .* pass policy='CnnPolicy'"):
        TLAC(rgb_view_env())
    for not_an_image in ("CartPole-v1", "FrozenLake-v1"):
        with pytest.raises(ConfigError, match="'CnnPolicy' needs an image observation space"):
            TLAC(not_an_image, policy="CnnPolicy")
    with pytest.raises(ConfigError, match="'MultiInputPolicy' needs a Dict"):
        TLAC("CartPole-v1", policy="MultiInputPolicy")
    with pytest.raises(ConfigError, match="TLAC takes the environment first"):
        TLAC("CnnPolicy", rgb_view_env())
    with pytest.raises(ConfigError, match=r"features_extractor_class .* is not supported"):
        TLAC(rgb_view_env(), policy_kwargs=dict(features_extractor_class=torch.nn.Identity))
    # a text key: refused before SB3's DummyVecEnv trips on it, naming the way out
    with pytest.raises(ConfigError, match=r"key 'mission' .*FilterObservation"):
        TLAC(gym.make("MiniGrid-Empty-5x5-v0"))
    # MiniGrid's 7x7x3 symbolic grid passes SB3's image test, but is too small for a CNN
    with pytest.raises(ConfigError, match=r"too small for SB3's NatureCNN; .*normalize_images"):
        TLAC(symbolic_env())


def test_policy_kwargs_name_the_extractor_as_sb3() -> None:
    small = dict(n_steps=8, batch_size=8)
    model = TLAC(rgb_view_env(), policy_kwargs=dict(features_extractor_class=NatureCNN), **small)
    assert model.obs_policy.policy == "CnnPolicy" and model.nets.encoder.out_dim == 512
    model = TLAC(
        rgb_view_env(),
        policy="CnnPolicy",
        policy_kwargs=dict(features_extractor_kwargs=dict(features_dim=32), net_arch=[16]),
        **small,
    )
    assert model.nets.encoder.out_dim == 32 and model.config.net_arch_low == [16]


# ----------------------------------------------------------------- FrozenLake: Discrete


FROZEN_LAKE_PATH = [1, 2, 1, 0, 1, 0, 1, 0, 2, 1, 1, 0, 0, 2, 2, 0]
"""The 4x4 non-slippery map's shortest way to the goal from every cell (0 left, 1 down,
2 right, 3 up; holes and the goal: anything)."""


def frozen_lake_teacher(state):
    assert isinstance(state, np.integer)  # the environment's own observation: an int
    return FROZEN_LAKE_PATH[state]


def episode_return(env: gym.Env, act, steps: int = 30) -> float:
    obs, _ = env.reset(seed=0)
    total = 0.0
    for _ in range(steps):
        obs, reward, terminated, truncated, _ = env.step(int(act(obs)))
        total += float(reward)
        if terminated or truncated:
            break
    return total


def test_frozen_lake_student_reaches_the_goal(tmp_path) -> None:
    def make():
        return gym.make("FrozenLake-v1", is_slippery=False)

    model = TLAC(make(), teachers=[frozen_lake_teacher], seed=0)
    assert model.nets.encoder.out_dim == 16  # one-hot of Discrete(16)
    model.learn(1000)
    alone = episode_return(make(), lambda s: model.predict(s, deterministic=True)[0])
    assert alone == 1.0  # the student alone, from the int observations
    actions = model.predict(np.arange(16), deterministic=True)[0]
    assert actions.shape == (16,)
    loaded = TLAC.load(model.save(tmp_path / "lake"))
    assert loaded.observation_space == gym.spaces.Discrete(16)
    assert np.array_equal(loaded.predict(np.arange(16), deterministic=True)[0], actions)
    with pytest.raises(ConfigError, match=r"must hold integers of Discrete\(16\)"):
        model.predict(16)


# ----------------------------------------------------------------- MiniGrid's Dict


GOAL, WALL = 8, 2  # MiniGrid's object indices
FORWARD, LEFT, RIGHT = 2, 0, 1


def towards_goal(goal: np.ndarray, wall: np.ndarray) -> int:
    """Empty-5x5 from the agent's 7x7 view ([x, y]; the agent at (3, 6) facing y = 0): ahead
    while the goal is ahead or the row in front is free, else turn towards it."""
    xs, ys = np.nonzero(goal)
    if len(xs) == 0:
        return RIGHT
    gx, gy = int(xs[0]), int(ys[0])
    if gx == 3 or (gy < 6 and not wall[3, 5]):
        return FORWARD
    return RIGHT if gx > 3 else LEFT


def dict_teacher(obs):
    assert set(obs) == {"direction", "image"}  # the environment's own dict
    cells = obs["image"][:, :, 0]
    return towards_goal(cells == GOAL, cells == WALL)


def symbolic_env() -> gym.Env:
    return FilterObservation(gym.make("MiniGrid-Empty-5x5-v0"), ["direction", "image"])


def test_minigrid_dict_learns_saves_and_resumes(tmp_path) -> None:
    flat = dict(normalize_images=False)  # the symbolic grid into the MLP, on purpose
    # DoorKey's preset (16-step rollouts): a user's default preset collects 2048 steps per update
    model = TLAC(
        symbolic_env(), teachers=[dict_teacher], seed=0, policy_kwargs=flat, preset="doorkey"
    )
    assert model.nets.obs_dim == 148 and model.nets.encoder.out_dim == 147 + 4  # direction one-hot
    model.learn(2000)
    act = lambda o: model.predict(o, deterministic=True)[0]  # noqa: E731
    assert episode_return(symbolic_env(), act) > 0.9  # the student alone, 5 steps

    obs, _ = symbolic_env().reset(seed=1)
    batch = {k: np.stack([v, v]) for k, v in obs.items()}
    path = model.save(tmp_path / "dict", training_state=True)
    loaded = TLAC.load(path)
    assert loaded.obs_policy == model.obs_policy
    assert loaded.predict(obs, deterministic=True)[0] == act(obs)
    assert loaded.predict(batch, deterministic=True)[0].tolist() == [act(obs)] * 2
    # the episodes in progress are re-created from their reset and actions (no pickle)
    resumed = TLAC.load(path, env=symbolic_env(), teachers=[dict_teacher], resume=True)
    resumed.learn(32, reset_num_timesteps=False)
    assert resumed.num_timesteps == 2032
    with pytest.raises(ConfigError, match="no key 'direction'"):
        model.predict({"image": obs["image"]})


# ----------------------------------------------------------------- images: CnnPolicy


def rgb_cells(image: np.ndarray) -> np.ndarray:
    """Each 8x8 tile's centre pixel, indexed [x, y] as MiniGrid's grid."""
    return image[4::8, 4::8].transpose(1, 0, 2)


def rgb_teacher(image):
    assert image.shape == (56, 56, 3) and image.dtype == np.uint8  # the raw image
    c = rgb_cells(image).astype(int)
    goal = (c[..., 1] == 255) & (c[..., 0] < 128)  # green
    wall = (c[..., 0] > 100) & (c[..., 0] == c[..., 1]) & (c[..., 1] == c[..., 2])  # grey
    return towards_goal(goal, wall)


def test_rgb_view_with_cnn_policy_learns_predicts_and_saves(tmp_path) -> None:
    assert episode_return(rgb_view_env(), rgb_teacher) > 0.9  # the scripted teacher works
    # one 64-step rollout, 2 epochs: the default preset's 2048 steps x 10 epochs took a minute
    model = TLAC(
        rgb_view_env(),
        teachers=[rgb_teacher],
        seed=0,
        policy="CnnPolicy",
        n_steps=64,
        batch_size=32,
        n_epochs=2,
    )
    assert model.advice_buffer.obs.dtype == torch.uint8  # images kept as bytes
    before = [p.detach().clone() for p in model.nets.extractor_params]
    model.learn(64)
    assert any(
        not torch.equal(a, b) for a, b in zip(before, model.nets.extractor_params, strict=True)
    )
    image, _ = rgb_view_env().reset(seed=0)
    action = model.predict(image, deterministic=True)[0]
    assert model.predict(np.stack([image] * 3), deterministic=True)[0].tolist() == [action] * 3

    model.deployed = model.nets.snapshot_student(
        model.num_timesteps
    )  # the kept student: its own copy of the CNN
    images = np.stack([rgb_view_env().reset(seed=s)[0] for s in range(4)])
    kept = model.predict(images, deterministic=True)[0]
    with torch.no_grad():
        for p in model.nets.extractor_params:
            p.add_(1.0)  # the live CNN moves on; the kept student does not
    assert np.array_equal(model.predict(images, deterministic=True)[0], kept)
    path = model.save(tmp_path / "cnn", training_state=True)
    loaded = TLAC.load(path)
    assert loaded.obs_policy.policy == "CnnPolicy"
    assert np.array_equal(loaded.predict(images, deterministic=True)[0], kept)
    assert all(
        torch.equal(a, b)
        for a, b in zip(loaded.nets.extractor_params, model.nets.extractor_params, strict=True)
    )
    resumed = TLAC.load(path, env=rgb_view_env(), teachers=[rgb_teacher], resume=True)
    resumed.learn(16, reset_num_timesteps=False)

    # the paper variant's per-level update: the shared CNN clipped on its own
    TLAC(rgb_view_env(), teachers=[rgb_teacher], policy="CnnPolicy", variant="paper").learn(32)


def test_a_dict_with_an_image_key_takes_multi_input_policy() -> None:
    def make():
        env = RGBImgPartialObsWrapper(gym.make("MiniGrid-Empty-5x5-v0"))
        return FilterObservation(env, ["direction", "image"])

    def teacher(obs):
        assert obs["image"].dtype == np.uint8 and obs["direction"].shape == ()
        return rgb_teacher(obs["image"])

    with pytest.raises(ConfigError, match=r"key 'image' is an image .*policy='MultiInputPolicy'"):
        TLAC(make(), teachers=[teacher])
    model = TLAC(
        make(), teachers=[teacher], seed=0, policy="MultiInputPolicy", n_steps=64, batch_size=32
    )
    assert model.nets.encoder.out_dim == 4 + 256  # direction one-hot, SB3's cnn_output_dim
    model.learn(64)
    obs, _ = make().reset(seed=0)
    assert model.predict(obs, deterministic=True)[0] in range(7)
