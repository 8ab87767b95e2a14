"""The README says what the code does.

* Every ```python block that follows a ``<!-- doctest -->`` line runs. What it prints must equal
  the ```text block that comes right after it.
* The results tables between ``<!-- results-tables: begin -->`` and ``<!-- results-tables: end -->``
  are the column tables of :mod:`fusioncut.io.result_columns`, row for row.
* The README holds no date and no time of day. Measurements with their dates belong in
  ``docs/benchmark.md``.
* Every relative link points to a file in the repository and every repository path named
  (``fusioncut/...``, ``docs/...``) exists, in the README and in the notes that took its evidence
  (``docs/benchmark.md``, ``docs/decisions/``); every dotted name the README gives
  (``fusioncut.io.results.load_results``) imports.
"""
from __future__ import annotations

import contextlib
import importlib
import io
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TEXT = README.read_text(encoding="utf-8")

DOCTEST_MARK = "<!-- doctest -->"
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\n", re.S | re.M)


def _doctest_blocks(text: str) -> list[tuple[int, str, str]]:
    """(line, code, expected output) of each python block marked to run: the marker on a line of its
    own, then the block (blank lines between allowed), then a text block with what it prints."""
    blocks = []
    for mark in re.finditer(rf"^{re.escape(DOCTEST_MARK)}$", text, re.M):  # a line of its own
        line = text.count("\n", 0, mark.start()) + 1
        rest = text[mark.end():].lstrip("\n")
        code = FENCE.match(rest)
        assert code and code.group(1) == "python", f"README.md:{line}: {DOCTEST_MARK} is not followed by a python block"
        after = rest[code.end():].lstrip("\n")
        expected = FENCE.match(after)
        assert expected and expected.group(1) == "text", \
            f"README.md:{line}: the python block marked to run is not followed by a text block of its output"
        blocks.append((line, code.group(2), expected.group(2)))
    return blocks


BLOCKS = _doctest_blocks(TEXT)


def test_the_readme_has_a_runnable_example():
    assert BLOCKS, f"no {DOCTEST_MARK} python block in README.md"


@pytest.mark.parametrize("line, code, expected", BLOCKS, ids=[f"README.md:{b[0]}" for b in BLOCKS])
def test_readme_example_prints_what_the_readme_says(line, code, expected, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # an example that writes files writes them here
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, f"README.md:{line}", "exec"), {"__name__": "__readme__"})
    assert out.getvalue() == expected


def test_readme_results_tables_are_the_code_s_columns():
    from fusioncut.io.result_columns import TABLES, column_table

    section = re.search(r"<!-- results-tables: begin -->\n(.*?)<!-- results-tables: end -->", TEXT, re.S)
    assert section, "README.md has no results-tables section"
    found = re.findall(r"(?:^\|.*\n)+", section.group(1), re.M)
    assert found == [column_table(name, "markdown") for name in TABLES], (
        "README.md's results tables differ from fusioncut.io.result_columns: paste column_table(name) for "
        f"{', '.join(TABLES)} between the results-tables markers")


def test_readme_holds_no_date_or_time_of_day():
    dates = re.findall(r"\b20\d\d-[01]\d-[0-3]\d\b", TEXT)
    times = re.findall(r"\b[0-2]?\d:[0-5]\d\b", TEXT)  # 18:18, 05:12 (a ratio is written 1:5)
    assert not dates and not times, f"dates {dates}, times of day {times}: measurements go to docs/benchmark.md"


# the README and the notes that took its evidence: links resolve from the file's folder, repository
# paths (fusioncut/..., docs/...) from the repository root
DOCUMENTS = [README, ROOT / "docs" / "benchmark.md",
             *(ROOT / "docs" / "decisions" / f"{name}.md"
               for name in ("README", "swept-volumes-and-booleans", "layers-and-planar-cuts",
                            "cells-bounds-and-merges"))]


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_links_point_to_files_in_the_repository(document):
    text = document.read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [link for link in links if not re.match(r"[a-z]+://", link)]
    assert local, "no relative link found: the pattern is wrong"
    missing = [link for link in local if not (document.parent / link).exists()]
    assert not missing, f"{document.name} links to missing files: {missing}"


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: str(p.relative_to(ROOT)))
def test_repository_paths_exist(document):
    text = document.read_text(encoding="utf-8")
    paths = set(re.findall(r"(?<![\w/.-])((?:fusioncut|tests|docs|benchmarks|frontend|\.ci)/[\w./-]*\w)", text))
    assert paths or document != README, "no repository path found in README.md: the pattern is wrong"
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert not missing, f"{document.name} names paths that do not exist: {missing}"


def _resolve(dotted: str) -> object:
    """The object a dotted name names: the longest importable module prefix, then attributes."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
            break
        except ModuleNotFoundError:
            continue
    for name in parts[i:]:
        obj = getattr(obj, name)
    return obj


def test_readme_dotted_names_import():
    names = set(re.findall(r"(?<![\w/.-])(fusioncut(?:\.\w+)+)", TEXT))
    assert names, "no dotted name found: the pattern is wrong"
    bad = []
    for name in sorted(names):
        try:
            _resolve(name)
        except (ImportError, AttributeError) as e:
            bad.append(f"{name} ({e})")
    assert not bad, f"README.md names what the code does not have: {bad}"


def test_the_decisions_index_lists_every_note():
    folder = ROOT / "docs" / "decisions"
    index = (folder / "README.md").read_text(encoding="utf-8")
    listed = set(re.findall(r"\]\(([\w-]+\.md)\)", index))
    notes = {p.name for p in folder.glob("*.md")} - {"README.md"}
    assert notes - listed == set(), f"docs/decisions/README.md does not list {sorted(notes - listed)}"
