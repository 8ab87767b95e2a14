"""The job file: one JSON naming stock, tools, toolpath files and options (mm, degrees).

``fusioncut run job.json`` is reproducible: the same file gives the same results, and the job hash
(SHA-256 of the normalised job and the bytes of every input file) is written into the results.
The JSON Schema is ``Job.model_json_schema()`` (``fusioncut schema`` prints it).
"""
from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, replace
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, get_args, get_type_hints

from pydantic import BaseModel, ConfigDict, Field, ValidationError, create_model, field_validator, model_validator

from fusioncut.model.options import EngineOptions
from fusioncut.errors import InputError, ToolDefinitionError
from fusioncut.io.json_input import read_json
from fusioncut.io.readers import read_toolpath  # noqa: F401 - the runner reads toolpaths from here
from fusioncut.model.stock import BoxStock, CylinderStock, SolidStock, Stock
from fusioncut.model.tools import (AptCutter, AptParameters, BallEndMill, BullNoseEndMill, ChamferMill, Drill,
                                   FlatEndMill, MillingTool, SpindleDirection, TaperedEndMill)

if TYPE_CHECKING:
    from fusioncut.io.tool_library import ToolLibrary


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class StockSpec(_Strict):
    """``box`` (min, max corners), ``cylinder`` (base_center, radius, height), ``file`` (STEP/BREP path)
    or ``infer`` (the feed moves' extents plus ``margin``, mm). ``top`` (mm, ``infer`` only) states
    the stock top instead of guessing it (see :func:`fusioncut.io.stock.infer_stock`): give it whenever
    the CAM setup says where the top is."""

    kind: Literal["box", "cylinder", "file", "infer"]
    min: tuple[float, float, float] | None = None
    max: tuple[float, float, float] | None = None
    base_center: tuple[float, float, float] | None = None
    radius: float | None = None
    height: float | None = None
    path: str | None = None
    margin: float = Field(2.0, ge=0, allow_inf_nan=False)
    top: float | None = Field(None, allow_inf_nan=False)

    @model_validator(mode="after")
    def _complete(self) -> StockSpec:
        need = {"box": ("min", "max"), "cylinder": ("base_center", "radius", "height"), "file": ("path",), "infer": ()}
        missing = [k for k in need[self.kind] if getattr(self, k) is None]
        if missing:
            raise ValueError(f"{self.kind} stock needs {', '.join(missing)}")
        if self.top is not None and self.kind != "infer":
            raise ValueError(f"'top' applies to inferred stock only; a {self.kind} stock states its own top")
        return self


def stock_spec(stock: Stock) -> StockSpec:
    """The job's stock entry of a model stock (a box, a cylinder or a STEP/BREP file)."""
    if isinstance(stock, BoxStock):
        return StockSpec(kind="box", min=stock.minimum, max=stock.maximum)
    if isinstance(stock, CylinderStock):
        return StockSpec(kind="cylinder", base_center=stock.base_center, radius=stock.radius, height=stock.height)
    if isinstance(stock, SolidStock):
        return StockSpec(kind="file", path=str(stock.path))
    raise InputError(f"a job cannot state a stock of type {type(stock).__name__}")


class LibraryRef(_Strict):
    """A tool of the job's ``tool_library`` picked by its ``name`` (Fusion ``description``, the
    table's comment; case ignored) or its ``id`` (Fusion ``guid``), whatever number it has there."""

    name: str | None = None
    id: str | None = None

    @model_validator(mode="after")
    def _one_key(self) -> LibraryRef:
        if (self.name is None) == (self.id is None):
            raise ValueError("give exactly one of 'name' and 'id'")
        return self


_GEOMETRY = ("kind", "diameter", "flute_length", "corner_radius", "taper_angle", "tip_diameter", "point_angle",
             "apt", "flutes", "helix_angle", "spindle", "shank_diameter", "overall_length", "neck_diameter",
             "shoulder_length", "name")


class ToolSpec(_Strict):
    """One tool, numbered as the program uses it: either its geometry (``kind``: flat, ball,
    bullnose, tapered, chamfer, drill, apt; lengths mm, angles degrees; ``point_angle`` is a drill's
    included angle; ``neck_diameter`` up to ``shoulder_length`` a reduced neck) or ``library``, a
    tool of the job's tool library picked by name or id (:class:`LibraryRef`) and given this number."""

    number: int
    kind: Literal["flat", "ball", "bullnose", "tapered", "chamfer", "drill", "apt"] | None = None
    diameter: float | None = Field(None, gt=0)
    flute_length: float | None = Field(None, gt=0)
    corner_radius: float = 0.0
    taper_angle: float = 0.0
    tip_diameter: float = 0.0
    point_angle: float = 118.0
    apt: tuple[float, float, float, float, float, float, float] | None = None  # d, r, e, f, alpha, beta, h
    flutes: int = 2
    helix_angle: float = 30.0
    spindle: Literal["cw", "ccw"] = "cw"
    shank_diameter: float | None = None
    overall_length: float | None = None
    neck_diameter: float | None = None
    shoulder_length: float | None = None
    name: str = ""
    library: LibraryRef | None = None

    @model_validator(mode="after")
    def _geometry_or_library(self) -> ToolSpec:
        if self.library is not None:
            given = sorted(k for k in _GEOMETRY if k in self.model_fields_set)
            if given:
                raise ValueError(f"a tool picked from the library takes only 'number' and 'library', not "
                                 f"{', '.join(given)}")
        else:
            missing = [k for k in ("kind", "diameter", "flute_length") if getattr(self, k) is None]
            if missing:
                raise ValueError(f"a tool needs {', '.join(missing)} (or 'library' to pick one from the tool library)")
        return self

    @classmethod
    def of(cls, tool: MillingTool, number: int | None = None) -> ToolSpec:
        """The job tool of a model tool, numbered ``number`` (default: the tool's own number);
        ``ToolSpec.of(t).build() == t`` but for the tool's ``source``. A tool whose family a job
        cannot state is a :class:`ToolDefinitionError`."""
        if tool.kind not in _TOOL_KINDS:
            raise ToolDefinitionError(f"tool {tool.label}: a job cannot state a {tool.kind!r} tool")
        number = tool.number if number is None else number
        if number is None:
            raise ToolDefinitionError(f"tool {tool.label}: a job tool needs its T number")
        data = {k: getattr(tool, k) for k in _GEOMETRY if k not in ("kind", "apt") and hasattr(tool, k)}
        data.update(number=number, kind=tool.kind, spindle=tool.spindle.value)
        if isinstance(tool, AptCutter):
            data["apt"] = dataclasses.astuple(tool.apt_parameters)
        return cls.model_validate(data)

    def build(self, library: ToolLibrary | None = None) -> MillingTool:
        """The model tool; a ``library`` pick needs the job's tool library (:class:`InputError` without)."""
        if self.library is not None:
            if library is None:
                raise InputError(f"tools: T{self.number} is picked from the tool library, but the job has no "
                                 "'tool_library'")
            tool = library.pick(name=self.library.name, id=self.library.id)
            return replace(tool, number=self.number)
        if self.kind == "apt" and self.apt is None:
            raise InputError(f"tool T{self.number}: kind 'apt' needs the 7 parameters in 'apt'")
        cls, own = _TOOL_KINDS[self.kind]  # type: ignore[index]
        common = dict(diameter=self.diameter, flute_length=self.flute_length, flutes=self.flutes,
                      helix_angle=self.helix_angle, spindle=SpindleDirection(self.spindle),
                      shank_diameter=self.shank_diameter, overall_length=self.overall_length,
                      neck_diameter=self.neck_diameter, shoulder_length=self.shoulder_length,
                      number=self.number, name=self.name)
        return cls(**common, **own(self))


# a job tool's kind -> the model class and the kind's own fields
_TOOL_KINDS: dict[str, tuple[type[MillingTool], Any]] = {
    "flat": (FlatEndMill, lambda t: {}),
    "ball": (BallEndMill, lambda t: {}),
    "bullnose": (BullNoseEndMill, lambda t: {"corner_radius": t.corner_radius}),
    "tapered": (TaperedEndMill, lambda t: {"taper_angle": t.taper_angle}),
    "chamfer": (ChamferMill, lambda t: {"tip_diameter": t.tip_diameter, "taper_angle": t.taper_angle}),
    "drill": (Drill, lambda t: {"point_angle": t.point_angle}),
    "apt": (AptCutter, lambda t: {"apt_parameters": AptParameters(*t.apt)}),
}


# --------------------------------------------------------------------------------------------------
# options: the engine options of a job are generated from the fields of EngineOptions (their types,
# defaults and help), so the job file, `fusioncut schema`, the service's form and the CLI's flags
# state one set of defaults and docs.

# EngineOptions fields that are not job options: the failures folder the runner sets, and the knobs
# that drive the kernel without changing what is computed (or only by the Booleans' tolerance).
ENGINE_ONLY = frozenset({"failure_dir", "merge_growth", "fuzzy", "fuzzy_retries", "kernel_threads",
                         "ceiling_pixel", "layers", "max_layers"})
# Bounds a job's value must keep (mm unless stated), also for the engine-only fields, so that one taken
# out of ENGINE_ONLY is bounded at once; EngineOptions' LOWER_BOUNDS come on top when the engine
# options are made. Every number must also be finite.
OPTION_BOUNDS: dict[str, dict[str, float]] = {
    "slice_height": {"gt": 0}, "max_segment_length": {"gt": 0}, "chord_tolerance": {"gt": 0},
    "ramp_step": {"gt": 0}, "cell_size": {"gt": 0}, "min_chip_thickness": {"ge": 0}, "max_layers": {"ge": 1},
    "merge_growth": {"gt": 0}, "fuzzy": {"ge": 0}, "ceiling_pixel": {"gt": 0}, "kernel_budget_s": {"gt": 0},
}
# the values a job may ask for where the option's type holds more (SweepMethod.STEP is only reported)
OPTION_TYPES: dict[str, Any] = {"sweep": Literal["exact", "sampled"], "engine": Literal["auto", "brep", "analytic"]}


@dataclass(frozen=True)
class OptionField:
    """One engine option as a job states it: ``name``, its Python ``type`` (the field's annotation, or
    :data:`OPTION_TYPES`'), ``default`` (EngineOptions', an enum as its value) and ``help`` (the
    field's ``metadata["help"]``, "" when it has none)."""

    name: str
    type: Any
    default: Any
    help: str

    @property
    def takes_none(self) -> bool:
        """Whether ``None`` is a value of the option (it then means something: see its help)."""
        return type(None) in get_args(self.type)

    @property
    def description(self) -> str:
        """The help with the default, as the CLI's flags and the service's form show it."""
        return f"{self.help} (default: {'none' if self.default is None else self.default})".lstrip()


def engine_option_fields() -> tuple[OptionField, ...]:
    """The engine options a job may set, in :class:`EngineOptions` order (see :data:`ENGINE_ONLY`)."""
    hints = get_type_hints(EngineOptions)
    return tuple(OptionField(f.name, OPTION_TYPES.get(f.name, hints[f.name]),
                             f.default.value if isinstance(f.default, Enum) else f.default,
                             str(f.metadata.get("help", "")))
                 for f in dataclasses.fields(EngineOptions) if f.name not in ENGINE_ONLY)


def _engine_option(f: OptionField) -> tuple[Any, Any]:
    numeric = f.type in (float, int, float | None, int | None)
    return f.type, Field(f.default, description=f.help or None, **({"allow_inf_nan": False} if numeric else {}),
                         **OPTION_BOUNDS.get(f.name, {}))


class _RunOptions(_Strict):
    """Run options (each field's description says what it does) do not change the results and are left
    out of the job hash. A parallel run (``workers`` > 1 or a ``scheduler``) always uses cells (20 mm
    when the job asks for none); its results equal the single-process run's to 0.001° and 1e-6 of the
    volumes, and a checkpoint of either resumes in the other."""

    checkpoint_every: int = Field(200, ge=0, description="save a resumable checkpoint every that many CLs "
                                  "(0: only when the run ends or is interrupted)")
    snapshot_cls: list[Annotated[int, Field(ge=0)]] = Field(
        [], description="write the workpiece as ipw_cl<N>.step after each of these CL indices (ipw_cl<N>.stl "
        "with the analytic engine)")
    workers: int = Field(1, ge=1, description="Dask worker processes of an embedded cluster sharing the cells")
    scheduler: str | None = Field(None, description="address of a running Dask scheduler whose workers run it")

    @field_validator("scheduler")
    @classmethod
    def _address(cls, value: str | None) -> str | None:
        if value is not None and (not value.strip() or any(c.isspace() for c in value.strip())):
            raise ValueError(f"{value!r} is not a Dask scheduler address (such as tcp://host:8786)")
        return value.strip() if value is not None else None


Options = create_model(  # type: ignore[call-overload]
    "Options", __base__=_RunOptions, __module__=__name__,
    __doc__="Engine options (the fields of :class:`fusioncut.model.options.EngineOptions` but "
            ":data:`ENGINE_ONLY`, with their defaults and help; lengths mm) and run options.\n\n"
            + (_RunOptions.__doc__ or ""),
    **{f.name: _engine_option(f) for f in engine_option_fields()})

# Options that steer the run but not its results: excluded from the engine options and the job hash,
# so changing them neither breaks a resume nor pretends the results differ.
RUN_OPTIONS = frozenset(_RunOptions.model_fields)


class Job(_Strict):
    """A FusionCut job. Relative paths are relative to the job file."""

    name: str = "job"
    stock: StockSpec
    tools: list[ToolSpec] = []
    tool_library: str | None = None
    tool_source: Literal["library", "program"] = "library"
    """Which definition of a T number wins when the tool library and the program (its tool comments,
    APT cutters, JSON sections) both give one: the job's ``tools`` always win, then this source, then
    the other. Disagreements on the cutting geometry are warned about either way."""
    toolpaths: list[str] = Field(min_length=1)
    strict: bool = False
    options: Options = Options()


def load_job(path: str | Path) -> tuple[Job, Path]:
    """Read and validate a job file; errors name the file and the JSON path of the bad field."""
    path = Path(path)
    if not path.exists():
        raise InputError("job file not found", path)
    data = read_json(path)
    try:
        return Job.model_validate(data), path.parent
    except ValidationError as exc:
        first = exc.errors()[0]
        loc = ".".join(str(p) for p in first["loc"]) or "<root>"
        raise InputError(f"{loc}: {first['msg']} ({exc.error_count()} problem(s) in all)", path) from None
    except RecursionError:
        raise InputError("not accepted: the JSON nests too deeply", path) from None


def make_options(values: Mapping[str, object], *, flags: bool = False) -> Options:
    """Job options from ``values`` (the others at their defaults), validated like a job file: a bad
    value is refused in one line naming it as ``options.<name>`` (``--<name>`` with ``flags``, for
    the command line's options)."""
    try:
        return Options.model_validate(dict(values))
    except ValidationError as exc:
        first = exc.errors()[0]
        name = ".".join(str(p) for p in first["loc"])
        message = first["msg"].removeprefix("Value error, ")
        raise InputError(f"--{name.replace('_', '-')}: {message}" if flags else f"options.{name}: {message}") from None


def with_options(job: Job, overrides: Mapping[str, object], *, flags: bool = False) -> Job:
    """``job`` with the options given (``None``: keep the job file's), validated like the file
    (:func:`make_options`; ``model_copy`` alone would not validate them)."""
    given = {k: v for k, v in overrides.items() if v is not None}
    if not given:
        return job
    options = make_options({**job.options.model_dump(), **given}, flags=flags)
    return job.model_copy(update={"options": options})


def with_run_options(job: Job, **overrides: object) -> Job:
    """``job`` with the run options given (``None``: keep the job file's), validated like the file:
    the command line's ``--workers`` and ``--scheduler`` come through here."""
    unknown = set(overrides) - RUN_OPTIONS
    if unknown:
        raise ValueError(f"not run options: {', '.join(sorted(unknown))}")
    return with_options(job, overrides, flags=True)


def job_options(options: EngineOptions | Mapping[str, object] | None) -> dict[str, object]:
    """The job options of engine options (the fields a job states, enums as their values) or of a
    mapping of option names (returned as given, for :func:`with_options` to validate)."""
    if options is None:
        return {}
    if isinstance(options, EngineOptions):
        values = {f.name: getattr(options, f.name) for f in engine_option_fields()}
        return {k: v.value if isinstance(v, Enum) else v for k, v in values.items()}
    return dict(options)


def stock_entry(stock: str | Stock | StockSpec | Mapping[str, object] | None) -> StockSpec:
    """The job's stock entry of a model stock, a :func:`fusioncut.io.stock.parse_stock` string (paths
    made absolute) or a job's stock entry (a :class:`StockSpec` or its JSON, validated); ``None`` or
    ``"infer"``: inferred from the toolpath."""
    if stock is None or (isinstance(stock, str) and stock.strip().lower() == "infer"):
        return StockSpec(kind="infer")
    if isinstance(stock, (StockSpec, Mapping)):
        try:
            return StockSpec.model_validate(stock)
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(("stock", *map(str, first["loc"])))
            raise InputError(f"{where}: {first['msg'].removeprefix('Value error, ')}") from None
    from fusioncut.io.stock import parse_stock

    spec = stock_spec(parse_stock(stock) if isinstance(stock, str) else stock)
    if spec.kind == "file":
        spec = spec.model_copy(update={"path": str(Path(spec.path).absolute())})  # type: ignore[arg-type]
    return spec


def tool_entries(tools: str | Path | Mapping[int, MillingTool] | None) -> dict[str, object]:
    """The job fields that give these tools: ``tools`` for ``{number: MillingTool}``, ``tool_library``
    (absolute) for a tool library file; none for ``None``."""
    if tools is None:
        return {}
    if isinstance(tools, Mapping):
        return {"tools": [ToolSpec.of(t, n) for n, t in sorted(tools.items())]}
    library = Path(tools).absolute()
    if not library.is_file():
        raise InputError("tool library not found", library)
    return {"tool_library": str(library)}


def program_job(program: str | Path, *, stock: str | Stock | StockSpec | Mapping[str, object] | None = None,
                tools: str | Path | Mapping[int, MillingTool] | None = None,
                options: EngineOptions | Mapping[str, object] | None = None, name: str | None = None) -> Job:
    """The job that runs one toolpath file (any suffix :mod:`fusioncut.io.readers` reads), with
    absolute paths so that it runs the same from any folder.

    ``stock``: a model stock, a :func:`fusioncut.io.stock.parse_stock` string (``box:x0,y0,z0,x1,y1,z1``,
    ``cylinder:...``, a STEP/BREP path, a ``.camotics`` project's bounds), ``"infer"`` or a job's stock
    entry (``{"kind": "infer", "top": 1.0}``); ``None``:
    a CAMotics project's own workpiece when it states one, else inferred from the toolpath.
    ``tools``: a tool library file or ``{number: MillingTool}``; ``None``: the program's own.
    ``options``: engine (and run) options. ``name``: default the program's file name without suffix."""
    path = Path(program).absolute()
    if not path.is_file():
        raise InputError("toolpath file not found", path)
    if stock is None and path.suffix.lower() == ".camotics":
        from fusioncut.io.tool_library import read_camotics_project

        if read_camotics_project(path).stock is not None:
            stock = str(path)
    data: dict[str, object] = {"name": name or path.stem, "stock": stock_entry(stock), "toolpaths": [str(path)]}
    data.update(tool_entries(tools))
    return with_options(Job.model_validate(data), job_options(options))


def with_inputs(job: Job, *, stock: str | Stock | StockSpec | Mapping[str, object] | None = None,
                tools: str | Path | Mapping[int, MillingTool] | None = None,
                options: EngineOptions | Mapping[str, object] | None = None, flags: bool = False) -> Job:
    """``job`` with this stock (:func:`stock_entry`) and tool library in place of its own, these tools
    by number added to its own (replacing those of the same number) and these options merged into its
    own (:func:`with_options`); ``None`` keeps the job's."""
    update: dict[str, Any] = tool_entries(tools)
    if "tools" in update:
        numbers = {t.number for t in update["tools"]}
        update["tools"] += [t for t in job.tools if t.number not in numbers]
    if stock is not None:
        update["stock"] = stock_entry(stock)
    if update:
        job = job.model_copy(update=update)
    return with_options(job, job_options(options), flags=flags)


def build_stock(spec: StockSpec, base: Path) -> Stock | None:
    """The stock of the job; ``None`` for ``infer`` (the caller infers it from the toolpath).

    A ``file`` stock must exist and be STEP/BREP; its solid is read and checked by the engine."""
    if spec.kind == "box":
        return BoxStock(spec.min, spec.max)  # type: ignore[arg-type]
    if spec.kind == "cylinder":
        return CylinderStock(spec.base_center, spec.radius, spec.height)  # type: ignore[arg-type]
    if spec.kind == "file":
        from fusioncut.io.stock import solid_stock

        return solid_stock(base / spec.path)  # type: ignore[operator]
    return None


def job_hash(job: Job, base: Path) -> str:
    """SHA-256 (16 hex digits) of the normalised job without its run options, and of the bytes of
    every input file (toolpaths, tool library, stock solid). Equal hashes mean equal results.
    The ``engine`` option counts only when it is ``analytic``: a job that asks for ``auto`` (the
    default) or ``brep`` hashes as it did before the option existed (the engine an ``auto`` run
    resolved to is in its checkpoint, which a resume checks: :mod:`fusioncut.runner`). The kernel's
    time budget never counts: it decides whether a CL fails, not what a computed CL is."""
    defaults = {"kernel_budget_s"} | ({"engine"} if job.options.engine in ("auto", "brep") else set())
    h = hashlib.sha256(job.model_dump_json(exclude={"options": set(RUN_OPTIONS) | defaults}).encode())
    files = [*job.toolpaths, *([job.tool_library] if job.tool_library else [])]
    if job.stock.kind == "file" and job.stock.path:
        files.append(job.stock.path)
    for p in files:
        f = base / p
        if f.is_file():
            h.update(f.read_bytes())
    return h.hexdigest()[:16]
