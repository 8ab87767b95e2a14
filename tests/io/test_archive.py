"""Zip members are inflated with a hard cap, never trusting the header (issue 24, item 2)."""
from __future__ import annotations

import io
import tracemalloc
import zipfile

import pytest

from fusioncut.errors import InputError
from fusioncut.io import archive
from fusioncut.io.archive import read_member
from fusioncut.io.tool_library import read_tool_library

MB = 1024 * 1024


def test_lying_header_is_refused_without_inflating_the_member(tmp_path, lying_archive):
    p = tmp_path / "bomb.tools"
    lying_archive(p, "tools.json", 200 * MB, 1000)
    assert p.stat().st_size < 2 * MB  # 200 MB of zeros deflate to ~200 KB
    assert zipfile.ZipFile(p).getinfo("tools.json").file_size == 1000
    tracemalloc.start()
    try:
        with pytest.raises(InputError) as err:
            read_tool_library(p)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 50 * MB, f"peak allocation {peak / MB:.1f} MB"
    assert str(p) in str(err.value) and "tools.json" in str(err.value)
    assert "damaged archive member" in str(err.value)


def test_member_over_the_cap_by_its_header(tmp_path, monkeypatch):
    monkeypatch.setattr(archive, "MAX_MEMBER_BYTES", MB)
    p = tmp_path / "big.tools"
    with zipfile.ZipFile(p, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("lib/tools.json", b" " * (2 * MB) + b"{}")
    with pytest.raises(InputError, match=r"big\.tools: lib/tools\.json: its header says 2097154 bytes, more than "
                                         r"the 1048576-byte limit"):
        read_tool_library(p)


class _Inflating:
    """A stand-in archive whose member inflates past what its header says (what a zip reader that
    trusted the header would hand over)."""

    def __init__(self, header_size: int, true_size: int):
        self.info = zipfile.ZipInfo("tools.json")
        self.info.file_size = header_size
        self.true_size = true_size
        self.read_sizes: list[int] = []

    def getinfo(self, name: str) -> zipfile.ZipInfo:
        return self.info

    def open(self, info: zipfile.ZipInfo):
        outer = self

        class _Stream(io.RawIOBase):
            left = outer.true_size

            def read(self, n: int = -1) -> bytes:
                outer.read_sizes.append(n)
                n = self.left if n < 0 else min(n, self.left)
                self.left -= n
                return bytes(n)

        return _Stream()


def test_stream_stops_at_cap_plus_one_whatever_the_header_says():
    zf = _Inflating(header_size=1000, true_size=50 * MB)
    with pytest.raises(InputError, match=r"lib\.tools: tools\.json: inflates to more than the 3145728-byte limit "
                                         r"for an archive member \(its header says 1000 bytes\)"):
        read_member(zf, "tools.json", "lib.tools", cap=3 * MB)  # type: ignore[arg-type]
    assert sum(zf.read_sizes) == 3 * MB + 1 and max(zf.read_sizes) <= archive.CHUNK_BYTES
    ok = _Inflating(header_size=10, true_size=10)
    assert read_member(ok, "tools.json", "lib.tools", cap=10) == bytes(10)  # type: ignore[arg-type]
