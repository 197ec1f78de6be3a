"""The compact form of an experiment folder's runs: ``DIR/runs.tar.xz``.

The reports read a handful of small text files from each run folder (:data:`KEPT_FILES`);
the rest of a folder (the model weights, ``monitor.csv`` which repeats ``episodes.csv``,
``progress.csv``, checkpoints, TensorBoard logs) is read by nothing once the grid is done.
``tlac results pack DIR`` (:mod:`tlac.experiments.packing`) puts exactly the kept files of
every run into one xz-compressed tar archive laid out as the folders were
(``runs/<name>/<file>``: ``tar -xJf DIR/runs.tar.xz -C DIR`` gives the folders back). The
archive is deterministic: the same runs always give the same bytes (:func:`archive_bytes`).

:class:`RunStore` is how everything that reads runs sees an experiment folder: a run folder
``DIR/runs/<name>/`` when there is one, else the archive's copy of that run. A packed run's
status follows the same rule as a folder's (:func:`~tlac.experiments.grid.status_of`).
"""

from __future__ import annotations

import io
import lzma
import tarfile
from collections.abc import Mapping
from pathlib import Path

from tlac.errors import ConfigError
from tlac.experiments.grid import ERROR_FILE, RUNS_DIR, run_dir, run_status, status_of
from tlac.run import RESULT_FILE

ARCHIVE_FILE = "runs.tar.xz"
KEPT_FILES = (
    "config.yaml",  # the run's settings: a resumed grid checks them (runner.spec_mismatch)
    "episodes.csv",  # training returns: every table and learning curve of the report
    "eval.csv",  # the student alone: the report's student columns and figure
    "teacher_usage.csv",  # teacher usage per region: the usage figures
    RESULT_FILE,  # present: the run finished (and its numbers)
    ERROR_FILE,  # present: the run failed (the report shows its last line)
)
"""The files of a run folder that the archive keeps; every other file is left out."""
XZ_PRESET = 6
"""xz compression level of the archive: xz's default. On these CSVs level 9 is no smaller
(results/doorkey-r1: 3,164,608 bytes at 9, 3,164,184 at 6) and takes some 7 times the memory."""

RunFiles = dict[str, bytes]
"""The kept files of one run: file name -> content."""


# --------------------------------------------------------------------------- writing


def _member(name: str, size: int | None) -> tarfile.TarInfo:
    """A tar header with nothing taken from the machine: a directory when ``size`` is None,
    else a regular file of ``size`` bytes; mtime 0, owner 0:0 without names, fixed modes."""
    info = tarfile.TarInfo(name)
    info.mtime = 0
    info.uid = info.gid = 0
    info.uname = info.gname = ""
    if size is None:
        info.type, info.mode = tarfile.DIRTYPE, 0o755
    else:
        info.type, info.mode, info.size = tarfile.REGTYPE, 0o644, size
    return info


def archive_bytes(runs: Mapping[str, Mapping[str, bytes]]) -> bytes:
    """The ``runs.tar.xz`` of ``runs`` (run name -> its files): ``runs/``, then per run in
    sorted order its folder and its files (sorted), with fixed headers (:func:`_member`), so
    that the same runs always give the same bytes. Only :data:`KEPT_FILES` are written."""
    buf = io.BytesIO()
    with tarfile.open(fileobj=buf, mode="w", format=tarfile.PAX_FORMAT) as tar:
        tar.addfile(_member(RUNS_DIR, None))
        for name in sorted(runs):
            tar.addfile(_member(f"{RUNS_DIR}/{name}", None))
            files = runs[name]
            for file in sorted(f for f in files if f in KEPT_FILES):
                data = files[file]
                tar.addfile(_member(f"{RUNS_DIR}/{name}/{file}", len(data)), io.BytesIO(data))
    return lzma.compress(buf.getvalue(), format=lzma.FORMAT_XZ, preset=XZ_PRESET)


def read_folder(folder: Path) -> RunFiles:
    """The kept files of the run folder ``folder`` (those it has); an unreadable one is a
    ConfigError naming it, so that packing never leaves a file out silently."""
    files: RunFiles = {}
    for file in KEPT_FILES:
        path = folder / file
        if not path.exists():
            continue
        try:
            files[file] = path.read_bytes()
        except OSError as exc:
            raise ConfigError(f"cannot read {str(path)!r}: {exc.strerror}") from None
    return files


# --------------------------------------------------------------------------- reading


def packed_status(files: RunFiles) -> str:
    """The status of a packed run from its kept files (all that a run's status depends on)."""
    return status_of(files.get(RESULT_FILE), ERROR_FILE in files, present=True)


def _run_and_file(member: tarfile.TarInfo) -> tuple[str | None, str | None] | None:
    """(run, file) of an archive member: (None, None) for ``runs/``, (run, None) for a run's
    folder, (run, file) for one of its files; None for anything else."""
    parts = member.name.split("/")
    if parts[0] != RUNS_DIR or len(parts) > 3 or any(p in ("", ".", "..") for p in parts):
        return None
    if len(parts) < 3:
        return (parts[1] if len(parts) == 2 else None, None) if member.isdir() else None
    return (parts[1], parts[2]) if member.isreg() else None


def read_archive(path: Path) -> dict[str, RunFiles]:
    """Every run packed in the archive ``path`` (run name -> its kept files); a damaged
    archive, or one with members other than ``runs/<run>/<file>``, is one ConfigError."""
    runs: dict[str, RunFiles] = {}
    try:
        with tarfile.open(path, mode="r:xz") as tar:
            for member in tar:
                where = _run_and_file(member)
                if where is None:
                    raise ConfigError(
                        f"{path}: unexpected member {member.name!r} "
                        f"(a runs archive holds {RUNS_DIR}/<run>/<file> only)"
                    )
                run, file = where
                if run is None:
                    continue
                files = runs.setdefault(run, {})
                if file in KEPT_FILES:
                    handle = tar.extractfile(member)
                    files[file] = handle.read() if handle is not None else b""
    except (tarfile.TarError, lzma.LZMAError, EOFError, OSError) as exc:
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ConfigError(f"{path}: not a readable runs archive ({reason})") from None
    return runs


class RunStore:
    """The runs of the experiment folder ``out``: run folders ``DIR/runs/<name>/`` and the runs
    packed in ``DIR/runs.tar.xz``. A run that has a folder is read from its folder only (the
    folder wins over the archive's copy); the archive is read once, when first needed."""

    def __init__(self, out: str | Path):
        self.out = Path(out)
        self.archive = self.out / ARCHIVE_FILE
        self._packed: dict[str, RunFiles] | None = None

    def packed(self) -> dict[str, RunFiles]:
        """The runs in ``DIR/runs.tar.xz`` (none when there is no archive)."""
        if self._packed is None:
            self._packed = read_archive(self.archive) if self.archive.exists() else {}
        return self._packed

    def folder(self, name: str) -> Path:
        return run_dir(self.out, name)

    def status(self, name: str) -> str:
        """``finished``, ``failed``, ``partial`` or ``missing``, as :func:`run_status` says of a
        folder; a run without a folder has the status of its copy in the archive."""
        folder = self.folder(name)
        if folder.exists():
            return run_status(folder)
        files = self.packed().get(name)
        return "missing" if files is None else packed_status(files)

    def read(self, name: str, file: str) -> bytes | None:
        """The content of one file of the run (None when it has no such file, or it cannot
        be read)."""
        folder = self.folder(name)
        if folder.exists():
            try:
                return (folder / file).read_bytes()
            except OSError:
                return None
        return self.packed().get(name, {}).get(file)

    def where(self, name: str, file: str | None = None) -> str:
        """Where the run (or one of its files) is, for messages: its folder's path, or the
        archive's path and the member's name."""
        folder = self.folder(name)
        if folder.exists() or name not in self.packed():
            return str(folder if file is None else folder / file)
        member = f"{RUNS_DIR}/{name}" + ("" if file is None else f"/{file}")
        return f"{self.archive}:{member}"
