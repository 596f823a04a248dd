"""Who may write the compiled-library cache: a library in it runs inside softcurve, so
whoever can put one there can run code as the user, as ssh's ``authorized_keys`` can.

As OpenSSH checks the folders of its keys, the cache folder and each folder above it
must be owned by the user (or root) and writable by no one else, and so must each
library and checksum file in it. A folder above it that everyone may write is accepted
with the sticky bit (``/tmp``): others cannot rename or delete what is in it. The cache
folder itself never: they could still add a library under a name softcurve has not
written yet. A group that holds the user alone (a user private group, as Debian's ssh
accepts) counts as the user.

A cache shared by a group (a cluster's, docs/sweeps.md) is declared with
``SOFTCURVE_SHARED_CACHE=1``: then libraries built by other users and folders their
group can write are accepted (the group is trusted to run code in each other's
processes); a folder or file that every user can write is still refused.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

SHARED_VARIABLE = "SOFTCURVE_SHARED_CACHE"
"""The environment variable that declares the cache shared with the folder's group."""


def shared() -> bool:
    """Whether the user declared the cache shared (``SOFTCURVE_SHARED_CACHE`` set, and
    not ``0``)."""
    return os.environ.get(SHARED_VARIABLE, "") not in ("", "0")


def _private_group(gid: int, uid: int) -> bool:
    """Whether the group ``gid`` holds the user ``uid`` alone: their primary group, of
    their name, with no other member listed."""
    import grp  # POSIX only, as this whole check
    import pwd

    try:
        user, group = pwd.getpwuid(uid), grp.getgrgid(gid)
    except KeyError:
        return False
    return (
        user.pw_gid == gid and group.gr_name == user.pw_name and set(group.gr_mem) <= {user.pw_name}
    )


def _problem(status: os.stat_result, is_cache: bool, shared_: bool) -> str | None:
    """Why an entry of these owner and mode is not trusted, or None; ``is_cache`` for the
    cache folder or a file in it (no sticky bit exception)."""
    uid = os.geteuid()
    if status.st_uid not in (uid, 0) and not shared_:
        return (
            f"is owned by another user (uid {status.st_uid}; declare a cache shared with "
            f"{SHARED_VARIABLE}=1)"
        )
    mode = stat.S_IMODE(status.st_mode)
    sticky = stat.S_ISDIR(status.st_mode) and mode & stat.S_ISVTX and not is_cache
    if mode & stat.S_IWOTH and not sticky:
        return f"is writable by every user (mode {mode:04o})"
    if mode & stat.S_IWGRP and not (sticky or shared_ or _private_group(status.st_gid, uid)):
        return (
            f"is writable by its group (mode {mode:04o}; declare a cache shared with the "
            f"group with {SHARED_VARIABLE}=1)"
        )
    return None


def folder_problem(folder: Path, shared_: bool) -> str | None:
    """Why libraries in ``folder`` must not be trusted, or None: the folder (when it
    exists) and each folder above it, by their real paths.

    Parameters
    ----------
    folder : pathlib.Path
        The cache folder.
    shared_ : bool
        Whether the user declared it shared (:func:`shared`).

    Returns
    -------
    str or None
        The reason in words, naming the folder at fault.
    """
    if not hasattr(os, "geteuid"):  # no POSIX owners and modes (Windows)
        return None
    real = folder.resolve()
    for path in [real, *real.parents]:
        try:
            status = path.stat()
        except (FileNotFoundError, NotADirectoryError):
            continue  # made by softcurve, writable by the user alone (or cannot be made)
        except OSError as exc:
            return f"cannot be checked ({path}: {exc.strerror or exc})"
        problem = _problem(status, path == real, shared_)
        if problem is not None:
            where = "" if path == folder else f" ({path}{', above it' * (path != real)})"
            return f"{problem}{where}: a library another user puts there would run in softcurve"
    return None


def file_problem(status: os.stat_result, shared_: bool) -> str | None:
    """Why a library or checksum file of this ``os.stat`` must not be trusted, or None.

    Parameters
    ----------
    status : os.stat_result
        The file's.
    shared_ : bool
        Whether the user declared the cache shared (:func:`shared`).

    Returns
    -------
    str or None
    """
    if not hasattr(os, "geteuid"):
        return None
    return _problem(status, True, shared_)
