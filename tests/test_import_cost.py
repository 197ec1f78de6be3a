"""``import tlac`` is cheap: it registers the Gymnasium ids by entry-point strings and leaves
the public names to the package's lazy ``__getattr__``, so neither torch nor
stable-baselines3 is imported until a model or an environment is made."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

SRC = str(Path(__file__).resolve().parent.parent / "src")

HEAVY = ("torch", "stable_baselines3")


def run_python(code: str) -> str:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([SRC, os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=False
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.strip()


def test_import_tlac_imports_neither_torch_nor_sb3() -> None:
    out = run_python(
        "import sys, gymnasium as gym, tlac\n"
        f"print([m for m in {HEAVY!r} if m in sys.modules])\n"
        "print(gym.spec('tlac/DoorKey-v0').entry_point)"
    )
    heavy, entry_point = out.splitlines()
    assert heavy == "[]", f"import tlac imported {heavy}"
    assert entry_point == "tlac.domains.doorkey.env:make_doorkey_env"


def test_the_public_names_and_ids_still_load_on_use() -> None:
    out = run_python(
        "import sys, gymnasium as gym, tlac\n"
        "from tlac import TLAC, Domain, StudentEvalCallback, TLACConfig, register_domain\n"
        "assert TLAC is tlac.TLAC and TLAC.__name__ == 'TLAC'\n"
        "gym.make('tlac/DoorKey-v0').reset(seed=0)\n"
        "print('torch' in sys.modules, sorted(set(tlac.__all__) - set(dir(tlac))))"
    )
    assert out == "True []"
