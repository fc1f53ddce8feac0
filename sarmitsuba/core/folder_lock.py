"""One output folder, one run: an exclusive lock on the folder a run writes into.

A run that writes into an output folder (``render``, ``focus --out``, ``preview``, the figures
of ``render --figures``) holds an exclusive, non-blocking ``flock`` on :data:`LOCK_FILE` inside
it from before any tracing until it ends, so that two runs into one folder cannot mix their
files (the raw data of one render beside the figures of another). A second run stops at once
with :class:`FolderInUseError`. The kernel releases the lock when the process ends, whatever
the way (``kill -9`` included), so a crashed run never blocks the folder.

While it holds the lock a run removes the staging folders (``.staging-*``,
:mod:`sarmitsuba.core.outputs`) a killed run left behind: no other run can be writing them.
The lock file is removed again when the run lets go of the folder, and so is the folder
itself when the run created it and it is still empty (a failed run leaves nothing behind).

The lock is held per process and counted: :func:`hold_folder` inside :func:`hold_folder`
(the command line around :func:`sarmitsuba.render` and its figures) takes it once.

>>> with hold_folder("out/urban"):           # doctest: +SKIP
...     render(...); redraw(...)             # a second process's hold_folder raises FolderInUseError
"""
from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path
from typing import Iterator

try:
    import fcntl
except ImportError:                                        # Windows: no lock, the runs are not guarded
    fcntl = None

__all__ = ["FolderInUseError", "LOCK_FILE", "STAGING_PREFIX", "hold_folder", "refuse_staging"]

#: The lock file inside an output folder (hidden: the folder's products are the visible files).
LOCK_FILE = ".sarmitsuba.lock"
#: Prefix of the staging folders of :class:`sarmitsuba.core.outputs.OutputDirectory`.
STAGING_PREFIX = ".staging-"

# resolved folder -> [open lock file descriptor, holds, folders created (deepest first)]
_HELD: dict[str, list] = {}


class FolderInUseError(OSError):
    """Another run holds the output folder's lock."""


@contextlib.contextmanager
def hold_folder(path: str | os.PathLike) -> Iterator[Path]:
    """Hold the lock of the output folder ``path`` (created when missing) for the with-block.

    Raises
    ------
    FolderInUseError
        Another process holds it: one line naming the folder, the other run's pid and the fix.
    OSError
        ``path`` is an existing file, or cannot be created or written, naming it.
    """
    folder = Path(path)
    key = os.path.realpath(folder)
    if key not in _HELD:
        _HELD[key] = [*_acquire(folder), 0]
    _HELD[key][2] += 1
    try:
        yield folder
    finally:
        entry = _HELD[key]
        entry[2] -= 1
        if entry[2] == 0:
            del _HELD[key]
            _release(folder, entry[0], entry[1])


def _acquire(folder: Path) -> tuple[int, list[Path]]:
    """Create ``folder`` if missing, lock it, remove its leftover staging folders; returns the
    lock file's descriptor and the folders created (deepest first)."""
    if folder.exists() and not folder.is_dir():
        raise OSError(f"output directory {str(folder)!r} is an existing file, not a directory: "
                      "give --out a directory path (new or existing)")
    created = [p for p in (folder, *folder.parents) if not p.exists()]
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd = _lock(folder / LOCK_FILE)
    except FolderInUseError:
        _remove_empty(created)
        raise
    except OSError as exc:
        _remove_empty(created)
        raise OSError(f"output directory {str(folder)!r} is not writable: {exc.strerror or exc}; "
                      "choose another --out") from None
    for leftover in folder.glob(STAGING_PREFIX + "*"):     # a killed run's: no run writes them now
        if leftover.is_dir() and not leftover.is_symlink():
            shutil.rmtree(leftover, ignore_errors=True)
    return fd, created


def _lock(lock_file: Path) -> int:
    """Open and lock ``lock_file``, writing this process's id into it; returns its descriptor.
    A lock file that another run removed while this one waited for it is opened again."""
    while True:
        fd = os.open(lock_file, os.O_RDWR | os.O_CREAT, 0o644)
        if fcntl is None:
            return fd
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            pid = os.read(fd, 32).decode("ascii", "replace").strip()
            os.close(fd)
            raise FolderInUseError(
                f"output directory {str(lock_file.parent)!r} is in use by another run"
                f"{f' (pid {pid})' if pid.isdigit() else ''}: wait for it to finish or choose another --out") from None
        except OSError:
            os.close(fd)
            raise
        try:
            same = os.fstat(fd).st_ino == os.stat(lock_file).st_ino
        except FileNotFoundError:
            same = False
        if same:                               # not a file the previous holder removed meanwhile
            os.ftruncate(fd, 0)
            os.write(fd, str(os.getpid()).encode())
            return fd
        os.close(fd)


def _release(folder: Path, fd: int, created: list[Path]) -> None:
    """Remove the lock file (still holding the lock), let go, and remove the folders this run
    created if they are empty."""
    with contextlib.suppress(OSError):
        (folder / LOCK_FILE).unlink()
    os.close(fd)
    _remove_empty(created)


def _remove_empty(folders: list[Path]) -> None:
    for path in folders:                       # deepest first; only while empty
        try:
            path.rmdir()
        except OSError:
            break


def refuse_staging(*paths: str | os.PathLike | None) -> None:
    """Raise OSError when a path lies in a staging folder (``.staging-*``): the leftover of a
    render that was killed before its files were moved into place, whose files may be partial
    or belong to no finished render. None entries are skipped."""
    for path in paths:
        if path is None:
            continue
        parts = Path(path).parts
        leftover = next((i for i, part in enumerate(parts) if part.startswith(STAGING_PREFIX)), None)
        if leftover is not None:
            folder = Path(*parts[:leftover]) if leftover else Path(".")
            raise OSError(f"{path} lies in {Path(*parts[:leftover + 1])}, the leftover of an interrupted "
                          f"run (killed before its files were moved into {str(folder)!r}): its files may be "
                          f"incomplete; use the files of {str(folder)!r} itself, or render again there (which "
                          "removes the leftover)")
