"""Turning a request into a job folder, and checking the job before it is queued.

Everything a worker would trip over is found here, while the user is still waiting for the answer:
the job must parse (pydantic), every file it names must have been uploaded under a safe name, the
tool library and every toolpath file are read once with the project's own readers (so a malformed
G-code line is reported with its file:line:column, as the CLI reports it), every tool a move uses
must be defined, and the job must not make more work (CL segments, slices, snapshots, checkpoints)
than the service's :class:`~fusioncut.engines.sizing.Budget` (:attr:`Settings.budget`).
"""
from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, get_args, get_origin

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from fusioncut.engines.sizing import Budget
from fusioncut.errors import FusionCutError, InputError
from fusioncut.io.job import Job, OptionField, engine_option_fields
from fusioncut.service.files import INPUT_DIR, JOB_FILE, check_name
from fusioncut.service.portable import portable_text

STOCK_SUFFIXES = (".step", ".stp", ".brep")
SCENE_FILE = "scene.json"  # stock outline for the 3D view, computed while checking the job


class SubmissionError(FusionCutError):
    """A request the service refuses: ``status`` (4xx) and a one-line message for the user."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status = status
        self.message = message


class JobSubmission(BaseModel):
    """JSON body of ``POST /api/jobs``: the demo, or a job with its input files given inline.

    ``files`` maps plain file names (as the job names them) to their text: G-code, APT/CLSF,
    Fusion JSON posts, tool libraries (.json/.tbl), or STEP stock. Binary files (Fusion ``.tools``
    archives, binary BREP) need the multipart form instead.
    """

    model_config = ConfigDict(extra="forbid", json_schema_extra={"examples": [
        {"demo": True},
        {"job": {"name": "slot", "stock": {"kind": "box", "min": [0, 0, -5], "max": [30, 20, 0]},
                 "tools": [{"number": 1, "kind": "flat", "diameter": 6, "flute_length": 12}],
                 "toolpaths": ["slot.nc"], "options": {"max_segment_length": 4}},
         "files": {"slot.nc": "T1 M6\nG0 X-5 Y10 Z5\nG1 Z-1 F300\nG1 X35 F600\nM30\n"}},
    ]})

    demo: bool = Field(False, description="run the built-in demo block (no job or files)")
    name: str | None = Field(None, max_length=200, description="job name (default: the job's own name)")
    job: Job | None = Field(None, description="the job, as in a job file; paths are names in `files`")
    files: dict[str, str] = Field(default_factory=dict, description="file name -> file text")


def _form_field(f: OptionField) -> tuple[dict[str, Any], Callable[[str], Any]]:
    """The form field of a job engine option: its JSON schema and how its text becomes the value
    (``none`` for an option whose ``None`` means something; the job's validation does the rest)."""
    kind = next(a for a in get_args(f.type) if a is not type(None)) if f.takes_none else f.type
    schema: dict[str, Any] = {"description": f.description}
    if get_origin(kind) is Literal:
        schema.update(type="string", enum=list(get_args(kind)))
        convert: Callable[[str], Any] = str
    elif kind is bool:
        schema["type"] = "boolean"
        convert = _flag
    else:
        schema["type"] = "integer" if kind is int else "number"
        convert = int if kind is int else float
    if f.takes_none:
        schema = {"anyOf": [schema, {"type": "string", "enum": ["none"]}], "description": schema.pop("description")}
        convert = _or_none(convert)
    return schema, convert


def _flag(text: str) -> bool:
    return text.lower() in ("1", "true", "on", "yes")


def _or_none(convert: Callable[[str], Any]) -> Callable[[str], Any]:
    return lambda text: None if text.strip().lower() in ("none", "null") else convert(text)


# the job engine options a form may set, generated from EngineOptions: name -> (schema, converter)
_OPTION_FORM = {f.name: _form_field(f) for f in engine_option_fields()}
OPTION_FIELDS: dict[str, Callable[[str], Any]] = {name: convert for name, (_, convert) in _OPTION_FORM.items()}

MULTIPART_SCHEMA: dict[str, Any] = {
    "type": "object",
    "description": (
        "Upload form. `job` is a job JSON whose file fields may be left out: `toolpaths` defaults to "
        "the uploaded toolpath files, `tool_library` to the uploaded library, `stock` to the uploaded "
        "STEP file (else {\"kind\": \"infer\"}). The option fields override the job's options."),
    "properties": {
        "toolpath": {"type": "array", "items": {"type": "string", "format": "binary"},
                     "description": "toolpath files: G-code, APT/CLSF (.apt/.cls), Fusion JSON post (.json)"},
        "tool_library": {"type": "string", "format": "binary", "description": "tool library (.json/.tools/.tbl)"},
        "stock": {"type": "string", "format": "binary", "description": "stock solid (.step/.stp/.brep)"},
        "job": {"type": "string", "description": "job JSON (may be partial, see above)"},
        "demo": {"type": "boolean", "description": "run the built-in demo instead"},
        "name": {"type": "string"},
        **{name: schema for name, (schema, _) in _OPTION_FORM.items()},
        "strict": {"type": "boolean"},
    },
}


@dataclass
class Checked:
    job: Job
    total_cls: int
    stock: dict[str, Any] | None


def validation_message(exc: ValidationError, prefix: str = "") -> str:
    """The first problem as ``path.to.field: message``, and how many there are."""
    first = exc.errors()[0]
    loc = ".".join(str(p) for p in (*([prefix] if prefix else []), *first["loc"])) or "<body>"
    more = f" ({exc.error_count()} problems in all)" if exc.error_count() > 1 else ""
    return f"{loc}: {first['msg']}{more}"


# Python's JSON parser recurses once per level of nesting: a body of 100,000 '[' raised RecursionError,
# answered 500. No job nests more than a few levels.
_TOO_DEEP = "the JSON nests too deeply"


def parse_json_body(raw: bytes) -> JobSubmission:
    try:
        data = json.loads(raw)
    except UnicodeDecodeError:
        raise SubmissionError(422, "the body is not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise SubmissionError(422, f"the body is not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    except RecursionError:
        raise SubmissionError(422, f"the body is not accepted: {_TOO_DEEP}") from None
    if isinstance(data, dict) and "toolpaths" in data and "job" not in data:
        raise SubmissionError(422, 'a job must be wrapped with its files: {"job": {...}, "files": {"name.nc": "text"}}')
    try:
        return JobSubmission.model_validate(data)
    except ValidationError as exc:
        raise SubmissionError(422, validation_message(exc)) from None
    except RecursionError:
        raise SubmissionError(422, f"the body is not accepted: {_TOO_DEEP}") from None


def write_text_files(files: dict[str, str], folder: Path) -> dict[str, Path]:
    out = {}
    for name, text in files.items():
        safe = _checked_name(name, "files")
        if safe in out:
            raise SubmissionError(422, f"files: two files named {safe!r}")
        p = folder / safe
        p.write_text(text, encoding="utf-8")
        out[safe] = p
    return out


def _checked_name(name: str, what: str) -> str:
    try:
        return check_name(name, f"{what}: file name")
    except InputError as exc:
        raise SubmissionError(422, str(exc)) from None


def build_job_from_form(job_text: str | None, uploads: dict[str, list[str]], form: dict[str, str]) -> Job:
    """The job of a multipart upload: the ``job`` field completed with the uploaded file names and the
    option fields (see :data:`MULTIPART_SCHEMA`)."""
    data: dict[str, Any] = {}
    if job_text:
        try:
            data = json.loads(job_text)
        except RecursionError:
            raise SubmissionError(422, f"job: not accepted: {_TOO_DEEP}") from None
        except json.JSONDecodeError as exc:
            raise SubmissionError(422, f"job: not valid JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
        if not isinstance(data, dict):
            raise SubmissionError(422, "job: must be a JSON object")
    if uploads.get("toolpath") and "toolpaths" not in data:
        data["toolpaths"] = list(uploads["toolpath"])
    if uploads.get("tool_library") and "tool_library" not in data:
        data["tool_library"] = uploads["tool_library"][0]
    if "stock" not in data:
        data["stock"] = ({"kind": "file", "path": uploads["stock"][0]} if uploads.get("stock") else {"kind": "infer"})
    if form.get("name"):
        data["name"] = form["name"]
    options = dict(data.get("options") or {})
    for key, conv in OPTION_FIELDS.items():
        value = form.get(key)
        if value not in (None, ""):
            try:
                options[key] = conv(value)
            except ValueError:
                raise SubmissionError(422, f"{key}: {value!r} is not a number") from None
    if options:
        data["options"] = options
    if form.get("strict") not in (None, ""):
        data["strict"] = _flag(form["strict"])
    if not data.get("toolpaths"):
        raise SubmissionError(422, "no toolpath file: upload at least one (field 'toolpath') or choose the demo")
    try:
        return Job.model_validate(data)
    except ValidationError as exc:
        raise SubmissionError(422, validation_message(exc, "job")) from None
    except RecursionError:
        raise SubmissionError(422, f"job: not accepted: {_TOO_DEEP}") from None


def check_job(job: Job, folder: Path, budget: Budget) -> Checked:
    """Check ``job`` against the files in ``folder`` (see the module doc); raises :class:`SubmissionError`.

    The checked job names its files in NFC, the form they were stored under (:func:`check_name`), so
    that a job typed on one system and its files uploaded from another (macOS names files in NFD)
    agree on every name."""
    job = _nfc_names(job)
    present = {p.name for p in folder.iterdir() if p.is_file()}
    named: list[tuple[str, str]] = [(f"toolpaths[{k}]", n) for k, n in enumerate(job.toolpaths)]
    if job.tool_library:
        named.append(("tool_library", job.tool_library))
    if job.stock.kind == "file":
        named.append(("stock.path", job.stock.path or ""))
    for where, name in named:
        if name not in present:
            raise SubmissionError(422, f"job.{where}: file {name!r} was not uploaded")
    if job.stock.kind == "file" and not (job.stock.path or "").lower().endswith(STOCK_SUFFIXES):
        raise SubmissionError(422, f"job.stock.path: {job.stock.path!r} is not a STEP or BREP file "
                                   f"({', '.join(STOCK_SUFFIXES)})")
    try:
        return _read_inputs(job, folder, budget)
    except FusionCutError as exc:
        raise SubmissionError(422, portable_text(str(exc), folder)) from None
    except (OSError, ValueError) as exc:
        raise SubmissionError(422, portable_text(f"{type(exc).__name__}: {exc}", folder)) from None


def _nfc_names(job: Job) -> Job:
    """``job`` with the file names it gives checked (:func:`check_name`) and in their NFC form."""
    update: dict[str, Any] = {
        "toolpaths": [_checked_name(n, f"job.toolpaths[{k}]") for k, n in enumerate(job.toolpaths)]}
    if job.tool_library:
        update["tool_library"] = _checked_name(job.tool_library, "job.tool_library")
    if job.stock.kind == "file":
        update["stock"] = job.stock.model_copy(update={"path": _checked_name(job.stock.path or "", "job.stock.path")})
    return job.model_copy(update=update)


def _read_inputs(job: Job, folder: Path, budget: Budget) -> Checked:
    # The runner's own reading and checking, so that the service accepts exactly what `fusioncut
    # run` accepts and refuses it with the same message; it writes nothing. The job is sized from its
    # moves (closed form, nothing expanded) and refused over the service's budget.
    from fusioncut.engines.sizing import size_toolpath
    from fusioncut.model.stock import BoxStock, CylinderStock
    from fusioncut.runner import prepare_job

    p = prepare_job(job, folder)
    total = size_toolpath(p.toolpath, p.options, p.default_tool, p.checkpoint_every, p.snapshot_cls, budget,
                          p.stock).cls
    stock: dict[str, Any] | None = None  # a STEP stock is only read by the worker
    if isinstance(p.stock, BoxStock):
        stock = {"kind": "box", "min": list(p.stock.minimum), "max": list(p.stock.maximum)}
    elif isinstance(p.stock, CylinderStock):
        stock = {"kind": "cylinder", "base_center": list(p.stock.base_center), "radius": p.stock.radius,
                 "height": p.stock.height}
    return Checked(job, total, stock)


def stage_folder(jobs_dir: Path, token: str) -> Path:
    folder = jobs_dir / f".staging-{token}" / INPUT_DIR
    folder.mkdir(parents=True)
    return folder


def commit_folder(staged_input: Path, job_dir: Path, checked: Checked) -> None:
    """Write the checked job and move the staged folder into place as the job's folder."""
    (staged_input / JOB_FILE).write_text(checked.job.model_dump_json(indent=2), encoding="utf-8")
    (staged_input.parent / SCENE_FILE).write_text(json.dumps({"stock": checked.stock}), encoding="utf-8")
    staged_input.parent.rename(job_dir)


def discard(staged_input: Path) -> None:
    shutil.rmtree(staged_input.parent, ignore_errors=True)
