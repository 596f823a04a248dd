"""The on-disk cache of compiled libraries: where it is, what proves a cached file is the
one asked for, and where a fresh build goes.

Every cached library (a model's, a generated function's, a hand-written C source's) is
found, checked, loaded or built through :func:`load_or_build`, under a name made of its
kind and its cache key. Beside each library is its checksum file (``<library>.sha256``:
the SHA-256 and size of its bytes and the full cache key it was built for). Before a
cached library is loaded its checksum file must record the key the caller computed
(identity: another model's library copied over this one's, checksum file and all, is
refused) and the bytes must match it (integrity: a damaged or partly copied file never
reaches the dynamic loader, where a truncated library would crash the process with
SIGBUS). A library that fails either check, has no checksum file or fails to load is
rebuilt once, with a :class:`CacheWarning` naming the file and the reason.

The bytes that passed must also be a whole library defining the symbols its caller
needs (:func:`~softcurve.compiled._elf.image_problem`: a checksum file written for a
truncated library matches it, and the loader would crash on it). Before anything in the
cache folder is trusted, the folder, the folders above it and each library and checksum
file must be the user's and writable by no one else, unless the cache is declared
shared (``softcurve.compiled._trust``); a folder that fails is not read at all, and
builds go to a temporary folder kept for the process, with one :class:`CacheWarning`.

A filled cache needs no compiler: the key is what the library computes (structure,
sources, flags, CPU, CasADi's version), not the compiler that built it, and the compiler
is asked for only when something must be built. A cache folder that cannot be written
(a file, a read-only folder) is found before building: the build then goes to a
temporary folder kept for the process, with one :class:`CacheWarning` naming both.
"""

from __future__ import annotations

import atexit
import hashlib
import os
import shutil
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path

from softcurve.base.docs import parameters_from
from softcurve.base.files import atomic_write
from softcurve.base.log import logger, timed
from softcurve.compiled import _trust as trust
from softcurve.compiled._elf import image_problem


class CacheWarning(UserWarning):
    """A cached compiled library was damaged (checksum, size, cut short), was built for
    another key, lacked its symbols, failed to load or could be written by other users,
    and was replaced by a fresh build; or the cache folder cannot be written or trusted
    and builds are kept for the process only."""


CACHE_VARIABLE = "SOFTCURVE_CACHE_DIR"
"""The environment variable that names the cache folder."""
_CHECKSUM_SUFFIX = ".sha256"
_LOG = logger("compiled")
_LOAD_ERRORS = (OSError, RuntimeError, AttributeError)
"""What loading a library raises: ``ctypes.CDLL`` an OSError, CasADi's ``external`` a
RuntimeError, a ctypes lookup of a symbol it lacks an AttributeError (the symbols a
caller names are checked before loading; this is for those it does not name)."""
_FILE_MODE = 0o644
"""Libraries and checksum files: replaced by renames, never written in place, so no one
needs to write them (whatever the umask, or :mod:`._trust` refuses them)."""


def cache_directory() -> Path:
    """Where compiled models are kept: ``$SOFTCURVE_CACHE_DIR``, else the user cache."""
    env = os.environ.get(CACHE_VARIABLE)
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "softcurve"


_library_docs = parameters_from(
    {"library": ("str or os.PathLike", "A compiled library in the cache (a ``.so`` file).")}
)


@_library_docs
def checksum_file(library) -> Path:
    """The checksum file beside a cached library: ``<library>.sha256``.

    Parameters
    ----------
    %(library)s

    Returns
    -------
    pathlib.Path
        Its checksum file, one line ``sha256 <hex digest> size <bytes> key <cache key>``.
    """
    library = Path(library)
    return library.with_name(library.name + _CHECKSUM_SUFFIX)


def _checksum_line(data: bytes, key: str) -> str:
    return f"sha256 {hashlib.sha256(data).hexdigest()} size {len(data)} key {key}\n"


@_library_docs
def library_problem(library, key: str | None = None, symbols: tuple[str, ...] = ()) -> str | None:
    """Why a cached library must not be loaded, or None when it is the one asked for.

    The recorded key is compared first (another library copied over this one, with its
    checksum file), then the size (a partial copy fails without being read), then the
    SHA-256 of the content: one read of the file (about 0.1-0.5 MB); the same bytes must
    then be a whole library defining ``symbols``
    (:func:`~softcurve.compiled._elf.image_problem`).

    Parameters
    ----------
    %(library)s
    key : str, optional
        The full cache key the caller computed (hex digits); None checks integrity only.
    symbols : tuple of str
        Names the library must define.

    Returns
    -------
    str or None
        The reason in words ("has no checksum file ...", "was built for another key
        ...", "has 0 bytes ..."), or None.
    """
    library, checksum = Path(library), checksum_file(library)
    try:
        fields = checksum.read_text(encoding="ascii").split()
    except FileNotFoundError:
        return f"has no checksum file ({checksum.name})"
    except (OSError, UnicodeDecodeError) as exc:
        return f"has an unreadable checksum file ({checksum.name}: {exc})"
    if len(fields) != 6 or fields[::2] != ["sha256", "size", "key"] or not fields[3].isdigit():
        return f"has a malformed checksum file ({checksum.name})"
    if key is not None and fields[5] != key:
        return (
            f"was built for another key ({checksum.name} records {fields[5][:16]}..., this "
            f"one needs {key[:16]}...: another model's or function's library copied over it)"
        )
    try:
        size = library.stat().st_size
        if size != int(fields[3]):
            return f"has {size} bytes where its checksum file records {fields[3]} (partial copy?)"
        data = library.read_bytes()
    except OSError as exc:
        return f"cannot be read ({exc})"
    if hashlib.sha256(data).hexdigest() != fields[1]:
        return "does not match its checksum (damaged)"
    return image_problem(data, symbols)


def install(library, data: bytes, key: str) -> Path:
    """Write ``data`` as ``library`` with its checksum file (recording ``key``), each
    renamed into place whole.

    The checksum file comes first, so a reader never finds the new library without it; a
    checksum file without its library only means the library is built again. Two
    processes installing at once write the same bytes (the build is deterministic).

    Parameters
    ----------
    library : str or os.PathLike
        The library's path.
    data : bytes
        Its content.
    key : str
        The full cache key it was built for.

    Returns
    -------
    pathlib.Path
        ``library``.
    """
    library = Path(library)
    atomic_write(checksum_file(library), _checksum_line(data, key).encode("ascii"), _FILE_MODE)
    return atomic_write(library, data, _FILE_MODE)


_VERIFIED: dict[tuple[Path, str], tuple] = {}
"""The libraries this process verified and loaded, by (path, key), with the (device,
inode, size, modification time, mode, owner) of the library and its checksum file: a
later model of the same structure skips the read while both are unchanged (a replaced,
rewritten or opened up file is verified again)."""


def _stats(library: Path) -> tuple[os.stat_result, ...] | None:
    try:
        return library.stat(), checksum_file(library).stat()
    except OSError:  # missing, or its folder is not one
        return None


def _identity(library: Path) -> tuple | None:
    stats = _stats(library)
    if stats is None:
        return None
    return tuple((s.st_dev, s.st_ino, s.st_size, s.st_mtime_ns, s.st_mode, s.st_uid) for s in stats)


_UNTRUSTED: dict[tuple[Path, bool], str | None] = {}
"""Per existing cache folder (and whether it was declared shared), why its libraries are
not trusted (:func:`softcurve.compiled._trust.folder_problem`), or None; checked once per
process (a folder not made yet is checked again once it is)."""


def _untrusted(folder: Path) -> str | None:
    shared = trust.shared()
    if (folder, shared) in _UNTRUSTED:
        return _UNTRUSTED[folder, shared]
    problem = trust.folder_problem(folder, shared)
    if folder.is_dir():
        _UNTRUSTED[folder, shared] = problem
    return problem


_PROCESS_FOLDERS: dict[Path, Path] = {}
"""Per unwritable cache folder, the temporary folder this process builds into instead
(removed when the process exits); its presence also means the warning was given."""


def _unwritable(folder: Path) -> str | None:
    """Why ``folder`` cannot hold new libraries, or None: it is created if missing and a
    file is created in it and removed (permissions alone do not show a read-only mount,
    nor what root may write)."""
    if folder.exists() and not folder.is_dir():
        return "is not a folder"
    try:  # a new folder writable by the user alone, or by the group of a shared one
        folder.mkdir(parents=True, exist_ok=True, mode=0o775 if trust.shared() else 0o755)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".softcurve-probe-"):
            pass
    except OSError as exc:
        return f"cannot be written ({exc.strerror or exc})"
    return None


def _process_folder(folder: Path, problem: str, stacklevel: int) -> Path:
    """The temporary folder that stands in for the unwritable cache ``folder`` in this
    process, made (with one :class:`CacheWarning`) on first use."""
    if folder not in _PROCESS_FOLDERS:
        temporary = Path(tempfile.mkdtemp(prefix="softcurve-cache-"))
        atexit.register(shutil.rmtree, temporary, ignore_errors=True)
        _PROCESS_FOLDERS[folder] = temporary
        named = "" if os.environ.get(CACHE_VARIABLE) else ", the default"
        warnings.warn(
            f"softcurve cache: the cache folder {folder} ({CACHE_VARIABLE}{named}) {problem}; "
            f"compiled libraries are kept in {temporary} for this process only (set "
            f"{CACHE_VARIABLE} to a writable folder of your own to keep them)",
            CacheWarning,
            stacklevel=stacklevel + 1,
        )
    return _PROCESS_FOLDERS[folder]


def _build_folder(folder: Path, stacklevel: int) -> Path:
    """Where a fresh build for the cache ``folder`` goes: the folder itself when it can be
    written (checked before building, so no build is lost), else the process's
    stand-in."""
    if folder in _PROCESS_FOLDERS:
        return _PROCESS_FOLDERS[folder]
    # checked again after _unwritable made a missing folder: as it is now
    problem = _untrusted(folder) or _unwritable(folder) or _untrusted(folder)
    return folder if problem is None else _process_folder(folder, problem, stacklevel + 1)


def _library_name(kind: str, key: str) -> str:
    return f"{kind}_{key[:24]}.so"


def _candidates(folder: Path, name: str) -> list[Path]:
    """Where the library ``name`` of the cache ``folder`` is looked for, in order: this
    process's stand-in first (a library it holds replaced one of the cache), then the
    folder unless it is not trusted."""
    candidates = [] if _untrusted(folder) else [folder / name]
    if folder in _PROCESS_FOLDERS:
        candidates.insert(0, _PROCESS_FOLDERS[folder] / name)
    return candidates


def _file_problem(library: Path) -> str | None:
    """Why the library or its checksum file is not trusted (another's, or writable by
    others: :func:`softcurve.compiled._trust.file_problem`), or None."""
    stats = _stats(library)
    for path, status in zip((library, checksum_file(library)), stats or (), strict=bool(stats)):
        problem = trust.file_problem(status, trust.shared())
        if problem is not None:
            return f"{'' if path == library else 'has a checksum file that '}{problem}"
    return None


def _found(
    folder: Path, name: str, key: str, symbols: tuple[str, ...] = ()
) -> tuple[Path, tuple | None, str | None] | None:
    """The first of :func:`_candidates` that exists, with its identity (before the check,
    so a file changed after it is checked again) and why it must not be loaded
    (:func:`_file_problem`, :func:`library_problem`; None when this process verified it
    unchanged); None when none exists."""
    for library in _candidates(folder, name):
        identity = _identity(library)
        if identity is None and not library.exists():
            continue
        if identity is not None and _VERIFIED.get((library, key)) == identity:
            return library, identity, None
        problem = _file_problem(library) or library_problem(library, key, symbols)
        return library, identity, problem
    return None


def cached_library(kind: str, key: str, symbols: tuple[str, ...] = ()) -> Path | None:
    """The library :func:`load_or_build` would load for ``kind`` and ``key`` without
    building, or None when it would build (nothing cached, or what is cached fails
    :func:`library_problem`); nothing is built, loaded or warned about.

    Parameters
    ----------
    kind : str
        Start of the file name: ``"model"``, ``"function"``, a C source's stem.
    key : str
        The full cache key (hex digits).
    symbols : tuple of str
        Names the library must define.

    Returns
    -------
    pathlib.Path or None
        The library, intact and recording ``key`` (loading it fails only if the dynamic
        loader refuses it), or None.
    """
    found = _found(cache_directory(), _library_name(kind, key), key, symbols)
    return found[0] if found is not None and found[2] is None else None


class UnusableLibrary(OSError):
    """A freshly built library failed to load."""


def load_or_build(
    kind: str,
    key: str,
    build: Callable[[], bytes],
    load: Callable,
    stacklevel: int,
    symbols: tuple[str, ...] = (),
    what: str | None = None,
):
    """The library ``<kind>_<key[:24]>.so``, checked against ``key`` and loaded, built
    first when missing; one that fails :func:`library_problem` or fails to load is
    replaced by a fresh build once, with a :class:`CacheWarning`. A build is said on the
    logger ``softcurve.compiled`` (:mod:`softcurve.base.log`): what is compiled and where
    it goes before, how long it took after.

    It is looked for in this process's stand-in for the cache folder (when the cache
    cannot be written or trusted), then in the cache folder (when it is trusted).
    ``build`` is called only when nothing usable is found, after the folder it will go
    to is known (the cache, else the stand-in).

    Parameters
    ----------
    kind : str
        Start of the file name: ``"model"``, ``"function"``, a C source's stem.
    key : str
        The full cache key (hex digits), recorded in the checksum file.
    build : callable
        ``build() -> bytes``: the library's content; raises what a failed build raises
        (``subprocess.CalledProcessError``, OSError), or whatever says nothing can build
        it (no compiler).
    load : callable
        ``load(path)`` opens the library; raises OSError or RuntimeError when it cannot.
    stacklevel : int
        Of the warnings, counted from the caller of this function.
    symbols : tuple of str
        Names the library must define, checked before it is loaded (a library that
        lacks them is another's, and is rebuilt).
    what : str, optional
        What is compiled, in words (``"the model of 2 segments"``; default ``kind``).

    Returns
    -------
    tuple of (pathlib.Path, object)
        The library's path and what ``load`` returned for it.

    Raises
    ------
    UnusableLibrary
        When the fresh build fails to load too; else what ``build`` raises.
    """
    folder = cache_directory()
    name = _library_name(kind, key)
    untrusted = _untrusted(folder)
    if untrusted is not None:  # its libraries are not even looked at
        _process_folder(folder, untrusted, stacklevel + 1)
    found = _found(folder, name, key, symbols)
    if found is not None:
        library, identity, problem = found
        if problem is None:  # checked before dlopen: a truncated file would SIGBUS in it
            try:
                loaded = load(library)
            except _LOAD_ERRORS as exc:
                problem = f"failed to load ({str(exc).strip()[:300]})"
            else:
                _VERIFIED[library, key] = identity
                return library, loaded
        warnings.warn(
            f"softcurve cache: the compiled library {library} {problem}; replacing it with a "
            "fresh build (a shared cache needs atomic renames: see docs/sweeps.md)",
            CacheWarning,
            stacklevel=stacklevel + 1,
        )
    target = _build_folder(folder, stacklevel + 1) / name
    what = what or kind
    where = (
        f"C, cached in {folder} for later runs"
        if target.parent == folder
        else f"C, kept in {target.parent} for this process only"
    )
    with timed(
        _LOG,
        f"compiling {what} ({where}) ...",
        f"compiled {what} in %.1f s: {target.name}",
        f"compiling {what}: %.0f s so far",
    ):
        data = build()
    try:
        install(target, data, key)
    except OSError as exc:  # the folder failed after the check (full, unmounted)
        if target.parent != folder:
            raise
        target = _process_folder(folder, f"cannot be written ({exc})", stacklevel + 1) / name
        install(target, data, key)
    try:
        loaded = load(target)
    except _LOAD_ERRORS as exc:
        raise UnusableLibrary(f"{target} failed to load after a fresh build: {exc}") from exc
    _VERIFIED[target, key] = _identity(target)
    return target, loaded
