"""Fixtures of the service tests: one service (subprocess on loopback) shared by the API and browser
tests of a test session (of each xdist worker): starting one costs seconds of a 2-core budget."""
from __future__ import annotations

import pytest
from service_helpers import ServiceProcess


@pytest.fixture(scope="session")
def service(tmp_path_factory):
    root = tmp_path_factory.mktemp("svc")
    svc = ServiceProcess(root / "data", workers=1,
                         env={"FUSIONCUT_MAX_UPLOAD_MB": "1", "FUSIONCUT_MAX_CLS": "2000",
                              "FUSIONCUT_MAX_SLICES": "100000"})
    yield svc
    svc.stop()


@pytest.fixture
def client(service):
    with service.client() as c:
        yield c
