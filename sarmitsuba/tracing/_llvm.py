"""Locate a libLLVM that Dr.Jit's LLVM backend can use (LLVM >= 16).

Dr.Jit 1.5 JIT-compiles its ``llvm_*`` kernels through ``libLLVM``. With the
LLVM 14/15 libraries that Debian 12 ships by default, kernel compilation
crashes ("Cannot select ... fminimum"), so the library must be LLVM 16 or
newer. Dr.Jit reads the ``DRJIT_LIBLLVM_PATH`` environment variable **once,
when ``drjit`` is imported**; without it, Dr.Jit globs
``/usr/lib/<triplet>/libLLVM*.so.*`` and may pick an old version.

Call :func:`ensure_libllvm` before the first ``import drjit`` or
``import mitsuba``::

    from sarmitsuba.tracing._llvm import ensure_libllvm
    ensure_libllvm()          # sets os.environ["DRJIT_LIBLLVM_PATH"]
    import mitsuba as mi

Search order of :func:`find_libllvm`:

1. an already-set ``DRJIT_LIBLLVM_PATH``, accepted if the file exists (a path)
   or the bare name resolves the way ``dlopen`` would, and rejected with
   :class:`LibLLVMError` if its LLVM version is < 16;
2. the standard Debian/Ubuntu directories (:func:`default_search_dirs`),
   newest version first;
3. the dynamic linker cache (``ldconfig -p``).

The search itself is made of pure functions (:func:`parse_llvm_version`,
:func:`scan_dirs`, :func:`parse_ldconfig`, :func:`choose_libllvm`) that take
directories or ``ldconfig`` text as parameters, so they can be tested on fake
file trees.
"""

from __future__ import annotations

import ctypes
import glob
import os
import platform
import re
import shutil
import subprocess
import sys
import warnings
from dataclasses import dataclass
from typing import Iterable, Mapping, Sequence

__all__ = [
    "MIN_LLVM_VERSION",
    "LibLLVMError",
    "LibLLVMCandidate",
    "parse_llvm_version",
    "llvm_version",
    "default_search_dirs",
    "scan_dirs",
    "parse_ldconfig",
    "choose_libllvm",
    "find_libllvm",
    "ensure_libllvm",
]

#: Oldest LLVM major version that Dr.Jit 1.5's LLVM backend works with.
#: LLVM 14/15 crash in instruction selection ("Cannot select ... fminimum").
MIN_LLVM_VERSION = 16

#: Name of the environment variable Dr.Jit reads to locate libLLVM.
ENV_VAR = "DRJIT_LIBLLVM_PATH"

_FIX_HINT = (
    "Fix: install a newer LLVM, e.g. `apt-get install libllvm19` "
    "(Debian/Ubuntu), or set DRJIT_LIBLLVM_PATH to the path of a "
    f"libLLVM >= {MIN_LLVM_VERSION} (for example "
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so)."
)

# libLLVM-15.so, libLLVM-15.so.1, libLLVM-14.0.6.so.1, libLLVM-19git.so
_RE_DASH = re.compile(r"^libLLVM-(\d+)(?:\.\d+)*[A-Za-z]*\.so(?:\.\d+)*$")
# libLLVM.so.19.1, libLLVM.so.15.0 (the bare "libLLVM.so" carries no version)
_RE_DOT = re.compile(r"^libLLVM\.so\.(\d+)(?:\.\d+)*$")
# /usr/lib/llvm-19/lib/libLLVM.so
_RE_DIR = re.compile(r"(?:^|/)llvm-(\d+)(?:/|$)")
_RE_ANY = re.compile(r"^libLLVM(?:-[0-9][0-9A-Za-z.]*)?\.so(?:\.\d+)*$")


class LibLLVMError(RuntimeError):
    """No usable libLLVM (>= 16) was found, or the configured one is too old."""


@dataclass(frozen=True)
class LibLLVMCandidate:
    """One libLLVM shared library found by the search.

    Attributes
    ----------
    path : str
        Absolute path as found (not symlink-resolved), or a bare library name.
    version : int or None
        LLVM major version, ``None`` if it could not be determined.
    source : str
        Where it was found: ``"env"``, ``"dir"`` or ``"ldconfig"``.
    """

    path: str
    version: int | None
    source: str

    def describe(self) -> str:
        """Return ``"<path> (LLVM <version>)"`` for error messages."""
        ver = "unknown version" if self.version is None else f"LLVM {self.version}"
        return f"{self.path} ({ver}, from {self.source})"


# --------------------------------------------------------------------------
# Version parsing
# --------------------------------------------------------------------------

def parse_llvm_version(name: str) -> int | None:
    """Parse the LLVM major version from a libLLVM file name.

    Parameters
    ----------
    name : str
        File name or path; only the base name is examined.

    Returns
    -------
    int or None
        Major version, or ``None`` if the name carries none (``libLLVM.so``)
        or is not a libLLVM shared-library name.

    Examples
    --------
    >>> [parse_llvm_version(n) for n in
    ...  ["libLLVM-15.so", "libLLVM.so.15.0", "libLLVM-14.0.6.so.1",
    ...   "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", "libLLVM.so"]]
    [15, 15, 14, 19, None]
    """
    base = os.path.basename(str(name))
    m = _RE_DASH.match(base) or _RE_DOT.match(base)
    return int(m.group(1)) if m else None


def llvm_version(path: str | os.PathLike, resolve: bool = True) -> int | None:
    """LLVM major version of a library path, from its names.

    Tries, in order: the file name; the name of the resolved symlink target
    (``resolve=True``); an ``llvm-N`` directory component of the path or of
    its resolved target (``/usr/lib/llvm-19/lib/libLLVM.so``).

    Parameters
    ----------
    path : str or os.PathLike
        Library path (absolute or relative) or bare name.
    resolve : bool
        Follow symlinks with :func:`os.path.realpath`.

    Returns
    -------
    int or None
        Major version, ``None`` if no name reveals it.
    """
    path = str(path)
    names = [path]
    if resolve and os.sep in path:
        real = os.path.realpath(path)
        if real != path:
            names.append(real)
    for n in names:
        v = parse_llvm_version(n)
        if v is not None:
            return v
    for n in names:
        m = _RE_DIR.search(n)
        if m:
            return int(m.group(1))
    return None


def _probe_version(name: str) -> int | None:
    """Load a library with ctypes and ask LLVM for its version.

    ``LLVMGetVersion`` exists only from LLVM 16 on, so a library that loads
    but lacks it is reported as version 15 (i.e. "older than 16"). Loading
    libLLVM-19 takes ~20 ms. Returns ``None`` if the library cannot be loaded.
    Used only as a last resort for a user-supplied name without a version.
    """
    try:
        lib = ctypes.CDLL(name)
    except OSError:
        return None
    try:
        fn = lib.LLVMGetVersion
    except AttributeError:
        return MIN_LLVM_VERSION - 1
    major, minor, patch = (ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint())
    fn.argtypes = [ctypes.POINTER(ctypes.c_uint)] * 3
    fn.restype = None
    fn(ctypes.byref(major), ctypes.byref(minor), ctypes.byref(patch))
    return int(major.value)


# --------------------------------------------------------------------------
# Candidate search (pure functions)
# --------------------------------------------------------------------------

def default_search_dirs() -> list[str]:
    """Standard Debian/Ubuntu locations of libLLVM.

    Returns
    -------
    list of str
        ``/usr/lib/x86_64-linux-gnu``, ``/usr/lib/aarch64-linux-gnu``, then
        every existing ``/usr/lib/llvm-N/lib``, newest N first.
    """
    llvm_dirs = glob.glob("/usr/lib/llvm-*/lib")
    llvm_dirs.sort(key=lambda d: -(llvm_version(d, resolve=False) or 0))
    return ["/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", *llvm_dirs]


def _name_rank(name: str) -> int:
    """Preference among equal versions: libLLVM-N.so, libLLVM.so.N.*, others."""
    base = os.path.basename(name)
    if re.match(r"^libLLVM-\d+\.so$", base):
        return 0
    if _RE_DOT.match(base):
        return 1
    return 2


def scan_dirs(dirs: Iterable[str | os.PathLike]) -> list[LibLLVMCandidate]:
    """List the libLLVM shared libraries in some directories.

    Parameters
    ----------
    dirs : iterable of str or os.PathLike
        Directories to list (not recursively); missing ones are skipped.

    Returns
    -------
    list of LibLLVMCandidate
        One entry per matching file name (``libLLVM-N.so``,
        ``libLLVM.so.N.*``, ``libLLVM-N.so.1``, ``libLLVM.so``...), with the
        version from :func:`llvm_version`. Static archives and the
        ``libLLVM<Component>.a`` files are ignored. Unsorted.
    """
    found = []
    for d in dirs:
        try:
            names = sorted(os.listdir(d))
        except OSError:
            continue
        for n in names:
            if not _RE_ANY.match(n):
                continue
            p = os.path.join(str(d), n)
            if os.path.exists(p):  # skips dangling symlinks
                found.append(LibLLVMCandidate(p, llvm_version(p), "dir"))
    return found


def _arch_tag() -> str | None:
    """The ldconfig architecture tag of this machine (None: accept all)."""
    return {"x86_64": "x86-64", "aarch64": "AArch64"}.get(platform.machine())


def parse_ldconfig(text: str, arch: str | None = "auto") -> list[LibLLVMCandidate]:
    """Extract the libLLVM entries from ``ldconfig -p`` output.

    Parameters
    ----------
    text : str
        Output of ``ldconfig -p``; lines look like
        ``\\tlibLLVM.so.19.1 (libc6,x86-64) => /lib/x86_64-linux-gnu/libLLVM.so.19.1``.
    arch : str or None
        Keep only entries whose flags contain this tag (``"x86-64"``,
        ``"AArch64"``). ``"auto"`` uses this machine's tag, ``None`` keeps
        all entries.

    Returns
    -------
    list of LibLLVMCandidate
        Target paths (as listed, not checked for existence) with versions
        parsed from the cache name, falling back to the target path.
    """
    if arch == "auto":
        arch = _arch_tag()
    out = []
    for line in text.splitlines():
        m = re.match(r"^\s*(\S+)\s+\(([^)]*)\)\s+=>\s+(\S.*?)\s*$", line)
        if not m:
            continue
        name, flags, target = m.groups()
        if not _RE_ANY.match(name):
            continue
        if arch is not None and arch not in flags:
            continue  # a library for another architecture (e.g. i386)
        version = parse_llvm_version(name)
        if version is None:
            version = llvm_version(target)
        out.append(LibLLVMCandidate(target, version, "ldconfig"))
    return out


def choose_libllvm(
    candidates: Sequence[LibLLVMCandidate],
    min_version: int = MIN_LLVM_VERSION,
) -> LibLLVMCandidate | None:
    """Pick the newest candidate with version >= ``min_version``.

    Ties are broken by name (``libLLVM-N.so`` before ``libLLVM.so.N.*``
    before ``libLLVM-N.so.1``), then by search order.

    Returns
    -------
    LibLLVMCandidate or None
        ``None`` if no candidate qualifies (unknown versions never do).
    """
    ok = [(i, c) for i, c in enumerate(candidates)
          if c.version is not None and c.version >= min_version]
    if not ok:
        return None
    ok.sort(key=lambda ic: (-ic[1].version, _name_rank(ic[1].path), ic[0]))
    return ok[0][1]


# --------------------------------------------------------------------------
# DRJIT_LIBLLVM_PATH handling
# --------------------------------------------------------------------------

def _run_ldconfig() -> str:
    """Return ``ldconfig -p`` output, or "" if ldconfig is unavailable."""
    exe = shutil.which("ldconfig") or next(
        (p for p in ("/sbin/ldconfig", "/usr/sbin/ldconfig") if os.path.exists(p)),
        None)
    if exe is None:
        return ""
    try:
        res = subprocess.run([exe, "-p"], capture_output=True, text=True,
                             timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return ""
    return res.stdout


#: glibc's default trusted directories on Debian multiarch systems.
_TRUSTED_DIRS = ("/lib/x86_64-linux-gnu", "/usr/lib/x86_64-linux-gnu",
                 "/lib/aarch64-linux-gnu", "/usr/lib/aarch64-linux-gnu",
                 "/lib", "/usr/lib")


def _resolve_bare_name(name: str, ldconfig_text: str,
                       env: Mapping[str, str]) -> str | None:
    """Find the file a bare library name refers to, as dlopen would.

    Looks in ``LD_LIBRARY_PATH``, the ldconfig cache, then glibc's default
    trusted directories (not ``/usr/lib/llvm-N/lib``, which dlopen does not
    search). Does not load anything.
    """
    ld_path = [d for d in env.get("LD_LIBRARY_PATH", "").split(":") if d]
    for d in ld_path:
        p = os.path.join(d, name)
        if os.path.exists(p):
            return p
    for c in parse_ldconfig(ldconfig_text, arch=None):
        if os.path.basename(c.path) == name and os.path.exists(c.path):
            return c.path
    for d in _TRUSTED_DIRS:
        p = os.path.join(d, name)
        if os.path.exists(p):
            return p
    return None


def _too_old_error(value: str, version: int, resolved: str | None,
                    min_version: int) -> LibLLVMError:
    where = f" (resolves to {resolved})" if resolved and resolved != value else ""
    return LibLLVMError(
        f"{ENV_VAR}={value!r}{where} is LLVM {version}, but Dr.Jit's LLVM "
        f"backend needs libLLVM >= {min_version} (LLVM 14/15 crash with "
        f"'Cannot select ... fminimum'). {_FIX_HINT}")


def _check_env_value(value: str, ldconfig_text: str, env: Mapping[str, str],
                     min_version: int) -> str:
    """Validate a user-set DRJIT_LIBLLVM_PATH; return it unchanged if usable."""
    if os.sep in value:  # a path: dlopen opens exactly this file
        if not os.path.exists(value):
            raise LibLLVMError(
                f"{ENV_VAR}={value!r} does not exist. Point it to an existing "
                f"libLLVM >= {min_version}, or unset it to search automatically. "
                f"{_FIX_HINT}")
        version = llvm_version(value)
        resolved = os.path.realpath(value)
    else:  # a bare name: dlopen searches the linker path
        version = parse_llvm_version(value)
        if version is not None and version < min_version:
            raise _too_old_error(value, version, None, min_version)
        resolved = _resolve_bare_name(value, ldconfig_text, env)
        if resolved is not None and version is None:
            version = llvm_version(resolved)
        if resolved is None:
            # Not found by name: let dlopen decide (loads it, ~20 ms).
            probed = _probe_version(value)
            if probed is None:
                raise LibLLVMError(
                    f"{ENV_VAR}={value!r} is a bare library name that the "
                    "dynamic linker cannot load (not in LD_LIBRARY_PATH, the "
                    "ldconfig cache or the standard library directories). "
                    f"Use an absolute path or unset it. {_FIX_HINT}")
            version = version if version is not None else probed
    if version is None:
        version = _probe_version(resolved or value)
        if version is None:
            raise LibLLVMError(
                f"{ENV_VAR}={value!r} exists but cannot be loaded as a shared "
                f"library. {_FIX_HINT}")
    if version < min_version:
        raise _too_old_error(value, version, resolved, min_version)
    return value


def find_libllvm(
    env: Mapping[str, str] = os.environ,
    *,
    search_dirs: Sequence[str | os.PathLike] | None = None,
    ldconfig_text: str | None = None,
    min_version: int = MIN_LLVM_VERSION,
) -> str:
    """Find a libLLVM >= 16 for Dr.Jit's LLVM backend.

    Parameters
    ----------
    env : mapping
        Environment to read ``DRJIT_LIBLLVM_PATH`` and ``LD_LIBRARY_PATH``
        from (default ``os.environ``; not modified).
    search_dirs : sequence of path, optional
        Directories to scan in step 2; default :func:`default_search_dirs`.
    ldconfig_text : str, optional
        ``ldconfig -p`` output for step 3; default: run ``ldconfig -p``
        (only if needed).
    min_version : int
        Minimum LLVM major version (default 16).

    Returns
    -------
    str
        The user's ``DRJIT_LIBLLVM_PATH`` unchanged if it is usable; otherwise
        the absolute path of the newest libLLVM found.

    Raises
    ------
    LibLLVMError
        If ``DRJIT_LIBLLVM_PATH`` is set but missing, unloadable or older than
        ``min_version``; or if no libLLVM >= ``min_version`` is found (the
        message lists every library found with its version, and how to fix it).
    """
    dirs = [str(d) for d in (default_search_dirs() if search_dirs is None
                             else search_dirs)]
    ld_text = ldconfig_text  # evaluated lazily: ldconfig runs only if needed

    value = env.get(ENV_VAR, "")
    if value:
        if ld_text is None and os.sep not in value:
            ld_text = _run_ldconfig()
        return _check_env_value(value, ld_text or "", env, min_version)

    from_dirs = scan_dirs(dirs)
    best = choose_libllvm(from_dirs, min_version)
    if best is not None:
        return best.path

    if ld_text is None:
        ld_text = _run_ldconfig()
    from_cache = [c for c in parse_ldconfig(ld_text) if os.path.exists(c.path)]
    best = choose_libllvm(from_cache, min_version)
    if best is not None:
        return best.path

    found = from_dirs + from_cache
    listing = ("\n  " + "\n  ".join(c.describe() for c in found)) if found else \
        " none (no libLLVM*.so in the searched directories or the ldconfig cache)"
    raise LibLLVMError(
        f"Dr.Jit's LLVM backend needs libLLVM >= {min_version}; LLVM 14/15 "
        "crash with 'Cannot select ... fminimum'. Searched "
        f"{', '.join(dirs)} and `ldconfig -p`. Found:{listing}\n{_FIX_HINT}")


def ensure_libllvm() -> str:
    """Set ``DRJIT_LIBLLVM_PATH`` to a usable libLLVM and return it.

    Must run before ``drjit`` (or ``mitsuba``) is first imported: Dr.Jit
    loads libLLVM at import time and ignores later changes of the variable.
    A :class:`RuntimeWarning` is issued if ``drjit`` is already imported and
    the variable had to be changed. Idempotent; costs ~2 ms.

    Returns
    -------
    str
        The value now in ``os.environ["DRJIT_LIBLLVM_PATH"]``.

    Raises
    ------
    LibLLVMError
        See :func:`find_libllvm`.
    """
    previous = os.environ.get(ENV_VAR)
    path = find_libllvm(os.environ)
    os.environ[ENV_VAR] = path
    if "drjit" in sys.modules and path != previous:
        warnings.warn(
            f"ensure_libllvm() set {ENV_VAR}={path!r} after drjit was imported;"
            " Dr.Jit has already loaded its libLLVM and will not reload it. "
            "Call ensure_libllvm() before importing drjit or mitsuba.",
            RuntimeWarning, stacklevel=2)
    return path
