"""A person as a teacher through a browser page (issue 68, tlac.human, docs/human-teacher.md):
the token, malformed and forged messages, a flood, the desk's timeouts, advice.csv and its
replay, the latency of a question, a run with a scripted person and a take-over, the CLI, and
(slow tier) a scripted person in headless Chromium."""

from __future__ import annotations

import csv
import json
import logging
import os
import shutil
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

pytest.importorskip("starlette", reason="tlac[human] is not installed")
pytest.importorskip("uvicorn", reason="tlac[human] is not installed")

from tlac.human.desk import Desk
from tlac.teachers.human import (
    AdviceLog,
    HumanTeacher,
    ReplayTeacher,
    decode_state,
    read_advice,
)

ROOT = Path(__file__).resolve().parent.parent
TOKEN = "test-token"
PORT = 8123
BASE = f"http://127.0.0.1:{PORT}"
WS = f"ws://127.0.0.1:{PORT}"  # TestClient.websocket_connect ignores base_url


def client(desk: Desk):
    from tlac.human.server import Refusals, make_app

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from starlette.testclient import TestClient

        refusals = Refusals()
        return TestClient(make_app(desk, TOKEN, refusals), base_url=BASE), refusals


def ask_in_thread(desk: Desk, n: int = 1) -> tuple[threading.Thread, list]:
    out: list = []

    def run() -> None:
        out.extend(desk.ask_many([(None, 0, None)] * n))

    thread = threading.Thread(target=run)
    thread.start()
    return thread, out


def wait_for(condition, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.005)


def doorkey_states(n: int = 30, seed: int = 0) -> list[np.ndarray]:
    from tlac.domains.doorkey.env import make_doorkey_env

    env = make_doorkey_env()
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    states = []
    for _ in range(n):
        states.append(obs)
        obs, _, term, trunc, _ = env.step(int(rng.integers(6)))
        if term or trunc:
            obs, _ = env.reset()
    return states


# -- the token -------------------------------------------------------------------------------


def test_a_request_or_socket_without_the_token_is_refused():
    from starlette.websockets import WebSocketDisconnect

    desk = Desk(["left", "right"])
    c, refusals = client(desk)
    for url in ("/", "/?token=", "/?token=wrong", "/ws", "/nothing-here", f"/?t={TOKEN}"):
        assert c.get(url).status_code == 403, url
    page = c.get(f"/?token={TOKEN}")
    assert page.status_code == 200 and "tlac teach" in page.text
    assert "<script src" not in page.text and "cdn" not in page.text.lower()  # nothing fetched
    for url in ("/ws", "/ws?token=wrong", f"/ws?token={TOKEN}x"):
        with pytest.raises(WebSocketDisconnect), c.websocket_connect(WS + url) as ws:
            ws.receive_json()
    assert desk.connections == 0 and refusals.total >= 9
    with c.websocket_connect(f"{WS}/ws?token={TOKEN}") as ws:
        assert ws.receive_json() == {"type": "hello", "actions": ["left", "right"], "timeout": 10.0}
        assert desk.connections == 1
    wait_for(lambda: desk.connections == 0)


def test_a_request_or_socket_for_another_host_or_origin_is_refused(caplog):
    """DNS rebinding (a page of evil.example whose name now points at 127.0.0.1) sends its
    own Host; a cross-site page's WebSocket sends its own Origin: both refused, token or not."""
    from starlette.websockets import WebSocketDisconnect

    desk = Desk(["left", "right"])
    c, refusals = client(desk)
    good = f"/?token={TOKEN}"
    with caplog.at_level(logging.WARNING, logger="tlac.human"):
        for host in (f"127.0.0.1:{PORT}", f"localhost:{PORT}", f"LOCALHOST:{PORT}"):
            assert c.get(good, headers={"Host": host}).status_code == 200, host
        assert refusals.total == 0
        bad_hosts = [
            f"evil.example:{PORT}",
            "evil.example",
            "127.0.0.1",
            f"127.0.0.1:{PORT + 1}",
            f"127.0.0.2:{PORT}",
            f"localhost.evil.example:{PORT}",
            f"[::1]:{PORT}",
            "",
        ]
        for host in bad_hosts:
            page = c.get(good, headers={"Host": host})
            assert page.status_code == 403 and "Host" in page.text, host
            assert "tlac teach" not in page.text
        assert refusals.total == len(bad_hosts)
        ws_url = f"{WS}/ws?token={TOKEN}"
        for host in bad_hosts[:3]:
            with (
                pytest.raises(WebSocketDisconnect),
                c.websocket_connect(ws_url, headers={"Host": host}) as ws,
            ):
                ws.receive_json()
        bad_origins = [
            "http://evil.example",
            f"http://evil.example:{PORT}",
            f"https://127.0.0.1:{PORT}",
            f"http://127.0.0.1:{PORT + 1}",
            f"http://localhost:{PORT}",  # a page from the other name is another origin
            "null",
            "",
        ]
        for origin in bad_origins:
            with (
                pytest.raises(WebSocketDisconnect),
                c.websocket_connect(ws_url, headers={"Origin": origin}) as ws,
            ):
                ws.receive_json()
        assert desk.connections == 0
        assert refusals.total == len(bad_hosts) + 3 + len(bad_origins)
        # the page's own origin, and none (a client that is not a browser): let in
        for headers in (
            {"Origin": BASE},
            {},
            {"Host": f"localhost:{PORT}", "Origin": f"http://localhost:{PORT}"},
        ):
            with c.websocket_connect(ws_url, headers=headers) as ws:
                assert ws.receive_json()["type"] == "hello", headers
            wait_for(lambda: desk.connections == 0)
    assert refusals.total == len(bad_hosts) + 3 + len(bad_origins)
    assert not any(r.exc_info for r in caplog.records)
    assert "Traceback" not in caplog.text
    assert "Host: 'evil.example:8123' is not 127.0.0.1:8123 or localhost:8123" in caplog.text
    assert "refused a request: http Host: 'evil.example:8123'" in caplog.text
    assert "from the page" not in caplog.text  # requests, not the page's messages
    assert refusals.counts == {
        "http Host": len(bad_hosts),
        "websocket Host": 3,
        "websocket Origin": len(bad_origins),
    }


def test_the_real_server_refuses_a_rebound_host_and_a_cross_site_origin():
    """The same through uvicorn on 127.0.0.1 (the port is the one it bound)."""
    pytest.importorskip("websockets")
    import socket

    import httpx
    from websockets.exceptions import InvalidStatus
    from websockets.sync.client import connect

    from tlac.human.server import PageServer

    desk = Desk(["a", "b"], timeout=5.0)
    server = PageServer(desk)
    url = server.start()
    try:
        assert httpx.get(url).status_code == 200
        assert httpx.get(url, headers={"Host": f"evil.example:{server.port}"}).status_code == 403
        ws_url = url.replace("http://", "ws://").replace("/?token=", "/ws?token=")
        with pytest.raises(InvalidStatus):
            connect(ws_url, origin="http://evil.example").close()
        with socket.create_connection(("127.0.0.1", server.port), timeout=5) as raw:
            raw.sendall(  # a rebound page's handshake: its own host name, and the token
                f"GET /ws?token={server.token} HTTP/1.1\r\nHost: evil.example:{server.port}\r\n"
                "Upgrade: websocket\r\nConnection: Upgrade\r\n"
                "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n".encode()
            )
            assert raw.recv(1024).startswith(b"HTTP/1.1 403")
        with connect(ws_url, origin=f"http://127.0.0.1:{server.port}") as ws:
            assert json.loads(ws.recv(timeout=5))["type"] == "hello"
        assert server.refusals.total == 3
    finally:
        server.stop()


# -- malformed, forged and flooding messages -------------------------------------------------


def test_forged_action_ids_and_malformed_messages_are_refused(caplog):
    desk = Desk(["left", "right", "forward"], timeout=5.0)
    c, refusals = client(desk)
    with (
        caplog.at_level(logging.WARNING, logger="tlac.human"),
        c.websocket_connect(f"{WS}/ws?token={TOKEN}") as ws,
    ):
        ws.receive_json()
        thread, answers = ask_in_thread(desk)
        question = ws.receive_json()
        assert question["type"] == "question"
        qid = question["id"]
        bad = [
            {"type": "answer", "id": qid, "action": 3},  # out of range
            {"type": "answer", "id": qid, "action": -1},
            {"type": "answer", "id": qid, "action": 1.0},
            {"type": "answer", "id": qid, "action": True},
            {"type": "answer", "id": qid, "action": "1"},
            {"type": "answer", "id": qid + 1000, "action": 1},  # forged question
            {"type": "answer", "id": qid, "action": 1, "extra": 1},
            {"type": "answer", "id": qid},
            {"type": "shutdown"},
            [1, 2, 3],
            "null",
        ]
        for message in bad:
            ws.send_text(json.dumps(message))
        ws.send_text("{not json")
        ws.send_text("x" * 5000)
        ws.send_bytes(b"\x00\x01")
        time.sleep(0.2)
        assert thread.is_alive() and desk.stats["answered"] == 0
        ws.send_text(json.dumps({"type": "answer", "id": qid, "action": 2}))
        thread.join(5)
    assert answers == [(2, answers[0][1])]
    assert refusals.total == 14
    # counted by a fixed set of reasons; the details are in the log only
    assert refusals.counts == {
        "bad value": 5,
        "not pending": 1,
        "fields": 2,
        "unknown type": 1,
        "not an object": 2,
        "not JSON": 1,
        "too long": 1,
        "not text": 1,
    }
    assert "refused a message from the page: action 3 is not one of the 3 actions" in caplog.text
    assert not any(r.exc_info for r in caplog.records)
    assert "Traceback" not in caplog.text


def test_refusals_are_counted_by_a_fixed_set_of_reasons():
    """The page's own text (a type, an action, a question id) never becomes a key."""
    from tlac.human.server import MESSAGE_REASONS, Refusals, parse_message

    refusals = Refusals()
    for i in range(300):
        for text in (
            json.dumps({"type": f"type{i}"}),
            json.dumps({"type": "answer", "id": 1, "action": 10 + i}),
            json.dumps({"type": "answer", "id": i, "action": 1, f"x{i}": 0}),
        ):
            message, reason, why = parse_message(text, 3)
            assert message is None and why
            refusals.refuse(reason, why)
    assert refusals.counts == {"unknown type": 300, "bad value": 300, "fields": 300}
    assert set(refusals.counts) <= set(MESSAGE_REASONS)
    with pytest.raises(ValueError):
        refusals.refuse("type0", "not a reason")


def test_a_flood_of_10000_messages_is_refused_without_changing_anything(caplog):
    desk = Desk(["a", "b"], timeout=30.0)
    c, refusals = client(desk)
    with (
        caplog.at_level(logging.WARNING, logger="tlac.human"),
        c.websocket_connect(f"{WS}/ws?token={TOKEN}") as ws,
    ):
        ws.receive_json()
        thread, answers = ask_in_thread(desk)
        qid = ws.receive_json()["id"]
        forged = json.dumps({"type": "answer", "id": qid, "action": 7})
        for _ in range(10_000):
            ws.send_text(forged)
        ws.send_text(json.dumps({"type": "here"}))  # the socket still reads
        wait_for(lambda: refusals.total >= 10_000, 60)
        assert thread.is_alive() and desk.stats["answered"] == 0
        time.sleep(0.1)  # the rate limit refills
        ws.send_text(json.dumps({"type": "answer", "id": qid, "action": 1}))
        thread.join(10)
    assert answers[0][0] == 1
    assert 10_000 <= refusals.total <= 10_001  # (the "here" may fall in the flood too)
    assert len(caplog.records) < 30  # the first few in full, then one line per thousand
    assert not any(r.exc_info for r in caplog.records)


def test_a_flood_of_valid_messages_is_cut_to_the_rate_limit():
    """Valid ``here`` messages, 2,000 at once: the rate limiter, not the parser, refuses the
    flood; the desk sees at most about BURST + RATE * seconds of them."""
    from tlac.human.server import BURST, RATE

    desk = Desk(["a", "b"], timeout=30.0)
    seen: list[float] = []
    here = desk.here
    desk.here = lambda: (seen.append(time.monotonic()), here())[1]
    c, refusals = client(desk)
    with c.websocket_connect(f"{WS}/ws?token={TOKEN}") as ws:
        ws.receive_json()
        start = time.monotonic()
        message = json.dumps({"type": "here"})
        for _ in range(2000):
            ws.send_text(message)
        wait_for(lambda: len(seen) + refusals.total >= 2000, 60)
        seconds = time.monotonic() - start
    assert refusals.counts["flood"] > 0 and refusals.total == 2000 - len(seen)
    assert len(seen) <= BURST + RATE * seconds + 2


# -- the desk ----------------------------------------------------------------------------------


def test_a_full_outbox_drops_progress_reports_first_and_questions_last():
    import asyncio

    from tlac.human.server import OUTBOX, Outbox

    box = Outbox()
    box.put({"type": "question", "id": 0})
    for i in range(OUTBOX + 50):  # a page that reads nothing, a run that reports on
        box.put({"type": "progress", "step": i})
    box.put({"type": "question", "id": 1})
    kinds = [m["type"] for m in box.items]
    assert len(kinds) == OUTBOX and kinds[0] == "question" and kinds[-1] == "question"
    assert [m["step"] for m in box.items if m["type"] == "progress"][-1] == OUTBOX + 49
    small = Outbox(3)
    for message in ({"type": "question", "id": 0}, {"type": "answered"}, {"type": "question"}):
        small.put(message)
    small.put({"type": "question", "id": 3})  # no progress: the other kind gives way
    assert [m["type"] for m in small.items] == ["question", "question", "question"]
    small.put({"type": "question", "id": 4})  # nothing but questions: the oldest gives way
    assert [m.get("id") for m in small.items] == [None, 3, 4]

    async def drain() -> list:
        got = [await small.get() for _ in range(3)]
        waiting = asyncio.create_task(small.get())
        await asyncio.sleep(0.01)
        small.put({"type": "finished"})
        return [*got, await asyncio.wait_for(waiting, 1)]

    assert [m["type"] for m in asyncio.run(drain())][-1] == "finished"


def test_desk_timeout_counts_the_person_absent_and_a_closed_tab_withdraws():
    desk = Desk(["a", "b"], timeout=0.05, away_seconds=0.3)
    assert desk.ask(None, 0) == (None, None) and desk.stats["asked"] == 0  # no page: not asked
    seen: list = []
    key = desk.subscribe(seen.append)
    assert desk.present()
    start = time.monotonic()
    assert desk.ask(None, 1) == (None, None)
    assert time.monotonic() - start < 1.0
    assert desk.stats["timed_out"] == 1 and not desk.present()  # away after a timeout
    assert [m["type"] for m in seen][-2:] == ["question", "withdrawn"]
    desk.here()  # the page says something: back
    assert desk.present()
    desk.timeout = 30.0
    thread, answers = ask_in_thread(desk, 3)
    wait_for(lambda: len(desk._pending) == 3)
    start = time.monotonic()
    desk.unsubscribe(key)  # the last tab closes: every question is withdrawn at once
    thread.join(5)
    assert answers == [(None, None)] * 3 and time.monotonic() - start < 1.0
    assert not desk.present()


def test_a_tab_closing_between_the_check_and_the_post_does_not_stall_the_run():
    """The last tab closes after ``ask_many`` saw the person present, before it posts: the
    check under the lock finds nobody, nothing is posted, and the run does not wait."""

    class Racing(Desk):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.checks = 0

        def present(self) -> bool:
            self.checks += 1
            if self.checks == 1:  # the check outside the lock: the tab is still open...
                self.unsubscribe(self.key)  # ... and closes right after it
                return True
            return super().present()

    desk = Racing(["a", "b"], timeout=3.0)
    desk.key = desk.subscribe(lambda message: None)
    start = time.monotonic()
    assert desk.ask_many([(None, 0, None)] * 2) == [(None, None)] * 2
    assert time.monotonic() - start < 1.0 and desk.stats["asked"] == 0


def test_a_page_whose_server_loop_ended_is_unsubscribed_not_raised():
    desk = Desk(["a", "b"], timeout=0.05)

    def dead(message: dict) -> None:  # call_soon_threadsafe on a closed loop
        raise RuntimeError("Event loop is closed")

    desk.subscribe(lambda message: None)
    key = next(iter(desk._listeners))
    desk._listeners[key] = dead
    desk.progress({"step": 1})  # no RuntimeError into the training thread
    assert desk.connections == 0 and not desk._listeners


def test_human_teacher_without_an_answer_plays_the_students_guess():
    import gymnasium as gym

    teacher = HumanTeacher(gym.spaces.Discrete(3))
    teacher.guess = lambda obs: np.full(len(obs), 2)
    obs = np.zeros((2, 4), dtype=np.uint8)
    assert teacher.predict(obs).tolist() == [2, 2]  # no desk: the student's own guess
    assert not teacher.presence(obs).any()
    teacher.desk = Desk(["a", "b", "c"], timeout=0.05)
    answered: list = []

    def person(message: dict) -> None:  # answers the first question only
        if message["type"] == "question" and not answered:
            answered.append(teacher.desk.answer(message["id"], 0))

    teacher.desk.subscribe(person)
    assert teacher.presence(obs).all()
    assert teacher.predict(np.array([[1, 0, 0, 0], [2, 0, 0, 0]], dtype=np.uint8)).tolist() == [
        0,
        2,
    ]
    probs = teacher.action_probabilities(np.array([[1, 0, 0, 0], [2, 0, 0, 0]], dtype=np.float32))
    assert probs.round(3).tolist() == [[1.0, 0.0, 0.0], [0.333, 0.333, 0.333]]


# -- advice.csv and its replay ---------------------------------------------------------------


def test_advice_csv_round_trip_and_the_replay_reproduces_the_answers(tmp_path):
    import gymnasium as gym

    from tlac.domains.doorkey.planner import DoorKeyOptimalTeacher

    states = doorkey_states(40)
    optimal = DoorKeyOptimalTeacher()
    person = optimal.predict(np.stack(states))
    log = AdviceLog(tmp_path / "advice.csv")
    for step, (state, action) in enumerate(zip(states, person, strict=True)):
        log.write(step, state, int(action), 0.5 + step, "ask")
    log.close()
    rows = read_advice(tmp_path)
    assert len(rows) == len(states)
    for row, state, action in zip(rows, states, person, strict=True):
        assert row["state"].dtype == state.dtype and np.array_equal(row["state"], state)
        assert row["action"] == action
    replay = ReplayTeacher(tmp_path, gym.spaces.Discrete(6), seed=0)
    batch = np.stack(states)
    assert replay.predict(batch).tolist() == person.tolist()
    assert replay.predict(batch.astype(np.float32)).tolist() == person.tolist()  # update's rows
    assert replay.presence(batch).all()
    unseen = batch[:1].copy()
    unseen[0, 0] = 99
    assert not replay.presence(unseen).any()
    assert replay.action_probabilities(unseen).round(3).tolist() == [[0.167] * 6]
    with pytest.raises(ValueError):
        decode_state("object:1:AAAA")


def test_a_resume_keeps_the_answers_asked_before_the_checkpoint_only(tmp_path):
    """advice.csv's ``step`` is the run's step before the transition: an answer at the
    checkpoint's step (a rollout's end) was asked in the next rollout, which the resumed run
    plays again; it is dropped (asked again), where episodes.csv keeps its row at that step
    (its timestep is the step after the transition)."""
    from tlac.run import _keep_rows_of_checkpoint

    state = np.zeros(3, dtype=np.uint8)
    log = AdviceLog(tmp_path / "advice.csv")
    for step in (126, 127, 128, 129):
        log.write(step, state, 1, 0.5, "ask")
    log.close()
    (tmp_path / "episodes.csv").write_text("timestep,return,length\n127,1,5\n128,1,5\n129,1,5\n")
    _keep_rows_of_checkpoint(tmp_path, 128)
    assert [r["step"] for r in read_advice(tmp_path)] == [126, 127]
    assert (tmp_path / "episodes.csv").read_text().count("\n") == 3  # header, 127, 128


def test_replay_teacher_parses_as_a_domain_teacher(tmp_path):
    from tlac.domains import get_domain, make_teachers
    from tlac.errors import ConfigError

    domain = get_domain("doorkey")
    with pytest.raises(ConfigError, match="does not exist"):
        make_teachers(domain, [f"replay:{tmp_path / 'none'}"], domain.make_env(), 0)
    log = AdviceLog(tmp_path / "advice.csv")
    log.write(0, doorkey_states(1)[0], 2, 1.0, "ask")
    log.close()
    teachers = make_teachers(domain, ["optimal", f"replay:{tmp_path}"], domain.make_env(), 0)
    assert [t.name for t in teachers] == ["optimal", "replay"]


# -- latency -----------------------------------------------------------------------------------


def test_a_question_reaches_the_page_within_200_ms():
    """From the desk's post (the training thread) to a WebSocket client on 127.0.0.1 through
    uvicorn (benchmarks/human_overhead.py's measurement): the median of 20 questions under
    200 ms (and each under 1 s on a loaded host)."""
    pytest.importorskip("websockets")
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import human_overhead

    latency = human_overhead.question_latency(20)
    print(f"question latency: median {latency['median_ms']:.1f} ms, max {latency['max_ms']:.1f} ms")
    assert latency["median_ms"] < 200 and latency["max_ms"] < 1000


# -- a run with a scripted person ------------------------------------------------------------


class ScriptedPerson:
    """Answers every question at the desk with the optimal DoorKey action, in process."""

    def __init__(self, desk: Desk):
        from tlac.domains.doorkey.planner import DoorKeyOptimalTeacher

        self.desk, self.teacher, self.answers = desk, DoorKeyOptimalTeacher(), 0

    def __call__(self, message: dict) -> None:
        if message["type"] == "question":
            state = decode_state(message["state"])
            action = int(self.teacher.predict(state[None])[0])
            self.answers += self.desk.answer(message["id"], action)


def teach_run(
    tmp_path: Path,
    steps: int,
    takeover: bool = False,
    person: bool = True,
    env: str = "doorkey",
    **overrides,
):
    from tlac.cli.teach import with_teach_defaults
    from tlac.human.session import TeachSession, action_names, drawn_run
    from tlac.run import RunSpec, resolve_run, train_run

    spec = RunSpec(
        env=env,
        teachers=["human", "random"],
        steps=steps,
        overrides=with_teach_defaults({"advice_budget": 300, **overrides}),  # as tlac teach
        eval_episodes=2,
    )
    run = drawn_run(resolve_run(spec))  # as tlac teach makes it
    probe = run.domain.make_env()
    session = TeachSession(action_names(probe), serve=False, timeout=5.0)
    probe.close()
    scripted = ScriptedPerson(session.desk)
    if person:
        session.desk.subscribe(scripted)
    if takeover:
        session.desk.request_takeover(True)
    with session:
        result = train_run(
            run, tmp_path / "run", on_model=session.on_model, on_eval=session.on_eval
        )
    return result, scripted, session


@pytest.mark.parametrize("variant", ["graduate", "paper"])
def test_a_run_with_a_scripted_person_writes_its_answers_and_a_take_over(tmp_path, variant):
    """The take-over goes through ``model.episode_leader`` (the session), a teacher-led
    episode in the graduate variant, the high level's choice forced in the paper variant."""
    result, person, session = teach_run(tmp_path, 800, takeover=True, variant=variant)
    assert session.model.episode_leader is None  # the closed session took its hook off
    assert (session.model.solo is None) == (variant == "paper")
    run = tmp_path / "run"
    assert result["finished"] and person.answers > 0
    rows = read_advice(run)
    assert len(rows) == person.answers == result["advice"]["teachers"]["human"]["acted"]
    assert all(r["seconds"] >= 0 for r in rows)
    with (run / "human_episodes.csv").open() as f:
        led = list(csv.DictReader(f))
    assert led and led[0]["led_by"] == "human" and led[0]["completed"] == "1"
    start, end, length = int(led[0]["start_step"]), int(led[0]["timestep"]), int(led[0]["length"])
    assert start == 0 and end - start == length
    # every state of that episode was the person's, and no other row is a take-over's
    takeover_steps = [r["step"] for r in rows if r["mode"] == "takeover"]
    assert takeover_steps == list(range(start, end))
    # the episode is the run's first in episodes.csv, of the same length
    with (run / "episodes.csv").open() as f:
        episodes = list(csv.DictReader(f))
    index = int(led[0]["episode"]) - 1
    assert int(episodes[index]["timestep"]) == end
    assert int(episodes[index]["length"]) == length
    assert float(episodes[index]["return"]) > 0  # the optimal person reached the goal
    # the answers replayed: a recorded teacher gives the person's actions in those states
    import gymnasium as gym

    replay = ReplayTeacher(run, gym.spaces.Discrete(6))
    states = np.stack([r["state"] for r in rows])
    assert replay.predict(states).tolist() == [r["action"] for r in rows]


@pytest.mark.parametrize("variant", ["graduate", "paper"])
def test_a_take_over_with_several_environments_is_the_first_ones_episode(tmp_path, variant):
    """With 2 environments, the take-over's row counts the first environment's steps, reads
    its own episode's return and row of episodes.csv, and only its answers are ``takeover``
    (the other environment's questions in the meantime are ``ask``)."""
    result, _, session = teach_run(tmp_path, 600, takeover=True, variant=variant, n_envs=2)
    run = tmp_path / "run"
    assert result["finished"] and session.takeovers >= 1
    with (run / "human_episodes.csv").open() as f:
        led = list(csv.DictReader(f))
    assert led[0]["completed"] == "1"
    length, episode = int(led[0]["length"]), int(led[0]["episode"])
    rows = read_advice(run)
    takeover = [r for r in rows if r["mode"] == "takeover"]
    assert len(takeover) == length
    assert [r["step"] for r in takeover] == list(range(0, 2 * length, 2))
    with (run / "episodes.csv").open() as f:
        episodes = list(csv.DictReader(f))
    assert int(episodes[episode - 1]["length"]) == length
    assert int(episodes[episode - 1]["timestep"]) == int(led[0]["timestep"])
    assert float(episodes[episode - 1]["return"]) == pytest.approx(float(led[0]["return"]))
    assert float(led[0]["return"]) > 0


@pytest.mark.parametrize("variant", ["graduate", "paper"])
def test_a_take_over_the_budget_stops_ends_not_completed(tmp_path, variant):
    """The ledger stops the person's lead when the budget is spent: the take-over ends
    there (``completed`` 0, the steps the person led), and the page no longer shows it."""
    _, person, session = teach_run(tmp_path, 200, takeover=True, variant=variant, advice_budget=4)
    with (tmp_path / "run" / "human_episodes.csv").open() as f:
        led = list(csv.DictReader(f))
    assert len(led) == 1 and led[0]["completed"] == "0" and int(led[0]["length"]) == 4
    assert not session.leading and person.answers == 4


def test_with_nobody_at_the_page_the_person_is_never_asked(tmp_path):
    result, _, session = teach_run(tmp_path, 300, person=False)
    assert result["finished"] and session.desk.stats["asked"] == 0
    assert result["advice"]["teachers"]["human"]["answers"] == 0
    assert read_advice(tmp_path / "run") == []


def test_with_nobody_at_the_page_the_audition_ends_without_the_person(tmp_path):
    """The graduate variant's audition (teacher_episodes, presets/default.yaml) neither waits
    for the person to lead its episodes nor picks the person to lead one: with nobody at the
    page it ends, and the random teacher is judged."""
    result, _, session = teach_run(tmp_path, 1500, person=False, env="CartPole-v1")
    solo = session.model.solo
    assert result["finished"] and solo is not None and solo.teacher_share > 0
    assert not solo.auditioning
    assert solo.led_counts[0] == 0 and solo.led_counts[1] >= 3
    assert solo.outside.tolist() == [True, False]
    assert session.desk.stats["asked"] == 0


class FramesSeen:
    """Answers every question with action 0, keeping whether each came with a picture."""

    def __init__(self, desk: Desk):
        self.desk, self.frames, self.answers = desk, [], 0

    def __call__(self, message: dict) -> None:
        if message["type"] == "question":
            self.frames.append(message["frame"])
            self.answers += self.desk.answer(message["id"], 0)


def test_a_gymnasium_ids_question_carries_the_environments_picture(tmp_path):
    """tlac teach makes a Gymnasium id's environments with render_mode rgb_array: a CartPole
    question (2 environments: the frame found by the environment's index) has a PNG."""
    import gymnasium as gym

    from tlac.human.render import Framer
    from tlac.human.session import drawn_run
    from tlac.run import RunSpec, resolve_run

    run = drawn_run(resolve_run(RunSpec(env="CartPole-v1", teachers=["human", "random"])))
    env = run.domain.make_env()
    assert env.render_mode == "rgb_array"
    env.close()
    teacher = HumanTeacher(gym.spaces.Discrete(2))
    teacher.desk = Desk(["left", "right"], timeout=5.0)
    seen = FramesSeen(teacher.desk)
    teacher.desk.subscribe(seen)

    class Model:  # two CartPoles, observations that match no row (as under VecNormalize)
        env = DummyVecEnv([run.domain.make_env, run.domain.make_env])
        _last_obs = np.zeros((2, 4), dtype=np.float32)

    Model.env.reset()
    teacher.framer = Framer(Model())
    teacher.env_rows = np.array([1])
    assert teacher.predict(np.ones((1, 4), dtype=np.float32)).tolist() == [0]
    assert seen.frames and seen.frames[0].startswith("data:image/png;base64,")


# -- the command line ------------------------------------------------------------------------


@pytest.mark.parametrize(
    "argv, says",
    [
        (["teach", "doorkey", "--port", "70000"], "--port"),
        (["teach", "doorkey", "--timeout", "0"], "--timeout"),
        (["teach", "doorkey", "--teachers", "human,nobody"], "nobody"),
        (["teach", "doorkey", "--teachers", "replay:/no/such/run"], "does not exist"),
        (["teach", "doorkey", "--advice-budget", "-1"], "advice-budget"),
        (["teach", "hopper-bullet"], ""),
        (["train", "--teachers", "human,optimal"], "tlac teach"),
    ],
)
def test_bad_teach_input_is_one_line_and_status_2(argv, says, capsys, tmp_path):
    from tlac.cli import main

    if argv[0] == "teach":
        argv = [*argv, "--out", str(tmp_path / "x")]
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse's own refusals
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and says in err, err
    assert not (tmp_path / "x").exists()


@pytest.mark.parametrize(
    "argv, budget",
    [
        ([], 1000.0),  # DEFAULT_BUDGET
        (["--advice-budget", "7"], 7.0),
        (["--set", "advice_budget=5"], 5.0),
        (["--set", "advice={advice_budget: 6}"], 6.0),
        (["--set", "advice_budget=null"], None),
        (["--set", "advice_budget=5", "--advice-budget", "7"], 7.0),
    ],
)
def test_an_explicit_advice_budget_wins_over_the_default(argv, budget, monkeypatch, tmp_path):
    import tlac.run
    from tlac.cli import main
    from tlac.errors import ConfigError

    resolved = []
    real = tlac.run.resolve_run

    def resolve_then_stop(spec):
        resolved.append(real(spec))
        raise ConfigError("stop here")

    monkeypatch.setattr(tlac.run, "resolve_run", resolve_then_stop)
    assert main(["teach", "doorkey", *argv, "--out", str(tmp_path / "x")]) == 2
    assert resolved[0].settings.advice.advice_budget == budget


def test_import_tlac_imports_no_web_framework():
    import subprocess
    import sys

    code = (
        "import sys, tlac, tlac.teachers.human, tlac.human.desk, tlac.cli\n"
        "bad = [m for m in ('starlette', 'uvicorn', 'websockets') if m in sys.modules]\n"
        "print(bad)"
    )
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.stdout.strip() == "[]", out.stderr


# -- the slow tier: a scripted person in headless Chromium -----------------------------------


def _chromium() -> tuple[str | None, str | None]:
    browser = shutil.which("chromium") or shutil.which("chromium-browser")
    driver = shutil.which("chromedriver") or (
        "/usr/bin/chromedriver" if Path("/usr/bin/chromedriver").exists() else None
    )
    return browser, driver


@pytest.mark.slow
def test_a_scripted_person_in_headless_chromium_teaches_the_student(tmp_path):
    """A person in Chromium (Selenium) presses, for each question, the key of the optimal
    DoorKey action for the state the page shows. TLAC_HUMAN_STEPS steps (default 5,000); at
    3e5 steps, the student alone reaches 0.9 with at most 1,000 answers. Writes the docs'
    screenshot, docs/img/human-teacher.png."""
    pytest.importorskip("selenium", reason="selenium is not installed (pip install 'tlac[dev]')")
    browser, driver = _chromium()
    if browser is None or driver is None:
        pytest.skip(
            "Debian's chromium and chromium-driver are not installed (apt-get install chromium chromium-driver)"
        )
    from tlac.human.scripted import BrowserPerson
    from tlac.human.session import TeachSession, action_names
    from tlac.run import RunSpec, train_run

    steps = int(os.environ.get("TLAC_HUMAN_STEPS", "5000"))
    spec = RunSpec(
        env="doorkey",
        teachers=["human", "random"],
        steps=steps,
        overrides={"advice_budget": 1000},
        eval_every=max(steps // 15, 200),  # a few points on the page's plot by the screenshot
        eval_episodes=20 if steps >= 100_000 else 5,
    )
    from tlac.domains.doorkey.env import make_doorkey_env

    screenshot = ROOT / "docs" / "img" / "human-teacher.png"
    with TeachSession(action_names(make_doorkey_env()), timeout=10.0) as session:
        person = BrowserPerson(session.server.url, browser, driver, screenshot=screenshot)
        person.start()
        try:
            result = train_run(
                spec, tmp_path / "run", on_model=session.on_model, on_eval=session.on_eval
            )
        finally:
            person.stop()
    assert person.error is None, person.error
    rows = read_advice(tmp_path / "run")
    assert 0 < len(rows) <= 1000 and person.answers >= len(rows) * 0.9
    assert screenshot.exists() and screenshot.stat().st_size > 1000
    if steps >= 300_000:
        assert result["final_eval_mean"] >= 0.9


@pytest.mark.slow
def test_with_nobody_answering_the_page_costs_at_most_10_percent():
    """benchmarks/human_overhead.py: steps per CPU second of this process (every thread, the
    server's included) with the page and without, interleaved, the best of 3 each."""
    import importlib.util

    path = ROOT / "benchmarks" / "human_overhead.py"
    spec = importlib.util.spec_from_file_location("human_overhead", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    result = bench.overhead(steps=2000, repeats=3)
    print(json.dumps(result))
    assert result["asked"] == 0
    assert result["ratio_cpu"] >= 0.9


@pytest.mark.slow
def test_the_page_never_shows_the_previous_questions_picture():
    """A question without a frame clears the picture and says so, with a short observation's
    values (headless Chromium)."""
    pytest.importorskip("selenium", reason="selenium is not installed (pip install 'tlac[dev]')")
    browser, driver_path = _chromium()
    if browser is None or driver_path is None:
        pytest.skip("Debian's chromium and chromium-driver are not installed")
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.common.by import By

    from tlac.human.render import data_url
    from tlac.human.server import PageServer
    from tlac.teachers.human import encode_state

    desk = Desk(["left", "right"], timeout=20.0)
    server = PageServer(desk, port=0)
    url = server.start()
    options = webdriver.ChromeOptions()
    options.binary_location = browser
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(driver_path), options=options)
    try:
        driver.get(url)
        wait_for(lambda: desk.connections > 0, 10.0)
        red = data_url(np.full((4, 4, 3), [255, 0, 0], dtype=np.uint8))
        for frame, state in ((red, None), (None, encode_state(np.array([0.5, -1.0], np.float32)))):
            out: list = []
            thread = threading.Thread(
                target=lambda f=frame, s=state, o=out: o.extend(desk.ask_many([(f, 0, s)]))
            )
            thread.start()
            wait_for(lambda: len(desk._pending) == 1)
            qid = next(iter(desk._pending))
            wait_for(
                lambda q=qid: (
                    driver.find_element(By.ID, "frame").get_attribute("data-question") == str(q)
                ),
                10.0,
            )
            img = driver.find_element(By.ID, "frame")
            noframe = driver.find_element(By.ID, "noframe")
            if frame is not None:
                assert img.get_attribute("src") == red and not noframe.is_displayed()
            else:
                assert not img.get_attribute("src") and not img.is_displayed()
                assert noframe.is_displayed() and "0.500, -1" in noframe.text
            driver.find_element(By.ID, "action-1").click()
            thread.join(10)
            assert out == [(1, pytest.approx(out[0][1]))]
    finally:
        driver.quit()
        server.stop()
        desk.close()
