"""Train a SAC teacher for Hopper and export its actor (``tlac teacher train``).

The paper's Hopper teacher is "an optimal policy [obtained] with SAC algorithm, which trained
for 1,000,000 steps" (appendix A.2.1; 1928 +- 646 over 1000 episodes). We train
stable-baselines3 SAC with rl-baselines3-zoo-like settings, checkpoint model and replay buffer
every 10k steps (a killed run resumes from its checkpoint and loses nothing finished), then
evaluate the exported deterministic actor over at least 100 episodes and write

* ``<out>/<env>-sac.pt``: the actor's state dict only (a few hundred kB);
* ``<out>/<env>-sac.json``: algorithm, steps reached, seed, command, hyperparameters, net
  arch, mean/std return over N episodes, wall-clock, library versions.
"""

from __future__ import annotations

import copy
import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import numpy as np

from tlac.errors import ConfigError
from tlac.recording import installed_versions
from tlac.teachers.sb3 import check_trust_pickle

SAC_HYPERPARAMS: dict[str, dict[str, Any]] = {
    # rl-baselines3-zoo's SAC settings for HopperBulletEnv-v0 (gSDE), but [128, 128] instead
    # of [400, 300]. Measured on the shared 2-core machine (one torch thread): 34 steps/s with
    # [400, 300] and 26 steps/s with [256, 256] under heavier load; gradient FLOPs dominate, so
    # the smaller net buys several times more steps in a wall-clock-limited run.
    "hopper-bullet": dict(
        learning_rate=7.3e-4,
        buffer_size=300_000,
        batch_size=256,
        gamma=0.98,
        tau=0.02,
        train_freq=8,
        gradient_steps=8,
        learning_starts=10_000,
        ent_coef="auto",
        use_sde=True,
        policy_kwargs=dict(log_std_init=-3, net_arch=[128, 128]),
    ),
    # rl-baselines3-zoo's SAC settings for MuJoCo Hopper: SB3 defaults, 10k warm-up steps.
    "hopper": dict(
        learning_rate=3e-4,
        buffer_size=1_000_000,
        batch_size=256,
        gamma=0.99,
        tau=0.005,
        train_freq=1,
        gradient_steps=1,
        learning_starts=10_000,
        ent_coef="auto",
        policy_kwargs=dict(net_arch=[256, 256]),
    ),
}
"""SAC settings per trainable environment (registry name)."""

PPO_HYPERPARAMS: dict[str, dict[str, Any]] = {
    # The paper trains its DoorKey teacher with PPO for 1e6 steps and gives no settings.
    # rl-baselines3-zoo-like MiniGrid settings (8 envs, 128-step rollouts, minibatch 64,
    # 10 epochs, lr 2.5e-4, GAE 0.95) with a small entropy bonus for the sparse reward.
    "doorkey": dict(
        n_steps=128,
        batch_size=64,
        n_epochs=10,
        learning_rate=2.5e-4,
        gamma=0.99,
        gae_lambda=0.95,
        clip_range=0.2,
        ent_coef=0.01,
        policy_kwargs=dict(net_arch=[64, 64]),
    ),
}
"""PPO settings per trainable environment (registry name)."""
PPO_ENVS = {"doorkey": ("doorkey-partial", 8)}
"""Registry name -> (the domain PPO trains on, number of environments). DoorKey's teacher
learns on MiniGrid's default observation, the agent's partial view (docs/reproduction.md)."""

CHECKPOINT_EVERY = 10_000
PAPER_RESULT = {
    "hopper-bullet": "SAC 1e6 steps: 1928 +- 646 over 1000 episodes (appendix A.2.1)",
    "doorkey": "PPO 1e6 steps: training reward 0.96; 0.77 +- 0.38 over 1000 test episodes "
    "(appendix A.1.1)",
}
TRAINABLE = (*SAC_HYPERPARAMS, *PPO_HYPERPARAMS)


def _versions() -> dict[str, str]:
    packages = (
        "stable-baselines3",
        "torch",
        "gymnasium",
        "pybullet",
        "pybullet-envs-gymnasium",
        "mujoco",
    )
    return {"python": platform.python_version(), **installed_versions(packages)}


def _atomic_write_text(path: Path, text: str) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def make_folders(out_dir: Path, work: Path) -> None:
    """Create the folders a teacher's training writes (``--out`` and ``--work-dir``); one that
    cannot be (a file on its path, no permission) is one ConfigError naming it, said before
    training starts.

    >>> import tempfile
    >>> file = Path(tempfile.mkdtemp()) / "f"; _ = file.write_text("")
    >>> make_folders(file / "teachers", file.parent / "work")
    Traceback (most recent call last):
    tlac.errors.ConfigError: --out '.../f/teachers' cannot be a folder: '.../f' is a file;
    expected a folder path
    """
    for option, folder in (("--out", out_dir), ("--work-dir", work)):
        blocking = next((p for p in (folder, *folder.parents) if p.is_file()), None)
        if blocking is not None:
            raise ConfigError(
                f"{option} {str(folder)!r} cannot be a folder: {str(blocking)!r} is a file; "
                "expected a folder path"
            )
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ConfigError(
                f"{option} {str(folder)!r} cannot be created: {exc.strerror}"
            ) from None
        if not os.access(folder, os.W_OK | os.X_OK):
            raise ConfigError(f"{option} {str(folder)!r} cannot be written: permission denied")


def _learn_with_checkpoints(
    model: Any,
    steps: int,
    save_checkpoint: Any,
    n_envs: int,
    start: float,
    time_limit_s: float | None,
    progress_bar: bool,
    **learn_kwargs: Any,
) -> None:
    """Train an SB3 ``model`` up to ``steps`` in all, calling ``save_checkpoint()`` every
    :data:`CHECKPOINT_EVERY` steps and at the end; stop early once ``time_limit_s`` seconds
    have passed since ``start``."""
    from stable_baselines3.common.callbacks import BaseCallback

    class _Checkpoint(BaseCallback):
        def _on_step(self) -> bool:
            if self.model.num_timesteps % CHECKPOINT_EVERY < n_envs:
                save_checkpoint()
            if time_limit_s is not None and time.time() - start > time_limit_s:
                print(f"time limit reached at {self.model.num_timesteps} steps", flush=True)
                return False
            return True

    remaining = steps - int(model.num_timesteps)
    if remaining > 0:
        model.learn(
            remaining,
            callback=_Checkpoint(),
            reset_num_timesteps=False,
            progress_bar=progress_bar,
            **learn_kwargs,
        )
        save_checkpoint()


def evaluate_actor(
    env_name: str, teacher: Any, episodes: int, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Run ``episodes`` episodes of a deterministic teacher; returns (returns, lengths).
    Episode ``i`` is reset with seed ``seed + i``."""
    from tlac.domains import get_domain

    env = get_domain(env_name).make_env()
    returns, lengths = [], []
    try:
        for i in range(episodes):
            obs, _ = env.reset(seed=seed + i)
            done, total, steps = False, 0.0, 0
            while not done:
                action = teacher.predict(obs[None])[0]
                obs, reward, terminated, truncated, _ = env.step(action)
                total += float(reward)
                steps += 1
                done = terminated or truncated
            returns.append(total)
            lengths.append(steps)
    finally:
        env.close()
    return np.array(returns), np.array(lengths)


def train_teacher(
    env_name: str,
    steps: int,
    seed: int,
    out_dir: str | Path,
    progress_bar: bool = True,
    work_dir: str | Path | None = None,
    eval_episodes: int = 100,
    time_limit_s: float | None = None,
    command: str | None = None,
    trust_pickle: bool = False,
) -> dict[str, Any]:
    """Train SAC on ``env_name`` for ``steps`` environment steps and export the actor.

    ``work_dir`` (default ``runs/teachers/<env>-seed<seed>``) holds the checkpoint
    (``checkpoint.zip`` + ``replay_buffer.pkl`` + ``state.json``), refreshed every 10k
    steps; if it exists, training resumes from it, and as SB3's files are pickles (they can run
    code when loaded) only with ``trust_pickle=True`` (``--trust-pickle``). ``time_limit_s``
    stops training early (at the next step after the limit) and still evaluates and exports
    what was reached; the metadata records the steps actually taken. Returns the metadata dict.
    """
    if env_name not in TRAINABLE:
        from tlac.errors import UnknownNameError

        raise UnknownNameError("trainable teacher environment", env_name, list(TRAINABLE))
    if steps <= 0:
        raise ConfigError(f"--steps must be a positive integer, got {steps}")
    if eval_episodes < 1:
        raise ConfigError(f"eval_episodes must be >= 1, got {eval_episodes}")

    if env_name in PPO_HYPERPARAMS:
        return train_ppo_teacher(
            env_name,
            steps,
            seed,
            out_dir,
            progress_bar,
            work_dir,
            eval_episodes,
            time_limit_s,
            command,
            trust_pickle,
        )
    import torch
    from stable_baselines3 import SAC
    from stable_baselines3.common.monitor import Monitor

    from tlac.domains import get_domain
    from tlac.teachers.sac import SACActor, SACActorTeacher, actor_state_dict, weights_paths

    torch.set_num_threads(1)
    out_dir = Path(out_dir)
    work = (
        Path(work_dir) if work_dir is not None else Path("runs/teachers") / f"{env_name}-seed{seed}"
    )
    make_folders(out_dir, work)
    ckpt, buf, state_path = work / "checkpoint.zip", work / "replay_buffer.pkl", work / "state.json"
    command = (
        command or f"tlac teacher train {env_name} --steps {steps} --seed {seed} --out {out_dir}"
    )

    env = Monitor(get_domain(env_name).make_env(), str(work / "monitor"), override_existing=False)
    hp = copy.deepcopy(SAC_HYPERPARAMS[env_name])  # SB3 mutates policy_kwargs
    state: dict[str, Any] = {"wall_s": 0.0}
    if ckpt.is_file():
        check_trust_pickle(ckpt, trust_pickle, "--trust-pickle (trust_pickle=True)")
        model = SAC.load(ckpt, env=env, device="cpu")
        if buf.is_file():
            model.load_replay_buffer(buf)
        if state_path.is_file():
            state = json.loads(state_path.read_text())
        print(f"resuming from {ckpt} at {model.num_timesteps} steps", flush=True)
    else:
        model = SAC("MlpPolicy", env, seed=seed, verbose=1, device="cpu", **hp)

    start = time.time()
    wall_before = float(state.get("wall_s", 0.0))

    def save_checkpoint() -> None:
        # Write temp files then rename: a kill mid-save leaves the previous checkpoint intact.
        model.save(work / "checkpoint.tmp.zip")
        model.save_replay_buffer(work / "replay_buffer.tmp.pkl")
        os.replace(work / "checkpoint.tmp.zip", ckpt)
        os.replace(work / "replay_buffer.tmp.pkl", buf)
        state["wall_s"] = wall_before + time.time() - start
        state["num_timesteps"] = int(model.num_timesteps)
        _atomic_write_text(state_path, json.dumps(state))

    _learn_with_checkpoints(
        model, steps, save_checkpoint, 1, start, time_limit_s, progress_bar, log_interval=20
    )
    reached = int(model.num_timesteps)
    train_wall = float(state["wall_s"]) if "wall_s" in state else 0.0

    # Export the actor only and evaluate the exported artifact itself.
    policy_kwargs = hp.get("policy_kwargs", {})
    net_arch = list(policy_kwargs.get("net_arch", [256, 256]))
    clip_mean = 2.0 if hp.get("use_sde", False) else 0.0
    obs_dim = int(np.prod(env.observation_space.shape))
    act_dim = int(np.prod(env.action_space.shape))
    actor = SACActor(obs_dim, act_dim, net_arch, clip_mean)
    actor.load_state_dict(actor_state_dict(model.actor))
    low, high = env.action_space.low, env.action_space.high
    teacher = SACActorTeacher(actor, low, high)

    # Sanity check: the rebuilt actor agrees with SB3's deterministic predict.
    probe = np.stack([env.observation_space.sample() for _ in range(8)]).astype(np.float32)
    probe = np.clip(probe, -5, 5)
    sb3_actions, _ = model.predict(probe, deterministic=True)
    if not np.allclose(sb3_actions, teacher.predict(probe), atol=1e-5):
        raise RuntimeError("exported SAC actor disagrees with stable-baselines3's predict")

    eval_seed = 1_000_000 + seed
    t0 = time.time()
    returns, lengths = evaluate_actor(env_name, teacher, eval_episodes, eval_seed)
    meta: dict[str, Any] = {
        "env": env_name,
        "algorithm": "SAC (stable-baselines3), deterministic actor: tanh(mu(latent_pi(obs)))",
        "steps": reached,
        "target_steps": int(steps),
        "seed": int(seed),
        "command": command,
        "hyperparameters": {k: v for k, v in hp.items() if k != "policy_kwargs"}
        | {"policy_kwargs": policy_kwargs},
        "net_arch": net_arch,
        "clip_mean": clip_mean,
        "obs_dim": obs_dim,
        "act_dim": act_dim,
        "action_low": low.tolist(),
        "action_high": high.tolist(),
        "train_wall_clock_s": round(train_wall, 1),
        "eval": _summary(returns, lengths, eval_episodes, eval_seed, time.time() - t0),
        "paper": PAPER_RESULT.get(env_name, "the paper used HopperPyBulletEnv-v0 only"),
        "versions": _versions(),
    }
    pt, meta_path = weights_paths(env_name, out_dir)
    tmp = pt.with_suffix(".pt.tmp")
    torch.save(actor.state_dict(), tmp)
    os.replace(tmp, pt)
    _atomic_write_text(meta_path, json.dumps(meta, indent=2) + "\n")
    env.close()
    print(
        f"{env_name}: {reached} steps, eval {returns.mean():.1f} +- {returns.std():.1f} "
        f"over {eval_episodes} episodes -> {pt}",
        flush=True,
    )
    return meta


def train_ppo_teacher(
    env_name: str,
    steps: int,
    seed: int,
    out_dir: str | Path,
    progress_bar: bool = True,
    work_dir: str | Path | None = None,
    eval_episodes: int = 1000,
    time_limit_s: float | None = None,
    command: str | None = None,
    trust_pickle: bool = False,
) -> dict[str, Any]:
    """Train SB3 PPO for DoorKey's teacher (see :func:`train_teacher`, which calls this), on
    MiniGrid's partial view, checkpointing every 10k steps (a rerun resumes), then export the
    actor and measure the exported greedy teacher on the full-grid domain (it converts each
    observation to its view), and the sampled policy beside it."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env as sb3_make_vec_env

    from tlac.domains import get_domain
    from tlac.domains.doorkey.view import partial_view
    from tlac.teachers.ppo import PPOActor, PPOActorTeacher, ppo_actor_state_dict, ppo_weights_paths

    torch.set_num_threads(1)
    train_domain, n_envs = PPO_ENVS[env_name]
    out_dir = Path(out_dir)
    work = (
        Path(work_dir) if work_dir is not None else Path("runs/teachers") / f"{env_name}-seed{seed}"
    )
    make_folders(out_dir, work)
    ckpt, state_path = work / "checkpoint.zip", work / "state.json"
    command = (
        command or f"tlac teacher train {env_name} --steps {steps} --seed {seed} --out {out_dir}"
    )
    env = sb3_make_vec_env(
        get_domain(train_domain).make_env,
        n_envs=n_envs,
        seed=seed,
        monitor_dir=str(work / "monitor"),
    )
    hp = copy.deepcopy(PPO_HYPERPARAMS[env_name])
    state: dict[str, Any] = {"wall_s": 0.0}
    if ckpt.is_file():
        check_trust_pickle(ckpt, trust_pickle, "--trust-pickle (trust_pickle=True)")
        model = PPO.load(ckpt, env=env, device="cpu")
        if state_path.is_file():
            state = json.loads(state_path.read_text())
        print(f"resuming from {ckpt} at {model.num_timesteps} steps", flush=True)
    else:
        model = PPO("MlpPolicy", env, seed=seed, verbose=0, device="cpu", **hp)
    start, wall_before = time.time(), float(state.get("wall_s", 0.0))

    def save_checkpoint() -> None:
        model.save(work / "checkpoint.tmp.zip")  # then rename: a kill mid-save keeps the old
        os.replace(work / "checkpoint.tmp.zip", ckpt)
        state["wall_s"] = wall_before + time.time() - start
        state["num_timesteps"] = int(model.num_timesteps)
        _atomic_write_text(state_path, json.dumps(state))

    _learn_with_checkpoints(
        model, steps, save_checkpoint, n_envs, start, time_limit_s, progress_bar
    )
    reached = int(model.num_timesteps)
    monitor_returns = _monitor_returns(work / "monitor")

    net_arch = list(hp["policy_kwargs"]["net_arch"])
    obs_dim = int(np.prod(env.observation_space.shape))
    n_actions = int(env.action_space.n)
    actor = PPOActor(obs_dim, n_actions, net_arch)
    actor.load_state_dict(ppo_actor_state_dict(model.policy.state_dict()))
    # the rebuilt actor agrees with SB3's greedy predict on the view it was trained on
    probe = np.stack([env.observation_space.sample() for _ in range(16)])
    teacher = PPOActorTeacher(actor)
    if not np.array_equal(model.predict(probe, deterministic=True)[0], teacher.predict(probe)):
        raise RuntimeError("exported PPO actor disagrees with stable-baselines3's predict")
    env.close()

    eval_seed = 1_000_000 + seed
    t0 = time.time()
    greedy = PPOActorTeacher(actor, transform=partial_view)
    returns, lengths = evaluate_actor(env_name, greedy, eval_episodes, eval_seed)
    sampled = _SampledPolicy(actor, seed)
    s_returns, _ = evaluate_actor(train_domain, sampled, eval_episodes, eval_seed)
    meta: dict[str, Any] = {
        "env": env_name,
        "algorithm": "PPO (stable-baselines3), greedy actor: argmax action_net(policy_net(view))",
        "trained_on": train_domain,
        "steps": reached,
        "target_steps": int(steps),
        "seed": int(seed),
        "n_envs": n_envs,
        "command": command,
        "hyperparameters": hp,
        "net_arch": net_arch,
        "obs_dim": obs_dim,
        "n_actions": n_actions,
        "train_wall_clock_s": round(float(state.get("wall_s", 0.0)), 1),
        "training_return_last_1000_episodes": monitor_returns,
        "eval": _summary(returns, lengths, eval_episodes, eval_seed, time.time() - t0)
        | {"success_rate": float((returns > 0).mean())},
        "eval_sampled": {
            "episodes": int(eval_episodes),
            "mean_return": float(s_returns.mean()),
            "std_return": float(s_returns.std()),
            "success_rate": float((s_returns > 0).mean()),
        },
        "paper": PAPER_RESULT[env_name],
        "versions": _versions(),
    }
    pt, meta_path = ppo_weights_paths(env_name, out_dir)
    tmp = pt.with_suffix(".pt.tmp")
    torch.save(actor.state_dict(), tmp)
    os.replace(tmp, pt)
    _atomic_write_text(meta_path, json.dumps(meta, indent=2) + "\n")
    print(
        f"{env_name}: PPO {reached} steps, greedy {returns.mean():.3f} +- {returns.std():.3f}, "
        f"sampled {s_returns.mean():.3f} +- {s_returns.std():.3f} over {eval_episodes} "
        f"episodes -> {pt}",
        flush=True,
    )
    return meta


class _SampledPolicy:
    """The PPO actor sampling its actions (SB3's ``predict(deterministic=False)``)."""

    def __init__(self, actor: Any, seed: int):
        self.actor, self.rng = actor, np.random.default_rng(seed)

    def predict(self, obs: np.ndarray) -> np.ndarray:
        import torch

        from tlac.algorithms.nets import np_sample_categorical

        with torch.inference_mode():
            logits = self.actor(torch.as_tensor(np.asarray(obs, dtype=np.float32))).numpy()
        return np_sample_categorical(logits, self.rng)


def _summary(
    returns: np.ndarray, lengths: np.ndarray, episodes: int, seed: int, seconds: float
) -> dict[str, Any]:
    """The ``eval`` block of a teacher's metadata: returns and lengths of its episodes."""
    return {
        "episodes": int(episodes),
        "seeds": f"{seed}..{seed + episodes - 1}",
        "mean_return": float(returns.mean()),
        "std_return": float(returns.std()),
        "min_return": float(returns.min()),
        "max_return": float(returns.max()),
        "mean_length": float(lengths.mean()),
        "wall_clock_s": round(seconds, 1),
    }


def _monitor_returns(monitor_dir: Path) -> float | None:
    """Mean return of the last 1000 training episodes, in time order over all the
    environments' SB3 Monitor files (SB3's ``load_results``), if any."""
    from stable_baselines3.common.monitor import get_monitor_files, load_results

    if not get_monitor_files(str(monitor_dir)):
        return None
    return float(load_results(str(monitor_dir))["r"].tail(1000).mean())
