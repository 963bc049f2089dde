"""The one way shellform puts a file on disk, and the lock of an output folder.

Every result file is written to a fresh temporary file next to its target
(created exclusively, so no other run and no planted symlink can share it),
flushed to disk and renamed over the target. An interruption at any moment
therefore leaves the previous file or the new one, never half a file; the
rename replaces a symlink at the target name instead of writing through it.
``mkstemp`` creates files readable by their owner only: the finished file
gets the mode an ordinary ``open`` would give (``0o666`` less the umask).

:func:`output_lock` keeps a second run out of a folder a run is writing to.
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

from ..errors import ShellformError

LOCK_NAME = ".shellform.lock"

_umask_lock = threading.Lock()


class OutputError(ShellformError):
    """An output folder or file cannot be used (a file in its place, taken by another run, unwritable)."""


def current_umask() -> int:
    """The process umask, read without changing it where the system allows."""
    # os.umask can only be read by setting it; between the two calls another
    # thread would create files with the wrong mode, so read /proc first
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    with _umask_lock:
        mask = os.umask(0o077)
        os.umask(mask)
    return mask


def file_mode() -> int:
    """The permission bits ``open`` gives a new file under the current umask."""
    return 0o666 & ~current_umask()


def _finish(tmp: str, path: Path, fd: int | None = None) -> None:
    """Set the mode of ``tmp``, flush it to disk and rename it to ``path``."""
    own = fd is None
    if own:
        # by-name writers are done: reopen without following a link someone swapped in
        fd = os.open(tmp, os.O_RDONLY | os.O_NOFOLLOW)
    try:
        os.fchmod(fd, file_mode())
        os.fsync(fd)
    finally:
        if own:
            os.close(fd)
    os.replace(tmp, path)


def _temporary(path: Path) -> tuple[int, str]:
    folder = path.parent
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"cannot write {path}: {folder} is a file, not a folder")
    folder.mkdir(parents=True, exist_ok=True)
    if path.is_dir():
        raise OutputError(f"cannot write {path}: a folder of that name is in the way")
    # the suffix stays last: meshio and rhino3dm choose the format from it
    return tempfile.mkstemp(prefix=f".{path.stem}-", suffix=f".tmp{path.suffix}", dir=folder)


@contextlib.contextmanager
def open_atomic(path, mode: str = "wb", **kwargs) -> Iterator:
    """A file object on a temporary file that becomes ``path`` when the block ends without error.

    ``mode`` is ``"w"`` or ``"wb"``; ``kwargs`` go to :func:`os.fdopen`
    (``newline``, ``encoding``).
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"open_atomic writes new files: mode 'w' or 'wb', got {mode!r}")
    path = Path(path)
    fd, tmp = _temporary(path)
    try:
        with os.fdopen(fd, mode, **kwargs) as fh:
            yield fh
            fh.flush()
            _finish(tmp, path, fh.fileno())
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


@contextlib.contextmanager
def atomic_target(path) -> Iterator[Path]:
    """A temporary file name (same folder and suffix) for writers that only take a name.

    When the block ends without error the file becomes ``path``.
    """
    path = Path(path)
    fd, tmp = _temporary(path)
    os.close(fd)
    try:
        yield Path(tmp)
        _finish(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)


def write_text(path, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with open_atomic(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    return Path(path)


def write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    with open_atomic(path, "wb") as fh:
        fh.write(data)
    return Path(path)


def output_folder(path) -> Path:
    """``path`` as an output folder: created if missing, refused if a file is in its place."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"output folder {path}: a file of that name exists; choose another --out")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise OutputError(f"output folder {path}: a file is in the way of a folder on its path") from None
    except NotADirectoryError:
        raise OutputError(f"output folder {path}: a file is in the way of a folder on its path") from None
    return path


#: the names :func:`_temporary` gives: ".<stem>-<8 random characters>.tmp<suffix>"
_TEMPORARY = re.compile(r"^\..*-[a-z0-9_]{8}\.tmp(\.[A-Za-z0-9]+)?$")


def remove_stale_temporaries(folder) -> list[str]:
    """Remove the temporary files that writers killed mid-write left in ``folder``.

    Call it with the folder's lock held (:func:`output_lock`): then no other
    run can be writing there, so every temporary file is a leftover.
    Returns the names removed.
    """
    removed = []
    for entry in os.scandir(folder):
        if _TEMPORARY.match(entry.name) and (entry.is_file(follow_symlinks=False) or entry.is_symlink()):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(entry.path)
                removed.append(entry.name)
    return sorted(removed)


_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


def safe_name(text: str, limit: int = 80) -> str:
    """A file name made from ``text`` that stays in the folder it is joined to.

    Every character outside ``A-Z a-z 0-9 . _ -`` becomes ``_`` and leading
    dots go, runs of dots become one, so ``"../../x"`` gives ``"_._x"``.
    """
    name = re.sub(r"\.{2,}", ".", _UNSAFE.sub("_", str(text))).lstrip(".")[:limit]
    if not name or set(name) <= {"_", "."}:
        raise OutputError(f"{text!r} gives no usable file name: use letters, digits, '.', '_' or '-'")
    return name


def _holder(fd: int) -> str:
    try:
        text = os.pread(fd, 64, 0).decode("ascii", "replace").strip()
    except OSError:
        return "unknown"
    return text if text.isdigit() else "unknown"


@contextlib.contextmanager
def output_lock(folder) -> Iterator[Path]:
    """Hold the lock of an output folder for the duration of the block.

    The lock is an ``flock`` on ``folder/.shellform.lock``, which holds the
    pid of the run and is removed when the block ends. The kernel drops the
    lock when its process ends however it ends, so the file a killed run
    leaves behind never blocks the next one.

    Raises
    ------
    OutputError
        Another process holds the lock (the message names the folder and its pid).
    """
    import fcntl

    folder = output_folder(folder)
    path = folder / LOCK_NAME
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, file_mode())
        except OSError as exc:
            if exc.errno == errno.ELOOP:
                raise OutputError(f"output folder {folder}: {LOCK_NAME} is a symlink; remove it") from None
            raise OutputError(f"output folder {folder}: cannot create its lock file ({exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(fd)
            os.close(fd)
            raise OutputError(f"output folder {folder.resolve()} is in use by another shellform run (pid "
                              f"{holder}); wait for it to end or choose another --out") from None
        except OSError as exc:
            if exc.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.EINVAL):
                os.close(fd)
                raise
            # a file system without locks (some network mounts): run unguarded rather than not at all
            break
        # the run before may have removed the file between our open and our lock:
        # a lock on a removed file guards nothing, so lock the file now there
        try:
            same = os.path.samestat(os.fstat(fd), os.stat(path, follow_symlinks=False))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield folder
    finally:
        # removed while still locked, so no one can lock this file after us
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)
        os.close(fd)
