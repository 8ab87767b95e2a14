"""The service application's shape: its routes (the contract the front end and API clients rely on),
rooms of one concern each, the failure types a user can see, and ``fusioncut serve`` without its extra.
No service process is started here."""
from __future__ import annotations

import ast
import importlib.util
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

import fusioncut.service
from fusioncut.errors import FusionCutError

SERVICE = Path(fusioncut.service.__file__).parent

# every /api route and its methods, as the front end (frontend/src) and the docs use them
API = {
    "/api/info": {"get"},
    "/api/jobs": {"get", "post"},
    "/api/jobs/{job_id}": {"get", "delete"},
    "/api/jobs/{job_id}/cancel": {"post"},
    "/api/jobs/{job_id}/events": {"get"},
    "/api/events": {"get"},
    "/api/jobs/{job_id}/files": {"get"},
    "/api/jobs/{job_id}/files/{name}": {"get"},
    "/api/jobs/{job_id}/summary": {"get"},
    "/api/jobs/{job_id}/cls/{cl}": {"get"},
    "/api/jobs/{job_id}/plots/{kind}": {"get"},
    "/api/jobs/{job_id}/scene": {"get"},
    "/api/jobs/{job_id}/scene.glb": {"get"},
}


@pytest.fixture(scope="module")
def app(tmp_path_factory):
    from fusioncut.service.app import create_app
    from fusioncut.service.settings import Settings

    return create_app(Settings(data_dir=tmp_path_factory.mktemp("data"), api_keys=("k" * 20,), warm_up=False))


def test_the_api_has_its_routes_and_methods(app):
    paths = app.openapi()["paths"]
    assert {p: set(ops) for p, ops in paths.items()} == API
    # every route but the key-less front end needs the key, and documents the refusal
    for p, ops in paths.items():
        for method, op in ops.items():
            assert op.get("security") == [{"APIKeyHeader": []}], (method, p)
            assert "401" in op["responses"], (method, p)
    submit = paths["/api/jobs"]["post"]["requestBody"]["content"]
    assert set(submit) == {"application/json", "multipart/form-data"}
    assert "JobSubmission" in app.openapi()["components"]["schemas"]


def test_the_front_end_and_api_pages_answer_without_a_key(app):
    from fastapi.testclient import TestClient

    client = TestClient(app)  # no lifespan: the service is not started, routes still answer
    assert client.get("/favicon.ico").status_code == 204
    assert client.get("/").status_code == 200
    r = client.get("/api/info")
    assert r.status_code == 401 and r.json() == {"detail": "missing X-API-Key header"}


def _module_lines() -> dict[str, int]:
    return {str(p.relative_to(SERVICE)): len(p.read_text(encoding="utf-8").splitlines())
            for p in SERVICE.rglob("*.py")}


def test_service_modules_are_rooms_under_400_lines():
    sizes = _module_lines()
    assert "routes/jobs.py" in sizes and "app.py" in sizes
    assert {m: n for m, n in sizes.items() if n >= 400} == {}


def test_create_app_is_an_assembly():
    tree = ast.parse((SERVICE / "app.py").read_text(encoding="utf-8"))
    fn = next(n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "create_app")
    assert fn.end_lineno - fn.lineno < 40
    routes = [d.func.attr for n in ast.walk(fn) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
              for d in n.decorator_list if isinstance(d, ast.Call) and isinstance(d.func, ast.Attribute)
              and d.func.attr in ("get", "post", "put", "patch", "delete", "api_route", "route")]
    assert routes == [], "routes belong to the routers of fusioncut.service.routes"


def test_routers_import_no_other_router():
    """Each router stands on access (and the service below it), never on another router."""
    for p in (SERVICE / "routes").glob("*.py"):
        tree = ast.parse(p.read_text(encoding="utf-8"))
        imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
        routers = {m for m in imported if m.startswith("fusioncut.service.routes.")}
        assert routers <= {"fusioncut.service.routes.access"}, p.name


def test_failures_a_user_sees_are_fusioncut_errors():
    from fusioncut.service.body_limit import BodyTooLarge
    from fusioncut.service.core import ClusterUnavailable
    from fusioncut.service.submit import SubmissionError

    for kind in (BodyTooLarge, ClusterUnavailable, SubmissionError):
        assert issubclass(kind, FusionCutError), kind
    assert str(BodyTooLarge(3 * 1024 * 1024)) == "request body larger than the limit of 3.0 MiB"


def test_serve_without_the_service_extra_names_it(tmp_path, monkeypatch):
    from fusioncut.cli import app as cli

    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "uvicorn" else find_spec(name, *a))
    monkeypatch.setitem(sys.modules, "uvicorn", None)  # `import uvicorn` fails as when it is not installed
    res = CliRunner().invoke(cli, ["serve", "--data-dir", str(tmp_path / "data")])
    assert res.exit_code == 2, res.output
    assert "[service] extra (uvicorn not installed): pip install 'fusioncut[service]'" in " ".join(res.output.split())
    assert not (tmp_path / "data").exists()  # refused before the service touched anything
