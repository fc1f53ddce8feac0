"""Output directories that are all or nothing (docs/design.md section 3, "Files").

A run (``render``, ``focus``, ``preview``) writes its files into a hidden staging folder inside
the output directory and moves them into place only when every file is written. A run that
fails (bad input found late, a full disk, Ctrl-C) removes its staging folder and any directory
it created, so it leaves neither half-written files nor empty directories behind, and a disk
error names the file the user asked for, not an internal temporary name. A failure between
two of the final moves takes the moved files back out (earlier files of the same names that
they replaced are lost).

>>> with OutputDirectory("out/urban") as out:          # doctest: +SKIP
...     out.write("raw.npz", raw.save)                  # written to out/urban/.staging-*/raw.npz
... # here, and only here, out/urban/raw.npz appears
"""
from __future__ import annotations

import errno
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np

__all__ = ["OutputDirectory", "WriteError", "atomic_savez", "atomic_write", "check_output_dir", "json_default"]


class OutputDirectory:
    """Context manager for one run's output directory.

    Parameters
    ----------
    path : path-like
        The directory the user named (``--out``). It is created when missing (with its missing
        parents) and removed again if the run fails and it is still empty.

    Raises
    ------
    OSError
        On entry, naming ``path``: it is an existing file, or it cannot be created or written.
        From :meth:`write`, naming the final file: the writer failed (for instance ``[Errno 28]``
        no space left on device).
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self.path = Path(path)
        self._created: list[Path] = []
        self._staging: Path | None = None
        self._written: list[str] = []

    def __enter__(self) -> "OutputDirectory":
        if self.path.exists() and not self.path.is_dir():
            raise OSError(f"output directory {str(self.path)!r} is an existing file, not a directory: "
                          "give --out a directory path (new or existing)")
        missing = [p for p in (self.path, *self.path.parents) if not p.exists()]
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            self._created = missing                         # deepest first
            self._staging = Path(tempfile.mkdtemp(prefix=".staging-", dir=self.path))
        except OSError as exc:
            self._remove_created()
            raise OSError(f"output directory {str(self.path)!r} is not writable: {exc.strerror or exc}; "
                          "choose another --out") from None
        return self

    def write(self, name: str, writer: Callable[[Path], Any]) -> Path:
        """Call ``writer(staged_path)`` for the file ``name``; returns its final path.

        Raises OSError naming the final path (``self.path / name``) when the writer fails.
        """
        if self._staging is None:
            raise RuntimeError("OutputDirectory.write outside its with-block")
        final = self.path / name
        try:
            writer(self._staging / name)
        except OSError as exc:
            reason = exc.strerror or str(exc)
            hint = ("free some space or choose another --out" if exc.errno in (errno.ENOSPC, errno.EDQUOT)
                    else "check the permissions, or choose another --out")
            raise OSError(f"cannot write {final}: {reason} ({hint}); nothing was written to "
                          f"{str(self.path)!r}") from None
        self._written.append(name)
        return final

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is not None:
            self.abandon()
            return
        moved: list[Path] = []
        try:
            for name in self._written:
                os.replace(self._staging / name, self.path / name)
                moved.append(self.path / name)
        except BaseException:            # Ctrl-C between two renames: take the moved ones back out
            for path in moved:
                path.unlink(missing_ok=True)
            self.abandon()
            raise
        shutil.rmtree(self._staging, ignore_errors=True)
        self._staging = None

    def abandon(self) -> None:
        """Remove the staged files, and the directories this run created if they are empty."""
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
            self._staging = None
        self._remove_created()

    def _remove_created(self) -> None:
        for folder in self._created:                      # deepest first; only if still empty
            try:
                folder.rmdir()
            except OSError:
                break


def check_output_dir(out_dir: str | os.PathLike) -> Path:
    """Check that ``out_dir`` is (or can be) a writable directory, leaving nothing behind.

    Returns ``Path(out_dir)``. Raises OSError naming the directory and the fix. A directory
    this call had to create is removed again: the run that follows creates it when it writes.
    """
    out = OutputDirectory(out_dir).__enter__()
    out.abandon()
    return out.path


class WriteError(OSError):
    """A product could not be written: names the file asked for, never the temporary one.

    ``errno`` and ``strerror`` are those of the underlying error; ``filename`` is the target
    path and ``what`` says what it is (``"figure"``, ``"quicklook"``, ...). ``str()`` reads
    ``cannot write figure /ro/fig.png: Permission denied (check the folder's permissions or
    choose another path)``.
    """

    what = "file"
    _HINTS = {errno.EACCES: "check the folder's permissions or choose another path",
              errno.EPERM: "check the folder's permissions or choose another path",
              errno.EROFS: "the file system is read-only: choose another path",
              errno.ENOENT: "its folder does not exist: create it or choose another path",
              errno.ENOTDIR: "a part of the path is a file, not a folder",
              errno.EISDIR: "it is a folder: give a file name",
              errno.ENOSPC: "free some space or choose another path"}

    def __str__(self) -> str:
        hint = self._HINTS.get(self.errno)
        return f"cannot write {self.what} {self.filename}: {self.strerror}" + (f" ({hint})" if hint else "")


def atomic_write(path: Path, write: Callable[[Path], Any], what: str = "file") -> Path:
    """Call ``write(tmp)`` for a temporary name beside ``path``, then rename it to ``path``.

    On any failure the temporary file is removed; an OSError comes back as :class:`WriteError`
    naming ``path`` (described as ``what``), not the temporary name.
    """
    tmp = path.with_name(f".{path.name}.partial")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException as exc:
        tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError) and not isinstance(exc, WriteError):
            error = WriteError(exc.errno, exc.strerror or str(exc), str(path))
            error.what = what
            raise error from None
        raise
    return path


def json_default(obj: Any) -> Any:
    """``default=`` for :func:`json.dumps` of metadata: NumPy scalars and arrays, paths.

    Raises
    ------
    TypeError
        For any other type, naming it.
    """
    if isinstance(obj, (np.floating, np.integer)):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"metadata value of type {type(obj).__name__} is not JSON-serialisable")


def atomic_savez(path: str | os.PathLike, what: str = "npz file", **arrays: Any) -> Path:
    """``np.savez`` (uncompressed) to ``path`` through :func:`atomic_write`."""
    def write(tmp: Path) -> None:
        with open(tmp, "wb") as f:
            np.savez(f, **arrays)
    return atomic_write(Path(path), write, what)
