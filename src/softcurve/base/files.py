"""Files written whole or not at all: a temporary file in the target's folder, renamed
over the target when complete, so readers see the old file or the new one, never a part.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

_UMASK = os.umask(0o022)
os.umask(_UMASK)  # read once: files are created with the usual permissions


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path next to ``path``; rename it over ``path`` on success,
    delete it on failure, so readers see the old file or the complete new one.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; its folder is created if missing.

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
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def atomic_write(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` whole or not at all.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; its folder is created if missing.
    data : bytes
        The file's complete content.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return Path(path)
