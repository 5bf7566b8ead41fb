"""The ``ncstab`` command's own process: its output, its memory, how it exits.

:mod:`ncstab.cli` turns every error into one line and an exit code; this
module holds what concerns the process around it:

* :func:`stdout_closed`, :func:`discard_stdout` -- a reader of the output that
  has gone away (``ncstab info A | head -c 5``) ends the command quietly;
* :func:`out_of_memory` -- an error that is the system refusing memory (a
  library that cannot be mapped under ``ulimit -v``) is said to be so;
* :func:`exit_now` -- the command's process ends as soon as its work is
  done: the interpreter's finalization, which puts the default signal
  handlers back before it tears the modules down (seconds with numba and
  llvmlite loaded), would let a SIGTERM then end the process silently with
  143.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import sys
from typing import NoReturn

__all__ = ["discard_stdout", "exit_now", "out_of_memory", "stdout_closed"]


def out_of_memory(error: BaseException) -> str | None:
    """What says that an error (or the error it was raised from) is the system refusing
    memory: a ``MemoryError``, ``ENOMEM``, or a shared library that could not be mapped for
    lack of it (``libllvmlite.so`` under ``ulimit -v``: "failed to map segment"); else None."""
    seen: set[int] = set()
    current: BaseException | None = error
    while current is not None and id(current) not in seen:
        seen.add(id(current))
        text = (str(current).strip().splitlines() or [type(current).__name__])[0]
        lowered = text.lower()
        if isinstance(current, MemoryError) or getattr(current, "errno", None) == errno.ENOMEM or any(
            words in lowered for words in ("cannot allocate memory", "out of memory", "failed to map segment")
        ):
            return f"{type(current).__name__}: {text[:200]}" if text else type(current).__name__
        current = current.__cause__ or current.__context__
    return None


def stdout_closed() -> bool:
    """Whether standard output is a pipe whose reader has gone away (``| head -c 5``)."""
    try:
        poller = select.poll()
        poller.register(sys.stdout.fileno(), select.POLLOUT)
        return any(events & (select.POLLERR | select.POLLHUP) for _, events in poller.poll(0))
    except (AttributeError, OSError, ValueError):  # no poll, or no descriptor (captured in Python)
        return False


def discard_stdout() -> None:
    """Point standard output at /dev/null: what is left in its buffer, flushed at the
    interpreter's exit, goes nowhere instead of raising again."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def exit_now(code: object) -> NoReturn:
    """End the command's process with ``code`` (as ``sys.exit`` reads it), its output flushed,
    without the interpreter's finalization (see the module)."""
    if code is None:
        code = 0
    elif not isinstance(code, int):
        with contextlib.suppress(Exception):
            print(code, file=sys.stderr)
        code = 1
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except BrokenPipeError:  # the reader has gone away: what it did not read is not kept
            if stream is sys.stdout:
                discard_stdout()
        except Exception:  # noqa: BLE001 - a stream closed or replaced: nothing more to say
            pass
    os._exit(code & 0xFF)
