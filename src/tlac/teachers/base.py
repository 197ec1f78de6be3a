"""The teacher protocol: anything that maps a batch of observations to a batch of actions.

A teacher is never trained and never pickled into a checkpoint (paper, section 3.1: teachers
are fixed). Three kinds of objects are accepted by :func:`as_teacher`:

* an object with a batched ``predict(obs_batch) -> action_batch`` (a :class:`Teacher`);
* a stable-baselines3 model, or its policy (``model.policy``, a ``BasePolicy`` as imitation's
  BC trainer gives), whose ``predict`` returns ``(actions, state)``; a model that trains
  under a ``VecNormalize`` of its own is asked on observations normalised by its statistics;
* a plain function from ONE observation to ONE action (a person's controller).

>>> import numpy as np, gymnasium as gym
>>> t = as_teacher(lambda obs: 1, gym.spaces.Discrete(3), name="always-one")
>>> t.predict(np.zeros((2, 4))).tolist()
[1, 1]
"""

from __future__ import annotations

import numbers
import sys
from collections.abc import Callable, Mapping
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np

from tlac.errors import TeacherError


@runtime_checkable
class Teacher(Protocol):
    """A fixed policy giving action advice. ``predict`` is batched over environments."""

    name: str

    def predict(self, obs: np.ndarray) -> np.ndarray:
        """Map observations of shape ``(n, *obs_shape)`` to actions: ``(n,)`` integers for a
        Discrete space, ``(n, action_dim)`` floats for a Box space."""
        ...


class FunctionTeacher:
    """Wraps a function from one observation to one action into a batched teacher."""

    def __init__(self, fn: Callable[[np.ndarray], Any], action_space: gym.Space, name: str):
        self.fn, self.action_space, self.name = fn, action_space, name

    def predict(self, obs: np.ndarray) -> np.ndarray:
        # no cast here: check_actions reports a NaN or an out-of-range value by name
        actions = [self.fn(o) for o in batch_rows(obs)]
        for a in actions:
            if a is None or np.asarray(a).dtype.kind not in "biuf":
                raise TeacherError(
                    f"teacher {self.name!r} returned {a!r:.60} for an observation; expected an "
                    f"action of {self.action_space}"
                )
        return np.asarray(actions)


class NamedTeacher:
    """Gives an existing batched teacher a (new) name without changing its behaviour."""

    def __init__(self, teacher: Any, name: str):
        self.teacher, self.name = teacher, name

    def predict(self, obs: np.ndarray) -> np.ndarray:
        return np.asarray(self.teacher.predict(obs))


class TeacherSpec:
    """A teacher with the terms of its advice (issue 66, docs/advice.md): ``cost`` per answer
    (what the run's ``advice_budget`` is spent in) and ``availability``, the chance it is
    present in an episode: a number, a schedule (``{steps: [[0, 1.0], [20000, 0.0]]}``) or a
    function of the environment step. ``policy``: anything :func:`as_teacher` takes, or (env a
    domain name) one of the domain's teacher names; ``name``: its name in logs and in the
    ``teacher_cost`` / ``availability`` settings it fills.

    >>> spec = TeacherSpec(lambda obs: 0, name="pd", cost=2.0, availability=0.5)
    >>> spec.name, spec.cost, spec.availability
    ('pd', 2.0, 0.5)
    >>> TeacherSpec(lambda obs: 0, cost=-1)
    Traceback (most recent call last):
    tlac.errors.ConfigError: TeacherSpec cost must be a number >= 0, got -1
    """

    def __init__(
        self, policy: Any, name: str | None = None, cost: float = 1.0, availability: Any = 1.0
    ):
        from tlac.errors import ConfigError
        from tlac.presets import availability_problem

        ok = isinstance(cost, numbers.Real) and not isinstance(cost, bool)
        if not ok or not float(cost) >= 0.0:
            raise ConfigError(f"TeacherSpec cost must be a number >= 0, got {cost!r}")
        number = isinstance(availability, numbers.Real) and not isinstance(availability, bool)
        if number and not 0.0 < float(availability) <= 1.0:  # NaN fails too
            raise ConfigError(
                f"TeacherSpec availability must be a number in (0, 1], got {availability!r}"
            )
        if not number and (expected := availability_problem(availability)) is not None:
            raise ConfigError(f"TeacherSpec availability must be {expected}, got {availability!r}")
        if name is not None and (not isinstance(name, str) or not name):
            raise ConfigError(f"TeacherSpec name must be a non-empty string, got {name!r}")
        self.policy, self.name = policy, name
        # a number as a float; a schedule or a function of the step as it is
        self.cost = float(cost)
        self.availability = float(availability) if number else availability

    def resolve(self, action_space: gym.Space) -> Any:
        """What it stands for among a run's teachers: a domain teacher's name as it is, else
        the teacher, under this spec's name where it has one."""
        if isinstance(self.policy, str) or self.name is None:
            return self.policy
        return as_teacher(self.policy, action_space, self.name)


def _is_sb3_model(obj: Any) -> bool:
    """Whether ``obj`` is an SB3 model or policy: its ``predict`` returns ``(actions, state)``."""
    # an object cannot be an SB3 model unless SB3 is loaded: skip its (slow) import otherwise
    if "stable_baselines3" not in sys.modules:
        return False
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.policies import BasePolicy

    return isinstance(obj, BaseAlgorithm | BasePolicy)


def as_teacher(obj: Any, action_space: gym.Space, name: str | None = None) -> Teacher:
    """Turn ``obj`` into a :class:`Teacher` (see the module docstring for what is accepted)."""
    if _is_sb3_model(obj):  # with the statistics of its own VecNormalize, if it has one
        from tlac.teachers.sb3 import SB3Teacher, own_obs_normalization

        label = name or type(obj).__name__.lower()
        return SB3Teacher(obj, label, normalize_obs=own_obs_normalization(obj, label))
    if hasattr(obj, "predict") and callable(obj.predict):
        if name is not None and getattr(obj, "name", None) != name:
            return NamedTeacher(obj, name)
        if not isinstance(getattr(obj, "name", None), str):
            return NamedTeacher(obj, type(obj).__name__.lower())
        return obj
    if callable(obj):
        return FunctionTeacher(obj, action_space, name or getattr(obj, "__name__", "function"))
    raise TeacherError(
        f"cannot use {obj!r} as a teacher; expected an object with predict(obs_batch), "
        "a stable-baselines3 model or policy, or a function from one observation to one action"
    )


def batch_len(obs: Any) -> int:
    """How many observations a batch holds: an array's rows, or (a Dict observation space's
    batch, a dict of arrays as SB3 gives it) the rows of its values.

    >>> batch_len({"a": np.zeros((3, 2)), "b": np.zeros(3)}), batch_len(np.zeros((2, 5)))
    (3, 2)
    """
    if isinstance(obs, Mapping):
        return len(next(iter(obs.values())))
    return len(obs)


def take_rows(obs: Any, rows: np.ndarray) -> Any:
    """The batch's ``rows`` (an index array), for an array or a dict of arrays."""
    if isinstance(obs, Mapping):
        return {key: np.asarray(value)[rows] for key, value in obs.items()}
    return obs[rows]


def batch_rows(obs: Any) -> Any:
    """The batch's observations one by one (a dict of arrays: one dict per row), as a
    function teacher takes them.

    >>> [o["b"] for o in batch_rows({"a": np.zeros((2, 2)), "b": np.array([4, 5])})]
    [np.int64(4), np.int64(5)]
    """
    if isinstance(obs, Mapping):
        return [{key: value[i] for key, value in obs.items()} for i in range(batch_len(obs))]
    return obs


def teacher_label(teacher: Any, index: int) -> str:
    """A teacher's name for logs and errors: its ``name``, else a function's ``__name__``."""
    name = getattr(teacher, "name", None)
    if isinstance(name, str) and name:
        return name
    fn_name = getattr(teacher, "__name__", "")
    if fn_name and fn_name != "<lambda>":
        return fn_name
    if hasattr(teacher, "predict"):  # a batched object or an SB3 model: its class
        return type(teacher).__name__.lower()
    return f"teacher{index}"


def unique_names(names: list[str]) -> list[str]:
    """Make teacher names unique for logs: ``[random, random] -> [random_1, random_2]``."""
    counts = {n: names.count(n) for n in names}
    seen: dict[str, int] = {}
    out = []
    for n in names:
        if counts[n] == 1:
            out.append(n)
        else:
            seen[n] = seen.get(n, 0) + 1
            out.append(f"{n}_{seen[n]}")
    return out


def _named_errors(teacher: Any, call: Callable[[], Any], method: str = "") -> Any:
    """``call()``; whatever a teacher raises is named in a :class:`TeacherError` (with its own
    message, and ``method`` where it is not ``predict``), never a bare library exception."""
    try:
        return call()
    except TeacherError:
        raise
    except Exception as exc:  # noqa: BLE001 - a user's teacher may raise anything
        where = f": {method}" if method else ""
        raise TeacherError(
            f"teacher {teacher.name!r}{where} raised {type(exc).__name__}: {str(exc)[:200]}"
        ) from exc


def _unwrapped(teacher: Any) -> Any:
    """The teacher a :class:`NamedTeacher` renames (its optional methods live there)."""
    return teacher.teacher if isinstance(teacher, NamedTeacher) else teacher


def ask_teacher(teacher: Any, obs: np.ndarray, action_space: gym.Space) -> np.ndarray:
    """``teacher``'s checked actions for the batch ``obs``; a teacher that raises is named in
    a :class:`TeacherError` (with its own message), never a bare library exception."""
    actions = _named_errors(teacher, lambda: teacher.predict(obs))
    return check_actions(teacher.name, actions, action_space, batch_len(obs))


def numeric_actions(teacher_name: str, actions: Any, action_space: gym.Space) -> np.ndarray:
    """``actions`` as a NumPy array of numbers (an object array of plain numbers becomes
    floats); text, complex numbers or other objects are a :class:`TeacherError` naming the
    teacher, where NumPy's own checks would raise a bare TypeError.

    >>> numeric_actions("t", np.array([1, 0], dtype=object), gym.spaces.Discrete(2)).tolist()
    [1.0, 0.0]
    >>> numeric_actions("t", np.array(["left"]), gym.spaces.Discrete(2))
    Traceback (most recent call last):
    tlac.errors.TeacherError: teacher 't' returned actions of dtype <U4 ('left');
    expected numbers, actions of Discrete(2)
    """
    try:
        arr = np.asarray(actions)
    except ValueError:  # ragged nested lists
        arr = np.asarray(actions, dtype=object)
    if arr.dtype == object and all(isinstance(a, numbers.Real) for a in arr.flat):
        arr = arr.astype(np.float64)
    if arr.dtype.kind not in "biuf":
        first = arr.flat[0] if arr.size else "empty"
        first = repr(first.item() if isinstance(first, np.generic) else first)[:40]
        raise TeacherError(
            f"teacher {teacher_name!r} returned actions of dtype {arr.dtype} ({first}); "
            f"expected numbers, actions of {action_space}"
        )
    return arr


def check_actions(teacher_name: str, actions: Any, action_space: gym.Space, n: int) -> np.ndarray:
    """Validate a batch of teacher actions; raise :class:`TeacherError` naming the teacher and
    the offending value. Nothing is clipped silently."""
    arr = numeric_actions(teacher_name, actions, action_space)
    if isinstance(action_space, gym.spaces.Discrete):
        if arr.shape != (n,):
            raise TeacherError(
                f"teacher {teacher_name!r} returned actions of shape {arr.shape}; "
                f"expected ({n},) integers for {action_space}"
            )
        if not np.issubdtype(arr.dtype, np.integer):
            if np.issubdtype(arr.dtype, np.floating) and np.isnan(arr).any():
                raise TeacherError(f"teacher {teacher_name!r} returned NaN action {arr.tolist()}")
            if not np.all(np.equal(np.mod(arr, 1), 0)):
                raise TeacherError(
                    f"teacher {teacher_name!r} returned non-integer action {arr.tolist()} "
                    f"for {action_space}"
                )
        low, high = action_space.start, action_space.start + action_space.n - 1
        bad = (arr < low) | (arr > high)  # before the cast: 1e30 is no int64
        if bad.any():
            raise TeacherError(
                f"teacher {teacher_name!r} returned action {arr[bad][0]} outside "
                f"{action_space} (expected an integer in [{low}, {high}])"
            )
        return arr.astype(np.int64)
    if isinstance(action_space, gym.spaces.Box):
        expected = (n, *action_space.shape)
        if arr.shape != expected:
            raise TeacherError(
                f"teacher {teacher_name!r} returned actions of shape {arr.shape}; "
                f"expected {expected}"
            )
        arr = arr.astype(np.float32)
        if np.isnan(arr).any():
            raise TeacherError(f"teacher {teacher_name!r} returned NaN in action {arr.tolist()}")
        tol = 1e-6
        bad = (arr < action_space.low - tol) | (arr > action_space.high + tol)
        if bad.any():
            row = int(np.argwhere(bad)[0][0])
            raise TeacherError(
                f"teacher {teacher_name!r} returned action {arr[row].tolist()} outside the "
                f"action box [{action_space.low.tolist()}, {action_space.high.tolist()}]"
            )
        return arr
    raise TeacherError(f"unsupported action space {action_space} for teacher {teacher_name!r}")


def advice_probabilities(teacher: Any, obs: np.ndarray, action_space: gym.Space) -> np.ndarray:
    """``(n, action_space.n)``: ``teacher``'s distribution over the actions of a Discrete space
    in every row of ``obs``. A teacher that knows it gives it (``action_probabilities(obs)``:
    tlac's random, good / noisy and partial teachers); any other is a point mass on its action
    (a deterministic teacher's is exact; a stochastic one's is one sample of it).

    >>> t = as_teacher(lambda obs: 2, gym.spaces.Discrete(3))
    >>> advice_probabilities(t, np.zeros((1, 4)), gym.spaces.Discrete(3)).tolist()
    [[0.0, 0.0, 1.0]]
    """
    n_actions, n = int(action_space.n), batch_len(obs)
    inner = _unwrapped(teacher)
    if hasattr(inner, "action_probabilities"):
        probs = np.asarray(inner.action_probabilities(obs))
        if probs.dtype.kind not in "biuf":
            raise TeacherError(
                f"teacher {teacher.name!r}: action_probabilities gave an array of dtype "
                f"{probs.dtype}; expected numbers, rows of probabilities summing to 1"
            )
        probs = probs.astype(np.float64)
        if probs.shape != (n, n_actions) or not np.allclose(probs.sum(1), 1.0):
            raise TeacherError(
                f"teacher {teacher.name!r}: action_probabilities gave an array of shape "
                f"{probs.shape} (rows summing to 1 expected, shape ({n}, {n_actions}))"
            )
        return probs
    actions = ask_teacher(teacher, obs, action_space) - int(action_space.start)
    probs = np.zeros((n, n_actions))
    probs[np.arange(n), actions] = 1.0
    return probs


def advice_actions(
    teacher: Any, obs: np.ndarray, action_space: gym.Space
) -> tuple[np.ndarray, np.ndarray]:
    """For a Box action space, what ``teacher`` means in every row of ``obs``: ``(actions (n,
    *shape) float32, information (n,))``. A teacher whose actions mix an informative part with
    uniformly random ones says so (``informative_actions(obs)``: tlac's random, good / noisy,
    Gaussian-noise and partial teachers): the action of its informative part (its base's) and
    that part's weight, 0 where it says nothing (a random teacher, a partial one outside its
    region). Any other teacher (a plain function, an SB3 agent) is asked twice: where its two
    answers agree it means that action, with information 1; where they differ it is
    stochastic, its label is their mean and its information is measured
    (:func:`self_agreement_information`), so a user's ``lambda obs: space.sample()`` means
    nothing. The Box counterpart of :func:`advice_probabilities`: a good teacher's label is its
    base's action, not one of its random draws.

    >>> box = gym.spaces.Box(-1.0, 1.0, (2,))
    >>> t = as_teacher(lambda obs: np.array([0.5, -0.5]), box)
    >>> actions, information = advice_actions(t, np.zeros((1, 3)), box)
    >>> actions.tolist(), information.tolist()
    ([[0.5, -0.5]], [1.0])
    """
    n = batch_len(obs)
    inner = _unwrapped(teacher)
    if not hasattr(inner, "informative_actions"):
        first = ask_teacher(teacher, obs, action_space)
        second = ask_teacher(teacher, obs, action_space)
        information = self_agreement_information(first, second, action_space)
        return (first + second) / 2, information
    actions, information = _named_errors(
        teacher, lambda: inner.informative_actions(obs), "informative_actions"
    )
    information = np.asarray(information, dtype=np.float64)
    if information.shape != (n,) or not np.all((information >= 0) & (information <= 1)):
        raise TeacherError(
            f"teacher {teacher.name!r}: informative_actions gave information of shape "
            f"{information.shape} (expected ({n},) values in [0, 1])"
        )
    return check_actions(teacher.name, actions, action_space, n), information


AGREEMENT_MARGIN = 2.0
"""Standard errors by which a Box teacher's two answers must agree more than a uniformly random
teacher's would, for its differing rows to carry any information
(:func:`self_agreement_information`)."""


def self_agreement_information(
    first: np.ndarray, second: np.ndarray, action_space: gym.spaces.Box
) -> np.ndarray:
    """``(n,)``: how much a teacher's Box advice means, from two answers for the same states.
    Rows where the answers are equal (a deterministic teacher) get 1. The differing rows share
    ``1 - mean ||a1 - a2||^2 / E ||u1 - u2||^2``, with ``u1, u2`` independent uniform draws
    from the action box (``E = sum (high - low)^2 / 6``): ``1 - sigma^2 / var(u)`` for a
    teacher that adds unclipped Gaussian noise of standard deviation ``sigma``, and 0 for a
    uniformly random one. 0 also unless it is above 0 by ``AGREEMENT_MARGIN`` standard errors
    of a uniformly random teacher's mean gap over those rows (``sd ||u1 - u2||^2 =
    sqrt(sum 7 (high - low)^4 / 180)``): estimated on a rollout's 2,048 rows, a random
    teacher's value is above 0 in half of them (up to 0.08), and where the high level trusts
    no other teacher, the imitation scales that crumb up to the state's whole trust
    (tlac.two_level.losses.reweighted_trust) and copies the mean of two random actions. So a
    few differing rows cannot tell a noisy teacher from a random one (with one action
    dimension, fewer than 6 never can). An unbounded box has no uniform draw to compare with:
    1. Answers drawn from a few values (a teacher choosing among fixed torques) can coincide
    by chance, and rows where they do read as meant.

    >>> box = gym.spaces.Box(-1.0, 1.0, (1,))
    >>> first = np.array([[0.5], [0.2], [0.1], [-0.3], [0.7], [0.0], [-0.6], [0.4]])
    >>> close = first + np.array([[0.0], [0.2], [-0.2], [0.2], [-0.2], [0.2], [-0.2], [0.2]])
    >>> self_agreement_information(first, close, box).round(2)   # 7 rows differ by 0.2
    array([1.  , 0.94, 0.94, 0.94, 0.94, 0.94, 0.94, 0.94])
    >>> self_agreement_information(first[:3], close[:3], box)   # 2 rows: too few to tell
    array([1., 0., 0.])
    """
    gap = ((first - second) ** 2).reshape(len(first), -1).sum(axis=1)
    differ = gap > 0
    information = np.ones(len(first))
    width = (action_space.high - action_space.low).astype(np.float64)
    if not differ.any() or not np.isfinite(width).all():
        return information
    uniform_gap = float(np.sum(width**2)) / 6.0
    uniform_gap_sd = float(np.sqrt(np.sum(7.0 * width**4) / 180.0))
    measured = 1.0 - gap[differ].mean() / uniform_gap
    noise = AGREEMENT_MARGIN * uniform_gap_sd / uniform_gap / np.sqrt(differ.sum())
    information[differ] = np.clip(measured, 0.0, 1.0) if measured > noise else 0.0
    return information
