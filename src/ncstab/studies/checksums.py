"""Checksums of archive variables: HDF5's Fletcher-32 and a SHA-256 digest attribute.

Every variable of an archive is verified when it is read:

* compressed (chunked) numeric variables carry HDF5's Fletcher-32 filter:
  HDF5 checks each chunk as it reads it.  A chunked run writes its
  compressed chunks directly (:mod:`ncstab.studies.streaming`), so it makes
  the filter's bytes itself (:func:`hdf5_chunk`);
* the others -- strings (``status``, ``message``, ``law``...) and numeric
  variables too small to be compressed, which HDF5 stores without filters --
  have the SHA-256 of their values (:func:`variable_digest`) in the global
  attribute :data:`DIGEST_ATTRIBUTE` (:func:`format_digests`), checked by
  :func:`ncstab.studies.open_study`.
"""

from __future__ import annotations

import hashlib
import zlib

import numpy as np

__all__ = ["DIGEST_ATTRIBUTE", "fletcher32", "format_digests", "hdf5_chunk", "parse_digests", "variable_digest"]

#: Global attribute holding the SHA-256 (hex) of the variables without a checksum filter.
DIGEST_ATTRIBUTE = "ncstab_sha256"
#: HDF5's Fletcher-32 sums are taken modulo 2^16 - 1 (ones' complement).
_MODULUS = 65535
#: Words summed at once in :func:`fletcher32` (2^22: the sum of a block's prefix sums stays below 2^60).
_BLOCK = 1 << 22


def fletcher32(data: bytes) -> int:
    """HDF5's Fletcher-32 checksum of ``data`` (``H5_checksum_fletcher32``).

    The bytes are read as big-endian 16-bit words w_0 .. w_{n-1} (an odd last
    byte is the high byte of a last word).  With S1 = sum w_k and
    S2 = sum (n - k) w_k, both modulo 65535 in ones' complement (a non-zero
    multiple of 65535 is 65535, not 0 -- what HDF5's folded sums give), the
    checksum is ``S2 << 16 | S1``.  Vectorised: S2 is the sum of the prefix
    sums of the words (sum_j sum_{k <= j} w_k = sum_k (n - k) w_k), taken
    :data:`_BLOCK` words at a time, exact in 64-bit integers, and the blocks
    combined in Python integers -- instead of HDF5's loop over blocks of 360
    words, the same value.

    Parameters
    ----------
    data
        The bytes, of any length.

    Returns
    -------
    int
        The 32-bit checksum (HDF5 stores it little-endian after the data).
    """
    buffer = np.frombuffer(data, dtype=np.uint8)
    if buffer.size % 2:
        buffer = np.concatenate([buffer, np.zeros(1, np.uint8)])
    words = buffer.view(">u2")
    n = words.size
    total = second = 0
    for start in range(0, n, _BLOCK):
        # A block of m words: prefix sums below 65535 m < 2^38, their sum below 2^60: exact.
        prefix = np.cumsum(words[start : start + _BLOCK], dtype=np.uint64)
        block_total, m = int(prefix[-1]), prefix.size
        # sum_{k in block} (n - k) w_k = (n - start - m) * block_total + sum of the block's prefix sums
        second += (n - start - m) * block_total + int(prefix.sum())
        total += block_total
    if total == 0:
        return 0
    return ((second % _MODULUS or _MODULUS) << 16) | (total % _MODULUS or _MODULUS)


def hdf5_chunk(values: np.ndarray, level: int) -> bytes:
    """One HDF5 chunk as the filters Fletcher-32, shuffle, deflate store it, in that order.

    The order is the one netCDF-C gives a variable with ``fletcher32``,
    ``shuffle`` and ``zlib`` (checked when a chunked archive is created): the
    checksum of the raw bytes is appended (4 bytes, little-endian), the
    whole buffer is byte-shuffled by the item size (:func:`_shuffle`: for
    4-byte items the checksum is one more item, for 8-byte ones it is left
    over at the end), then deflated.

    Parameters
    ----------
    values
        The chunk's values, of the chunk's full shape.
    level
        Deflate level.
    """
    values = np.ascontiguousarray(values)
    raw = values.tobytes()
    return zlib.compress(_shuffle(raw + fletcher32(raw).to_bytes(4, "little"), values.itemsize), level)


def _shuffle(data: bytes, itemsize: int) -> bytes:
    """HDF5's byte shuffle of ``data`` as items of ``itemsize`` bytes (``H5Z_filter_shuffle``).

    The first bytes of every item, then the second bytes...; the bytes left
    over (``len(data) % itemsize``) are copied at the end as they are.
    Nothing is shuffled for items of one byte or a buffer of one item.
    """
    count = len(data) // itemsize
    if itemsize <= 1 or count <= 1:
        return data
    body = np.frombuffer(data, dtype=np.uint8, count=count * itemsize).reshape(count, itemsize)
    return body.T.tobytes() + data[count * itemsize :]


def variable_digest(values: np.ndarray) -> str:
    """SHA-256 (hex) of an array's values as an archive holds them.

    The digest covers the dtype kind, the shape and the values in C order;
    NaNs count as one value (xarray reads every NaN of a variable whose fill
    value is NaN as the same NaN), and strings are taken at the width of the
    longest one (the width they are read back at).

    Parameters
    ----------
    values
        Numbers (any shape) or strings (numpy unicode).
    """
    values = np.asarray(values)
    if values.dtype.kind in "OSU":
        values = values.astype(str)
        width = int(np.char.str_len(values).max()) if values.size else 0
        values = values.astype(f"<U{max(width, 1)}")
    elif values.dtype.kind == "f":
        values = np.where(np.isnan(values), np.nan, values).astype(values.dtype.newbyteorder("<"))
    elif values.dtype.kind in "biu":
        values = values.astype(values.dtype.newbyteorder("<"))
    head = f"{values.dtype.str}|{values.shape}|".encode()
    return hashlib.sha256(head + np.ascontiguousarray(values).tobytes()).hexdigest()


def format_digests(digests: dict[str, str]) -> str:
    """The :data:`DIGEST_ATTRIBUTE` text: one ``name sha256`` pair per line."""
    return "\n".join(f"{name} {digest}" for name, digest in digests.items())


def parse_digests(text: str) -> dict[str, str]:
    """``name -> sha256`` from a :data:`DIGEST_ATTRIBUTE` text.

    Raises
    ------
    ValueError
        A line that is not a name and 64 hexadecimal digits.
    """
    digests = {}
    for line in str(text).splitlines():
        name, _, digest = line.rpartition(" ")
        if not name or len(digest) != 64 or any(c not in "0123456789abcdef" for c in digest):
            raise ValueError(f"{line[:80]!r} is not 'name sha256'")
        digests[name] = digest
    return digests
