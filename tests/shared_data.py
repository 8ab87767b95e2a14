"""Where the shared test data lives (real programs, tool tables, reference interpreter output; not in
the repository): ``$FUSIONCUT_SHARED_DATA`` when set, else ``../shared/data`` beside the repository.

Tests that need a file skip without it; ``FUSIONCUT_REQUIRE_SHARED_DATA=1`` (CI, ``.ci/run``) turns a
missing folder into a failure of the whole run instead (``tests/conftest.py``).
"""
import os
from pathlib import Path

DATA = Path(os.environ.get("FUSIONCUT_SHARED_DATA") or Path(__file__).resolve().parents[2] / "shared" / "data")
