"""The ``ncstab`` command: a thin layer over the library."""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import NoReturn, Sequence

import ncstab
from ncstab.cli_process import discard_stdout, exit_now, out_of_memory, stdout_closed
from ncstab.run_command import command_run
from ncstab.terminal_text import fitted_table, printable

__all__ = ["advise_numpy_memory", "build_parser", "main"]


class OneLineErrorParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit code 2, as argparse's)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def command_laws(args: argparse.Namespace) -> int:
    """Print the law catalogue, or a study's laws, with each law's computed class;
    ``--explain NAME``: the derivation of one law's class (exit 2: bad study or name)."""
    from ncstab.laws import law_definition, law_names
    from ncstab.symbolic import class_summary, kinematic_integrability, law_explanation

    study = None
    if args.study is not None:
        from ncstab.studies import StudyFileError, load_study

        try:
            study = load_study(args.study)
        except StudyFileError as error:
            print(str(error), file=sys.stderr)
            return 2
        except OSError as error:
            print(f"{args.study}: cannot read the study file: {error}", file=sys.stderr)
            return 2
    if args.explain is not None:
        try:
            definition = study.law_definition(args.explain) if study is not None else law_definition(args.explain)
        except ValueError as error:
            where = f" in {args.study}" if study is not None else " (a user law needs its study: ncstab laws STUDY.toml --explain NAME)"
            print(f"ncstab laws: {error}{where}", file=sys.stderr)
            return 2
        print(law_explanation(definition))
        return 0
    names = list(study.laws) if study is not None else law_names(with_modifiers=args.all)
    rows, notes = [], []
    for name in names:
        definition = study.law_definition(name) if study is not None else law_definition(name)
        summary = class_summary(definition)  # classified once, then read from the cache directory
        rows.append([name, summary.kind, definition.equations])
        notes.append([f"energy W(l, alpha): {summary.energy or '- (none)'}", f"decided by: {summary.reason}"])
    if study is not None:
        print(printable(f"{args.study}: the laws of study {study.name!r}"))
    table = fitted_table(rows, ["law", "class", "seed"], notes=notes)  # 100 columns
    print("\n".join(printable(line) for line in table.splitlines()))
    print()
    print(f"System kinematics: {kinematic_integrability()}")
    print("Variables are dimensionless (seed Eq. 37): l = l/2R, N, T in units of 2R k_n,")
    print("W in units of k_n (2R)^2 per contact, gamma = k_t/k_n.")
    return 0


def _existing_archive(archive: str) -> Path:
    """The archive's path; InvalidInputError (exit 2) where there is no such file."""
    from ncstab.studies.errors import InvalidInputError

    path = Path(archive)
    if not path.exists():
        raise InvalidInputError(f"no such archive: {path}")
    return path


def command_plot(args: argparse.Namespace) -> int:
    """Redraw the figures of an archive from the archive alone.

    The archive is opened lazily (:func:`ncstab.studies.open_study_lazily`:
    its invariants and the digests of its small variables checked on opening,
    HDF5's checksum of each chunk as the figures read it), so only what the
    figures show is read.  Every figure is built before any is written; where
    building fails, the whole archive is read and verified
    (:func:`ncstab.studies.open_study`) to say which variable cannot be read.
    """
    from ncstab.plotting import draw_figures, figure_kinds
    from ncstab.studies import open_study, open_study_lazily
    from ncstab.studies.errors import ArchiveError, InvalidInputError, WriteError, write_error

    from ncstab.dask_probe import defer_dask_array_import
    from ncstab.heap import settle

    defer_dask_array_import()  # xarray's probe for dask arrays without importing dask.array (0.8 s)
    path = _existing_archive(args.archive)
    kinds = args.kinds.split(",") if args.kinds else None
    directory = Path(args.directory) if args.directory else path.parent
    try:
        with open_study_lazily(path) as dataset:
            try:
                figure_kinds(dataset, kinds)
            except ValueError as error:  # an unknown kind, said before anything is read
                raise InvalidInputError(f"{path}: cannot draw the figures: {error}") from None
            settle()  # the imports' objects out of the collector's scans while drawing (ncstab.heap)
            figures = draw_figures(dataset, directory, kinds=kinds, stem=path.stem)
    except (ArchiveError, InvalidInputError):
        raise
    except Exception as error:
        open_study(path)  # a variable that cannot be read: ArchiveError naming it
        if isinstance(error, ValueError):
            raise InvalidInputError(f"{path}: cannot draw the figures: {error}") from None
        if isinstance(error, OSError):
            raise (write_error(error, directory) or WriteError(f"could not write the figures: {error}")) from error
        raise
    for figure in figures:
        print(figure)
    return 0


def command_info(args: argparse.Namespace) -> int:
    """Summarise an archive: study, sweep, statuses, then each law's statuses and events
    (:func:`ncstab.studies.summary.archive_summary`; only the archive's small variables are read)."""
    from ncstab.studies.archive_contents import open_archive_contents
    from ncstab.studies.errors import InvalidInputError
    from ncstab.studies.summary import archive_summary

    path = Path(args.archive)
    if not path.exists():
        raise InvalidInputError(f"no such archive: {path}")
    with open_archive_contents(path) as contents:
        lines = archive_summary(contents, path) if contents is not None else None
    if lines is None:  # encodings only xarray decodes
        from ncstab.studies import open_study_lazily

        with open_study_lazily(path) as dataset:
            lines = archive_summary(dataset, path)
    print("\n".join(printable(line) for line in lines))  # a description's ESC or NUL shown, not obeyed
    return 0


def build_parser() -> argparse.ArgumentParser:
    debug = argparse.ArgumentParser(add_help=False)
    debug.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                       help="show the Python traceback of an error instead of one line")
    parser = OneLineErrorParser(
        prog="ncstab",
        description=(
            "Stability analysis of non-conservative discrete systems: the diamond "
            "granular chain with hypo- and hyperelastic contact laws."
        ),
    )
    parser.add_argument("--version", action="version", version=f"ncstab {ncstab.__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the Python traceback of an error instead of one line")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    laws = sub.add_parser(
        "laws",
        help="print the law catalogue (or a study's laws) and each law's computed class",
        description="Print the law catalogue, or the laws of a study file (its user laws too), with each "
        "law's class computed from its expressions. --explain NAME shows the derivation: which condition "
        "fails and its residual. Exit code 2: invalid study file or unknown law.",
    )
    laws.add_argument("study", nargs="?", metavar="STUDY.toml", help="a study file: list its laws instead")
    laws.add_argument(
        "--all", action="store_true", help="also list every law with the no_tension modifier"
    )
    laws.add_argument("--explain", metavar="NAME",
                      help="the derivation of one law's class (a catalogue law, or a law of STUDY.toml)")
    laws.set_defaults(handler=command_laws)

    run = sub.add_parser(
        "run",
        help="run study files: write the NetCDF archive and the figures",
        description="Run study files (TOML). Exit code 0: every case finished or stopped at an "
        "event; 1: some case failed (the archive is written); 2: invalid input, nothing is run or "
        "written (a study file, an option, a study over its limits); 3: the run could not complete "
        "(output not writable or in use, disk full, cluster unreachable or lost, interrupted), "
        "with what was kept. See docs/when-things-go-wrong.md.",
        parents=[debug],
    )
    run.add_argument("studies", nargs="+", metavar="STUDY.toml", help="study files")
    run.add_argument("-o", "--output", metavar="OUT.nc", help="archive path (one study only): absent, or an "
                     "ncstab archive replaced with --overwrite; default the study's [output] file, else "
                     "results/<study name>.nc")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    run.add_argument("--chunk-cases", type=int, metavar="N",
                     help="run in chunks of at most N cases, each kept in OUT.nc.parts/ as it "
                          "finishes (default: 8192 in this process; with --workers, about four chunks per "
                          "worker, 256 to 8192). Studies of more than 8192 cases per law always run in chunks")
    again = run.add_mutually_exclusive_group()
    again.add_argument("--resume", action="store_true",
                       help="keep the chunks an interrupted run left in OUT.nc.parts/ and compute "
                            "only the missing ones")
    again.add_argument("--overwrite", action="store_true",
                       help="replace an existing ncstab archive at OUT.nc, and discard the chunks an "
                            "interrupted run left in OUT.nc.parts/ (without it, a run refuses both; any "
                            "other file at OUT.nc is never replaced)")
    run.add_argument("--max-cases", type=int, metavar="N",
                     help="run at most N cases (default: the study's [options] max_cases, 1,000,000 "
                          "unless given)")
    where = run.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, metavar="N",
                       help="run the chunks on a local dask cluster of N worker processes "
                            "(needs ncstab[distributed])")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="run the chunks on an existing dask.distributed cluster "
                            "(e.g. tcp://host:8786; needs ncstab[distributed])")
    run.add_argument("--threads", type=int, metavar="N",
                     help="threads of this process's compiled stepper (default: every core, or "
                          "NUMBA_NUM_THREADS); results are the same for any N")
    run.add_argument("--scheduler-timeout", type=float, default=30.0, metavar="SECONDS",
                     help="seconds to wait for the scheduler to answer (default 30)")
    run.set_defaults(handler=command_run)

    plot = sub.add_parser("plot", help="redraw the figures of an archive", parents=[debug])
    plot.add_argument("archive", metavar="OUT.nc")
    plot.add_argument("--kinds", help="comma-separated figure kinds (default: the study's)")
    plot.add_argument("--directory", help="where to write the PNGs (default: beside the archive)")
    plot.set_defaults(handler=command_plot)

    info = sub.add_parser("info", help="summarise an archive: study, sweep, statuses, events", parents=[debug])
    info.add_argument("archive", metavar="OUT.nc")
    info.set_defaults(handler=command_info)

    from ncstab.analyse_command import add_analyse_parser  # the standard library only
    from ncstab.cache_command import add_cache_parser  # the standard library only

    add_analyse_parser(sub, [debug])
    add_cache_parser(sub, [debug])
    return parser


def advise_numpy_memory() -> None:
    """Switch numpy's transparent-huge-page advice off for a command, unless the
    environment sets ``NUMPY_MADVISE_HUGEPAGE`` (numpy reads it once, on import, so this
    acts only before numpy is imported: not where ``main`` is called from Python).

    numpy advises the kernel to back arrays of 4 MB and more with huge pages.  On a
    virtual machine whose host takes memory back, the first touch of such pages stalled
    for seconds: ``ncstab run studies/stability_diagram.toml`` took 11.6-13.1 s with the
    advice and 6.4-6.9 s without, for the same 7 s of CPU (docs/paths.md).
    """
    if "numpy" not in sys.modules:
        os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``ncstab`` command; its exit code (docs/when-things-go-wrong.md).

    Called without ``argv`` (the ``ncstab`` command itself, ``python -m ncstab``),
    it reads ``sys.argv`` and ends the process when done
    (:func:`~ncstab.cli_process.exit_now`: a signal after the work cannot
    end it silently during the interpreter's finalization); with ``argv``
    (from Python) it returns the exit code.

    A named error (:mod:`ncstab.studies.errors`) is printed as one line,
    ``ncstab <command>: <what>; <what was kept>``, and gives its exit code (2
    invalid input, 3 the run could not complete); SIGINT, SIGTERM and SIGHUP
    stop cleanly with exit code 3 (called as the command, ``argv`` None: also
    while it starts and ends, :func:`~ncstab.studies.interrupts.stop_at_once_on_signals`);
    a reader of the output that goes away (``ncstab info A | head -c 5``) ends
    it quietly, exit code 0; running out of memory is said so, exit code 3;
    any other error is one line and exit code 3.  With ``--debug`` the
    traceback is shown instead.
    """
    if argv is None:
        try:
            code = _main(None)
        except SystemExit as exit_:  # argparse's usage errors, --help, --version
            code = exit_.code
        exit_now(code)
    return _main(argv)


def _main(argv: Sequence[str] | None) -> int:
    """:func:`main`, returning the exit code whatever ``argv``."""
    advise_numpy_memory()
    from ncstab.heap import settled_heap
    from ncstab.studies.errors import EXIT_RUN_INCOMPLETE
    from ncstab.studies.interrupts import stop_at_once_on_signals, stop_on_signals

    if argv is None:  # the command's own process: no signal is ever a traceback or a silent death
        stop_at_once_on_signals("ncstab")
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "handler", None) is None:
        parser.print_help()
        return 0
    prefix = f"ncstab {args.command}"
    if argv is None:
        stop_at_once_on_signals(prefix)
    debug = bool(getattr(args, "debug", False))
    on_cluster = getattr(args, "workers", None) is not None or getattr(args, "scheduler", None) is not None
    try:
        with stop_on_signals(prefix), _quiet_cluster_logs(on_cluster and not debug), settled_heap():
            return _handled(args, prefix, debug)
    except KeyboardInterrupt as interrupt:  # a signal as the blocks above close, after the handler
        if debug:
            raise
        name = getattr(interrupt, "signal_name", "SIGINT")
        print(f"{prefix}: interrupted by {name}; nothing more was written", file=sys.stderr)
        return EXIT_RUN_INCOMPLETE


def _handled(args: argparse.Namespace, prefix: str, debug: bool) -> int:
    """Run the command's handler; each error as one line and its exit code (see :func:`main`)."""
    from ncstab.studies.errors import EXIT_RUN_INCOMPLETE, NcstabError, RunError

    try:
        code = int(args.handler(args))
        sys.stdout.flush()  # a reader gone away is seen here, not at the interpreter's exit
        return code
    except BrokenPipeError:
        if debug or not stdout_closed():
            raise
        discard_stdout()
        return 0
    except NcstabError as error:
        if debug:
            raise
        print(f"{prefix}: {_which(error)}{error.line() if isinstance(error, RunError) else error}", file=sys.stderr)
        return error.exit_code
    except KeyboardInterrupt as interrupt:
        if debug:
            raise
        name = getattr(interrupt, "signal_name", "SIGINT")
        kept = getattr(interrupt, "kept", "") or "nothing more was written"
        print(f"{prefix}: {_which(interrupt)}interrupted by {name}; {kept}", file=sys.stderr)
        return EXIT_RUN_INCOMPLETE
    except Exception as error:  # a bug: one line, the traceback with --debug
        if debug:
            raise
        first = (str(error).strip().splitlines() or [""])[0]
        memory = out_of_memory(error)
        if memory is not None:
            print(f"{prefix}: {_which(error)}out of memory ({memory}); nothing more was written: free "
                  "memory or raise the limit (ulimit -v) and run again", file=sys.stderr)
            return EXIT_RUN_INCOMPLETE
        print(f"{prefix}: {_which(error)}internal error: {type(error).__name__}: {first} (rerun with --debug for the "
              "traceback, and please report it)", file=sys.stderr)
        return EXIT_RUN_INCOMPLETE


def _which(error: BaseException) -> str:
    """``"<study>: "`` for an error of ``ncstab run`` while it ran that study, else ``""``."""
    study = getattr(error, "study", None)
    return f"{study}: " if study else ""


@contextlib.contextmanager
def _quiet_cluster_logs(quiet: bool) -> Iterator[None]:
    """dask.distributed logs what it raises (a lost scheduler, a refused connection) with
    tracebacks: the command says it in one line instead (``--debug`` keeps the logs)."""
    if not quiet:
        yield
        return
    with contextlib.suppress(ImportError):
        import distributed  # noqa: F401  (its import sets its loggers' levels: set them after)
    names = ["distributed", "tornado", "asyncio", "bokeh"]
    names += [name for name in logging.root.manager.loggerDict if name.startswith(("distributed.", "tornado."))]
    loggers = [logging.getLogger(name) for name in names]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
