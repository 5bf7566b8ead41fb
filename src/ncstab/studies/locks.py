"""A lock on an output: one run at a time writes an archive, its parts and its figures.

The lock is the file ``<output>.lock`` beside the archive, holding the
holder's process id and host name.  It is held with ``fcntl.flock`` for as
long as the run lasts (the kernel releases it when the process dies, however
it dies) and removed when the run ends.  A run that finds the lock

* held (``flock`` refused, or the recorded process is alive on this host):
  raises :class:`~ncstab.studies.errors.OutputLockedError` naming the pid;
* left by a process that is gone (a *stale* lock, e.g. after ``kill -9``):
  takes it over and says so (:attr:`OutputLock.stale_pid`).

The lock is re-entrant within a thread: a run that already holds it (the
command line around :func:`~ncstab.studies.run_study_chunked`) takes it again
at no cost.
"""

from __future__ import annotations

import contextlib
import errno
import os
import socket
import threading
from pathlib import Path as FilePath
from types import TracebackType

from ncstab.studies.errors import DiskFullError, OutputLockedError, OutputNotWritableError, write_error

try:  # POSIX; elsewhere the recorded pid alone decides
    import fcntl
except ImportError:  # pragma: no cover
    fcntl = None  # type: ignore[assignment]

__all__ = ["OutputLock", "lock_path", "process_is_alive"]

#: Locks this process holds: (lock path, thread id) -> [lock, depth].
_HELD: dict[tuple[str, int], list] = {}


def lock_path(output: str | os.PathLike[str]) -> FilePath:
    """The lock file of an output archive: ``<output>.lock``."""
    output = FilePath(output)
    return output.with_name(output.name + ".lock")


def process_is_alive(pid: int) -> bool:
    """Whether a process with this id exists on this host (a zombie counts as gone)."""
    if pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    try:  # a zombie (dead, not yet reaped by its parent) holds nothing
        with open(f"/proc/{pid}/stat", "rb") as stat:
            return stat.read().rsplit(b")", 1)[-1].split()[0] != b"Z"
    except OSError:
        return True


def _holder(text: str) -> tuple[int | None, str]:
    """(pid, host) recorded in a lock file (``pid <n>`` and ``host <name>`` lines)."""
    pid, host = None, ""
    for line in text.splitlines():
        key, _, value = line.partition(" ")
        if key == "pid" and value.strip().isdigit():
            pid = int(value)
        elif key == "host":
            host = value.strip()
    return pid, host


class OutputLock:
    """The lock of one output archive (a context manager).

    Parameters
    ----------
    output
        The archive the run writes; the lock is :func:`lock_path` of it.

    Attributes
    ----------
    path
        The lock file.
    stale_pid
        After :meth:`acquire`: the pid of the dead process whose lock was
        taken over, or None.
    """

    def __init__(self, output: str | os.PathLike[str]) -> None:
        self.output = FilePath(output)
        self.path = lock_path(output)
        self.stale_pid: int | None = None
        self._descriptor: int | None = None
        self._key = (str(self.path.absolute()), threading.get_ident())

    def acquire(self) -> "OutputLock":
        """Take the lock (or take it again, in the thread that holds it).

        Raises
        ------
        OutputLockedError
            Another process (or another thread of this one) holds it.
        OutputNotWritableError, DiskFullError
            The lock file cannot be created.
        """
        held = _HELD.get(self._key)
        if held is not None:
            held[1] += 1  # (a stale lock was taken over, and said, by the outer holder)
            return self
        host = socket.gethostname()
        while True:
            descriptor = self._open()
            try:
                if fcntl is not None:
                    try:
                        fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    except OSError as error:
                        if error.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                            raise
                        self._refuse(descriptor, host, held_by_lock=True)
                # The holder before us may have removed the file after we opened it.
                if os.fstat(descriptor).st_ino != os.stat(self.path).st_ino:
                    os.close(descriptor)
                    continue
            except FileNotFoundError:
                os.close(descriptor)
                continue
            except BaseException:
                os.close(descriptor)
                raise
            break
        pid, recorded_host = _holder(os.pread(descriptor, 4096, 0).decode("utf-8", "replace"))
        if pid is not None and pid != os.getpid() and recorded_host in ("", host):
            if process_is_alive(pid):  # a holder without flock support (or on a file system without it)
                os.close(descriptor)
                self._refuse(None, host, pid=pid, recorded_host=recorded_host)
            self.stale_pid = pid
        elif pid is not None and recorded_host not in ("", host):
            os.close(descriptor)
            self._refuse(None, host, pid=pid, recorded_host=recorded_host)
        os.ftruncate(descriptor, 0)
        os.pwrite(descriptor, f"pid {os.getpid()}\nhost {host}\n".encode(), 0)
        self._descriptor = descriptor
        _HELD[self._key] = [self, 1]
        return self

    def _open(self) -> int:
        try:
            return os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as error:
            if isinstance(write_error(error, self.path), DiskFullError):
                raise DiskFullError(f"disk full: cannot create the lock {self.path}") from None
            raise OutputNotWritableError(f"cannot create the lock {self.path}: {error.strerror or error}") from None

    def _refuse(
        self, descriptor: int | None, host: str, held_by_lock: bool = False, pid: int | None = None,
        recorded_host: str = "",
    ) -> None:
        if descriptor is not None:
            pid, recorded_host = _holder(os.pread(descriptor, 4096, 0).decode("utf-8", "replace"))
        where = f" on {recorded_host}" if recorded_host and recorded_host != host else ""
        who = f"process {pid}{where}" if pid is not None else "another process"
        if pid == os.getpid() and held_by_lock:
            who = f"this process ({pid}, another thread)"
        raise OutputLockedError(
            f"{self.output} is being written by {who} (lock {self.path}); wait for that run "
            "to end, or remove the lock if no ncstab run is using it",
            pid=pid,
            host=recorded_host,
        )

    def release(self) -> None:
        """Give the lock up (the file is removed when the outermost holder releases it)."""
        held = _HELD.get(self._key)
        if held is None:
            return
        held[1] -= 1
        if held[1] > 0:
            return
        del _HELD[self._key]
        lock = held[0]
        with contextlib.suppress(OSError):
            lock.path.unlink()
        if lock._descriptor is not None:
            os.close(lock._descriptor)  # closing releases the flock
            lock._descriptor = None

    def __enter__(self) -> "OutputLock":
        return self.acquire()

    def __exit__(
        self, kind: type[BaseException] | None, value: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.release()
