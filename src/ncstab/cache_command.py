"""``ncstab cache``: where ncstab's caches are, what they hold, and clearing them.

``ncstab cache`` (or ``ncstab cache info``) prints the cache root and one line
per cache folder of :data:`ncstab.cache.CACHE_KINDS`: its files and their size.
``ncstab cache compile`` compiles the compiled stepper's loops now
(:mod:`ncstab.engine_warmup`), so that no later study waits for the compiler.
``ncstab cache clear`` removes those folders (:func:`ncstab.cache.clear_cache`)
and says what it freed; a root that does not exist has nothing to clear (exit
code 0).  A file that cannot be removed is the error of a write that failed
(exit code 3, docs/when-things-go-wrong.md), named in one line.

Only the standard library is imported: the command answers at once.
"""

from __future__ import annotations

import argparse
import errno
from typing import Any

from ncstab.sizes import readable_size

__all__ = ["add_cache_parser", "cache_lines", "command_cache", "readable_size"]


def _count(files: int) -> str:
    return f"{files:,} file" if files == 1 else f"{files:,} files"


def _row(name: str, files: int, size: int, description: str = "") -> str:
    """One line of the table: at most 100 characters (for up to 999,999 files)."""
    return f"  {name:<13}  {_count(files):>13}  {readable_size(size):>9}  {description}".rstrip()


def cache_lines() -> list[str]:
    """What ``ncstab cache`` prints: the root, a line per cache folder, the total.

    Lines are at most 100 characters, but the first, which holds the root's
    path whole.
    """
    from ncstab.cache import CACHE_KINDS, cache_root, cache_usage

    root = cache_root()
    lines = [f"cache root: {root}" + ("" if root.is_dir() else " (nothing cached yet)")]
    usages = cache_usage()
    lines += [_row(usage.kind, usage.files, usage.size, CACHE_KINDS[usage.kind]) for usage in usages]
    lines.append(_row("total", sum(u.files for u in usages), sum(u.size for u in usages)))
    try:
        others = sum(1 for entry in root.iterdir() if entry.name not in CACHE_KINDS) if root.is_dir() else 0
    except OSError:
        others = 0
    if others:
        entries = "1 other entry" if others == 1 else f"{others:,} other entries"
        lines.append(f"  and {entries} under the root, not a cache of ncstab (ncstab cache clear leaves them)")
    return lines


def _clear() -> int:
    """``ncstab cache clear``: remove the cache folders; exit code 0, or raise for what stayed."""
    from ncstab.cache import clear_cache
    from ncstab.studies.errors import OutputNotWritableError, WriteError

    clearance = clear_cache()
    if not clearance.root.exists():
        print(f"nothing to clear: the cache root {clearance.root} does not exist")
        return 0
    if not clearance.removed:
        print(f"nothing to clear: no ncstab cache folder in {clearance.root}")
        return 0
    print(f"cache root: {clearance.root}")
    for usage in clearance.removed:
        print(f"  removed {usage.kind}: {_count(usage.files)}, {readable_size(usage.size)}")
    freed = f"freed {readable_size(clearance.size)} ({_count(clearance.files)})"
    if not clearance.failures:
        print(freed)
        return 0
    first, *more = clearance.failures
    others = f" (and {len(more):,} more)" if more else ""
    kind = OutputNotWritableError if first.errno in (errno.EACCES, errno.EPERM, errno.EROFS) else WriteError
    raise kind(f"cannot remove {first.filename or clearance.root}: {first.strerror or first}{others}",
               kept=f"{freed}; the rest is kept")


def _compile(processes: int | None) -> int:
    """``ncstab cache compile``: compile every loop of the compiled stepper now; exit code 0,
    or a :class:`~ncstab.studies.errors.RunError` (exit code 3) naming what failed."""
    import os

    from ncstab.cache import cache_root, unusable_cache
    from ncstab.engine_warmup import ENGINE_ITEMS, compile_loops, groups_by_model
    from ncstab.studies.errors import RunError

    reason = unusable_cache("compiled")
    if reason is not None:  # before any work: nothing compiled could be kept
        raise RunError(f"nothing can be cached: {reason}", kept="nothing was compiled")

    if processes is None:
        processes = min(2, os.cpu_count() or 1)
    groups = groups_by_model(ENGINE_ITEMS, processes)
    print(f"compiling the compiled stepper's 2 loops (the reduced diamond's, the general models') into {cache_root() / 'compiled'} in {len(groups)} "
          f"process{'es' if len(groups) > 1 else ''} (30-90 s a loop on 2 cores, once per machine) ...", flush=True)

    def done(group: tuple[str, ...], seconds: float) -> None:
        print(f"  compiled for {', '.join(group)} in {seconds:.0f} s", flush=True)

    try:
        seconds = compile_loops(ENGINE_ITEMS, processes, done)
    except (OSError, RuntimeError) as error:
        raise RunError(f"compiling failed: {error}", kept="the loops compiled before it stay cached") from None
    print(f"done in {seconds:.0f} s: studies of any size now start at once")
    return 0


def command_cache(args: argparse.Namespace) -> int:
    """``ncstab cache [info]``: print the caches (:func:`cache_lines`); ``clear``: remove them;
    ``compile``: compile the compiled stepper's loops now."""
    if args.action == "clear":
        return _clear()
    if args.action == "compile":
        return _compile(args.processes)
    print("\n".join(cache_lines()))
    return 0


def add_cache_parser(sub: Any, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``cache`` and its actions ``info`` (the default) and ``clear`` to the subcommands ``sub``."""
    cache = sub.add_parser(
        "cache",
        help="where ncstab's caches are and what they hold; 'ncstab cache clear' removes them",
        description="Print the cache root ($NCSTAB_CACHE_DIR, else $XDG_CACHE_HOME/ncstab, else "
        "~/.cache/ncstab) and, for each of ncstab's cache folders, its files and their size. "
        "'ncstab cache clear' removes those folders (what they held is derived again when needed; "
        "nothing else under the root is touched). 'ncstab cache compile' compiles the engine's "
        "loops now, once per machine (a small study runs without them; a large one would compile "
        "them first). Exit code 0; 3: a file could not be removed, or compiling failed.",
        usage="%(prog)s [-h] [--debug] [info | clear | compile [--processes N]]",
        parents=parents,
    )
    actions = cache.add_subparsers(dest="action", metavar="ACTION")
    actions.add_parser("info", help="the cache root and each cache folder's files and size (the default)",
                       parents=parents)
    actions.add_parser("clear", help="remove ncstab's cache folders; say what was freed", parents=parents)
    compile_ = actions.add_parser(
        "compile", help="compile the compiled stepper's loops now (30-90 s each, once per machine)", parents=parents
    )
    compile_.add_argument("--processes", type=_positive, metavar="N", default=None,
                          help="processes compiling side by side (default: 2, or 1 on one core)")
    cache.set_defaults(handler=command_cache, action="info", processes=None)


def _positive(text: str) -> int:
    """A whole number of at least 1 (``--processes``)."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number of at least 1, not {text!r}")
    return value
