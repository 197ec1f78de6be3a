"""Frames for the page: an environment's ``rgb_array`` as a PNG (zlib only, no imaging
library), and the frame of a training environment whose state a question is about.

>>> png = png_bytes(np.zeros((2, 3, 3), dtype=np.uint8))
>>> png[:8] == b"\\x89PNG\\r\\n\\x1a\\n", len(png) > 40
(True, True)
"""

from __future__ import annotations

import base64
import struct
import zlib
from typing import Any

import numpy as np


def png_bytes(rgb: np.ndarray) -> bytes:
    """An ``(H, W, 3)`` (or ``(H, W, 4)``) uint8 image as PNG bytes."""
    img = np.ascontiguousarray(np.asarray(rgb, dtype=np.uint8))
    if img.ndim != 3 or img.shape[2] not in (3, 4):
        raise ValueError(f"expected an (H, W, 3) or (H, W, 4) image, got shape {img.shape}")
    height, width, channels = img.shape
    raw = b"".join(b"\x00" + img[y].tobytes() for y in range(height))  # filter 0 per row

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    colour = 2 if channels == 3 else 6
    header = struct.pack(">IIBBBBB", width, height, 8, colour, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw, 6))
        + chunk(b"IEND", b"")
    )


def data_url(rgb: np.ndarray | None) -> str | None:
    """The image as a ``data:image/png;base64,...`` URL (the page shows it as it is)."""
    if rgb is None:
        return None
    return "data:image/png;base64," + base64.b64encode(png_bytes(rgb)).decode("ascii")


def env_frame(env: Any) -> np.ndarray | None:
    """What one environment shows now, as ``rgb_array``: MiniGrid's full grid
    (``get_frame``, whatever the render mode it was made with), else ``render()`` where the
    environment was made to render ``rgb_array``; None where it cannot be drawn."""
    base = getattr(env, "unwrapped", env)
    get_frame = getattr(base, "get_frame", None)
    if callable(get_frame):
        try:
            return np.asarray(get_frame(highlight=False, tile_size=24))
        except TypeError:
            return np.asarray(get_frame())
    if getattr(env, "render_mode", None) == "rgb_array":
        frame = env.render()
        return None if frame is None else np.asarray(frame)
    return None


def vec_envs(venv: Any) -> list[Any] | None:
    """The environments of a (wrapped) in-process VecEnv, or None (subprocesses)."""
    inner = venv
    for _ in range(10):
        if hasattr(inner, "envs"):
            return list(inner.envs)
        inner = getattr(inner, "venv", None)
        if inner is None:
            return None
    return None


class Framer:
    """The frame of a training environment: the one numbered ``env`` where the teacher asked
    knows it (TL-AC's collection says: ``env_rows``), else the one whose current observation
    is ``obs`` (found by its bytes; none under a VecNormalize, whose observations differ)."""

    def __init__(self, model: Any):
        self.model = model
        self.envs = vec_envs(model.env)

    def frame(self, obs: np.ndarray, env: int | None = None) -> str | None:
        if not self.envs:
            return None
        if env is not None and 0 <= env < len(self.envs):
            return data_url(env_frame(self.envs[env]))
        last = getattr(self.model, "_last_obs", None)
        if isinstance(last, np.ndarray) and len(last) == len(self.envs):
            row = np.asarray(obs).reshape(-1)
            for i, other in enumerate(last):
                if np.array_equal(np.asarray(other).reshape(-1), row):
                    return data_url(env_frame(self.envs[i]))
        return data_url(env_frame(self.envs[0])) if len(self.envs) == 1 else None
