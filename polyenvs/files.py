"""Files written atomically, output directories checked before any work, and locked while a process writes them.

Every result file is written through :func:`atomic_path` (a hidden, gitignored temp file in the same folder,
renamed into place, with the usual file mode), so an interrupted run never leaves a half-written file under its
real name.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from polyenvs.errors import InputError

__all__ = [
    "LOCK_FILE",
    "atomic_path",
    "check_writable_directory",
    "directory_lock",
    "lock_holder",
    "temp_path_for",
    "write_json_atomic",
    "write_text_atomic",
]

#: Held (flock) by the process writing a run's directory (training, tuning); hidden and gitignored like every
#: temporary file.
LOCK_FILE = ".training.lock.tmp"


def check_writable_directory(directory: Path, flag: str, shown: Path | None = None) -> None:
    """``directory`` exists and we can create files in it, or it can be created: else an :class:`InputError`.

    Creates nothing: a non-existent directory is judged by its nearest existing ancestor, and writability by
    creating (and at once deleting) an anonymous file, which also works where permission bits do not tell
    (root, read-only or virtual file systems such as /proc).
    """
    directory = Path(directory)
    if directory.exists() and not directory.is_dir():
        raise InputError(f"{flag} {shown or directory}: {directory} is not a directory")
    existing = directory.absolute()
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(f"{flag} {shown or directory}: cannot create {directory}: {existing} is not a directory")
    try:
        with tempfile.TemporaryFile(dir=existing):
            pass
    except OSError as exc:
        raise InputError(f"{flag} {shown or directory}: cannot write in {existing}: {exc.strerror or exc}") from None


def temp_path_for(path: str | os.PathLike, keep_suffix: bool = False) -> Path:
    """A fresh temporary name next to ``path``: ``.NAME.<random>.tmp`` (hidden, and matched by ``.gitignore``).

    With ``keep_suffix`` the name ends in ``path``'s suffix too (``.NAME.<random>.tmp.mp4``), for writers that
    choose the format from the file name (ffmpeg).
    """
    path = Path(path)
    return path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp{path.suffix if keep_suffix else ''}"


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, keep_suffix: bool = False) -> Iterator[Path]:
    """Yield a new, empty temporary file next to ``path``; rename it onto ``path`` when the block succeeds.

    The temporary file is created with the usual mode (``0o666 & ~umask``, like ``open(path, "w")``), not
    ``mkstemp``'s 0600. If the block raises (or the process is interrupted), the temporary file is removed and
    ``path`` is left as it was. The parent directory is created if needed. ``keep_suffix``: see
    :func:`temp_path_for`.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        tmp = temp_path_for(path, keep_suffix)
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:  # pragma: no cover - 32 random bits collided
            continue
        os.close(fd)
        break
    try:
        yield tmp
        with open(tmp, "rb+") as fh:  # the data must be on disk before the rename makes it visible
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    """Write a file so that a crash never leaves it half-written (temp file in the same directory + rename)."""
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)


def write_json_atomic(path: str | os.PathLike, document: Any) -> None:
    write_text_atomic(path, json.dumps(document, indent=1) + "\n")


def lock_holder(directory: Path) -> str | None:
    """``"pid N"`` if another process holds ``directory``'s lock (is writing its run now), else None."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: no locking
        return None
    lock = Path(directory) / LOCK_FILE
    try:
        fd = os.open(lock, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        try:
            pid = lock.read_text().strip()
        except OSError:
            pid = ""
        return f"pid {pid}" if pid.isdigit() else "another process"
    finally:
        os.close(fd)  # releases the probe's lock, if it got it
    return None


@contextlib.contextmanager
def directory_lock(directory: Path, doing: str) -> Iterator[None]:
    """Hold ``directory``'s lock for the block (the kernel releases it when the process dies, however it ends); a
    directory another process holds raises :class:`InputError` ("... is being ``doing`` by pid N")."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows: no locking
        yield
        return
    lock = Path(directory) / LOCK_FILE
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise InputError(f"output directory {directory} is being {doing} by {lock_holder(directory)}") from None
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        try:
            yield
        finally:
            lock.unlink(missing_ok=True)  # while still held: a finished directory keeps no lock file
    finally:
        os.close(fd)
