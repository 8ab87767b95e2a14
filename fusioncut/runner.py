"""Running a whole job: read inputs, run the engine CL by CL, write results as they come.

Shared by the CLI (and later the service) so there is one implementation of a run. Ctrl-C stops
cleanly: the results of every finished CL are flushed before the run returns.
"""
from __future__ import annotations

import logging
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.segments import cl_segments
from fusioncut.errors import InputError
from fusioncut.io.job import Job, build_stock, job_hash
from fusioncut.io.results import ResultWriter
from fusioncut.model import CLStatus, EngagementMap, MillingTool, Stock, Toolpath

log = logging.getLogger("fusioncut.run")


@dataclass
class OperationSummary:
    operation: str
    cls: int = 0
    engaged: int = 0
    air: int = 0
    rapid: int = 0
    failed: int = 0
    removed: float = 0.0
    max_ae: float = 0.0
    max_ap: float = 0.0
    times_ms: list[float] = field(default_factory=list)

    def add(self, m: EngagementMap) -> None:
        self.cls += 1
        setattr(self, m.status.value, getattr(self, m.status.value) + 1)
        self.removed += m.removed_volume
        self.max_ae = max(self.max_ae, m.ae)
        self.max_ap = max(self.max_ap, m.ap)
        total = dict(m.timings_ms).get("total")
        if total is not None:
            self.times_ms.append(total)

    @property
    def median_ms(self) -> float:
        return statistics.median(self.times_ms) if self.times_ms else 0.0


@dataclass
class RunResult:
    operations: dict[str, OperationSummary]
    stock_volume: float
    final_volume: float
    removed_volume: float
    seconds: float
    out_dir: Path
    interrupted: bool = False

    @property
    def conservation_error(self) -> float:
        """|stock - final - Σ removed| / stock volume."""
        return abs(self.stock_volume - self.final_volume - self.removed_volume) / self.stock_volume


def run_toolpath(toolpath: Toolpath, stock: Stock, out_dir: Path, options: EngineOptions | None = None,
                 default_tool: MillingTool | None = None, job_id: str = "",
                 on_cl: Callable[[EngagementMap, int], None] | None = None) -> RunResult:
    """Run every CL of ``toolpath`` on ``stock``, writing results into ``out_dir`` as they come.

    ``on_cl(map, total)`` is called after each CL (progress reporting).
    """
    options = options or EngineOptions()
    engine = BRepEngine(options)
    segments = cl_segments(toolpath.moves, options.max_segment_length, options.chord_tolerance)
    expected: dict[str, int] = {}
    for s in segments:
        expected[s.operation] = expected.get(s.operation, 0) + 1
    ops: dict[str, OperationSummary] = {}
    t0 = time.perf_counter()
    interrupted = False
    tools = {t.label: {"kind": t.kind, "diameter_mm": t.diameter, "flute_length_mm": t.flute_length}
             for t in toolpath.tools.values()}
    engine.start(stock)
    with ResultWriter(out_dir, job_hash=job_id, tools=tools, expected_cls=expected) as writer:
        try:
            for m, seg in zip(engine.process(toolpath, default_tool), segments):
                writer.add(m, length_mm=seg.length)
                ops.setdefault(m.operation, OperationSummary(m.operation)).add(m)
                if m.status == CLStatus.FAILED:
                    log.error("CL %d (%s): %s", m.cl_index, m.source, m.reason)
                if on_cl:
                    on_cl(m, len(segments))
        except KeyboardInterrupt:
            interrupted = True
            log.warning("interrupted: results of the finished CLs are kept in %s", out_dir)
    return RunResult(ops, engine.stock_volume, engine.ipw_volume, engine.removed_total,
                     time.perf_counter() - t0, out_dir, interrupted)


def read_toolpath(path: Path, tools: dict[int, MillingTool], strict: bool) -> Toolpath:
    """Dispatch on the file suffix: G-code, APT/CLSF, or Fusion 360 JSON."""
    suffix = path.suffix.lower()
    if suffix in (".apt", ".cls", ".clsf", ".aptsource"):
        from fusioncut.io.apt import read_apt

        return read_apt(path)
    if suffix == ".json":
        from fusioncut.io.fusion_json import read_fusion_json

        return read_fusion_json(path)
    try:
        from fusioncut.io.gcode import read_gcode
    except ImportError:  # the interpreter is issue 3's work in progress
        raise InputError("reading G-code is not available in this version yet", path) from None
    return read_gcode(path, tools=tools or None, strict=strict)


def run_job(job: Job, base: Path, out_dir: Path,
            on_cl: Callable[[EngagementMap, int], None] | None = None) -> RunResult:
    tools: dict[int, MillingTool] = {}
    if job.tool_library:
        from fusioncut.io.tool_library import read_tool_library

        tools.update(read_tool_library(base / job.tool_library))
    tools.update({t.number: t.build() for t in job.tools})
    moves, warnings = [], []
    for name in job.toolpaths:
        tp = read_toolpath(base / name, tools, job.strict)
        for n, t in tp.tools.items():
            tools.setdefault(n, t)
        moves.extend(tp.moves)
        warnings.extend(tp.warnings)
    for w in warnings:
        log.warning("%s", w)
    toolpath = Toolpath(tuple(moves), tools, tuple(warnings), source=",".join(job.toolpaths))
    stock = build_stock(job.stock, base)
    if stock is None:
        from fusioncut.io.stock import infer_stock

        stock = infer_stock(toolpath, margin=job.stock.margin)
        log.warning("stock inferred from the toolpath extents: %s .. %s", stock.minimum, stock.maximum)
    missing = sorted({m.tool for m in moves if m.tool is not None and m.tool not in tools})
    if missing:
        raise InputError(f"no tool definition for {', '.join(f'T{n}' for n in missing)} "
                         "(give them in the job's 'tools' or a 'tool_library')", base)
    options = EngineOptions(**job.options.model_dump(), failure_dir=out_dir / "failures")
    return run_toolpath(toolpath, stock, out_dir, options, job_id=job_hash(job, base), on_cl=on_cl)
