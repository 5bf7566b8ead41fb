"""Checks before computing: can the output be written, and does the study fit?

:func:`check_output_path` -- the archive's name fits the file system, its
parent is a directory, and the directory can be written (a probe file is
created and removed).  :func:`check_study_size` -- the number of cases
against ``max_cases``, the archive against the free disk space, and the
``[map]`` arrays against the memory available.  Each refusal is a named
error (:mod:`ncstab.studies.errors`) naming the key and the estimate, raised
before anything is computed.

The size estimates (:func:`size_estimate`) are lower bounds for cases that
run to the end of their programme: a stored state per ``sample_step`` of driven
length at least (the arclength, in displacements and forces, is longer than
the driven quantity's change), of the bytes the archive's variables take per
state and per case; on disk, compressed to :data:`COMPRESSED_FRACTION`.
"""

from __future__ import annotations

import errno
import os
import secrets
import shutil
from dataclasses import dataclass
from pathlib import Path as FilePath

from ncstab.sizes import available_memory, readable_count, readable_size
from ncstab.studies.errors import (
    DiskFullError,
    LimitError,
    OutputNotWritableError,
    OutputPathError,
)
from ncstab.studies.stage_extent import stage_extents
from ncstab.studies.study import DEFAULT_MAX_CASES, Study

__all__ = [
    "COMPRESSED_FRACTION",
    "DEFAULT_MAX_CASES",
    "SizeEstimate",
    "available_memory",
    "check_output_path",
    "free_disk",
    "map_memory",
    "check_study_size",
    "size_estimate",
]

#: Archive size over the raw bytes of its values (measured: 0.67 on a 512-case
#: stability diagram, 51 states per case on average, deflate level 1 with shuffle).
COMPRESSED_FRACTION = 0.67
#: Bytes of an archive whatever its cases (HDF5 headers and indexes), at least:
#: measured 100-110 kB for a 2-case archive of about 90 variables.
ARCHIVE_OVERHEAD = 64 * 1024
#: Longest name ncstab derives from an archive's name: the temporary
#: ``.<name>.<8 hex>.tmp`` (14 more bytes) and the figure temporaries
#: ``.<stem>_<kind>.png.<pid>.<12 hex>.tmp`` (at most 60 more bytes than the stem).
_NAME_MARGIN = 14
_FIGURE_MARGIN = 60
#: Scalars stored per state besides u, F and K: alpha, l, N, T (per contact), s,
#: lam, work, det_K, hill, d2W, flutter, mixed_control.
_STATE_SCALARS = 12
#: Per case and event: s, s_lower, s_upper, alpha, l, N, T (floats) and the stage (int32).
_EVENT_SCALARS = 7
_EVENTS = 6


def _existing_ancestor(path: FilePath) -> FilePath:
    """The nearest of ``path`` and its parents that exists (and that this user can see)."""
    for candidate in (path, *path.parents):
        try:
            if candidate.exists():
                return candidate
        except OSError:  # this user may not search it, or its name is too long
            continue
    return FilePath(".")  # pragma: no cover - the root exists


def check_output_path(output: str | os.PathLike[str]) -> None:
    """Refuse an archive path that cannot be written, before anything is computed.

    Creates the missing directories of the path, and a probe file beside the
    archive, removed at once.

    Raises
    ------
    OutputPathError
        The path is empty or a directory, a parent is a file, a ``..`` follows
        a directory that does not exist, or a name (of the archive or of a
        directory on the way) or the whole path is too long for the file
        system (with room for ncstab's temporaries) -- exit code 2.
    OutputNotWritableError
        The directory cannot be created or written -- exit code 3.
    DiskFullError
        Not even the probe fits -- exit code 3.
    """
    if not str(output):
        raise OutputPathError("output '' is empty: give the archive's file name, e.g. out.nc")
    output = FilePath(output)
    try:
        _check_output_path(output)
    except PermissionError as error:  # a directory on the way that this user may not even search
        raise OutputNotWritableError(f"cannot reach {output.parent}: {error.strerror}") from None
    except OSError as error:
        if error.errno == errno.ENAMETOOLONG:
            raise OutputPathError(f"output path {str(output)[:40]!r}... is too long for the file system "
                                  f"({error.strerror})") from None
        raise


def _check_dotdot(output: FilePath) -> None:
    """Refuse a ``..`` after a directory that does not exist: ``nosuch/../out.nc`` would
    otherwise create ``nosuch`` to resolve it."""
    so_far = FilePath(output.anchor) if output.is_absolute() else FilePath()
    missing = None
    for part in output.parent.parts[1 if output.is_absolute() else 0:]:
        if part == ".." and missing is not None:
            raise OutputPathError(
                f"output {output}: {missing} does not exist, so {missing}/.. cannot be resolved; "
                "give the path without it"
            )
        so_far = so_far / part
        if missing is None and part != ".." and not os.path.lexists(so_far):
            missing = so_far


def _check_name_lengths(output: FilePath, name_max: int) -> None:
    """Each directory on the way fits the file system's longest name."""
    for part in output.parent.parts:
        if len(part.encode()) > name_max:
            raise OutputPathError(
                f"output {str(output)[:40]!r}...: the directory name {part[:20]!r}... is {len(part.encode())} "
                f"bytes long, and the file system allows {name_max} per name"
            )


def _check_output_path(output: FilePath) -> None:
    if output.name in ("", ".", ".."):
        raise OutputPathError(f"output {str(output)!r} is not a file name: give the archive's name, e.g. out.nc")
    if output.is_dir():
        raise OutputPathError(f"output {output} is a directory: give the archive's file name, e.g. {output / 'out.nc'}")
    ancestor = _existing_ancestor(output.parent)
    if not ancestor.is_dir():
        raise OutputPathError(f"output {output}: {ancestor} is a file, not a directory")
    try:
        name_max = os.pathconf(ancestor, "PC_NAME_MAX")
        path_max = os.pathconf(ancestor, "PC_PATH_MAX")
    except (OSError, ValueError, AttributeError):  # pragma: no cover - no pathconf
        name_max, path_max = 255, 4096
    _check_name_lengths(output, name_max)
    _check_dotdot(output)
    name_bytes = len(output.name.encode())
    longest = max(name_bytes + _NAME_MARGIN, len(output.stem.encode()) + _FIGURE_MARGIN)
    if longest > name_max:
        raise OutputPathError(
            f"output name {output.name[:40]!r}... is too long: {name_bytes} bytes, and the file system allows "
            f"{name_max} per name, of which ncstab needs up to {longest - name_bytes} for its temporary and "
            f"figure files; use a shorter study name or -o"
        )
    if len(str(output.absolute()).encode()) + _FIGURE_MARGIN > path_max:
        raise OutputPathError(f"output path {str(output)[:40]!r}... is too long for the file system ({path_max} bytes)")
    for directory in reversed([output.parent, *output.parent.parents]):
        if directory.exists():
            if not directory.is_dir():
                raise OutputPathError(f"output {output}: {directory} is a file, not a directory")
            continue
        try:
            directory.mkdir()
        except FileExistsError:
            continue
        except OSError as error:
            _refuse_write(error, directory, "create the directory")
    probe = output.with_name(f".{output.name}.{secrets.token_hex(4)}.probe")
    try:
        os.close(os.open(probe, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
        probe.unlink()
    except OSError as error:
        _refuse_write(error, output.parent, "write in")


def _refuse_write(error: OSError, where: FilePath, what: str) -> None:
    if error.errno in (errno.ENOSPC, errno.EDQUOT):
        raise DiskFullError(f"disk full: cannot {what} {where}") from None
    raise OutputNotWritableError(f"cannot {what} {where}: {error.strerror or error}") from None


@dataclass(frozen=True)
class SizeEstimate:
    """Lower bounds on what a run of a study stores (cases that run to their end).

    Attributes
    ----------
    cases
        Laws times the sweep's cases.
    mean_states, longest_states
        Stored states of an average case and of the longest one.
    bytes_per_state, bytes_per_case
        Raw bytes of the archive's variables per stored state and per case
        (events, counters), ``[map]`` arrays aside.
    """

    cases: int
    mean_states: float
    longest_states: float
    bytes_per_state: int
    bytes_per_case: int

    @property
    def disk_bytes(self) -> float:
        """The archive: cases x (states x bytes per state + bytes per case), compressed."""
        raw = self.cases * (self.mean_states * self.bytes_per_state + self.bytes_per_case)
        return ARCHIVE_OVERHEAD + COMPRESSED_FRACTION * raw


def size_estimate(study: Study) -> SizeEstimate:
    """What a run of ``study`` stores, from the study file alone (:class:`SizeEstimate`).

    Stored states of a case: 1 + (driven length of each stage) / ``sample_step``
    (``max_step`` where it is not set; :func:`~ncstab.studies.stage_extent.stage_extents`),
    at most ``max_steps`` times the most pieces of a step, + 1; bytes: 8 per float of ``u``, ``F`` (n each), ``K``,
    ``K_sym``, ``K_skew`` (n^2 each, stored up to 64 dofs) and the 12 scalars of a state, 4 for
    ``stage``; per case, the 6 events' located state and 12 bytes of counters.
    """
    from ncstab.studies.system_size import study_dofs
    from ncstab.systems.registry import DERIVED_DOFS_LIMIT

    n = study_dofs(study)
    contacts = int(getattr(study.system, "n_contacts", 1))
    squares = n * n
    if n > DERIVED_DOFS_LIMIT:  # assembled: K, K_sym, K_skew stored up to STORED_K_LIMIT dofs
        from ncstab.paths.assembled_result import STORED_K_LIMIT  # (scipy: only for such a system)

        squares = n * n if n <= STORED_K_LIMIT else 0
    extents = stage_extents(study.programme.stages, study.parameters)
    step = float(study.options.stored_spacing)
    cap = float(study.options.max_steps) * study.options.max_pieces + 1
    mean = 1.0 + sum(float(e.measured_from_rest.mean()) for e in extents) / step
    longest = 1.0 + max((float(e.measured_from_rest.max()) for e in extents), default=0.0) / step
    per_state = 8 * (2 * n + 3 * squares + _STATE_SCALARS + 4 * (contacts - 1)) + 4
    per_case = _EVENTS * (8 * (_EVENT_SCALARS + 2 * n + squares) + 4) + 12
    return SizeEstimate(study.n_cases, min(mean, cap), min(longest, cap), per_state, per_case)


def free_disk(path: str | os.PathLike[str]) -> int | None:
    """Free bytes for this user on the file system of ``path``, or None if unknown
    (a pseudo file system such as /proc or /sys reports a size of 0)."""
    try:
        usage = shutil.disk_usage(path)
    except OSError:
        return None
    return usage.free if usage.total > 0 else None


def map_memory(study: Study, estimate: SizeEstimate, cases: int) -> dict[str, float]:
    """Bytes of the ``[map]`` arrays of ``cases`` cases held at once, at least.

    ``"directions"``: ``d2W_dir``, 8 bytes per case, stored state (of the
    longest case: arrays are padded to it) and direction; ``"grid"``: the
    state maps, 8 bytes per field, case and grid point (exactly the arrays'
    size; computing them takes about 4 times more, measured).
    """
    from ncstab.operators.state_map import STATE_MAP_FIELDS

    needs: dict[str, float] = {}
    study_map = study.map
    if study_map is not None and study_map.directions is not None:
        needs["directions"] = 8.0 * cases * estimate.longest_states * study_map.directions
    if study_map is not None and study_map.grid is not None:
        (_, _, n1), (_, _, n2) = study_map.grid
        needs["grid"] = 8.0 * len(STATE_MAP_FIELDS) * cases * n1 * n2
    return needs


def check_study_size(
    study: Study,
    output: str | os.PathLike[str],
    max_cases: int | None = None,
    cases_in_memory: int | None = None,
    chunked: bool = False,
) -> SizeEstimate:
    """Refuse a study too large for its limits, before anything is computed.

    Parameters
    ----------
    study
        The validated study.
    output
        Its archive (the disk checked is the one it will be on).
    max_cases
        The most cases allowed (``--max-cases``); default the study's
        ``[options] max_cases`` (:data:`DEFAULT_MAX_CASES` unless given).
    cases_in_memory
        Cases computed at once (a chunk on each worker); default every case.
    chunked
        The run keeps its chunks beside the archive while it writes it:
        twice the archive's size on disk at the end.

    Returns
    -------
    SizeEstimate

    Raises
    ------
    LimitError
        Naming the key (``max_cases``, ``[parameters]``, ``[map] directions``,
        ``[map] grid``) and the estimate.
    """
    limit = int(study.max_cases if max_cases is None else max_cases)
    estimate = size_estimate(study)
    cases = estimate.cases
    on_disk = estimate.disk_bytes * (2 if chunked else 1)
    if cases > limit:
        raise LimitError(
            "max_cases", f"{cases:,} cases",
            f"study {study.name!r} has {cases:,} cases ({len(study.laws)} law(s) x {cases // len(study.laws):,}), "
            f"more than max_cases = {limit:,} (at least {readable_size(on_disk)} on disk); reduce the sweep, or raise "
            "[options] max_cases or --max-cases",
        )
    ancestor = _existing_ancestor(FilePath(output).absolute().parent)
    free = free_disk(ancestor)
    if free is not None and on_disk > free:
        raise LimitError(
            "[parameters]", readable_size(on_disk),
            f"study {study.name!r} needs at least {readable_size(on_disk)} on disk ({cases:,} cases x "
            f"{readable_count(estimate.mean_states)} states x {estimate.bytes_per_state} bytes, compressed"
            f"{', parts and archive' if chunked else ''}) and {ancestor} has {readable_size(free)} free; "
            "reduce the sweep ([parameters]) or free space",
        )
    memory = available_memory()
    in_memory = cases if cases_in_memory is None else min(cases, int(cases_in_memory))
    needs = map_memory(study, estimate, in_memory)
    study_map = study.map
    if memory is not None and needs.get("directions", 0.0) > memory:
        need = needs["directions"]
        raise LimitError(
            "[map] directions", readable_size(need),
            f"[map] directions = {study_map.directions}: the directional work d2W_dir of {in_memory:,} "
            f"cases x {readable_count(estimate.longest_states)} states x {study_map.directions} directions needs at "
            f"least {readable_size(need)} of memory, more than the {readable_size(memory)} available; use fewer "
            "directions (or fewer cases per chunk: --chunk-cases)",
        )
    if memory is not None and needs.get("grid", 0.0) > memory:
        from ncstab.operators.state_map import STATE_MAP_FIELDS

        need = needs["grid"]
        (_, _, n1), (_, _, n2) = study_map.grid
        raise LimitError(
            "[map] grid", readable_size(need),
            f"[map] grid of {n1} x {n2} points: the {len(STATE_MAP_FIELDS)} state maps of {in_memory:,} "
            f"cases need at least {readable_size(need)} of memory, more than the {readable_size(memory)} available; use "
            "fewer grid points (or fewer cases per chunk: --chunk-cases)",
        )
    return estimate
