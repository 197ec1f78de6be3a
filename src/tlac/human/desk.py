"""The desk between a training run and the person at the page: a thread-safe queue of
questions and their answers (issue 68, docs/human-teacher.md).

The training thread posts a question (:meth:`Desk.ask`: the state, its frame, the student's
guess) and waits for its answer at most ``timeout`` seconds; the web server's thread hands the
person's answers in (:meth:`Desk.answer`). Training never waits on the person more than that:

* with no page connected, nothing is asked (the person is absent);
* a question not answered in time is dropped, and the person counts as away for
  ``away_seconds`` (or until the page says something again);
* closing the last tab withdraws every pending question at once.

Everything the page should see goes out through the listeners (:meth:`Desk.subscribe`), which
the server turns into WebSocket messages.

>>> desk = Desk(["left", "right"], timeout=0.01)
>>> desk.present(), desk.ask(None, None)[0]     # nobody at the page: absent
(False, None)
"""

from __future__ import annotations

import itertools
import threading
import time
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

MAX_PENDING = 64
"""Questions waiting at once, at most (several environments can ask in one step)."""


@dataclass
class Question:
    """One question to the person: ``id`` (unique in the run), ``state`` (the observation as
    the run serialises it), ``frame`` (a PNG data URL, or None), the student's ``guess``, the
    ``mode`` (``ask``: the high level chose the person; ``takeover``: the person plays the
    episode) and, once answered, ``action`` and the seconds it took."""

    id: int
    frame: str | None
    guess: int | None
    mode: str = "ask"
    state: str | None = None
    asked_at: float = field(default_factory=time.monotonic)
    done: threading.Event = field(default_factory=threading.Event)
    action: int | None = None
    seconds: float | None = None

    def message(self, pending: int, left: float | None) -> dict[str, Any]:
        """The question as the page reads it."""
        return {
            "type": "question",
            "id": self.id,
            "frame": self.frame,
            "guess": self.guess,
            "mode": self.mode,
            "state": self.state,
            "pending": pending,
            "left": left,
        }


class Desk:
    """Questions from the run to the person and answers back (see the module docstring).
    ``action_names``: one per action id (the page's buttons); ``timeout``: seconds a question
    waits; ``away_seconds``: how long a person who let a question time out counts as away."""

    def __init__(
        self,
        action_names: list[str],
        timeout: float = 10.0,
        away_seconds: float = 10.0,
        max_pending: int = MAX_PENDING,
    ):
        self.action_names = list(action_names)
        self.timeout, self.away_seconds, self.max_pending = timeout, away_seconds, max_pending
        self._lock = threading.Lock()
        self._pending: OrderedDict[int, Question] = OrderedDict()
        self._ids = itertools.count(1)
        self._listeners: dict[int, Callable[[dict[str, Any]], None]] = {}
        self._listener_ids = itertools.count(1)
        self.connections = 0
        self.away_until = 0.0
        self.takeover_wanted = False
        self.left: float | None = None  # questions left (the budget), for the page
        self.last_progress: dict[str, Any] | None = None
        self.stats = {"asked": 0, "answered": 0, "timed_out": 0, "refused": 0}

    # -- the page's side (the server's thread) ------------------------------------------------

    def subscribe(self, send: Callable[[dict[str, Any]], None]) -> int:
        """Register a page: ``send(message)`` is called (from any thread, so it must only
        hand the message over) with every question, withdrawal and progress report. Counts as
        a connection; returns its id for :meth:`unsubscribe`. The page is sent the pending
        questions and the latest progress at once."""
        with self._lock:
            key = next(self._listener_ids)
            self._listeners[key] = send
            self.connections += 1
            self.away_until = 0.0
            pending = list(self._pending.values())
            progress = self.last_progress
        send({"type": "hello", "actions": self.action_names, "timeout": self.timeout})
        for q in pending:
            send(q.message(len(pending), self.left))
        if progress is not None:
            send(progress)
        return key

    def unsubscribe(self, key: int) -> None:
        """A page went away; with the last one, every pending question is withdrawn (a closed
        tab is the person absent)."""
        with self._lock:
            if self._listeners.pop(key, None) is None:
                return
            self.connections -= 1
            withdrawn = list(self._pending.values()) if self.connections == 0 else []
            if withdrawn:
                self._pending.clear()
                self.takeover_wanted = False
        for q in withdrawn:
            q.done.set()

    def answer(self, question_id: int, action: int) -> bool:
        """The person's ``action`` for question ``question_id``; False (nothing changes) for a
        question that is not pending or an action that is not one of the buttons."""
        if not (isinstance(action, int) and 0 <= action < len(self.action_names)):
            self.stats["refused"] += 1
            return False
        with self._lock:
            q = self._pending.pop(question_id, None)
            if q is None:
                self.stats["refused"] += 1
                return False
            q.action, q.seconds = action, time.monotonic() - q.asked_at
            self.away_until = 0.0
            self.stats["answered"] += 1
        q.done.set()
        self._broadcast({"type": "answered", "id": question_id, "pending": len(self._pending)})
        return True

    def here(self) -> None:
        """The page said something (a button, the take-over): the person is back."""
        self.away_until = 0.0

    def request_takeover(self, on: bool = True) -> None:
        """The person wants to play the next episode (``on``), or no longer."""
        self.takeover_wanted = bool(on)
        self.here()
        self._broadcast({"type": "takeover", "wanted": self.takeover_wanted})

    # -- the run's side (the training thread) -------------------------------------------------

    def present(self) -> bool:
        """Whether a question asked now can be answered: a page is open and the person is not
        away (a question timed out less than ``away_seconds`` ago)."""
        return self.connections > 0 and time.monotonic() >= self.away_until

    def ask(
        self, frame: str | None, guess: int | None, state: str | None = None, mode: str = "ask"
    ) -> tuple[int | None, float | None]:
        """Post one question and wait for it; see :meth:`ask_many`. Returns ``(action,
        seconds)``, ``(None, None)`` where the person did not answer."""
        return self.ask_many([(frame, guess, state)], mode)[0]

    def ask_many(
        self,
        questions: list[tuple[str | None, int | None, str | None]],
        mode: str | list[str] = "ask",
    ) -> list[tuple[int | None, float | None]]:
        """Post ``questions`` (``(frame, guess, state)`` each: the frame's data URL, the
        student's guess, the observation as text; ``mode``: theirs, or one per question) at
        once and wait for their answers,
        ``timeout`` seconds in all; ``(None, None)`` for each one not answered: no page open,
        the queue full, the time out (the person then counts as away) or the tab closed."""
        if not self.present():
            return [(None, None)] * len(questions)
        posted: list[Question | None] = []
        with self._lock:
            # again under the lock: a last tab closed since withdraws nothing posted after it
            # (:meth:`unsubscribe` clears what is pending under this lock), so nothing is
            # posted to nobody and waited for until the timeout
            if not self.present():
                return [(None, None)] * len(questions)
            modes = [mode] * len(questions) if isinstance(mode, str) else list(mode)
            for (frame, guess, state), kind in zip(questions, modes, strict=True):
                if len(self._pending) >= self.max_pending:
                    posted.append(None)
                    continue
                q = Question(next(self._ids), frame, guess, kind, state)
                self._pending[q.id] = q
                posted.append(q)
                self.stats["asked"] += 1
            n_pending = len(self._pending)
        for q in posted:
            if q is not None:
                self._broadcast(q.message(n_pending, self.left))
        deadline = time.monotonic() + self.timeout
        out: list[tuple[int | None, float | None]] = []
        for q in posted:
            if q is None:
                out.append((None, None))
                continue
            q.done.wait(max(deadline - time.monotonic(), 0.0))
            with self._lock:
                if q.action is None and self._pending.pop(q.id, None) is not None:
                    self.stats["timed_out"] += 1
                    self.away_until = time.monotonic() + self.away_seconds
                    timed_out = True
                else:
                    timed_out = False
            if timed_out:
                self._broadcast({"type": "withdrawn", "id": q.id, "why": "timeout"})
            out.append((q.action, q.seconds))
        return out

    def progress(self, report: dict[str, Any]) -> None:
        """Send the page a progress report (the plot's points: ``step``, the student alone's
        return, the teachers' shares); the latest is kept for pages that open later."""
        message = {"type": "progress", **report}
        self.last_progress = message
        self._broadcast(message)

    def close(self) -> None:
        """The run ends: withdraw every question, tell the pages."""
        with self._lock:
            withdrawn = list(self._pending.values())
            self._pending.clear()
        for q in withdrawn:
            q.done.set()
        self._broadcast({"type": "finished"})

    def _broadcast(self, message: dict[str, Any]) -> None:
        """Hand ``message`` to every page; one that cannot take it any more (its server's
        loop has ended: RuntimeError) is unsubscribed, never raised into the training."""
        with self._lock:
            listeners = list(self._listeners.items())
        for key, send in listeners:
            try:
                send(message)
            except RuntimeError:
                self.unsubscribe(key)
