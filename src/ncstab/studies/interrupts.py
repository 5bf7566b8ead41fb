"""SIGINT and SIGTERM stop a command cleanly: one exception, then the cleanup runs.

Inside :func:`stop_on_signals`, the first SIGINT (Ctrl-C) or SIGTERM raises
:class:`~ncstab.studies.errors.RunInterrupted` in the main thread, so that
every ``with`` block and ``except BaseException`` cleanup on the way out runs:
the dask cluster is closed, temporary files are removed, finished parts stay.
A second signal during that cleanup stops the process at once (exit code 3,
one line): what it leaves is cleaned by the next run on the same output.
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator
from types import FrameType

from ncstab.studies.errors import EXIT_RUN_INCOMPLETE, RunInterrupted

__all__ = ["STOP_SIGNALS", "stop_on_signals"]

#: The signals that stop a run cleanly.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def stop_on_signals(prefix: str = "ncstab") -> Iterator[None]:
    """Turn SIGINT/SIGTERM into :class:`RunInterrupted` while the block runs (main thread only).

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
