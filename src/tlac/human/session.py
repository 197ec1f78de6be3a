"""A TL-AC run with a person as one of its teachers (``tlac teach``): the run machinery of
``tlac train`` (tlac.run: the run folder, checkpoints, resume) with the desk, the page's
server, ``advice.csv`` and the take-over wired in (docs/human-teacher.md).

* The ``human`` teacher (tlac.teachers.human.HumanTeacher) gets the desk, the student's greedy
  guess, the frames of the training environments and the run's ``advice.csv``.
* Under limited advice (``tlac teach`` always gives a budget), the ledger masks the person
  while no tab is open or after a question timed out (tlac.algorithms.advice.AdviceLedger.
  outside_presence): with nobody at the page, the high level cannot choose ``human`` and
  training runs as without it.
* Take-over: the person asks to play; the next episode of the first environment is led by
  ``human`` in every state (a teacher-led episode: the graduate variant counts its return as
  the person's own), and is written to ``human_episodes.csv``. The session is the model's
  ``episode_leader`` (tlac.two_level.collect.EpisodeLeader, :meth:`TeachSession.lead`).
* A thread sends the page the run's progress twice a second while a page is open: the step,
  the questions left, the student alone's evaluations and the teachers' shares of the steps.
"""

from __future__ import annotations

import contextlib
import csv
import threading
from pathlib import Path
from typing import Any

import numpy as np

from tlac.errors import ConfigError
from tlac.human.desk import Desk
from tlac.human.render import Framer
from tlac.recording import find_episode_recorder
from tlac.teachers.human import ADVICE_FILE, AdviceLog, HumanTeacher, open_csv_to_append
from tlac.two_level.collect import episode_leaders

EPISODES_FILE = "human_episodes.csv"
EPISODE_COLUMNS = ("timestep", "start_step", "length", "return", "episode", "led_by", "completed")
PROGRESS_EVERY = 0.5
"""Seconds between progress reports to an open page."""
MAX_POINTS = 400
"""Points of the teachers' shares the plot keeps (older ones thinned)."""


def action_names(env: Any) -> list[str]:
    """The buttons: the environment's action meanings where it has them (MiniGrid's
    ``Actions`` names: left, right, forward, pickup, drop, toggle, done; Atari's
    ``get_action_meanings``), else ``action 0``, ``action 1``, ..."""
    n = int(env.action_space.n)
    base = getattr(env, "unwrapped", env)
    meanings = getattr(base, "get_action_meanings", None)
    if callable(meanings):
        with contextlib.suppress(Exception):
            names = [str(m).lower() for m in meanings()]
            if len(names) >= n:
                return names[:n]
    actions = getattr(base, "actions", None)
    if actions is not None:
        with contextlib.suppress(Exception):
            names = [actions(i).name for i in range(n)]
            return names
    return [f"action {i}" for i in range(n)]


def drawn_run(run: Any) -> Any:
    """``run`` (tlac.run.ResolvedRun) with its environments made to draw themselves
    (``render_mode="rgb_array"``) where they are a Gymnasium id's that can: the page then
    shows the state as the environment draws it (tlac.human.render.env_frame). A tlac domain
    is left as it is (MiniGrid's DoorKey draws its grid whatever its render mode), and so is
    an id that cannot draw ``rgb_array`` (the page then says it has no picture)."""
    import dataclasses
    import functools

    import gymnasium as gym

    from tlac.domains import is_gym_domain

    domain = run.domain
    make = domain.make_env
    if not is_gym_domain(domain) or not isinstance(make, functools.partial) or not make.args:
        return run
    env_id = make.args[0]
    try:
        probe = gym.make(env_id, render_mode="rgb_array")
    except Exception:  # noqa: BLE001 - an id that cannot draw: no picture, as before
        return run
    drawn = getattr(probe, "render_mode", None) == "rgb_array"
    probe.close()
    if not drawn:
        return run
    make_env = functools.partial(gym.make, env_id, render_mode="rgb_array")
    return dataclasses.replace(run, domain=dataclasses.replace(domain, make_env=make_env))


def find_human(model: Any) -> tuple[int, HumanTeacher] | None:
    """The ``human`` teacher among the model's teachers, with its index."""
    for k, teacher in enumerate(getattr(model, "teachers", None) or []):
        inner = getattr(teacher, "teacher", teacher)
        if isinstance(inner, HumanTeacher):
            return k, inner
    return None


class TeachSession:
    """The desk and the page's server for one run; use as a context manager around
    :func:`tlac.run.train_run`, giving it :meth:`on_model` and :meth:`on_eval`."""

    def __init__(
        self,
        action_names: list[str],
        port: int = 0,
        timeout: float = 10.0,
        away_seconds: float = 10.0,
        serve: bool = True,
    ):
        self.desk = Desk(action_names, timeout=timeout, away_seconds=away_seconds)
        self.serve = serve
        self.server: Any = None
        if serve:
            from tlac.human.server import PageServer

            self.server = PageServer(self.desk, port=port)
        self.model: Any = None
        self.teacher: HumanTeacher | None = None
        self.index = -1
        self.log: AdviceLog | None = None
        self.episodes: Any = None
        self.evals: list[list[float]] = []
        self.shares: list[list[float]] = []
        self._last_sample: tuple[int, np.ndarray] | None = None
        self.leading = False
        self.lead_start = 0
        self.lead_steps = 0
        self.takeovers = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # -- lifetime -----------------------------------------------------------------------------

    def start(self) -> str | None:
        """Start the page's server; returns its URL (with the token)."""
        return None if self.server is None else self.server.start()

    def __enter__(self) -> TeachSession:
        try:
            self.start()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        if self.model is not None and getattr(self.model, "episode_leader", None) is self:
            self.model.episode_leader = None
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self.desk.close()
        if self.server is not None:
            self.server.stop()
        for f in (self.log, self.episodes):
            if f is not None:
                with contextlib.suppress(OSError):
                    f.close()
        self.log = self.episodes = None

    # -- hooks of tlac.run.train_run ------------------------------------------------------------

    def on_model(self, model: Any, out: Path) -> None:
        """Wire the built (or resumed) model to the desk."""
        found = find_human(model)
        if found is None:
            raise ConfigError("tlac teach: the run has no teacher named human")
        if not getattr(model, "limited_advice", False):
            raise ConfigError(
                "tlac teach: the person is a teacher only under limited advice (an advice "
                "budget): give --advice-budget"
            )
        self.model = model
        self.index, self.teacher = found
        teacher = self.teacher
        teacher.desk = self.desk
        teacher.framer = Framer(model)
        teacher.guess = lambda obs: model.predict(obs, deterministic=True)[0]
        teacher.step = lambda: int(model.num_timesteps)
        self.log = AdviceLog(Path(out) / ADVICE_FILE)
        teacher.log = self.log
        self.episodes = open_csv_to_append(Path(out) / EPISODES_FILE, EPISODE_COLUMNS)
        model.episode_leader = self  # the take-over (:meth:`lead`); not saved with the model
        self.desk.left = self._left()
        self._thread = threading.Thread(
            target=self._report, name="tlac-teach-progress", daemon=True
        )
        self._thread.start()

    def on_eval(self, timestep: int, student: float, train_return: float | None) -> None:
        """An evaluation of the student alone: a point of the page's plot."""
        self.evals.append([int(timestep), float(student)])

    # -- take-over -------------------------------------------------------------------------------

    def lead(self, episode_starts: np.ndarray) -> np.ndarray | None:
        """The model's ``episode_leader`` (tlac.two_level.collect.EpisodeLeader), called by
        TL-AC's collection at every step: the take-over's bookkeeping (its start and end, the
        lead stopped by the person leaving or the budget), and ``human`` to lead the first
        environment's episode where a take-over starts now (None elsewhere). TL-AC plays it
        as a teacher-led episode (the graduate variant counts its return as the person's
        own), or with the high level's choice forced to ``human`` in every state (the paper
        variant); with the person gone or the budget spent, the lead stops as any
        teacher-led episode's does, and so does the take-over (``completed`` 0)."""
        starts = np.asarray(episode_starts, dtype=bool)
        if self.leading:  # the step just played: the person's, or the lead has stopped
            if episode_leaders(self.model)[0] == self.index:
                self.lead_steps += 1
            else:
                self._end_takeover(completed=False)
        self._episode_boundary(starts)
        if not (self.leading and len(starts) and starts[0]):
            return None
        named = np.full(len(starts), -1, dtype=np.int64)
        named[0] = self.index
        return named

    def _episode_boundary(self, episode_starts: np.ndarray) -> None:
        if not len(episode_starts) or not episode_starts[0]:
            if self.leading and not self.desk.present():  # the person left mid-episode
                self._end_takeover(completed=False)
            return
        if self.leading:
            self._end_takeover(completed=True)
        if self.desk.takeover_wanted and self.desk.present():
            self.leading = True
            self.lead_start = int(self.model.num_timesteps)
            self.lead_steps = 0
            assert self.teacher is not None
            self.teacher.takeover_env = 0
            self.desk.request_takeover(False)  # one episode per request

    def _end_takeover(self, completed: bool) -> None:
        """A row of ``human_episodes.csv``: ``timestep`` the step the episode ended at (as
        ``episodes.csv`` counts it; where the lead stopped before, the run's step then),
        ``start_step`` the run's step at its start, ``length`` the steps the person led (the
        first environment's), ``return`` and ``episode`` (its row in ``episodes.csv``) of the
        first environment's episode where it was played to its end (NaN, -1 otherwise)."""
        assert self.teacher is not None
        self.leading = False
        self.teacher.takeover_env = None
        step = int(self.model.num_timesteps)
        ret, episode = float("nan"), -1
        recorder = find_episode_recorder(self.model.env)
        if completed and recorder is not None and recorder.last_episode[0] > 0:
            ret = float(recorder.last_return[0])
            episode = int(recorder.last_episode[0])
            step = int(recorder.last_end[0])
        if self.episodes is not None:
            csv.writer(self.episodes).writerow(
                [step, self.lead_start, self.lead_steps, ret, episode, "human", int(completed)]
            )
            self.episodes.flush()
        self.takeovers += 1

    # -- progress ---------------------------------------------------------------------------------

    def _left(self) -> float | None:
        ledger = getattr(self.model, "advice", None)
        if ledger is None or not np.isfinite(ledger.budget):
            return None
        cost = float(ledger.costs[self.index]) if len(ledger.costs) else 1.0
        return float(ledger.remaining) / cost if cost > 0 else None

    def _sample_shares(self) -> None:
        model = self.model
        ledger = getattr(model, "advice", None)
        if ledger is None:
            return
        step, acted = int(model.num_timesteps), ledger.acted.astype(np.float64).copy()
        if self._last_sample is not None and step > self._last_sample[0]:
            share = (acted - self._last_sample[1]) / (step - self._last_sample[0])
            self.shares.append([step, *np.clip(share, 0.0, 1.0).round(4).tolist()])
            if len(self.shares) > MAX_POINTS:
                self.shares = self.shares[::2]
        if self._last_sample is None or step > self._last_sample[0]:
            self._last_sample = (step, acted)

    def report(self) -> dict[str, Any]:
        """The page's progress report now."""
        model = self.model
        names = list(getattr(model, "teacher_names", []) or [])
        return {
            "step": int(model.num_timesteps),
            "left": self._left(),
            "teachers": names,
            "student": self.evals[-MAX_POINTS:],
            "shares": self.shares,
            "takeovers": self.takeovers,
            "leading": self.leading,
        }

    def _report(self) -> None:
        while not self._stop.wait(PROGRESS_EVERY):
            try:
                self._sample_shares()
                self.desk.left = self._left()
                if self.desk.connections > 0:
                    self.desk.progress(self.report())
            except Exception:  # noqa: BLE001 - a report must never stop the run
                continue
