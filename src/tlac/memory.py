"""Memory estimates checked before allocation: a setting that would need more memory than
the machine has (``net_arch_low: [1000000000000, 64]``, ``n_steps: 100000000``,
``buffer_size: 10000000000``) is one :class:`~tlac.errors.ConfigError` naming the setting and
what it would take, rather than an allocator's traceback or a machine that starts swapping.

>>> human_bytes(3 * 2**30)
'3.0 GiB'
>>> check_fits({"tiny": 10}, "lower it")  # no error: far below any machine's memory
>>> check_fits({"rollout (n_steps=10**20)": 4 * 10**20}, "lower n_steps")
Traceback (most recent call last):
tlac.errors.ConfigError: rollout (n_steps=10**20) would take about 347 EiB of memory,
more than this machine has available (...); lower n_steps
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Sequence
from pathlib import Path

from tlac.errors import ConfigError

FLOAT_BYTES = 4
"""float32, the dtype of every network and buffer tlac allocates."""


def human_bytes(n: float) -> str:
    """``3221225472`` -> ``'3.0 GiB'``."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024:
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1024
    return f"{n:.0f} EiB"


def _read_int(path: str, key: str | None = None) -> int | None:
    try:
        text = Path(path).read_text()
    except OSError:
        return None
    if key is None:
        value = text.strip()
        return int(value) if value.isdigit() else None
    for line in text.splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) * 1024  # /proc/meminfo counts kB
    return None


def available_bytes() -> int | None:
    """Memory this process may still allocate: the kernel's ``MemAvailable``, or less where a
    cgroup limit (a container) leaves less; None where neither can be read (then nothing is
    refused)."""
    limits = []
    meminfo = _read_int("/proc/meminfo", "MemAvailable")
    if meminfo is not None:
        limits.append(meminfo)
    cgroup_max = _read_int("/sys/fs/cgroup/memory.max")
    cgroup_used = _read_int("/sys/fs/cgroup/memory.current")
    if cgroup_max is not None and cgroup_used is not None:
        limits.append(max(0, cgroup_max - cgroup_used))
    if not limits and hasattr(os, "sysconf"):
        try:
            limits.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (ValueError, OSError):
            pass
    return min(limits) if limits else None


def check_fits(parts: dict[str, float], fix: str) -> None:
    """Raise ConfigError when the estimated sizes ``parts`` (what -> bytes) add up to more
    than :func:`available_bytes`; the message names the largest part and ``fix``."""
    total = sum(parts.values())
    available = available_bytes()
    if available is None or total <= available:
        return
    largest = max(parts, key=lambda k: parts[k])
    raise ConfigError(
        f"{largest} would take about {human_bytes(parts[largest])} of memory, more than this "
        f"machine has available ({human_bytes(available)}); {fix}"
    )


def mlp_params(in_dim: int, hidden: Sequence[int], out_dim: int) -> int:
    """Weights and biases of an MLP ``in_dim -> hidden... -> out_dim``."""
    widths = [int(in_dim), *(int(h) for h in hidden), int(out_dim)]
    return sum((a + 1) * b for a, b in itertools.pairwise(widths))


def network_bytes(n_params: int) -> int:
    """A network's memory while it trains: weights, gradients and Adam's two moments."""
    return 4 * FLOAT_BYTES * int(n_params)
