"""tlac: reinforcement learning with advice from several teachers.

The Two-Level Actor-Critic of "Two-Level Actor-Critic Using Multiple Teachers" (TMLR 2023):
a high-level actor picks, in every state, which teacher to follow (or the agent itself); a
low-level actor learns the control policy; both share one critic.

>>> from tlac import TLAC
>>> model = TLAC("doorkey", teachers=["optimal", "random", "random"])  # doctest: +SKIP
>>> model.learn(50_000)                                                # doctest: +SKIP
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"
__all__ = [
    "TLAC",
    "Domain",
    "StudentEvalCallback",
    "TLACConfig",
    "__version__",
    "register_domain",
]

if TYPE_CHECKING:
    from tlac.domains import Domain, register_domain
    from tlac.evaluation import StudentEvalCallback
    from tlac.two_level import TLAC, TLACConfig


def __getattr__(name: str) -> Any:  # lazy: `import tlac` imports neither torch nor SB3
    if name in ("TLAC", "TLACConfig"):
        from tlac import two_level

        return getattr(two_level, name)
    if name in ("Domain", "register_domain"):
        from tlac import domains

        return getattr(domains, name)
    if name == "StudentEvalCallback":
        from tlac.evaluation import StudentEvalCallback

        return StudentEvalCallback
    raise AttributeError(f"module 'tlac' has no attribute {name!r}")


def __dir__() -> list[str]:  # the lazy names too (tab completion)
    return sorted({*globals(), *__all__})


def _register_gym_ids() -> None:
    """``gym.make("tlac/DoorKey-v0")`` and the other domains' ids work after ``import tlac``;
    registered by entry-point strings, so no domain is imported until an id is made."""
    from tlac.gym_ids import register_gym_ids

    register_gym_ids()


_register_gym_ids()
