"""Algorithm registry: ``tlac train --algo NAME`` and experiment configs resolve names here.

Every class follows the contract in ``docs/architecture.md``:
``Algo(env, teachers, seed, recorder, **hyperparameters)`` with ``learn``, ``predict``,
``save`` and ``load`` as :class:`~tlac.algorithms.protocol.Algorithm` states them (a
``typing.Protocol``, re-exported here). Modules are imported lazily: TL-AC from
:mod:`tlac.two_level`, the baselines from :mod:`tlac.baselines`; this package holds the parts
they share.
"""

from __future__ import annotations

import importlib
from typing import Any

from tlac.algorithms.protocol import Algorithm
from tlac.errors import UnknownNameError

__all__ = ["ALGORITHMS", "NO_ADVICE", "Algorithm", "algorithm_names", "get_algorithm"]

ALGORITHMS: dict[str, str] = {
    "tlac": "tlac.two_level:TLAC",
    "ppo": "tlac.baselines.sb3_baselines:PPOBaseline",
    "a2c": "tlac.baselines.sb3_baselines:A2CBaseline",
    "dqn-tlql": "tlac.baselines.dqn_tlql:DQNTLQL",
    "ac-teach": "tlac.baselines.ac_teach:ACTeach",
}

# algorithms that take no teachers (the no-advice baselines)
NO_ADVICE = frozenset({"ppo", "a2c"})


def algorithm_names() -> list[str]:
    return list(ALGORITHMS)


def get_algorithm(name: str) -> Any:
    """The algorithm class registered under ``name``."""
    if not isinstance(name, str) or name not in ALGORITHMS:  # a list is no name (unhashable)
        raise UnknownNameError("algorithm", name, algorithm_names())
    module_name, attr = ALGORITHMS[name].split(":")
    return getattr(importlib.import_module(module_name), attr)
