"""``tlac results pack DIR``: an experiment folder's run folders into one ``DIR/runs.tar.xz``.

Packing keeps, of every run folder ``DIR/runs/<name>/``, the files the reports read
(:data:`~tlac.experiments.archive.KEPT_FILES`), writes them into the deterministic archive
``DIR/runs.tar.xz`` (:func:`~tlac.experiments.archive.archive_bytes`), reads the new archive
back to check it holds exactly those files, and only then removes ``DIR/runs/``. The report,
``tlac experiment list`` and a resumed ``tlac experiment run`` read the archive directly, so
the study reads the same before and after.

A study packed earlier and grown since (new runs in a new ``DIR/runs/``) is packed again by
merging: the new archive holds the old archive's runs and the folders' runs, a folder winning
over the archive's copy of the same run, which is what the readers see before packing too.
Packing holds the folder's lock (``DIR/.lock``), so it never races a running grid.
"""

from __future__ import annotations

import os
import shutil
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from tlac.errors import ConfigError
from tlac.experiments.archive import (
    ARCHIVE_FILE,
    RunFiles,
    RunStore,
    archive_bytes,
    packed_status,
    read_archive,
    read_folder,
)
from tlac.experiments.grid import RUNS_DIR
from tlac.experiments.runner import EXPERIMENT_FILE, dir_lock

REMOVING_DIR = RUNS_DIR + ".packed"
"""``DIR/runs/`` is renamed to this just before it is deleted: a deletion that stops half-way
then leaves no half-deleted run folder that would win over the archive's complete copy."""


@dataclass
class PackSummary:
    """What one ``tlac results pack`` did."""

    archive: Path
    statuses: Counter[str] = field(default_factory=Counter)
    """Runs in the new archive, by status."""
    from_archive: int = 0
    """Runs kept from the earlier archive (no folder of theirs was packed now)."""
    from_folders: int = 0
    archive_size: int = 0
    removed_size: int = 0
    """Bytes of the removed ``DIR/runs/`` (every file, weights included)."""

    def line(self) -> str:
        if not self.from_folders:
            return f"{self.archive.parent}: nothing to pack (no run folder in {RUNS_DIR}/)"
        counts = ", ".join(f"{n} {status}" for status, n in sorted(self.statuses.items()))
        earlier = (
            f", {self.from_archive} of them from the earlier archive" if self.from_archive else ""
        )
        return (
            f"packed {sum(self.statuses.values())} runs ({counts}{earlier}) into {self.archive} "
            f"({self.archive_size:,} bytes); removed {self.archive.parent / RUNS_DIR}/ "
            f"({self.removed_size:,} bytes)"
        )


def check_study(out: Path) -> None:
    """A ConfigError unless ``out`` is an experiment folder (it has ``experiment.yaml``)."""
    if not out.is_dir():
        raise ConfigError(f"{str(out)!r} is not a folder; expected an experiment folder")
    if not (out / EXPERIMENT_FILE).is_file():
        raise ConfigError(
            f"{str(out)!r} is not an experiment folder ({EXPERIMENT_FILE} is missing); "
            "expected the --out folder of 'tlac experiment run'"
        )


def run_folders(out: Path) -> dict[str, Path]:
    """The run folders in ``DIR/runs/`` by name (none when it does not exist); anything else
    there is a ConfigError naming it, since packing removes ``DIR/runs/`` as a whole."""
    runs = out / RUNS_DIR
    if not runs.is_dir():
        return {}
    strays = sorted(p.name for p in runs.iterdir() if not p.is_dir())
    if strays:
        raise ConfigError(
            f"{str(runs / strays[0])!r} is not a run folder; move it out of {RUNS_DIR}/ "
            "before packing (packing removes the whole folder)"
        )
    return {p.name: p for p in sorted(runs.iterdir())}


def folder_size(folder: Path) -> int:
    """Bytes of every file under ``folder`` (their apparent sizes)."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file() and not p.is_symlink())


def write_archive(path: Path, runs: dict[str, RunFiles]) -> int:
    """Write the archive of ``runs`` to ``path`` atomically, after checking that the written
    file reads back as exactly ``runs``; returns its size. Nothing is replaced on failure."""
    tmp = path.with_name(path.name + ".tmp")
    data = archive_bytes(runs)
    tmp.write_bytes(data)
    if read_archive(tmp) != runs:
        tmp.unlink()
        raise ConfigError(f"{path}: the new archive does not read back as written; nothing changed")
    os.replace(tmp, path)
    return len(data)


def pack_study(out_dir: str | Path) -> PackSummary:
    """Pack the run folders of the experiment folder ``out_dir`` (merged with its earlier
    ``runs.tar.xz``, a folder winning) into ``runs.tar.xz`` and remove ``runs/``; with no run
    folder, change nothing. See the module's docstring."""
    out = Path(out_dir)
    check_study(out)
    summary = PackSummary(archive=out / ARCHIVE_FILE)
    with dir_lock(out):
        folders = run_folders(out)
        if not folders:
            return summary
        runs = dict(RunStore(out).packed())
        summary.from_archive = len(set(runs) - set(folders))
        summary.from_folders = len(folders)
        runs.update({name: read_folder(folder) for name, folder in folders.items()})
        summary.statuses = Counter(packed_status(files) for files in runs.values())
        summary.archive_size = write_archive(summary.archive, runs)
        summary.removed_size = folder_size(out / RUNS_DIR)
        removing = out / REMOVING_DIR
        if removing.exists():  # left by a pack that stopped while deleting: already archived
            shutil.rmtree(removing)
        os.replace(out / RUNS_DIR, removing)
        shutil.rmtree(removing)
    return summary
