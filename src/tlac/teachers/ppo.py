"""A shipped PPO policy used as DoorKey's paper-like teacher (paper, appendix A.1.1).

The paper's DoorKey teacher is "a optimal policy with PPO algorithm, which trained for 1e6
steps" (training reward 0.96; 0.77 +- 0.38 over 1000 test episodes). ``tlac teacher train
doorkey`` trains stable-baselines3 PPO on MiniGrid's default observation, the agent's partial
7x7 view (the ``doorkey-partial`` domain), and ships the actor only: ``doorkey-ppo.pt`` (state
dict) + ``doorkey-ppo.json`` (metadata and its measured return). :class:`PPOActorTeacher`
rebuilds SB3's actor path (``action_net(policy_net(obs))``, tanh MLP) and acts greedily, as
``PPO.predict(obs, deterministic=True)``; with a ``transform`` it first converts each
observation into the one it was trained on (DoorKey: the full grid into the agent's partial
view, :func:`tlac.domains.doorkey.view.partial_view`), so it advises a student that sees
something else.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from tlac.errors import TeacherError
from tlac.teachers.sac import DATA_DIR


def ppo_weights_paths(env_name: str, data_dir: Path | None = None) -> tuple[Path, Path]:
    """``(<env>-ppo.pt, <env>-ppo.json)``."""
    base = Path(data_dir) if data_dir is not None else DATA_DIR
    return base / f"{env_name}-ppo.pt", base / f"{env_name}-ppo.json"


class PPOActor(nn.Module):
    """SB3's ``ActorCriticPolicy`` actor path: ``action_net(policy_net(obs))`` with tanh hidden
    layers; parameter names as SB3's (``policy_net.0.weight``, ``action_net.weight``)."""

    def __init__(self, obs_dim: int, n_actions: int, net_arch: list[int]):
        super().__init__()
        layers: list[nn.Module] = []
        last = obs_dim
        for width in net_arch:
            layers += [nn.Linear(last, width), nn.Tanh()]
            last = width
        self.policy_net = nn.Sequential(*layers)
        self.action_net = nn.Linear(last, n_actions)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.action_net(self.policy_net(obs))


def ppo_actor_state_dict(policy_state: Mapping[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """The weights :class:`PPOActor` needs, from the state dict of an SB3 ``model.policy``
    (MlpPolicy), live or saved."""
    out: dict[str, torch.Tensor] = {}
    for key, value in policy_state.items():
        if key.startswith("mlp_extractor.policy_net."):
            out[key.removeprefix("mlp_extractor.")] = value.detach().clone().float()
        elif key.startswith("action_net."):
            out[key] = value.detach().clone().float()
    return out


class PPOActorTeacher:
    """A batched, greedy teacher from shipped PPO actor weights: ``predict(obs)`` takes
    ``(n, obs_dim)`` observations and returns ``(n,)`` int64 actions."""

    def __init__(
        self,
        actor: PPOActor,
        name: str = "ppo",
        transform: Callable[[np.ndarray], np.ndarray] | None = None,
        metadata: dict[str, Any] | None = None,
    ):
        self.actor = actor.eval()
        self.name = name
        self.transform = transform
        self.metadata = dict(metadata or {})

    @classmethod
    def load(
        cls,
        env_name: str = "doorkey",
        name: str = "ppo",
        transform: Callable[[np.ndarray], np.ndarray] | None = None,
        data_dir: Path | None = None,
    ) -> PPOActorTeacher:
        """Load ``<env>-ppo.pt`` / ``.json``; a missing file raises :class:`TeacherError`
        naming the path and the command that creates it."""
        pt, meta_path = ppo_weights_paths(env_name, data_dir)
        if not pt.is_file() or not meta_path.is_file():
            missing = pt if not pt.is_file() else meta_path
            raise TeacherError(
                f"no trained PPO teacher for {env_name!r}: {missing} does not exist; create it "
                f"with `tlac teacher train {env_name} --steps 1000000 --seed 0 --out {pt.parent}`"
            )
        meta = json.loads(meta_path.read_text())
        actor = PPOActor(int(meta["obs_dim"]), int(meta["n_actions"]), list(meta["net_arch"]))
        actor.load_state_dict(torch.load(pt, map_location="cpu", weights_only=True))
        return cls(actor, name, transform, meta)

    @torch.inference_mode()
    def predict(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs)
        if self.transform is not None:
            obs = self.transform(obs)
        x = torch.as_tensor(np.asarray(obs, dtype=np.float32)).reshape(len(obs), -1)
        return self.actor(x).argmax(-1).numpy().astype(np.int64)
