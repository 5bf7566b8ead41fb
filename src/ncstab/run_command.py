"""``ncstab run``: validate every study and check every output first, then run, write and draw.

The command's handler (:func:`command_run`) and its steps; :mod:`ncstab.cli`
builds the parser and turns errors into one line and an exit code.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

__all__ = ["command_run"]


def _study_output(study, args: argparse.Namespace) -> Path:
    """``-o`` (the user's choice, anywhere), else the study's ``[output] file``, kept inside
    the folder it is resolved in, else ``results/<name>.nc``."""
    from ncstab.studies import default_output_path

    if args.output is not None:
        return Path(args.output)
    if study.output:
        _check_study_output(study)
    return default_output_path(study)


def _check_study_output(study) -> None:
    """A study file's ``[output] file`` is a relative path without ``..``: resolved in the
    directory ``ncstab run`` runs in, it stays inside it (a shared study file cannot
    write anywhere else; ``-o`` can)."""
    from ncstab.studies.errors import OutputPathError

    where = f" of {study.path}" if study.path else ""
    raw = study.output
    if Path(raw).is_absolute() or Path(raw).anchor:
        raise OutputPathError(
            f"[output] file = {raw!r}{where} is an absolute path: a study file's output stays inside the "
            "directory ncstab run runs in; give a relative path such as \"results/study.nc\", or choose the "
            "path on the command line with -o"
        )
    if ".." in Path(raw).parts:
        raise OutputPathError(
            f"[output] file = {raw!r}{where} leaves the directory ncstab run runs in ('..'): a study file's "
            "output stays inside it; give a path without '..', or choose the path on the command line with -o"
        )


def _runs_in_chunks(study, args: argparse.Namespace) -> bool:
    from ncstab.studies.chunk_plan import DEFAULT_CHUNK_CASES, study_cases

    flags = args.chunk_cases is not None or args.resume or args.workers is not None or args.scheduler is not None
    return flags or study_cases(study) > DEFAULT_CHUNK_CASES


def _check_run_options(args: argparse.Namespace) -> None:
    """Options that are wrong whatever the study (exit code 2, nothing run)."""
    from ncstab.studies.chunked import scheduler_address
    from ncstab.studies.errors import InvalidInputError

    if args.output is not None and len(args.studies) != 1:
        raise InvalidInputError("-o/--output needs exactly one study file")
    if args.output is not None and not args.output.strip():
        raise InvalidInputError(f"-o/--output {args.output!r} is empty: give the archive's file name, e.g. out.nc")
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
            studies.append(load_study(path))  # parse_study remembers it valid: plot/info skip the parse
        except StudyFileError as error:
            print(str(error), file=sys.stderr)
            bad = True
        except OSError as error:
            print(f"ncstab run: {path}: cannot read the study file: {error.strerror or error}", file=sys.stderr)
            bad = True
    return None if bad else studies


def _preflight(study, output: Path, args: argparse.Namespace) -> None:
    """Size limits, then what is at the output's path (absent, or an ncstab archive and
    ``--overwrite``): read only, refused before anything runs or is written (exit code 2)."""
    from ncstab.studies.chunked import default_chunk_cases
    from ncstab.studies.cycle_limits import check_cycle_turns
    from ncstab.studies.outputs import check_existing_output
    from ncstab.studies.preflight import check_study_size
    from ncstab.studies.system_size import check_system_size

    chunked = _runs_in_chunks(study, args)
    if chunked and study.boundary is not None:
        from ncstab.studies.errors import InvalidInputError

        raise InvalidInputError(
            "a study with [boundary] traces its curves in one process: run it without --workers, "
            "--scheduler, --chunk-cases and --resume"
        )
    if chunked and study.programme.dynamic is not None:
        from ncstab.studies.errors import InvalidInputError

        raise InvalidInputError(
            "a study with a dynamic stage runs in one process (its motions are not streamed in "
            "chunks yet): run it without --workers, --scheduler, --chunk-cases and --resume, with at most "
            "the cases of one chunk"
        )
    in_memory = None
    if chunked:
        in_memory = (args.chunk_cases or default_chunk_cases(study, args.workers)) * (args.workers or 1)
    check_study_size(study, output, max_cases=args.max_cases, cases_in_memory=in_memory, chunked=chunked)
    check_system_size(study)
    check_cycle_turns(study, cases_in_memory=in_memory)
    check_existing_output(output, overwrite=args.overwrite, resume=args.resume, inputs=tuple(args.studies),
                          study_text=study.text)


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
    with claim_output(output, resume=args.resume, overwrite=args.overwrite, notify=note, protect_existing=True,
                      study_text=study.text):
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
    from ncstab.heap import settle
    from ncstab.plotting import draw_figures
    from ncstab.studies import open_study_lazily
    from ncstab.studies.errors import RunError, RunInterrupted, WriteError, write_error
    from ncstab.studies.summary import status_lines

    try:
        with open_study_lazily(output) as dataset:
            settle()  # the imports' objects out of the collector's scans while drawing (ncstab.heap)
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
    from ncstab.dask_probe import defer_dask_array_import
    from ncstab.studies.errors import InvalidInputError, NcstabError, RunError, RunInterrupted

    _check_run_options(args)
    defer_dask_array_import()  # xarray's probe for dask arrays without importing dask.array (0.8 s)
    studies = _load_studies(args.studies)
    if studies is None:
        return 2
    outputs: list[Path] = []
    for study in studies:
        try:
            output = _study_output(study, args)
            for earlier, other in zip(studies, outputs):
                if os.path.abspath(other) == os.path.abspath(output):
                    raise InvalidInputError(f"output {output} is also the output of study {earlier.name!r} "
                                            f"({earlier.path}): give each study its own output")
            outputs.append(output)
        except NcstabError as error:
            error.study = study.name  # type: ignore[attr-defined]
            raise
    from ncstab.studies.preflight import check_output_path

    for check in (lambda study, output: _preflight(study, output, args),  # read only, every study first
                  lambda study, output: check_output_path(output)):  # then directories and a probe file
        for study, output in zip(studies, outputs):
            try:
                check(study, output)
            except NcstabError as error:
                error.study = study.name  # type: ignore[attr-defined]
                raise
    from ncstab.numba_cache import harden_numba_cache
    from ncstab.paths.threads import using_threads

    harden_numba_cache()  # a damaged numba cache entry is compiled again, not an error
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
        except Exception as error:  # out of memory, a bug: the line names the study too
            with contextlib.suppress(AttributeError, TypeError):
                error.study = study.name  # type: ignore[attr-defined]
            raise
        written.append(output)
    return 1 if any_failed else 0
