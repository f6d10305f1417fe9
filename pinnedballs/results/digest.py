"""Digests: a damaged results file is refused before anything parses it (format 3).

The index begins with a header of `HEADER_SIZE` bytes (an HDF5 user block, which HDF5 and
h5py skip) holding the SHA-256 of the rest of the file; the index's attribute ``digests``
holds the SHA-256 of the static file and of every segment. A file whose bytes differ from
their digest (one flipped bit, a file cut short, a dataset deleted or copied by another program)
is refused with one message naming it: a damaged file is never read as data, and HDF5 never
parses bytes that could make it crash or hang. Files of formats 1 and 2 have no digests (they
begin with HDF5's signature) and are checked by their structure alone (`check`).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import BinaryIO

from .format import ResultsError

__all__ = ["HEADER_SIZE", "seal", "unseal", "file_digest", "bytes_digest"]

HEADER_SIZE = 512
#: the first bytes of an HDF5 file (whose superblock is at its start)
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_MAGIC = b"pinnedballs results index; the SHA-256 of the bytes after the first 512:\n"
_HEX = 64


def bytes_digest(data: bytes) -> str:
    """The SHA-256 of ``data``, in hex."""
    return hashlib.sha256(data).hexdigest()


def file_digest(path: Path) -> str:
    """The SHA-256 of the file at ``path``, in hex, read a few MB at a time."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while block := f.read(1 << 22):
            h.update(block)
    return h.hexdigest()


def seal(image: bytes) -> bytes:
    """The HDF5 file ``image`` behind a header holding its digest."""
    header = _MAGIC + bytes_digest(image).encode("ascii") + b"\n"
    return header.ljust(HEADER_SIZE, b"\0") + image


def unseal(path: Path, f: BinaryIO) -> bool:
    """True if the index ``f`` (open at its start, at ``path``) carries a digest and its bytes match
    it; False if it is an HDF5 file without one (formats 1 and 2: only its first bytes are read);
    else a `ResultsError` naming ``path``. HDF5 thus never parses a damaged index of format 3."""
    header = f.read(HEADER_SIZE)
    if header.startswith(HDF5_SIGNATURE):
        return False
    if not header.startswith(_MAGIC):
        raise ResultsError(f"{path}: not a readable HDF5 file (it begins neither as one nor with the digest "
                           f"pinnedballs writes: not a results file, or damaged)")
    written = header[len(_MAGIC):len(_MAGIC) + _HEX].decode("ascii", "replace")
    h = hashlib.sha256()
    while block := f.read(1 << 22):
        h.update(block)
    if len(header) < HEADER_SIZE or h.hexdigest() != written:
        raise ResultsError(f"{path}: damaged results file: its bytes differ from the digest written with them "
                           f"(changed or cut short since pinnedballs wrote it)")
    return True
