"""argparse value types shared by every ``tlac`` sub-command: each rejects bad input with a
message that names the value (argparse turns it into one line and exit status 2)."""

from __future__ import annotations

import argparse
import math

DEPLOY_MODES = ("greedy", "sampled", "choose")
"""How a run deploys its student (``tlac train --deploy``, ``tlac.run.RunSpec.deploy``):
greedy (``predict(deterministic=True)``), sampled (``predict``'s default, as SB3's), or
whichever of the two scores higher."""


def positive_int(text: str) -> int:
    """An integer >= 1; ``1e5`` style is accepted for step counts."""
    try:
        number = float(text) if "e" in text.lower() else int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if not math.isfinite(number) or number != int(number):
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    value = int(number)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    """An integer >= 0 (seeds, episode counts that may be zero)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a non-negative integer, got {text!r}")
    return value
