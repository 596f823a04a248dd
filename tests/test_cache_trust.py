"""The compiled-library cache trusts only what the user alone can write (issue 44, item 4).

A library in the cache runs inside softcurve: before, one planted in a folder other
users can write, with a checksum line for the key it is looked up by, ran its
constructor in the process. Now, as ssh does with ``authorized_keys``, the cache folder,
each folder above it and each library and checksum file must be the user's (or root's)
and writable by no one else, unless the cache is declared shared with the folder's
group (``SOFTCURVE_SHARED_CACHE=1``); a folder every user can write is refused even
then. A refused folder is not read: builds go to a temporary folder of the process, with
one ``CacheWarning`` naming the folder and why.

Every case runs in a child process (a planted constructor runs there, and the dynamic
loader keeps a library it has opened by its path); the cached function is a small CasADi
function (it compiles in a second). The planted library is ``tests/c/planted.c``: it
defines the symbol the function is looked up by, and its constructor creates a marker
file.
"""

from __future__ import annotations

import grp
import os
import pwd
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from softcurve.compiled import _cache as cache_module
from softcurve.compiled._cache import checksum_file

COMPILER = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
pytestmark = [
    pytest.mark.skipif(COMPILER is None, reason="no C compiler found"),
    pytest.mark.skipif(not hasattr(os, "geteuid"), reason="no POSIX owners and modes"),
]
ROOT = hasattr(os, "geteuid") and os.geteuid() == 0
PLANTED = Path(__file__).parent / "c" / "planted.c"
NAME = "softcurve_test_trust"
CHILD = """
import sys, warnings
import casadi as ca
from softcurve.compiled import compile_function
warnings.simplefilter("always")
x = ca.SX.sym("x", 2)
f = compile_function(ca.Function(sys.argv[1], [x], [3 * x[0] + x[1]]))
print(float(f([1.0, 2.0])), f.class_name())
"""
EXPECTED = "5.0 External"


def child(cache: Path, marker: Path | None = None, shared: bool = False, umask=None):
    """The child process compiling the function with ``cache``: ``(exit code, stdout,
    stderr)``."""
    env = {**os.environ, "SOFTCURVE_CACHE_DIR": str(cache)}
    env.pop("SOFTCURVE_SHARED_CACHE", None)
    if shared:
        env["SOFTCURVE_SHARED_CACHE"] = "1"
    if marker is not None:
        env["SOFTCURVE_TEST_MARKER"] = str(marker)
    done = subprocess.run(
        [sys.executable, "-c", CHILD, NAME],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=None if umask is None else lambda: os.umask(umask),
    )
    return done.returncode, done.stdout.strip(), done.stderr


@pytest.fixture(scope="module")
def genuine(tmp_path_factory):
    """``(library, key)``: the function's library as a child process builds it (its
    checksum file records the key a child computes)."""
    folder = tmp_path_factory.mktemp("genuine")
    code, out, err = child(folder)
    assert code == 0 and out == EXPECTED and "Warning" not in err, err
    (library,) = folder.glob("function_*.so")
    return library, checksum_file(library).read_text().split()[5]


@pytest.fixture(scope="module")
def planted(genuine, tmp_path_factory):
    """The bytes of ``tests/c/planted.c`` compiled, defining the function's name."""
    out = tmp_path_factory.mktemp("planted") / "planted.so"
    command = [COMPILER, "-shared", "-fPIC", f"-DSYMBOL={NAME}", str(PLANTED), "-o", str(out)]
    subprocess.run(command, check=True, capture_output=True)
    return out.read_bytes()


def plant(folder: Path, genuine, data: bytes) -> Path:
    """``data`` installed in ``folder`` under the genuine library's name, with a
    checksum file that matches it and records the genuine key."""
    library, key = genuine
    folder.mkdir(exist_ok=True)
    return cache_module.install(folder / library.name, data, key)


def _other_user() -> int:
    return pwd.getpwnam("nobody").pw_uid


def _other_group() -> int:
    """A group other than the user's own (as root: any existing non-root group)."""
    own = os.getegid()
    return next(g.gr_gid for g in grp.getgrall() if g.gr_gid != own)


def _world_writable(cache, library):
    cache.chmod(0o777)
    return cache, "is writable by every user (mode 0777)"


def _group_writable(cache, library):
    os.chown(cache, -1, _other_group())
    cache.chmod(0o775)
    return cache, "is writable by its group (mode 0775"


def _another_users(cache, library):
    os.chown(cache, _other_user(), -1)
    return cache, f"is owned by another user (uid {_other_user()}"


def _open_above(cache, library):
    cache.parent.chmod(0o777)  # no sticky bit: others may rename the cache folder
    return cache, f"is writable by every user (mode 0777) ({cache.parent}, above it)"


def _world_writable_library(cache, library):
    library.chmod(0o666)
    return library, "is writable by every user (mode 0666)"


PLANTED_IN = {
    "world_writable_folder": (_world_writable, False),
    "group_writable_folder": (_group_writable, True),
    "another_users_folder": (_another_users, True),
    "folder_above_open": (_open_above, False),
    "world_writable_library": (_world_writable_library, False),
}


@pytest.mark.parametrize("case", PLANTED_IN)
def test_a_planted_library_is_not_loaded(genuine, planted, tmp_path, case):
    """Before: the planted library's constructor ran (the marker file), then CasADi
    refused it as a function and it was rebuilt."""
    expose, needs_root = PLANTED_IN[case]
    if needs_root and not ROOT:
        pytest.skip("giving a folder to another user or group needs root")
    cache = tmp_path / "above" / "cache"
    cache.parent.mkdir()
    library = plant(cache, genuine, planted)
    where, reason = expose(cache, library)
    marker = tmp_path / "marker"
    code, out, err = child(cache, marker)
    assert code == 0 and out == EXPECTED, err
    assert not marker.exists(), "the planted library's constructor ran"
    assert "CacheWarning" in err and str(where) in err and reason in err, err
    assert err.count("CacheWarning") == 1, err


def test_a_world_writable_folder_is_refused_even_when_shared(genuine, planted, tmp_path):
    cache = tmp_path / "cache"
    plant(cache, genuine, planted)
    cache.chmod(0o777)
    code, out, err = child(cache, tmp_path / "marker", shared=True)
    assert code == 0 and out == EXPECTED, err
    assert not (tmp_path / "marker").exists()
    assert f"{cache} (SOFTCURVE_CACHE_DIR) is writable by every user (mode 0777)" in err, err


@pytest.mark.skipif(not ROOT, reason="giving files to another user and group needs root")
def test_a_declared_shared_cache_loads_its_groups_libraries(genuine, tmp_path):
    """A library another user of the group built, in a folder the group can write: used
    as it is when the cache is declared shared, refused (and left alone) otherwise."""
    cache = tmp_path / "cache"
    library = plant(cache, genuine, genuine[0].read_bytes())
    os.chown(cache, _other_user(), _other_group())
    cache.chmod(0o2775)
    for path in (library, checksum_file(library)):
        os.chown(path, _other_user(), _other_group())
    before = library.stat()
    code, out, err = child(cache, shared=True)
    assert code == 0 and out == EXPECTED and "Warning" not in err, err
    code, out, err = child(cache)
    assert code == 0 and out == EXPECTED, err
    assert f"{cache} (SOFTCURVE_CACHE_DIR) is owned by another user" in err, err
    assert "SOFTCURVE_SHARED_CACHE=1" in err and err.count("CacheWarning") == 1, err
    assert library.stat().st_ino == before.st_ino and sorted(os.listdir(cache)) == sorted(
        [library.name, checksum_file(library).name]
    )


def test_a_new_cache_is_writable_by_the_user_alone_whatever_the_umask(tmp_path):
    """With umask 002 (user private groups) a new cache folder and its files are made
    not group-writable, so the next process trusts them (no rebuild at every run)."""
    cache = tmp_path / "new" / "cache"
    code, out, err = child(cache, umask=0o002)
    assert code == 0 and out == EXPECTED and "Warning" not in err, err
    (library,) = cache.glob("function_*.so")
    modes = {p.name: p.stat().st_mode & 0o777 for p in (cache, library, checksum_file(library))}
    assert modes == {cache.name: 0o755, library.name: 0o644, f"{library.name}.sha256": 0o644}
    before = library.stat().st_ino
    code, out, err = child(cache, umask=0o002)
    assert code == 0 and out == EXPECTED and "Warning" not in err, err
    assert library.stat().st_ino == before
