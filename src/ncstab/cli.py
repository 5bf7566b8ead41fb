"""The ``ncstab`` command: a thin layer over the library."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

import ncstab

__all__ = ["main", "build_parser"]


def _format_table(rows: list[list[str]], header: list[str]) -> str:
    widths = [max(len(str(r[i])) for r in rows + [header]) for i in range(len(header))]
    line = "  ".join("-" * w for w in widths)
    out = ["  ".join(h.ljust(w) for h, w in zip(header, widths)), line]
    out += ["  ".join(str(c).ljust(w) for c, w in zip(r, widths)) for r in rows]
    return "\n".join(row.rstrip() for row in out)


def command_laws(args: argparse.Namespace) -> int:
    """Print the law catalogue, or a study's laws, with each law's computed class;
    ``--explain NAME``: the derivation of one law's class (exit 2: bad study or name)."""
    import sympy as sp

    from ncstab.laws import law_definition, law_names
    from ncstab.studies import StudyFileError, load_study
    from ncstab.symbolic import classify, kinematic_integrability
    from ncstab.symbolic.explain import explain_law

    study = None
    if args.study is not None:
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
        print(explain_law(definition))
        return 0
    names = list(study.laws) if study is not None else law_names(with_modifiers=args.all)
    rows = []
    for name in names:
        definition = study.law_definition(name) if study is not None else law_definition(name)
        result = classify(definition)
        energy = sp.sstr(result.energy) if result.energy is not None else "-"
        rows.append([name, result.kind, definition.equations, energy, result.reason])
    if study is not None:
        print(f"{args.study}: the laws of study {study.name!r}")
    print(_format_table(rows, ["law", "class", "seed", "energy W(l, alpha)", "decided by"]))
    print()
    print(f"System kinematics: {kinematic_integrability()}")
    print("Variables are dimensionless (seed Eq. 37): l = l/2R, N, T in units of 2R k_n,")
    print("W in units of k_n (2R)^2 per contact, gamma = k_t/k_n.")
    return 0


def _status_summary(dataset) -> list[str]:
    """Lines summarising case statuses: finished, stopped at events, failed with reasons."""
    import numpy as np

    status = np.asarray(dataset["status"].values).astype(str).ravel()
    message = np.asarray(dataset["message"].values).astype(str).ravel()
    lines = [f"  cases: {status.size}"]
    finished = int(np.sum(status == "finished"))
    lines.append(f"  finished: {finished}")
    stopped = sorted({s for s in status if s.startswith("stopped:")})
    for state in stopped:
        lines.append(f"  stopped at {state.split(':', 1)[1]}: {int(np.sum(status == state))}")
    failed = sorted({s for s in status if s.startswith("failed:")})
    for state in failed:
        which = status == state
        example = message[which][0]
        lines.append(f"  FAILED ({state.split(':', 1)[1]}): {int(which.sum())} -- e.g. {example}")
    return lines


def _event_summary(dataset) -> list[str]:
    import numpy as np

    from ncstab.paths.programme import EVENTS

    lines = []
    for event in EVENTS:
        name = f"{event}_s"
        if name not in dataset:
            continue
        found = np.isfinite(np.asarray(dataset[name].values))
        if found.any():
            f1 = np.asarray(dataset[f"{event}_F"].isel(dof=0).values)[found]
            lines.append(
                f"  {event}: found in {int(found.sum())} of {found.size} cases"
                f" (F1 from {np.nanmin(f1):.6g} to {np.nanmax(f1):.6g})"
            )
    return lines or ["  no events located"]


def command_run(args: argparse.Namespace) -> int:
    """Validate every study first (exit 2 if any is bad), then run, write, draw."""
    from ncstab.plotting import draw_figures
    from ncstab.studies import (
        ResumeError,
        StudyFileError,
        default_output_path,
        load_study,
        open_study_lazily,
        run_study,
        run_study_chunked,
        write_dataset,
    )
    from ncstab.studies.chunked import DEFAULT_CHUNK_CASES, study_cases

    if args.output is not None and len(args.studies) != 1:
        print("ncstab run: -o/--output needs exactly one study file", file=sys.stderr)
        return 2
    for flag, value in (("--chunk-cases", args.chunk_cases), ("--workers", args.workers)):
        if value is not None and value < 1:
            print(f"ncstab run: {flag} must be at least 1, got {value}", file=sys.stderr)
            return 2
    chunked = args.chunk_cases is not None or args.resume or args.workers is not None or args.scheduler is not None
    studies = []
    bad = False
    for path in args.studies:
        try:
            studies.append(load_study(path))
        except StudyFileError as error:
            print(str(error), file=sys.stderr)
            bad = True
        except OSError as error:
            print(f"{path}: cannot read the study file: {error}", file=sys.stderr)
            bad = True
    if bad:
        print("ncstab run: nothing was run (fix the study file errors above)", file=sys.stderr)
        return 2
    progress = sys.stderr.isatty() and not args.quiet
    any_failed = False
    for study in studies:
        output = Path(args.output) if args.output else default_output_path(study)
        if chunked or study_cases(study) > DEFAULT_CHUNK_CASES:
            # Large sweeps stream chunk by chunk to the archive: memory bounded by the chunk.
            try:
                run_study_chunked(
                    study,
                    output,
                    chunk_cases=args.chunk_cases,
                    resume=args.resume,
                    workers=args.workers,
                    scheduler=args.scheduler,
                    progress=progress,
                )
            except (ImportError, ResumeError) as error:
                print(f"ncstab run: {study.name}: {error}", file=sys.stderr)
                return 2
        else:
            write_dataset(run_study(study, progress=progress), output)
        with open_study_lazily(output) as dataset:
            figures = draw_figures(dataset, output.parent, stem=output.stem, progress=progress)
            print(f"{study.name}: wrote {output}")
            for figure in figures:
                print(f"  figure {figure}")
            summary = _status_summary(dataset)
            for line in summary:
                print(line)
            any_failed |= any(line.startswith("  FAILED") for line in summary)
    return 1 if any_failed else 0


def _open_archive(command: str, archive: str):
    """The archive's Dataset, or None (after saying why) if there is no such file."""
    from ncstab.studies import open_study

    path = Path(archive)
    if not path.exists():
        print(f"ncstab {command}: no such archive: {path}", file=sys.stderr)
        return None
    return open_study(path)


def command_plot(args: argparse.Namespace) -> int:
    """Redraw the figures of an archive from the archive alone."""
    from ncstab.plotting import draw_figures

    path = Path(args.archive)
    dataset = _open_archive("plot", args.archive)
    if dataset is None:
        return 2
    kinds = args.kinds.split(",") if args.kinds else None
    directory = Path(args.directory) if args.directory else path.parent
    for figure in draw_figures(dataset, directory, kinds=kinds, stem=path.stem):
        print(figure)
    return 0


def command_info(args: argparse.Namespace) -> int:
    """Summarise an archive: study, sweep, statuses, events."""
    path = Path(args.archive)
    ds = _open_archive("info", args.archive)
    if ds is None:
        return 2
    attrs = ds.attrs
    print(f"{path}")
    print(f"  study: {attrs.get('study_name', '?')} -- {attrs.get('study_description', '')}".rstrip(" -"))
    print(f"  created {attrs.get('created', '?')} with ncstab {attrs.get('ncstab_version', '?')}")
    print(f"  system: {attrs.get('system', '?')} (normal {attrs.get('normal', '?')}, secondary contacts "
          f"{attrs.get('secondary_contacts', '?')}), forces in units of {attrs.get('force_unit', '?')}")
    laws = [f"{law} ({cls})" for law, cls in zip(ds["law"].values, ds["law_class"].values)]
    print(f"  laws: {', '.join(laws)}")
    sweep = [d for d in ds["status"].dims if d != "law"]
    for name in sweep:
        values = ", ".join(f"{v:g}" for v in ds[name].values)
        print(f"  sweep {name}: [{values}]")
    fixed = {k[len('parameter_'):]: v for k, v in attrs.items() if k.startswith("parameter_")}
    if fixed:
        print("  fixed: " + ", ".join(f"{k} = {v:g}" for k, v in fixed.items()))
    print(f"  stored states: up to {ds.sizes.get('step', 0)} per case")
    for line in _status_summary(ds) + _event_summary(ds):
        print(line)
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ncstab",
        description=(
            "Stability analysis of non-conservative discrete systems: the diamond "
            "granular chain with hypo- and hyperelastic contact laws."
        ),
    )
    parser.add_argument("--version", action="version", version=f"ncstab {ncstab.__version__}")
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
        "event; 1: some case failed; 2: a study file is invalid (nothing is run).",
    )
    run.add_argument("studies", nargs="+", metavar="STUDY.toml", help="study files")
    run.add_argument("-o", "--output", metavar="OUT.nc", help="archive path (one study only); "
                     "default results/<study name>.nc")
    run.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    run.add_argument("--chunk-cases", type=int, metavar="N",
                     help="run in chunks of at most N cases, each kept in OUT.nc.parts/ as it "
                          "finishes (default: 8192 in this process; with --workers, about four chunks per "
                          "worker, 256 to 8192). Studies of more than 8192 cases per law always run in chunks")
    run.add_argument("--resume", action="store_true",
                     help="keep the chunks an interrupted run left in OUT.nc.parts/ and compute "
                          "only the missing ones")
    where = run.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, metavar="N",
                       help="run the chunks on a local dask cluster of N worker processes "
                            "(needs ncstab[distributed])")
    where.add_argument("--scheduler", metavar="ADDRESS",
                       help="run the chunks on an existing dask.distributed cluster "
                            "(e.g. tcp://host:8786; needs ncstab[distributed])")
    run.set_defaults(handler=command_run)

    plot = sub.add_parser("plot", help="redraw the figures of an archive")
    plot.add_argument("archive", metavar="OUT.nc")
    plot.add_argument("--kinds", help="comma-separated figure kinds (default: the study's)")
    plot.add_argument("--directory", help="where to write the PNGs (default: beside the archive)")
    plot.set_defaults(handler=command_plot)

    info = sub.add_parser("info", help="summarise an archive: study, sweep, statuses, events")
    info.add_argument("archive", metavar="OUT.nc")
    info.set_defaults(handler=command_info)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "handler", None) is None:
        parser.print_help()
        return 0
    return int(args.handler(args))


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
