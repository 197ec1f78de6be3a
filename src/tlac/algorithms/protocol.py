"""The contract every algorithm class keeps (TL-AC, DQN-TLQL, AC-Teach, the SB3 baselines):
:class:`Algorithm`, a ``typing.Protocol`` with stable-baselines3's names and signatures, so
that ``tlac.run``, the evaluation and a user's script drive any of them the same way.

``tests/test_algorithm_contract.py`` checks every registered algorithm against it: the
signatures (parameter names, kinds and defaults), a few hundred learning steps, the shapes of
``predict``, and a save/load round trip.

>>> from tlac.algorithms import get_algorithm
>>> all(conforms(get_algorithm(name)) == [] for name in ("dqn-tlql", "ac-teach"))
True
"""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Algorithm(Protocol):
    """What an algorithm class offers (besides its constructor ``Algo(env, teachers, seed,
    recorder, **hyperparameters)``; docs/architecture.md, "Algorithm")."""

    @property
    def num_timesteps(self) -> int:
        """Environment steps taken so far, over all environments."""
        ...

    def learn(self, total_timesteps: int, callback: Any = None, progress_bar: bool = False) -> Any:
        """Train for ``total_timesteps`` more steps and return the model itself. ``callback``:
        a function ``f(model)`` run after every update (``False`` stops), an SB3
        ``BaseCallback`` or a list of them."""
        ...

    def predict(
        self,
        observation: np.ndarray,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = False,
    ) -> tuple[np.ndarray, Any]:
        """SB3's ``predict``: ``(actions, None)`` of the student alone (no teacher); one
        observation gives one action, a batch one per row."""
        ...

    def save(
        self,
        path: str | Path,
        training_state: bool = False,
        run_state: dict[str, Any] | None = None,
    ) -> Path:
        """Write the model and return the file's path. ``training_state``: also what an exact
        resume needs (a ConfigError where the class has ``exact_resume = False``);
        ``run_state``: plain data of ``tlac.run`` saved in the same file (likewise)."""
        ...

    @classmethod
    def load(
        cls,
        path: str | Path,
        env: Any = None,
        teachers: Any = None,
        resume: bool = False,
        trust_pickle: bool = False,
    ) -> Any:
        """Rebuild a model written by :meth:`save`; pass ``env`` (and the teachers) to train
        on. ``resume``: restore the training state too (ConfigError where there is none).
        ``trust_pickle``: required to open a format that holds pickles (SB3's zip, which can
        run code when loaded); tlac's own files hold none and ignore it."""
        ...


_METHODS = ("learn", "predict", "save", "load")


def _shape(func: Any) -> list[tuple[str, Any, Any]]:
    """``func``'s parameters after the first (self or cls): name, kind and default."""
    params = list(inspect.signature(getattr(func, "__func__", func)).parameters.values())
    return [(p.name, p.kind, p.default) for p in params[1:]]


def conforms(cls: type) -> list[str]:
    """How ``cls``'s methods differ from :class:`Algorithm`'s (parameter names, kinds and
    defaults; ``learn``'s ``progress_bar`` default is each algorithm's own, and its other SB3
    keywords are allowed, as are ``load``'s after the protocol's, with defaults); empty when
    they match."""
    problems = []
    for name in _METHODS:
        want = _shape(getattr(Algorithm, name))
        impl = getattr(cls, name, None)
        if impl is None:
            problems.append(f"{cls.__name__} has no {name}")
            continue
        if name == "load" and not isinstance(inspect.getattr_static(cls, name), classmethod):
            problems.append(f"{cls.__name__}.load is not a classmethod")
        got = _shape(impl)
        if name == "learn":  # SB3's other keywords (TL-AC: log_interval...) may come between
            names = {w[0] for w in want}
            want, got = [w[:2] for w in want], [g[:2] for g in got if g[0] in names]
        elif name == "load" and all(g[2] is not inspect.Parameter.empty for g in got[len(want) :]):
            got = got[: len(want)]  # SB3's other keywords (TL-AC: device...) may follow
        if got != want:
            problems.append(f"{cls.__name__}.{name}{got} != Algorithm.{name}{want}")
    return problems
