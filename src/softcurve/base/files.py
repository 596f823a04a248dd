"""Files written whole or not at all: a temporary file in the target's folder, renamed
over the target when complete, so readers see the old file or the new one, never a part;
and the one check of the files a user gives to read (:func:`read_input`).
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import secrets
import socket
import stat
from pathlib import Path

from softcurve.base.validation import ParameterError

_UMASK = os.umask(0o022)
os.umask(_UMASK)  # read once: files are created with the usual permissions


@contextlib.contextmanager
def atomic_path(path, mode: int = 0o666):
    """Yield a temporary path next to ``path``; rename it over ``path`` on success,
    delete it on failure, so readers see the old file or the complete new one.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; its folder is created if missing.
    mode : int
        Its permissions less the umask, set before it is renamed into place (so nobody
        the mode leaves out ever opened it for writing).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = tempfile.TemporaryDirectory()
    >>> target = pathlib.Path(folder.name) / "table.csv"
    >>> with atomic_path(target) as tmp:
    ...     _ = tmp.write_text("t,x")
    ...     target.exists()  # nothing visible until the block ends
    False
    >>> target.read_text()
    't,x'
    >>> folder.cleanup()
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(path)
    # the writer's pid in the name: a later write can tell a killed writer's leftover
    tmp = path.parent / f".{path.name}.{temporary_tag()}.{secrets.token_hex(4)}{path.suffix}"
    os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
    try:
        yield Path(tmp)
        os.chmod(tmp, mode & ~_UMASK)
        os.replace(tmp, path)
    except BaseException as exc:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.filename in (None, str(tmp)):
            # a failed write names no file (a full disk), or the temporary one: name the
            # file that was not written
            raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc
        raise


def atomic_write(path, data: bytes, mode: int = 0o666) -> Path:
    """Write ``data`` to ``path`` whole or not at all.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; its folder is created if missing.
    data : bytes
        The file's complete content.
    mode : int
        As :func:`atomic_path`'s.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    with atomic_path(path, mode) as tmp:
        tmp.write_bytes(data)
    return Path(path)


_TEMPORARY = re.compile(r"\.(?P<name>.+)\.pid(?P<pid>\d+)@(?P<host>[\w-]*)\.[0-9a-f]{8}")


def temporary_tag() -> str:
    """``pid<PID>@<host>``: who writes a temporary file of :func:`atomic_path`, so that
    a later write can tell the leftover of a killed writer on this machine."""
    return f"pid{os.getpid()}@{re.sub(r'[^A-Za-z0-9_-]', '-', socket.gethostname())}"


def _running(pid: int) -> bool:
    """Whether a process ``pid`` exists (on this machine)."""
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # e.g. EPERM: it exists but belongs to someone else
        return True
    return True


def remove_stale_temporaries(path) -> list[Path]:
    """Delete the temporary files of :func:`atomic_path` for ``path`` whose writer is no
    longer running (a killed writer leaves its part behind); returns those deleted.

    Temporary files of running writers are kept, and so are those written on other
    machines (the name carries the host: on a folder shared by a cluster, a pid means
    nothing elsewhere).

    Parameters
    ----------
    path : str or os.PathLike
        The target file; its folder is searched.
    """
    path = Path(path)
    removed = []
    try:
        candidates = list(path.parent.glob(f".{glob_escape(path.name)}.pid*{path.suffix}"))
    except OSError:
        return removed
    for candidate in candidates:
        match = _TEMPORARY.match(candidate.name)
        if (
            match
            and match["name"] == path.name
            and match["host"] == temporary_tag().partition("@")[2]
            and not _running(int(match["pid"]))
        ):
            with contextlib.suppress(OSError):
                candidate.unlink()
                removed.append(candidate)
    return removed


def glob_escape(name: str) -> str:
    """``name`` with the glob metacharacters ``*?[`` escaped.

    Parameters
    ----------
    name : str
        A file name.
    """
    return re.sub(r"([*?\[])", r"[\1]", name)


def writable_folder(folder, option: str = "--output") -> Path:
    """Create ``folder`` if needed and check that files can be written in it, before any
    work is done; :class:`~softcurve.ParameterError` naming ``option``, the folder and
    the cause otherwise (under a file, read-only, read-only filesystem, no space).

    Parameters
    ----------
    folder : str or os.PathLike
        The output folder.
    option : str
        How the user gave it (e.g. ``"--output"``), for the message.

    Returns
    -------
    pathlib.Path
        ``folder``.
    """
    folder = Path(folder)
    try:
        os.stat(folder)
    except FileNotFoundError:  # to be created, unless it is a link to nothing
        if folder.is_symlink():
            raise ParameterError(
                f"{option} {folder}: a symbolic link to nothing; choose another folder"
            ) from None
    except OSError as exc:  # a loop of symbolic links, no permission
        raise ParameterError(
            f"{option} {folder}: cannot write there ({_cause(exc)}); choose another folder"
        ) from None
    if folder.exists() and not folder.is_dir():
        raise ParameterError(f"{option} {folder}: exists and is not a folder; choose a folder")
    probe = folder / f".softcurve-probe.pid{os.getpid()}.{secrets.token_hex(4)}"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        os.close(os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
        probe.unlink()
    except OSError as exc:
        raise ParameterError(
            f"{option} {folder}: cannot write there ({_cause(exc)}); choose another folder"
        ) from None
    return folder


def writable_file(path, option: str) -> Path:
    """Check, before any work, that the file ``path`` can be written: its folder is
    created and probed by :func:`writable_folder`, and ``path`` must not be a folder.

    Parameters
    ----------
    path : str or os.PathLike
        The file to be written.
    option : str
        How the user gave it (e.g. ``"--plot"``), for the message.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    if path.is_dir():
        raise ParameterError(f"{option} {path}: is a folder; give a file name")
    writable_folder(path.parent, f"{option} {path}: folder")
    return path


def _cause(exc: OSError) -> str:
    """A short reason for an OSError: the usual ones in words, else its text."""
    reasons = {
        errno.ENOTDIR: "a part of the path is a file, not a folder",
        errno.EEXIST: "a part of the path is a file, not a folder",
        errno.EACCES: "permission denied",
        errno.EPERM: "operation not permitted",
        errno.EROFS: "read-only filesystem",
        errno.ENOSPC: "no space left on the device",
        errno.ELOOP: "a loop of symbolic links",
    }
    return reasons.get(exc.errno, exc.strerror or str(exc))


class InputFileError(ParameterError):
    """A file given to read cannot be read: a folder, a device, a loop of symbolic links,
    no permission (:func:`input_file`)."""


class InputFileNotFound(InputFileError, FileNotFoundError):
    """A file given to read does not exist (also a :class:`FileNotFoundError`)."""


def input_file(path, what: str = "") -> Path:
    """Check, before reading, that ``path`` is a file that can be read:
    :class:`InputFileNotFound` if it does not exist, :class:`InputFileError` naming the
    cause if it is a folder, a device (``/dev/null``), a loop of symbolic links or
    forbidden. Pipes are files here (``softcurve fit <(...)``).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What it is, for the message (e.g. ``"experiment file"``); default: nothing.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    name = f"{what} {path}" if what else str(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        broken = " (a broken symbolic link)" if path.is_symlink() else ""
        raise InputFileNotFound(f"{name}: does not exist{broken}") from None
    except OSError as exc:
        raise InputFileError(f"{name}: cannot be read ({_cause(exc)})") from None
    if stat.S_ISDIR(mode):
        raise InputFileError(f"{name}: is a folder, not a file; give a file")
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) or stat.S_ISSOCK(mode):
        raise InputFileError(f"{name}: is a device, not a file; give a file")
    return path


def read_input(path, what: str = "") -> str:
    """The text of the file ``path``, checked by :func:`input_file`, read as UTF-8 with or
    without a byte-order mark (as spreadsheets and Windows editors save it).

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What it is, for the message (e.g. ``"experiment file"``).

    Returns
    -------
    str
        Its text, without the byte-order mark.
    """
    path = input_file(path, what)
    name = f"{what} {path}" if what else str(path)
    try:
        return path.read_bytes().decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputFileError(
            f"{name}: not a UTF-8 text file (byte {exc.start}); save it as UTF-8"
        ) from None
    except OSError as exc:
        raise InputFileError(f"{name}: cannot be read ({_cause(exc)})") from None


class FolderLocked(ParameterError):
    """Another process holds the lock of a folder (:func:`folder_lock`)."""


@contextlib.contextmanager
def folder_lock(folder, what: str = "softcurve"):
    """Hold an exclusive lock on ``folder`` (its file ``.softcurve.lock``) for the block,
    so that two processes never work in one folder at once; :class:`FolderLocked`
    naming the folder and the holder's pid when another process holds it.

    The lock is ``fcntl.flock``: released by the system when its holder exits, however
    it exits, so a killed process never leaves a stale lock. On systems without
    ``fcntl`` (Windows) the block runs without a lock.

    Parameters
    ----------
    folder : str or os.PathLike
        An existing folder.
    what : str
        What holds the lock (e.g. ``"sweep"``), for the message.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        yield
        return
    lock = Path(folder) / ".softcurve.lock"
    fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666 & ~_UMASK)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EWOULDBLOCK, errno.EACCES, errno.EAGAIN):
                raise
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip() or "unknown"
            raise FolderLocked(
                f"{folder}: another {what} is running in this folder (pid {holder}); "
                "wait for it to finish, or choose another output folder"
            ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        os.close(fd)  # releases the lock
