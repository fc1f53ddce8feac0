"""Output directories that are all or nothing and own their products (docs/design.md section 3, "Files").

A run (``render``, ``focus``, ``preview``) writes its files into a hidden staging folder inside
the output directory and moves them into place only when every file is written. A run that
fails (bad input found late, a full disk, Ctrl-C) removes its staging folder and any directory
it created, so it leaves neither half-written files nor empty directories behind, and a disk
error names the file the user asked for, not an internal temporary name. A failure between
two of the final moves takes the moved files back out (earlier files of the same names that
they replaced are lost). The run holds the folder's lock (:mod:`sarmitsuba.core.folder_lock`)
while it is in the with-block, so a second run into the folder stops at once, and staging
folders a killed run left there are removed on entry.

Products and stale products. A render owns the products it writes: its
``summary.json`` (:data:`MANIFEST_FILE`) lists every file it wrote under ``"files"``
(:data:`MANIFEST_KEY`; plain names, ``summary.json`` included), and the next render into the
folder (``products="replace"``) removes the files on that earlier list that it does not write
again: other channels (``raw_HV.npz``), bounce orders (``*_order2.*``), figures, ``pauli.png``,
standard formats. The removal happens at commit time, after the new products are moved in and
before the new list is, so an interrupted commit leaves the earlier list (a later render still
cleans up), and a failed or interrupted render (before the commit) leaves the earlier render
as it was. A file not on the earlier list (a user's ``notes.txt``, a file merely named like a
product) is never touched, nor is a listed name that is not a plain file name (``../x``,
``.hidden``) or not a file. Runs that add to a render (``products="add"``: the figures of
``render --figures``, ``focus --out`` into a render folder) join its list, so the next render
replaces their files too; in a folder without a list they record nothing. A folder whose
``summary.json`` has no list (an older version) keeps all its files; the render warns once that
stale files may remain. ``preview`` and ``interferogram`` keep no list (``products=None``).

>>> with OutputDirectory("out/urban", products="replace") as out:     # doctest: +SKIP
...     out.write("raw.npz", raw.save)                  # written to out/urban/.staging-*/raw.npz
... # here, and only here, out/urban/raw.npz appears; an earlier raw_HV.npz goes
"""
from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
import warnings
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .folder_lock import STAGING_PREFIX, hold_folder

__all__ = ["OutputDirectory", "WriteError", "atomic_savez", "atomic_write", "check_output_dir", "json_default",
           "product_kind", "read_manifest", "MANIFEST_FILE", "MANIFEST_KEY"]

#: The file that lists a render's products, and its key (a list of file names).
MANIFEST_FILE = "summary.json"
MANIFEST_KEY = "files"
#: ``products=`` of :class:`OutputDirectory`.
PRODUCT_MODES = (None, "replace", "add")


class OutputDirectory:
    """Context manager for one run's output directory.

    Parameters
    ----------
    path : path-like
        The directory the user named (``--out``). It is created when missing (with its missing
        parents) and removed again if the run fails and it is still empty.
    products : {None, "replace", "add"}
        ``"replace"`` (a render): this run's files are the folder's products; at commit the
        files of the earlier list (:func:`read_manifest`) it did not write are removed and
        :data:`MANIFEST_FILE` (the one the run wrote, else a new one) lists only its files.
        ``"add"``: its files join the folder's list, if the folder has one. None: no list.

    Raises
    ------
    ValueError
        ``products`` is none of these.
    OSError
        On entry, naming ``path``: it is an existing file, or it cannot be created or written;
        :class:`~sarmitsuba.core.folder_lock.FolderInUseError` when another run holds it.
        From :meth:`write`, naming the final file: the writer failed (for instance ``[Errno 28]``
        no space left on device).
    """

    def __init__(self, path: str | os.PathLike, products: str | None = None) -> None:
        if products not in PRODUCT_MODES:
            raise ValueError(f"products = {products!r}; valid: None, 'replace' (a render), 'add'")
        self.path = Path(path)
        self.products = products
        self._hold: Any = None
        self._staging: Path | None = None
        self._written: list[str] = []

    def __enter__(self) -> "OutputDirectory":
        hold = hold_folder(self.path)          # one run per folder (core/folder_lock.py): creates it,
        hold.__enter__()                       # removes a killed run's staging folders
        try:
            self._staging = Path(tempfile.mkdtemp(prefix=STAGING_PREFIX, dir=self.path))
        except OSError as exc:
            hold.__exit__(None, None, None)
            raise OSError(f"output directory {str(self.path)!r} is not writable: {exc.strerror or exc}; "
                          "choose another --out") from None
        self._hold = hold
        return self

    def write(self, name: str, writer: Callable[[Path], Any]) -> Path:
        """Call ``writer(staged_path)`` for the file ``name``; returns its final path. Writing
        a name again replaces the staged file.

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
        if name not in self._written:
            self._written.append(name)
        return final

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        if exc_type is not None:
            self.abandon()
            return
        notes: list[str] = []
        moved: list[Path] = []
        try:
            listed, stale = self._manifest_names(notes)
            for name in self._written:                  # the list (summary.json) moves last
                if listed is None or name != MANIFEST_FILE:
                    os.replace(self._staging / name, self.path / name)
                    moved.append(self.path / name)
            if listed is not None:
                kept = self._remove(stale, notes)       # names it could not remove stay listed
                self._stage_manifest(sorted(listed | set(kept)))
                os.replace(self._staging / MANIFEST_FILE, self.path / MANIFEST_FILE)
        except BaseException:            # Ctrl-C between two renames or removals: take the moved ones back
            # out; the earlier list stays in place, so the next render still removes what is left
            for path in moved:
                path.unlink(missing_ok=True)
            self.abandon()
            raise
        shutil.rmtree(self._staging, ignore_errors=True)
        self._staging = None
        self._let_go()
        for note in notes:
            warnings.warn(note, stacklevel=2)

    def _manifest_names(self, notes: list[str]) -> tuple[set[str] | None, tuple[str, ...]]:
        """The names the folder's new list holds (None: no list to write) and the stale names,
        those of the earlier list that this run did not write."""
        if self.products is None:
            return None, ()
        earlier = read_manifest(self.path)
        written = set(self._written) | {MANIFEST_FILE}
        if self.products == "add":
            return (None, ()) if earlier is None else (written | set(earlier), ())
        if earlier is None and (self.path / MANIFEST_FILE).exists():
            notes.append(f"{self.path} holds a render by an older sarmitsuba that did not list its files: "
                         "those this render did not write again (other channels, bounce orders, figures, "
                         "formats) are left as they were; delete them by hand if they are stale")
        return written, tuple(name for name in earlier or () if name not in written)

    def _stage_manifest(self, names: list[str]) -> None:
        """Stage MANIFEST_FILE listing ``names``: the one this run wrote, else for ``"add"`` the
        folder's, with its list replaced; for ``"replace"`` without one, a file of the list alone."""
        staged = self._staging / MANIFEST_FILE
        source = staged if MANIFEST_FILE in self._written else self.path / MANIFEST_FILE
        body = _read_json(source) if source == staged or self.products == "add" else None
        body = body if isinstance(body, dict) else {}
        body[MANIFEST_KEY] = names
        self.write(MANIFEST_FILE, lambda path: path.write_text(json.dumps(body, indent=2, default=json_default)))

    def _remove(self, stale: tuple[str, ...], notes: list[str]) -> list[str]:
        """Remove the files ``stale`` names (plain files and links only); returns the names
        that could not be removed, with a note for each."""
        kept = []
        for name in stale:
            path = self.path / name
            if not (path.is_symlink() or path.is_file()):
                continue
            try:
                path.unlink()
            except FileNotFoundError:
                pass
            except OSError as exc:
                kept.append(name)
                notes.append(f"cannot remove {path}, a product of the earlier render: {exc.strerror or exc}")
        return kept

    def abandon(self) -> None:
        """Remove the staged files, let go of the folder and remove the directories this run
        created if they are empty."""
        if self._staging is not None:
            shutil.rmtree(self._staging, ignore_errors=True)
            self._staging = None
        self._let_go()

    def _let_go(self) -> None:
        hold, self._hold = self._hold, None
        if hold is not None:
            hold.__exit__(None, None, None)


def read_manifest(folder: str | os.PathLike) -> tuple[str, ...] | None:
    """The files the render in ``folder`` listed as its products (``summary.json["files"]``),
    sorted; None when there is no list (no ``summary.json``, an unreadable one, or one by an
    older version). Only plain file names count: an entry with a path separator, ``..`` or a
    leading dot is dropped. Raises nothing."""
    body = _read_json(Path(folder) / MANIFEST_FILE)
    names = body.get(MANIFEST_KEY) if isinstance(body, dict) else None
    if not isinstance(names, list):
        return None
    return tuple(sorted({name for name in names if _plain_name(name)}))


def _plain_name(name: Any) -> bool:
    return (isinstance(name, str) and bool(name) and not name.startswith(".") and "/" not in name
            and (os.altsep is None or os.altsep not in name) and os.sep not in name)


def _read_json(path: Path) -> Any:
    """The JSON in ``path``; None when it is missing or cannot be read."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


#: Leading bytes and file-name endings of the files a run writes, by what they hold.
_PRODUCT_MAGIC = ((b"PK\x03\x04", (".npz",), "a NumPy archive (raw data or an image)"),
                  (b"CPHD/", (".cphd",), "CPHD phase history (raw data)"),
                  (b"NITF", (".nitf", ".ntf"), "a NITF file (a SICD image)"),
                  (b"II*\x00", (".tif", ".tiff"), "a GeoTIFF image"), (b"MM\x00*", (), "a GeoTIFF image"),
                  (b"\x89PNG", (".png",), "a PNG picture"), (b"v/1\x01", (".exr",), "an OpenEXR image"))


def product_kind(path: str | os.PathLike) -> str | None:
    """What the file ``path`` holds when it is a product a run writes (raw data, an image, a
    picture), by its first bytes or, when it cannot be read, its name; None for anything else
    (a scene XML). Raises nothing."""
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError:
        head = None
    suffix = Path(path).suffix.lower()
    for magic, suffixes, kind in _PRODUCT_MAGIC:
        if (head.startswith(magic) if head is not None else suffix in suffixes):
            return kind
    return None


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
