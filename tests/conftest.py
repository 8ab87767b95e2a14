"""Test-wide settings.

The shared test data's folder is :data:`shared_data.DATA` (``tests/shared_data.py``).

CI (``.ci/run`` sets ``HYPOTHESIS_PROFILE=ci``) draws the same property-test examples every run, so
that a landing is red or green for the code, not for the draw; local runs draw new examples (and
replay the failures they found from ``.hypothesis/``).
"""
import os
import struct
import zipfile

import pytest

from hypothesis import settings

settings.register_profile("ci", derandomize=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


def pytest_sessionstart(session):
    """With ``FUSIONCUT_REQUIRE_SHARED_DATA=1`` (CI) a missing shared-data folder stops the run: the
    real-program tests would otherwise all skip and the run look green (``tests/shared_data.py``)."""
    from shared_data import DATA

    if os.environ.get("FUSIONCUT_REQUIRE_SHARED_DATA") == "1" and not DATA.is_dir():
        pytest.exit(f"shared test data not found at {DATA} (set FUSIONCUT_SHARED_DATA)", returncode=4)


@pytest.fixture
def lying_archive():
    """``make(path, member, true_size, header_size)``: a zip whose one member inflates to ``true_size``
    zero bytes while its local header and central-directory entry both say ``header_size``."""
    def make(path, member: str, true_size: int, header_size: int) -> None:
        with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
            with zf.open(member, "w") as out:
                block = bytes(1 << 20)
                for _ in range(true_size >> 20):
                    out.write(block)
        raw = bytearray(path.read_bytes())
        struct.pack_into("<I", raw, raw.index(b"PK\x03\x04") + 22, header_size)  # local header
        struct.pack_into("<I", raw, raw.rindex(b"PK\x01\x02") + 24, header_size)  # central directory
        path.write_bytes(bytes(raw))
    return make


@pytest.fixture
def frontend_packages():
    """The front end's npm packages (three.js and Swagger UI, from `npm ci` in frontend/), which the 3D
    view and the service's pages serve: a test that needs them skips without them, unless CI requires
    them (``FUSIONCUT_REQUIRE_BROWSER=1``, ``.ci/run``)."""
    from fusioncut.errors import FusionCutError
    from fusioncut.service.settings import default_frontend_dir
    from fusioncut.viz.scene import three_dir

    swagger = default_frontend_dir() / "node_modules" / "swagger-ui-dist" / "swagger-ui-bundle.js"
    try:
        three_dir()
        if not swagger.is_file():
            raise FileNotFoundError(f"Swagger UI not found ({swagger} is missing): run `npm ci` in frontend/")
    except (FusionCutError, FileNotFoundError) as exc:
        if os.environ.get("FUSIONCUT_REQUIRE_BROWSER") == "1":
            pytest.fail(str(exc))
        pytest.skip(str(exc))
