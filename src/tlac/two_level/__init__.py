"""TL-AC, the Two-Level Actor-Critic using multiple teachers, in one package.

:mod:`~tlac.two_level.model` holds the model, :class:`TLAC`, composed of plain parts:
:mod:`~tlac.two_level.networks` (the stacked networks and what is computed from them),
:mod:`~tlac.two_level.collect` (Algorithm 1, lines 11-23), :mod:`~tlac.two_level.update`
(lines 5-9, top to bottom), :mod:`~tlac.two_level.fast` (the speed-ups, each beside the plain
formula it equals), :mod:`~tlac.two_level.persistence` (save / load),
:mod:`~tlac.two_level.config` (the settings). docs/architecture.md describes them."""

from tlac.two_level.config import VARIANT_DEFAULTS, TLACConfig
from tlac.two_level.model import TLAC

__all__ = ["TLAC", "VARIANT_DEFAULTS", "TLACConfig"]
