"""SIGINT, SIGTERM and SIGHUP stop a command cleanly: one exception, then the cleanup runs.

Inside :func:`stop_on_signals`, the first SIGINT (Ctrl-C), SIGTERM or SIGHUP raises
:class:`~ncstab.studies.errors.RunInterrupted` in the main thread, so that
every ``with`` block and ``except BaseException`` cleanup on the way out runs:
the dask cluster is closed, temporary files are removed, finished parts stay.
A second signal during that cleanup stops the process at once (exit code 3,
one line): what it leaves is cleaned by the next run on the same output.
Outside it, while the ``ncstab`` process starts or ends,
:func:`stop_at_once_on_signals` says the same in one line and exits 3.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Iterator
from types import FrameType

from ncstab.studies.errors import EXIT_RUN_INCOMPLETE, RunInterrupted

__all__ = ["STOP_SIGNALS", "stop_at_once_on_signals", "stop_on_signals"]

#: The signals that stop a run cleanly (SIGHUP: the terminal closed; POSIX only).
STOP_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
)


def stop_at_once_on_signals(prefix: str = "ncstab") -> None:
    """Make SIGINT/SIGTERM/SIGHUP stop the process at once with one line and exit code 3.

    For the ``ncstab`` command's own process, before and after
    :func:`stop_on_signals` (while it starts, and once a run has ended and
    the interpreter exits): archives and figures are written whole or not at
    all, so nothing is left half-written.  The handlers are not restored.
    """
    if threading.current_thread() is not threading.main_thread():
        return

    def handler(number: int, frame: FrameType | None) -> None:
        name = signal.Signals(number).name
        with contextlib.suppress(Exception):
            sys.stdout.flush()
        os.write(2, f"{prefix}: interrupted by {name}; stopped at once (archives and figures are written "
                    "whole or not at all)\n".encode())
        os._exit(EXIT_RUN_INCOMPLETE)

    for number in STOP_SIGNALS:
        signal.signal(number, handler)


@contextlib.contextmanager
def stop_on_signals(prefix: str = "ncstab") -> Iterator[None]:
    """Turn SIGINT/SIGTERM/SIGHUP into :class:`RunInterrupted` while the block runs (main thread only).

    Parameters
    ----------
    prefix
        Start of the line printed if a second signal stops the process at once.
    """
    if threading.current_thread() is not threading.main_thread():
        yield  # signal handlers can only be set in the main thread
        return
    received: list[str] = []

    def handler(number: int, frame: FrameType | None) -> None:
        name = signal.Signals(number).name
        received.append(name)
        if len(received) == 1:
            raise RunInterrupted(name)
        os.write(2, f"{prefix}: {name} again: stopped at once (temporary files are removed by the next run "
                    "on this output)\n".encode())
        os._exit(EXIT_RUN_INCOMPLETE)

    previous = {number: signal.signal(number, handler) for number in STOP_SIGNALS}
    try:
        yield
    finally:
        for number, action in previous.items():
            signal.signal(number, action)
