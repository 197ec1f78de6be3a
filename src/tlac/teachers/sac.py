"""A shipped SAC actor used as the "optimal" Hopper teacher (paper, appendix A.2.1).

The paper obtains its Hopper teacher by training SAC for 1e6 steps. We train it with
stable-baselines3 (``tlac teacher train``, see :mod:`tlac.teacher_training`) and ship only
the actor's weights: a small ``.pt`` state dict plus a ``.json`` metadata file under
``src/tlac/data/teachers/``. :class:`SACActorTeacher` rebuilds the actor's deterministic path
(MLP latent -> ``mu`` -> optional clip -> ``tanh`` -> rescale to the action box), which is
exactly what ``SAC.predict(obs, deterministic=True)`` computes, without needing SB3 or the
replay buffer at inference time.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from tlac.errors import TeacherError

DATA_DIR = Path(__file__).resolve().parent.parent / "data" / "teachers"
"""Where the shipped teacher weights live (package data)."""


def weights_paths(env_name: str, data_dir: Path | None = None) -> tuple[Path, Path]:
    """``(<env>-sac.pt, <env>-sac.json)`` for a registry environment name."""
    base = Path(data_dir) if data_dir is not None else DATA_DIR
    return base / f"{env_name}-sac.pt", base / f"{env_name}-sac.json"


class SACActor(nn.Module):
    """The deterministic part of an SB3 SAC actor: ``tanh(mu(latent_pi(obs)))``.

    Parameter names follow SB3's ``Actor`` (``latent_pi.0.weight``, ``mu.weight``, ...), so a
    state dict taken from ``model.actor`` (minus ``log_std`` and the features extractor)
    loads directly.
    """

    def __init__(self, obs_dim: int, act_dim: int, net_arch: list[int], clip_mean: float = 0.0):
        super().__init__()
        layers: list[nn.Module] = []
        last = obs_dim
        for width in net_arch:
            layers += [nn.Linear(last, width), nn.ReLU()]
            last = width
        self.latent_pi = nn.Sequential(*layers)
        self.mu = nn.Linear(last, act_dim)
        # gSDE actors clip the mean with a Hardtanh before squashing (SB3 ``clip_mean``).
        self.clip_mean = float(clip_mean)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        mean = self.mu(self.latent_pi(obs))
        if self.clip_mean > 0:
            mean = torch.clamp(mean, -self.clip_mean, self.clip_mean)
        return torch.tanh(mean)


def actor_state_dict(sb3_actor: nn.Module) -> dict[str, torch.Tensor]:
    """Extract the weights :class:`SACActor` needs from an SB3 SAC ``model.actor``.

    Works for the plain actor (``mu`` is a ``Linear``) and the gSDE one (``mu`` is
    ``Sequential(Linear, Hardtanh)``).
    """
    out: dict[str, torch.Tensor] = {}
    for key, value in sb3_actor.state_dict().items():
        if key.startswith("latent_pi.") or key in ("mu.weight", "mu.bias"):
            out[key] = value.detach().clone().float()
        elif key in ("mu.0.weight", "mu.0.bias"):
            out["mu." + key.split(".")[-1]] = value.detach().clone().float()
    return out


class SACActorTeacher:
    """A batched, deterministic teacher from shipped SAC actor weights.

    ``predict(obs)`` takes ``(n, obs_dim)`` observations and returns ``(n, act_dim)`` float32
    actions inside the action box.
    """

    def __init__(
        self,
        actor: SACActor,
        low: np.ndarray,
        high: np.ndarray,
        name: str = "optimal",
        metadata: dict[str, Any] | None = None,
    ):
        self.actor = actor.eval()
        self.low = np.asarray(low, dtype=np.float32)
        self.high = np.asarray(high, dtype=np.float32)
        self.name = name
        self.metadata = dict(metadata or {})

    @classmethod
    def load(
        cls,
        env_name: str,
        name: str = "optimal",
        data_dir: Path | None = None,
    ) -> SACActorTeacher:
        """Load ``<env>-sac.pt`` / ``<env>-sac.json``; a missing file raises
        :class:`TeacherError` naming the path and the command that creates it."""
        pt, meta_path = weights_paths(env_name, data_dir)
        if not pt.is_file() or not meta_path.is_file():
            missing = pt if not pt.is_file() else meta_path
            raise TeacherError(
                f"no trained SAC teacher for {env_name!r}: {missing} does not exist; create it "
                f"with `tlac teacher train {env_name} --steps 1000000 --seed 0 --out {pt.parent}`"
            )
        meta = json.loads(meta_path.read_text())
        state = torch.load(pt, map_location="cpu", weights_only=True)
        actor = SACActor(
            int(meta["obs_dim"]),
            int(meta["act_dim"]),
            [int(w) for w in meta["net_arch"]],
            float(meta.get("clip_mean", 0.0)),
        )
        actor.load_state_dict(state)
        return cls(actor, np.array(meta["action_low"]), np.array(meta["action_high"]), name, meta)

    @torch.inference_mode()
    def predict(self, obs: np.ndarray) -> np.ndarray:
        x = torch.as_tensor(np.asarray(obs, dtype=np.float32)).reshape(len(obs), -1)
        squashed = self.actor(x).numpy()
        # Same rescaling as SB3's ``unscale_action`` from [-1, 1] to the action box.
        return (self.low + 0.5 * (squashed + 1.0) * (self.high - self.low)).astype(np.float32)
