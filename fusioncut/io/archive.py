"""Reading one member of a zip archive with a hard cap on the inflated bytes.

A zip header's ``file_size`` is written by whoever made the archive and is not evidence of
anything: :meth:`zipfile.ZipFile.read` inflates a member's whole compressed stream in one call
before cutting it to the header's size, so a member whose header says 1,000 bytes and inflates to
gigabytes takes gigabytes. :func:`read_member` instead inflates in chunks of
:data:`CHUNK_BYTES` and stops as soon as more than ``cap`` bytes came out, so memory stays within
``cap + CHUNK_BYTES`` whatever the headers say. A member whose inflated bytes disagree with its
header (size or CRC-32) is refused as damaged.
"""
from __future__ import annotations

import zipfile

from fusioncut.errors import InputError, SourceLocation

__all__ = ["MAX_MEMBER_BYTES", "CHUNK_BYTES", "read_member"]

MAX_MEMBER_BYTES = 64 * 1024 * 1024
"""Default cap (bytes) on one inflated archive member: the archives FusionCut reads (Fusion
``.tools`` libraries) hold kilobytes of JSON; anything beyond this is refused, not read."""

CHUNK_BYTES = 1024 * 1024
"""Inflated bytes asked for per read; bounds the decompressor's output per call."""


def read_member(zf: zipfile.ZipFile, member: str, file: str, cap: int | None = None) -> bytes:
    """The inflated bytes of ``member`` of the open archive ``zf`` (``file`` names it in errors).

    Raises :class:`InputError` naming ``file`` and ``member`` when the header announces more than
    ``cap`` bytes (default :data:`MAX_MEMBER_BYTES`), when more than ``cap`` bytes come out
    whatever the header says, or when the member is damaged (its bytes disagree with its header).
    """
    limit = MAX_MEMBER_BYTES if cap is None else cap
    where = SourceLocation(file)
    info = zf.getinfo(member)
    if info.file_size > limit:
        raise InputError(f"{member}: its header says {info.file_size} bytes, more than the "
                         f"{limit}-byte limit for an archive member; not read", where)
    chunks: list[bytes] = []
    total = 0
    try:
        with zf.open(info) as stream:
            while True:
                chunk = stream.read(min(CHUNK_BYTES, limit + 1 - total))
                if not chunk:
                    break
                chunks.append(chunk)
                total += len(chunk)
                if total > limit:
                    raise InputError(f"{member}: inflates to more than the {limit}-byte limit for an "
                                     f"archive member (its header says {info.file_size} bytes); not read", where)
    except (zipfile.BadZipFile, EOFError) as e:
        # zipfile stops at the header's size and then checks the CRC-32: a header that lies about the
        # size ends here
        raise InputError(f"{member}: damaged archive member (its bytes disagree with its header: {e})",
                         where) from e
    return b"".join(chunks)
