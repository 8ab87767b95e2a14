"""JSON documents read from users' files: every failure an :class:`~fusioncut.errors.InputError`
naming the file (and the line and column where the parser stopped).

Python's parser recurses once per level of nesting, so a file of 100,000 ``[`` raises
``RecursionError``; no document FusionCut reads nests more than a few levels, and such a file is
refused like any other malformed one. ``NaN`` and ``Infinity`` are not JSON numbers and are refused.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from fusioncut.errors import InputError, SourceLocation


def _reject(token: str) -> Any:
    raise ValueError(f"{token} is not a number")


def parse_json(text: str, file: str | Path) -> Any:
    """The document in ``text`` (read from ``file``, which errors name)."""
    try:
        return json.loads(text, parse_constant=_reject)
    except json.JSONDecodeError as e:
        raise InputError(f"not valid JSON: {e.msg}", SourceLocation(str(file), e.lineno, e.colno)) from None
    except RecursionError:
        raise InputError("not accepted: the JSON nests too deeply", file) from None
    except ValueError as e:
        raise InputError(f"not valid JSON: {e}", file) from None


def read_json(path: str | Path) -> Any:
    """The JSON document in the file ``path`` (UTF-8, a byte-order mark allowed)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise InputError("file not found", path) from None
    except UnicodeDecodeError as exc:
        raise InputError(f"not a UTF-8 text file ({exc.reason} at byte {exc.start})", path) from None
    return parse_json(text, path)
