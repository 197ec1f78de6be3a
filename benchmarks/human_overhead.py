"""A person as a teacher (issue 68): how fast a question reaches the page, and what the page
costs a run that nobody answers.

* **Latency**: from the desk's post (the training thread) to a WebSocket client on 127.0.0.1
  receiving the question through uvicorn, ``--questions`` times: median, 95th percentile and
  maximum. The issue's target: within 200 ms.
* **Overhead**: TL-AC on DoorKey with the teachers ``human`` and ``random`` and an advice
  budget of 1,000, ``--steps`` steps, with and without the page: ``page`` runs the server,
  the desk and the progress thread (tlac.human.session, nobody connected); ``plain`` has the
  same ``human`` teacher with no desk (never there). Nobody answers in either, so both runs
  compute exactly the same steps: the difference is the page's cost alone. Measured in CPU
  time of this process (``time.process_time``: every thread, the server's included), which a
  loaded machine changes far less than wall time; the repeats are interleaved and the best of
  ``--repeats`` kept for each. The issue's target: ``page`` at >= 90% of ``plain``'s steps/s.

    PYTHONPATH=src .venv/bin/python benchmarks/human_overhead.py --steps 4000 --repeats 3
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

BUDGET = 1000


def question_latency(n: int = 50) -> dict[str, float]:
    """Seconds from the desk's post to a WebSocket client's receipt, over ``n`` questions."""
    from websockets.sync.client import connect

    from tlac.human.desk import Desk
    from tlac.human.server import PageServer

    desk = Desk(["a", "b"], timeout=5.0)
    server = PageServer(desk)
    url = server.start()
    delays = []
    try:
        with connect(url.replace("http://", "ws://").replace("/?token=", "/ws?token=")) as ws:
            json.loads(ws.recv(timeout=5))  # hello
            while not desk.present():
                time.sleep(0.01)
            for _ in range(n):
                box: list[Any] = []
                posted = time.perf_counter()
                thread = threading.Thread(target=lambda box=box: box.append(desk.ask(None, 0)))
                thread.start()
                while True:
                    message = json.loads(ws.recv(timeout=5))
                    if message["type"] == "question":
                        break
                delays.append(time.perf_counter() - posted)
                ws.send(json.dumps({"type": "answer", "id": message["id"], "action": 1}))
                thread.join(5)
    finally:
        server.stop()
    delays.sort()
    return {
        "median_ms": statistics.median(delays) * 1e3,
        "p95_ms": delays[int(0.95 * (len(delays) - 1))] * 1e3,
        "max_ms": delays[-1] * 1e3,
        "questions": n,
    }


def _model(seed: int) -> Any:
    from tlac import TLAC

    return TLAC("doorkey", teachers=["human", "random"], advice_budget=BUDGET, seed=seed)


def timed_learn(steps: int, page: bool, seed: int = 0) -> dict[str, float]:
    """CPU and wall seconds of ``learn(steps)`` with (``page``) or without the page."""
    import torch

    torch.set_num_threads(1)
    model = _model(seed)
    session = None
    folder = tempfile.TemporaryDirectory()
    if page:
        from tlac.human.session import TeachSession

        session = TeachSession([f"a{i}" for i in range(6)])
        session.start()
        session.on_model(model, Path(folder.name))
    try:
        cpu, wall = time.process_time(), time.perf_counter()
        model.learn(steps)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    finally:
        if session is not None:
            session.close()
        folder.cleanup()
    asked = 0 if session is None else session.desk.stats["asked"]
    return {"cpu_s": cpu, "wall_s": wall, "asked": asked}


def overhead(steps: int = 4000, repeats: int = 3) -> dict[str, Any]:
    """Best-of-``repeats`` CPU steps/s with and without the page, interleaved."""
    runs: dict[str, list[dict[str, float]]] = {"plain": [], "page": []}
    timed_learn(500, page=False)  # warm up: imports, torch's first calls
    for _ in range(repeats):
        for name in ("plain", "page"):
            runs[name].append(timed_learn(steps, page=name == "page"))
    best = {name: min(r["cpu_s"] for r in rs) for name, rs in runs.items()}
    best_wall = {name: min(r["wall_s"] for r in rs) for name, rs in runs.items()}
    return {
        "steps": steps,
        "repeats": repeats,
        "plain_steps_per_cpu_s": steps / best["plain"],
        "page_steps_per_cpu_s": steps / best["page"],
        "ratio_cpu": best["plain"] / best["page"],
        "ratio_wall": best_wall["plain"] / best_wall["page"],
        "asked": max(r["asked"] for r in runs["page"]),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--steps", type=int, default=4000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--questions", type=int, default=50)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    result = {
        "latency": question_latency(args.questions),
        "overhead": overhead(args.steps, args.repeats),
    }
    if args.json:
        print(json.dumps(result, indent=2))
        return 0
    lat, ovh = result["latency"], result["overhead"]
    print(
        f"latency over {lat['questions']} questions: median {lat['median_ms']:.1f} ms, "
        f"p95 {lat['p95_ms']:.1f} ms, max {lat['max_ms']:.1f} ms (target 200 ms)"
    )
    print(
        f"overhead, {ovh['steps']} steps, best of {ovh['repeats']}: without the page "
        f"{ovh['plain_steps_per_cpu_s']:.0f} steps per CPU second, with it "
        f"{ovh['page_steps_per_cpu_s']:.0f}: {100 * ovh['ratio_cpu']:.1f}% "
        f"(wall time {100 * ovh['ratio_wall']:.1f}%; target >= 90%)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
