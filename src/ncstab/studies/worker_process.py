"""Imported by the forkserver that starts a local cluster's workers: they ignore SIGINT.

A Ctrl-C in a terminal sends SIGINT to every process of the foreground
process group: the ``ncstab run`` process and, without this, each dask
worker, which would print its own ``KeyboardInterrupt`` traceback.  The
forkserver imports this module (``WORKER_PRELOAD`` of
:mod:`ncstab.studies.cluster`) before it records its signal handlers, and
restores them in every worker it forks: the workers ignore SIGINT, and the
run process, which does stop, closes them.
"""

from __future__ import annotations

import signal

__all__: list[str] = []

signal.signal(signal.SIGINT, signal.SIG_IGN)
