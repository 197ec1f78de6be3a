"""A person as a teacher (``human``) and a person's recorded answers as one (``replay:RUN``).

Neither imports a web framework: :class:`HumanTeacher` asks a :class:`tlac.human.desk.Desk`
that ``tlac teach`` (tlac.human.session) gives it; without one it is never there.

Every answer goes to the run folder's ``advice.csv`` (:class:`AdviceLog`): the step, the state
(:func:`encode_state`: the observation's dtype, shape and bytes in base64), the action, the
seconds the person took and the mode (``ask``: the high level chose the person; ``takeover``:
the person played the episode). :class:`ReplayTeacher` reads it back.

>>> import gymnasium as gym
>>> state = np.arange(6, dtype=np.uint8).reshape(2, 3)
>>> decode_state(encode_state(state)).tolist() == state.tolist()
True
"""

from __future__ import annotations

import base64
import csv
import math
from collections import Counter
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from tlac.errors import ConfigError

ADVICE_FILE = "advice.csv"
ADVICE_COLUMNS = ("step", "state", "action", "seconds", "mode")


def is_person_teacher(name: str) -> bool:
    """Whether the teacher ``name`` is a person: ``human`` (the person at tlac teach's page)
    or ``replay:RUN`` (a person's answers recorded in RUN/advice.csv).

    >>> [is_person_teacher(n) for n in ("human", "replay:runs/me", "optimal", "humane")]
    [True, True, False, False]
    """
    return name == "human" or name.startswith("replay:")


def encode_state(obs: Any) -> str:
    """One observation as text: ``dtype:shape:base64`` (``uint8:147:AAEC...``; the shape's
    sides joined by ``x``)."""
    arr = np.ascontiguousarray(np.asarray(obs))
    shape = "x".join(str(s) for s in arr.shape)
    return f"{arr.dtype.str}:{shape}:{base64.b64encode(arr.tobytes()).decode('ascii')}"


def decode_state(text: str) -> np.ndarray:
    """:func:`encode_state`'s inverse; ValueError for text that is not one."""
    dtype, shape, data = text.split(":", 2)
    dims = tuple(int(s) for s in shape.split("x")) if shape else ()
    if np.dtype(dtype).kind not in "biuf":
        raise ValueError(f"not a numeric dtype: {dtype!r}")
    return np.frombuffer(base64.b64decode(data, validate=True), dtype=dtype).reshape(dims)


def state_key(obs: Any) -> bytes:
    """The key of a state: its values as float64 bytes, so that the same state matches
    whether the run hands it over as uint8 (acting) or as float32 rows (the update's labels).
    """
    return np.asarray(obs, dtype=np.float64).reshape(-1).tobytes()


def _rows(obs: Any) -> np.ndarray:
    arr = np.asarray(obs)
    if arr.dtype == object:
        raise ConfigError("the human and replay teachers take array observations, not dicts")
    return arr


def open_csv_to_append(path: str | Path, columns: tuple[str, ...] | list[str]) -> Any:
    """``path`` opened to append CSV rows, its header ``columns`` written (and flushed) first
    where the file is new or empty: a resumed run carries on the rows it wrote before."""
    path = Path(path)
    new = not path.exists() or path.stat().st_size == 0
    file = path.open("a", newline="")
    if new:
        csv.writer(file).writerow(columns)
        file.flush()
    return file


class AdviceLog:
    """The run folder's ``advice.csv``: one row per answer, flushed at once (a run stopped at
    any moment keeps every answer given)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._file = open_csv_to_append(self.path, ADVICE_COLUMNS)
        self._writer = csv.writer(self._file)
        self.rows = 0

    def write(self, step: int, obs: Any, action: int, seconds: float | None, mode: str) -> None:
        seconds_text = "" if seconds is None else f"{seconds:.3f}"
        self._writer.writerow([int(step), encode_state(obs), int(action), seconds_text, mode])
        self._file.flush()
        self.rows += 1

    def close(self) -> None:
        self._file.close()


def read_advice(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a run's ``advice.csv`` (``path``: the file or its run folder), states
    decoded; ConfigError naming the file and line for one that is not an answer."""
    path = Path(path)
    if path.is_dir():
        path = path / ADVICE_FILE
    if not path.is_file():
        raise ConfigError(f"replay: {str(path)!r} does not exist (a tlac teach run's answers)")
    out = []
    with path.open(newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None or tuple(header[:4]) != ADVICE_COLUMNS[:4]:
            raise ConfigError(f"replay: {str(path)!r} is not an advice.csv (header {header!r:.60})")
        for line, row in enumerate(reader, start=2):
            try:
                seconds = float(row[3]) if row[3] else math.nan
                out.append(
                    {
                        "step": int(row[0]),
                        "state": decode_state(row[1]),
                        "action": int(row[2]),
                        "seconds": seconds,
                        "mode": row[4] if len(row) > 4 else "ask",
                    }
                )
            except (ValueError, IndexError, TypeError):
                raise ConfigError(
                    f"replay: {str(path)!r} line {line} is not an answer ({str(row)[:60]})"
                ) from None
    return out


class HumanTeacher:
    """The person at ``tlac teach``'s page as a teacher named ``human`` (Discrete actions).

    Asked to act (the high level chose it, or the person took an episode over), it posts one
    question per state to its desk and waits at most the desk's timeout; a state it gets no
    answer for is played by the student's own guess (the person is absent there). It is there
    (:meth:`presence`) only while a page is open and the person not away, so with nobody at
    the page the high level cannot choose it. It answers only when it acts
    (``acting_only``): its labels are the answers it gave (:meth:`action_probabilities`), never
    questions about the states of a whole rollout."""

    acting_only = True

    def __init__(self, action_space: gym.Space, name: str = "human"):
        if not isinstance(action_space, gym.spaces.Discrete):
            raise ConfigError(
                f"the human teacher presses buttons: it needs Discrete actions, not {action_space}"
            )
        self.action_space, self.name = action_space, name
        self.desk: Any = None  # tlac.human.desk.Desk, given by the session
        self.guess: Any = None  # obs batch -> the student's greedy actions
        self.framer: Any = None  # obs row -> the frame's data URL
        self.log: AdviceLog | None = None
        self.step: Any = lambda: 0  # the run's step now
        # the training environments the rows asked now are (set before each question by
        # TL-AC's collection: tlac.algorithms.common.query_teachers; None: not known)
        self.env_rows: np.ndarray | None = None
        # the environment whose rows are the person's take-over (the session sets it while
        # the person leads; None: none): its answers are written with mode ``takeover``
        self.takeover_env: int | None = None
        self.answers: dict[bytes, int] = {}

    def presence(self, obs: Any) -> np.ndarray:
        n = len(_rows(obs))
        return np.full(n, self.desk is not None and self.desk.present())

    def _guesses(self, obs: np.ndarray) -> np.ndarray:
        start = int(self.action_space.start)
        if self.guess is None:
            return np.full(len(obs), start, dtype=np.int64)
        return np.asarray(self.guess(obs), dtype=np.int64).reshape(len(obs))

    def predict(self, obs: Any) -> np.ndarray:
        obs = _rows(obs)
        out = self._guesses(obs)
        if self.desk is None:
            return out
        start = int(self.action_space.start)
        envs: list[int | None] = [None] * len(obs)
        if self.env_rows is not None and len(self.env_rows) == len(obs):
            envs = [int(e) for e in self.env_rows]
        self.env_rows = None  # for this question only
        frames = [
            None if self.framer is None else self.framer.frame(o, e)
            for o, e in zip(obs, envs, strict=True)
        ]
        modes = ["takeover" if e is not None and e == self.takeover_env else "ask" for e in envs]
        asked = self.desk.ask_many(
            [
                (f, int(g) - start, encode_state(o))
                for f, g, o in zip(frames, out, obs, strict=True)
            ],
            modes,
        )
        for i, (action, seconds) in enumerate(asked):
            if action is None:
                continue
            out[i] = action + start
            self.answers[state_key(obs[i])] = int(out[i])
            if self.log is not None:
                self.log.write(self.step(), obs[i], int(out[i]), seconds, modes[i])
        return out

    def action_probabilities(self, obs: Any) -> np.ndarray:
        """The person's answer where it gave one in that state (a point mass), else the
        uniform distribution (it says nothing there)."""
        return _known_probabilities(self.answers, _rows(obs), self.action_space)


def _known_probabilities(
    answers: dict[bytes, int], obs: np.ndarray, space: gym.spaces.Discrete
) -> np.ndarray:
    n_actions, start = int(space.n), int(space.start)
    probs = np.full((len(obs), n_actions), 1.0 / n_actions)
    for i, row in enumerate(obs):
        action = answers.get(state_key(row))
        if action is not None:
            probs[i] = 0.0
            probs[i, action - start] = 1.0
    return probs


class ReplayTeacher:
    """A person's answers replayed (``replay:RUN``): in a state the person answered it gives
    that answer (the most frequent where it answered differently, the latest of a tie); it
    is there (:meth:`presence`) only in those states, so under limited advice it is never
    chosen elsewhere; asked elsewhere all the same (a run without limits), it answers a
    uniformly random action and its label says nothing (the uniform distribution)."""

    def __init__(
        self, run: str | Path, action_space: gym.Space, seed: int = 0, name: str = "replay"
    ):
        if not isinstance(action_space, gym.spaces.Discrete):
            raise ConfigError(
                f"replay: a person's answers are Discrete actions, not {action_space}"
            )
        self.action_space, self.name, self.source = action_space, name, str(run)
        rows = read_advice(run)
        votes: dict[bytes, Counter[int]] = {}
        latest: dict[bytes, int] = {}
        for row in rows:
            key = state_key(row["state"])
            votes.setdefault(key, Counter())[row["action"]] += 1
            latest[key] = row["action"]
        self.answers = {}
        for key, counts in votes.items():
            best = max(counts.values())
            tied = [a for a, c in counts.items() if c == best]
            self.answers[key] = latest[key] if latest[key] in tied else tied[0]
        self.rng = np.random.default_rng([seed, 0x4E91A7])

    def known(self, obs: Any) -> np.ndarray:
        return np.array([state_key(o) in self.answers for o in _rows(obs)], dtype=bool)

    def presence(self, obs: Any) -> np.ndarray:
        return self.known(obs)

    def predict(self, obs: Any) -> np.ndarray:
        obs = _rows(obs)
        start, n_actions = int(self.action_space.start), int(self.action_space.n)
        out = self.rng.integers(start, start + n_actions, size=len(obs))
        for i, row in enumerate(obs):
            action = self.answers.get(state_key(row))
            if action is not None:
                out[i] = action
        return out.astype(np.int64)

    def action_probabilities(self, obs: Any) -> np.ndarray:
        return _known_probabilities(self.answers, _rows(obs), self.action_space)
