"""The ``ncstab`` command: a thin layer over the library."""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import NoReturn, Sequence

import ncstab

__all__ = ["main", "build_parser"]


class OneLineErrorParser(argparse.ArgumentParser):
    """An argument parser whose usage errors are one line (exit code 2, as argparse's)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: {message} (see {self.prog} --help)\n")


def _format_table(rows: list[list[str]], header: list[str]) -> str:
    widths = [max(len(str(r[i])) for r in rows + [header]) for i in range(len(header))]
    line = "  ".join("-" * w for w in widths)
    out = ["  ".join(h.ljust(w) for h, w in zip(header, widths)), line]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(row.rstrip() for row in out)


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
    rows = []
    for name in names:
        definition = study.law_definition(name) if study is not None else law_definition(name)
        summary = class_summary(definition)  # classified once, then read from the cache directory
        rows.append([name, summary.kind, definition.equations, summary.energy or "-", summary.reason])
    if study is not None:
        print(f"{args.study}: the laws of study {study.name!r}")
    print(_format_table(rows, ["law", "class", "seed", "energy W(l, alpha)", "decided by"]))
    print()
    print(f"System kinematics: {kinematic_integrability()}")
    print("Variables are dimensionless (seed Eq. 37): l = l/2R, N, T in units of 2R k_n,")
    print("W in units of k_n (2R)^2 per contact, gamma = k_t/k_n.")
    return 0


def _study_output(study, args: argparse.Namespace) -> Path:
    from ncstab.studies import default_output_path

    return Path(args.output) if args.output else default_output_path(study)


def _runs_in_chunks(study, args: argparse.Namespace) -> bool:
    from ncstab.studies.chunked import DEFAULT_CHUNK_CASES, study_cases

    flags = args.chunk_cases is not None or args.resume or args.workers is not None or args.scheduler is not None
    return flags or study_cases(study) > DEFAULT_CHUNK_CASES


def _check_run_options(args: argparse.Namespace) -> None:
    """Options that are wrong whatever the study (exit code 2, nothing run)."""
    from ncstab.studies.chunked import scheduler_address
    from ncstab.studies.errors import InvalidInputError

    if args.output is not None and len(args.studies) != 1:
        raise InvalidInputError("-o/--output needs exactly one study file")
    for flag, value in (("--chunk-cases", args.chunk_cases), ("--workers", args.workers),
                        ("--max-cases", args.max_cases)):
        if value is not None and value < 1:
            raise InvalidInputError(f"{flag} must be at least 1, got {value}")
    if args.threads is not None:
        from ncstab.paths.threads import check_thread_count

        try:
            check_thread_count(args.threads)
        except ValueError as error:
            raise InvalidInputError(str(error)) from None
    if not args.scheduler_timeout > 0:
        raise InvalidInputError(f"--scheduler-timeout must be a positive number of seconds, got {args.scheduler_timeout}")
    if args.scheduler is not None:
        args.scheduler = scheduler_address(args.scheduler)


def _load_studies(paths: Sequence[str]) -> list | None:
    """Every study file validated (each error printed, one line each), or None if any is bad."""
    from ncstab.studies import StudyFileError, load_study

    studies, bad = [], False
    for path in paths:
        try:
            studies.append(load_study(path))
        except StudyFileError as error:
            print(str(error), file=sys.stderr)
            bad = True
        except OSError as error:
            print(f"ncstab run: {path}: cannot read the study file: {error.strerror or error}", file=sys.stderr)
            bad = True
    return None if bad else studies


def _preflight(study, args: argparse.Namespace) -> Path:
    """Size limits, then the output path: refused before anything runs (exit code 2 or 3)."""
    from ncstab.studies.chunked import default_chunk_cases
    from ncstab.studies.preflight import check_output_path, check_study_size

    output = _study_output(study, args)
    chunked = _runs_in_chunks(study, args)
    in_memory = None
    if chunked:
        in_memory = (args.chunk_cases or default_chunk_cases(study, args.workers)) * (args.workers or 1)
    check_study_size(study, output, max_cases=args.max_cases, cases_in_memory=in_memory, chunked=chunked)
    check_output_path(output)
    return output


def _note(study_name: str):
    def note(line: str) -> None:
        print(f"ncstab run: {study_name}: {line}", file=sys.stderr)

    return note


def _run_one(study, output: Path, args: argparse.Namespace) -> bool:
    """Run a study, write its archive and figures; whether some case failed."""
    from ncstab.studies import run_study, run_study_chunked, write_dataset
    from ncstab.studies.errors import InvalidInputError, RunError, RunInterrupted
    from ncstab.studies.outputs import claim_output

    progress = _wants_progress(args)
    note = _note(study.name)
    # The lock covers the run, the archive, its parts and its figures.
    with claim_output(output, resume=args.resume, overwrite=args.overwrite, notify=note):
        if _runs_in_chunks(study, args):
            # Large sweeps stream chunk by chunk to the archive: memory bounded by the chunk.
            try:
                run_study_chunked(
                    study, output, chunk_cases=args.chunk_cases, resume=args.resume, workers=args.workers,
                    scheduler=args.scheduler, progress=progress, overwrite=args.overwrite,
                    scheduler_timeout=args.scheduler_timeout, notify=note,
                )
            except ImportError as error:
                raise InvalidInputError(str(error)) from None
        else:
            try:
                dataset = run_study(study, progress=progress)
                with _announced(f"{study.name}: writing {output}", progress):
                    write_dataset(dataset, output)
            except (RunError, RunInterrupted) as error:
                error.kept = error.kept or f"nothing was written to {output}"
                raise
        figures, summary = _draw(output, progress)
    print(f"{study.name}: wrote {output}")
    for figure in figures:
        print(f"  figure {figure}")
    for line in summary:
        print(line)
    return any(line.startswith("  FAILED") for line in summary)


def _wants_progress(args: argparse.Namespace) -> bool:
    """Progress bars and notices on a terminal, unless ``--quiet``."""
    return sys.stderr.isatty() and not args.quiet


@contextlib.contextmanager
def _announced(what: str, progress: bool) -> Iterator[None]:
    """On a terminal, say what is being done before it starts and how long it took."""
    if not progress:
        yield
        return
    print(f"ncstab run: {what} ...", file=sys.stderr, flush=True)
    start = time.perf_counter()
    yield
    print(f"ncstab run: {what}: done in {time.perf_counter() - start:.1f} s", file=sys.stderr, flush=True)


def _draw(output: Path, progress: bool = False) -> tuple[list[Path], list[str]]:
    """The figures of a written archive, and its status summary."""
    from ncstab.plotting import draw_figures
    from ncstab.studies import open_study_lazily
    from ncstab.studies.errors import RunError, RunInterrupted, WriteError, write_error
    from ncstab.studies.summary import status_lines

    try:
        with open_study_lazily(output) as dataset:
            return draw_figures(dataset, output.parent, stem=output.stem, progress=progress), status_lines(dataset)
    except (RunError, RunInterrupted) as error:
        error.kept = error.kept or f"the archive {output} was written, its figures were not all drawn"
        raise
    except (OSError, RuntimeError, ValueError) as error:
        named = write_error(error, output.parent) or WriteError(f"could not draw the figures: {error}")
        named.kept = f"the archive {output} was written, its figures were not all drawn (ncstab plot {output})"
        raise named from error


def command_run(args: argparse.Namespace) -> int:
    """Validate every study and check every output first (exit 2 if any is bad), then run, write, draw."""
    from ncstab.studies.errors import NcstabError, RunError, RunInterrupted

    _check_run_options(args)
    studies = _load_studies(args.studies)
    if studies is None:
        return 2
    outputs = []
    for study in studies:
        try:
            outputs.append(_preflight(study, args))
        except NcstabError as error:
            error.study = study.name  # type: ignore[attr-defined]
            raise
    from ncstab.paths.threads import using_threads

    any_failed = False
    written: list[Path] = []
    for study, output in zip(studies, outputs):
        try:
            with using_threads(args.threads):
                any_failed |= _run_one(study, output, args)
        except (NcstabError, RunInterrupted) as error:
            error.study = study.name  # type: ignore[attr-defined]
            if written and isinstance(error, (RunError, RunInterrupted)):
                before = "written before: " + ", ".join(map(str, written))
                error.kept = f"{error.kept}; {before}" if error.kept else before
            raise
        written.append(output)
    return 1 if any_failed else 0


def _open_archive(archive: str):
    """The archive's Dataset, verified (:func:`ncstab.studies.open_study`)."""
    from ncstab.studies import open_study
    from ncstab.studies.errors import InvalidInputError

    path = Path(archive)
    if not path.exists():
        raise InvalidInputError(f"no such archive: {path}")
    return open_study(path)


def command_plot(args: argparse.Namespace) -> int:
    """Redraw the figures of an archive from the archive alone."""
    from ncstab.plotting import draw_figures
    from ncstab.studies.errors import InvalidInputError, WriteError, write_error

    path = Path(args.archive)
    dataset = _open_archive(args.archive)
    kinds = args.kinds.split(",") if args.kinds else None
    directory = Path(args.directory) if args.directory else path.parent
    try:
        figures = draw_figures(dataset, directory, kinds=kinds, stem=path.stem)
    except ValueError as error:
        raise InvalidInputError(f"{path}: cannot draw the figures: {error}") from None
    except OSError as error:
        raise (write_error(error, directory) or WriteError(f"could not write the figures: {error}")) from error
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
    print("\n".join(lines))
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
    run.add_argument("-o", "--output", metavar="OUT.nc", help="archive path (one study only); "
                     "default results/<study name>.nc")
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
                       help="discard the chunks an interrupted run left in OUT.nc.parts/ and start over "
                            "(without --resume or --overwrite, a run refuses to start over them)")
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

    from ncstab.cache_command import add_cache_parser  # the standard library only

    add_cache_parser(sub, [debug])
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``ncstab`` command; its exit code (docs/when-things-go-wrong.md).

    A named error (:mod:`ncstab.studies.errors`) is printed as one line,
    ``ncstab <command>: <what>; <what was kept>``, and gives its exit code (2
    invalid input, 3 the run could not complete); SIGINT and SIGTERM stop
    cleanly with exit code 3; any other error is one line and exit code 3.
    With ``--debug`` the traceback is shown instead.
    """
    from ncstab.studies.errors import EXIT_RUN_INCOMPLETE, NcstabError, RunError
    from ncstab.studies.interrupts import stop_on_signals

    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "handler", None) is None:
        parser.print_help()
        return 0
    prefix = f"ncstab {args.command}"
    debug = bool(getattr(args, "debug", False))
    on_cluster = getattr(args, "workers", None) is not None or getattr(args, "scheduler", None) is not None
    with stop_on_signals(prefix), _quiet_cluster_logs(on_cluster and not debug):
        try:
            return int(args.handler(args))
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
            print(f"{prefix}: internal error: {type(error).__name__}: {first} (rerun with --debug for the "
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
