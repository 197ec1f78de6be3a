"""Teachers named by file, as ``tlac train --teachers`` takes them beside a domain's names:

* ``path/to/file.py:NAME``: the object ``NAME`` of that Python file (imported: its code
  runs, as a domain file's does), anything ``TLAC(teachers=...)`` takes: a function of one
  observation, an object with a batched ``predict``, an SB3 model or policy;
* ``path/to/agent.zip``: a stable-baselines3 or rl-baselines3-zoo agent, with the
  ``vecnormalize.pkl`` that rl-zoo keeps beside it (``<folder>/<EnvId>/vecnormalize.pkl``);
* ``path/to/rl-zoo/run/folder``: an rl-zoo run folder (``logs/<algo>/<EnvId>_<n>``), as
  :func:`tlac.teachers.sb3.from_rl_zoo` reads it.

Each may end in ``:P`` as a domain's names do (the teacher's action with probability P, a
random one otherwise). An agent's files are pickles, which can run code when loaded: they are
opened only with ``trust_pickle`` (``--trust-pickle``), checked before anything is written
(:func:`check_teacher_files`).

>>> teacher_file("teachers.py:pd:0.7")
TeacherFile(kind='python', path='teachers.py', attr='pd', prob='0.7')
>>> teacher_file("agents/ppo.zip"), teacher_file("optimal:0.5")
(TeacherFile(kind='sb3', path='agents/ppo.zip', attr='', prob=None), None)
"""

from __future__ import annotations

import importlib.util
import json
import re
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

from tlac.errors import ConfigError, import_failure
from tlac.teachers.human import is_person_teacher
from tlac.teachers.sb3 import check_trust_pickle, from_rl_zoo, from_sb3

POLICY_MODULES = {
    "stable_baselines3.common.policies": "ppo",  # ActorCriticPolicy: PPO's and A2C's
    "stable_baselines3.dqn.policies": "dqn",
    "stable_baselines3.sac.policies": "sac",
    "stable_baselines3.td3.policies": "td3",  # TD3's and DDPG's
}
"""The module of a saved agent's policy class -> the SB3 class that loads it for ``predict``."""


@dataclass(frozen=True)
class TeacherFile:
    """A teacher spec naming a file: ``kind`` python (``path.py:attr``), sb3 (a ``.zip``) or
    rl-zoo (a folder); ``prob``: the text after ``:`` that mixes in random actions, or None."""

    kind: str
    path: str
    attr: str = ""
    prob: str | None = None

    def source(self) -> str:
        """The spec without its ``:P``."""
        return f"{self.path}:{self.attr}" if self.kind == "python" else self.path

    def label(self) -> str:
        """The teacher's name in logs: the Python object's name, the agent file's stem, or
        rl-zoo's ``<algo>-<EnvId>``."""
        if self.kind == "python":
            return self.attr
        if self.kind == "sb3":
            return Path(self.path).stem
        folder = Path(self.path)
        env_id = re.sub(r"_\d+$", "", folder.name)
        return f"{folder.parent.name.lower()}-{env_id}"


def teacher_file(spec: str) -> TeacherFile | None:
    """The file that the teacher spec ``spec`` names, or None for a domain's teacher name."""
    if ".py:" in spec:
        path, _, rest = spec.partition(".py:")
        attr, colon, prob = rest.partition(":")
        return TeacherFile("python", path + ".py", attr, prob if colon else None)
    if ".zip" in spec:
        path, _, rest = spec.rpartition(".zip")
        if rest == "" or rest.startswith(":"):
            return TeacherFile("sb3", path + ".zip", "", rest[1:] if rest else None)
    head, colon, prob = spec.rpartition(":")
    if colon and ("/" in head or "\\" in head) and Path(head).is_dir():
        return TeacherFile("rl-zoo", head, "", prob)
    if ("/" in spec or "\\" in spec) and Path(spec).is_dir():
        return TeacherFile("rl-zoo", spec)
    return None


def check_teacher_files(specs: list[str], trust_pickle: bool, how: str = "--trust-pickle") -> None:
    """ConfigError, before anything is written, for a teacher file that is missing, a Python
    file's teacher without a name, or an agent's pickles without ``trust_pickle``."""
    for spec in specs:
        found = None if is_person_teacher(spec) else teacher_file(spec)
        if found is None:
            continue
        if found.kind == "python" and not found.attr:
            raise ConfigError(
                f"teacher {spec!r}: name the teacher in the file, path/to/file.py:NAME"
            )
        if found.kind != "rl-zoo" and not Path(found.path).is_file():
            raise ConfigError(f"teacher {spec!r}: no such file {found.path!r}")
        if found.kind != "python":
            check_trust_pickle(found.path, trust_pickle, how)


def load_teacher_file(found: TeacherFile, env: gym.Env, trust_pickle: bool) -> Any:
    """The teacher that ``found`` names, for ``env``'s action space."""
    if found.kind == "python":
        from tlac.teachers.base import as_teacher

        return as_teacher(_python_object(found), env.action_space, name=found.label())
    if found.kind == "rl-zoo":
        return from_rl_zoo(found.path, name=found.label(), trust_pickle=trust_pickle)
    path = Path(found.path)
    check_trust_pickle(path, trust_pickle, "--trust-pickle")
    stats = _rl_zoo_statistics(path)
    return from_sb3(path, stats, _sb3_algo(path), found.label(), trust_pickle=trust_pickle)


def _python_object(found: TeacherFile) -> Any:
    """The object ``found.attr`` of the Python file ``found.path`` (the file is run)."""
    path = Path(found.path)
    module_spec = importlib.util.spec_from_file_location(path.stem, path)
    if not path.is_file() or module_spec is None or module_spec.loader is None:
        raise ConfigError(f"teacher {found.path}:{found.attr}: no such file {found.path!r}")
    module = importlib.util.module_from_spec(module_spec)
    try:
        module_spec.loader.exec_module(module)
    except Exception as exc:  # the user's file itself: a syntax error, or code that raises
        raise ConfigError(f"teacher {found.path}:{found.attr}: {import_failure(exc)}") from None
    if not hasattr(module, found.attr):
        raise ConfigError(
            f"teacher {found.path}:{found.attr}: the file defines no {found.attr!r}; expected a "
            "function of one observation, an object with predict(obs_batch) or an SB3 model"
        )
    return getattr(module, found.attr)


def _sb3_algo(path: Path) -> str:
    """The SB3 class that loads the agent ``path``, from its policy class's module as the
    zip's JSON ``data`` names it (read without unpickling anything)."""
    try:
        with zipfile.ZipFile(path) as archive:
            data = json.loads(archive.read("data"))
        module = data["policy_class"]["__module__"]
    except (OSError, KeyError, TypeError, ValueError, zipfile.BadZipFile):
        raise ConfigError(
            f"teacher {str(path)!r} is not a stable-baselines3 agent (no policy class in its "
            "data); expected a .zip saved by model.save()"
        ) from None
    if module not in POLICY_MODULES:
        raise ConfigError(
            f"teacher {str(path)!r}: its policy comes from {module}; tlac loads the agents of "
            "stable-baselines3 (A2C, DDPG, DQN, PPO, SAC, TD3): load it yourself in Python and "
            "pass it as a teacher, TLAC(env, teachers=[model])"
        )
    return POLICY_MODULES[module]


def _rl_zoo_statistics(path: Path) -> Path | None:
    """The ``vecnormalize.pkl`` that rl-zoo keeps beside the agent ``path``
    (``<run>/<EnvId>.zip`` or ``<run>/best_model.zip`` with ``<run>/<EnvId>/``), or None."""
    env_id = re.sub(r"_\d+$", "", path.parent.name)
    for folder in (path.with_suffix(""), path.parent / env_id):
        if (folder / "vecnormalize.pkl").is_file():
            return folder / "vecnormalize.pkl"
    return None
