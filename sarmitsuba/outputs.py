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

__all__ = ["OutputDirectory", "check_output_dir"]


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
