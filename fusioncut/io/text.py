"""Reading a source file's text, with the file named in every error (:class:`InputError`)."""
from __future__ import annotations

from pathlib import Path

from fusioncut.errors import InputError, SourceLocation

__all__ = ["read_source_text", "read_utf8_text"]


def read_source_text(path: str | Path) -> str:
    """The file's text: UTF-8 (with or without BOM), else Windows-1252/Latin-1 as CAM posts on
    Windows write it. Unreadable files raise :class:`InputError`."""
    data = _read_bytes(path)
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def read_utf8_text(path: str | Path) -> str:
    """The text of a file that must be UTF-8 (JSON), with or without BOM; else :class:`InputError`
    naming the file and the first byte that is not."""
    try:
        return _read_bytes(path).decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputError(f"not UTF-8 text (byte {e.start})", SourceLocation(str(path))) from e


def _read_bytes(path: str | Path) -> bytes:
    try:
        return Path(path).read_bytes()
    except OSError as e:
        raise InputError(f"cannot read the file: {e.strerror or e}", SourceLocation(str(path))) from e
