"""The parts of a chunked run: one file per finished chunk of cases, and a manifest.

A chunked run (:func:`~ncstab.studies.run_study_chunked`) keeps each finished
chunk, atomically, as ``<archive>.parts/<law>_<k>.npz`` (the compressed HDF5
chunks as one byte array, the text variables, and a JSON header of names,
offsets, dimensions and attributes; no pickle), beside ``manifest.json``
(the SHA-256 of the study text and the chunk size).  Parts are zip files:
``np.load`` checks each array's CRC-32, so a damaged part is seen when it is
read back (:func:`read_kept_part`) and computed again.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
from collections.abc import Iterator
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.studies.atomic_files import atomic_destination
from ncstab.studies.errors import ResumeError, write_error
from ncstab.studies.streaming import EncodedChunk
from ncstab.studies.study import Study

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.studies.chunked import Chunk

__all__ = [
    "MANIFEST",
    "PARTS_FORMAT",
    "DamagedPart",
    "create_parts",
    "read_kept_part",
    "read_part",
    "resumed_chunk_size",
    "study_digest",
    "write_part",
    "writing",
]

#: Version of the part-file layout (stored in the manifest).
PARTS_FORMAT = 4
MANIFEST = "manifest.json"


def study_digest(study: Study) -> str:
    """SHA-256 of the study text: parts are only ever combined for the same study."""
    return hashlib.sha256(study.text.encode("utf-8")).hexdigest()


def resumed_chunk_size(directory: FilePath, study: Study, chunk_cases: int | None) -> int | None:
    """On resume: the chunk size of the parts in ``directory`` (checked against this study), or None if none.

    Raises
    ------
    ResumeError
        The parts belong to another study, chunk size or ncstab version, or the manifest is damaged.
    """
    manifest_path = directory / MANIFEST
    if not manifest_path.exists():
        return None
    try:
        manifest = json.loads(manifest_path.read_text())
        stored = int(manifest["chunk_cases"])
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise ResumeError(
            "format", f"{manifest_path} is damaged ({error}); run with --overwrite to start over"
        ) from None
    if manifest.get("format") != PARTS_FORMAT:
        raise ResumeError("format", f"{directory}: parts of another ncstab version; run with --overwrite to start over")
    if manifest.get("study_sha256") != study_digest(study):
        raise ResumeError(
            "study",
            f"{directory}: the parts belong to another version of study {manifest.get('study_name')!r}; "
            "run with --overwrite to start over",
        )
    if chunk_cases is not None and chunk_cases != stored:
        raise ResumeError(
            "chunk_cases",
            f"{directory}: the parts were written with chunk_cases = {stored}, "
            f"not {chunk_cases}; resume with the same chunk size (or none)",
        )
    return stored


def create_parts(directory: FilePath, study: Study, chunk_cases: int) -> None:
    """A new parts directory (any old one removed: the caller has checked it holds no finished part)."""
    if directory.exists():
        shutil.rmtree(directory)
    directory.mkdir(parents=True)
    manifest = {
        "format": PARTS_FORMAT,
        "study_name": study.name,
        "study_sha256": study_digest(study),
        "chunk_cases": chunk_cases,
    }
    with atomic_destination(directory / MANIFEST, ".part") as temporary:
        temporary.write_text(json.dumps(manifest, indent=1))


@contextlib.contextmanager
def writing(path: FilePath) -> Iterator[None]:
    """Turn a failed write of ``path`` into its named error (disk full, not writable...)."""
    try:
        yield
    except (OSError, RuntimeError) as error:
        named = write_error(error, path)
        if named is None:
            raise
        raise named from error


def _json_attribute(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return {"__ndarray__": value.tolist(), "dtype": value.dtype.str}
    return value


def _attribute_from_json(value: Any) -> Any:
    if isinstance(value, dict) and "__ndarray__" in value:
        return np.asarray(value["__ndarray__"], dtype=value["dtype"])
    return value


def write_part(directory: FilePath, chunk: Chunk, digest: str, encoded: EncodedChunk) -> None:
    """Keep an encoded chunk as ``directory/<law>_<k>.npz``, atomically.

    The compressed HDF5 chunks as one byte array, the text variables and the
    template's arrays as they are (no pickle); names, offsets, dimensions and
    attributes in a JSON header.  Parts are only ncstab's own scratch, read
    back by :func:`read_part`.
    """
    template = encoded.template
    header = {
        "study_sha256": digest,
        "law": encoded.law,
        "start": encoded.start,
        "stop": encoded.stop,
        "steps": encoded.steps,
        "events_met": list(encoded.events_met),
        "chunks": [[name, list(offset), len(data)] for name, offset, data in encoded.chunks],
        "strings": list(encoded.strings),
        "attrs": {k: _json_attribute(v) for k, v in template.attrs.items()},
        "variables": {
            name: {
                "dims": list(variable.dims),
                "attrs": {k: _json_attribute(v) for k, v in variable.attrs.items()},
                "coordinate": name in template.coords,
            }
            for name, variable in template.variables.items()
        },
    }
    arrays = {f"variable_{k}": variable.values for k, variable in enumerate(template.variables.values())}
    arrays.update({f"string_{k}": values for k, values in enumerate(encoded.strings.values())})
    blob = np.frombuffer(b"".join(data for _, _, data in encoded.chunks), dtype=np.uint8)
    with atomic_destination(directory / chunk.file_name, ".part") as temporary, open(temporary, "wb") as handle:
        np.savez(handle, header=np.array(json.dumps(header)), chunks=blob, **arrays)


def read_part(directory: FilePath, chunk: Chunk, digest: str) -> EncodedChunk:
    import xarray as xr

    path = directory / chunk.file_name
    with open(path, "rb") as handle, np.load(handle, allow_pickle=False) as stored:  # closed even if damaged
        header = json.loads(str(stored["header"]))
        if header["study_sha256"] != digest:
            raise ResumeError("part", f"{path} belongs to another study")
        if (header["law"], header["start"], header["stop"]) != (chunk.law, chunk.start, chunk.stop):
            raise ResumeError(
                "part",
                f"{path} holds cases {header['start']}:{header['stop']} of {header['law']}, "
                f"expected {chunk.start}:{chunk.stop} of {chunk.law}",
            )
        variables = {
            name: xr.Variable(
                spec["dims"],
                stored[f"variable_{k}"],
                {key: _attribute_from_json(v) for key, v in spec["attrs"].items()},
            )
            for k, (name, spec) in enumerate(header["variables"].items())
        }
        strings = {name: stored[f"string_{k}"] for k, name in enumerate(header["strings"])}
        blob = stored["chunks"].tobytes()
    coordinates = {name: v for name, v in variables.items() if header["variables"][name]["coordinate"]}
    data = {name: v for name, v in variables.items() if name not in coordinates}
    attrs = {key: _attribute_from_json(v) for key, v in header["attrs"].items()}
    chunks = []
    position = 0
    for name, offset, length in header["chunks"]:
        chunks.append((name, tuple(offset), blob[position : position + length]))
        position += length
    return EncodedChunk(
        law=header["law"], start=header["start"], stop=header["stop"], steps=header["steps"],
        events_met=tuple(header["events_met"]),
        template=xr.Dataset(data, coords=coordinates, attrs=attrs),
        chunks=chunks, strings=strings,
    )


class DamagedPart(Exception):
    """A part file that cannot be read back (its zip checksum, header or chunk table is wrong)."""


def read_kept_part(directory: FilePath, chunk: Chunk, digest: str) -> EncodedChunk:
    """:func:`read_part`, with a damaged part raised as :class:`DamagedPart` (the run recomputes it).

    ``np.load`` checks each array's CRC-32 (parts are zip files), so a flipped
    byte or a truncated file is seen here; a part of another study or of
    other cases is a :class:`~ncstab.studies.errors.ResumeError`.
    """
    try:
        encoded = read_part(directory, chunk, digest)
    except ResumeError:
        raise
    except Exception as error:  # zipfile.BadZipFile, ValueError, KeyError, OSError...
        raise DamagedPart(f"{chunk.file_name}: {error}") from None
    if any(len(data) == 0 for _, _, data in encoded.chunks):
        raise DamagedPart(f"{chunk.file_name}: its chunk table does not match its data")
    return encoded
