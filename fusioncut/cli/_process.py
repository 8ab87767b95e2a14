"""What the process commands (``forces``, ``advise``, ``stability``) share: the results folder read
with its recorded spindle speeds, tools and slice height (:func:`_setup`), the cutting coefficients from
``--material`` or a coefficients file, the tools' dynamics from ``--modes``, and the tables they write.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any, Optional

from rich.console import Console
from rich.markup import escape

console = Console(soft_wrap=True)  # messages name paths: the terminal wraps them, rich does not break them


@dataclasses.dataclass
class _Setup:
    results: Any
    maps: list
    groups: dict[str, list[int]]  # tool label -> row indices
    tools: dict[str, Any]
    rpms: list[float | None]
    coefficients: Any
    dz: float
    program: Any = None


def _tool_from_metadata(label: str, meta: dict[str, Any]) -> Any:
    from fusioncut.errors import InputError
    from fusioncut.model import BallEndMill, FlatEndMill

    desc = (meta.get("tools") or {}).get(label) or {}
    kind, d, fl = desc.get("kind"), desc.get("diameter_mm"), desc.get("flute_length_mm")
    if kind not in ("flat", "ball") or not d or not fl:
        raise InputError(f"tool {label}: the results only describe it as {desc or 'nothing'}; give the program "
                         "(--program) so its tool comments define it")
    cls = FlatEndMill if kind == "flat" else BallEndMill
    return cls(diameter=float(d), flute_length=float(fl))


DEFAULT_MATERIAL = "al7075-t6"


def _coefficients(material: Optional[str], coefficients_file: Optional[Path]) -> Any:
    """The cutting coefficients of ``--material`` or ``--coefficients`` (not both; neither:
    :data:`DEFAULT_MATERIAL`). A file's implausible values are warned about, naming it."""
    from fusioncut.analysis.calibrate import plausibility_warnings, read_coefficients_json
    from fusioncut.analysis.materials import get_coefficients
    from fusioncut.errors import InputError

    if coefficients_file is None:
        return get_coefficients(material or DEFAULT_MATERIAL)
    if material is not None:
        raise InputError(f"give --material or --coefficients, not both (--material {material}, --coefficients "
                         f"{coefficients_file})")
    coefficients = read_coefficients_json(coefficients_file)
    for w in plausibility_warnings(coefficients):
        console.print(f"[yellow]warning:[/] {escape(str(coefficients_file))}: {escape(w)}", highlight=False)
    return coefficients


def _setup(results_dir: Path, program: Optional[Path], coefficients: Any, rpm: Optional[float],
           flutes: Optional[int], helix: Optional[float], slice_height: Optional[float]) -> _Setup:
    """What forces, advise and stability need of a results folder, from what it records.

    ``coefficients``: from :func:`_coefficients`. Slice height: the recorded one (``--slice-height``
    only for folders that do not record it, and must agree otherwise;
    :func:`~fusioncut.analysis.result_maps.results_slice_height`). Tools: the recorded full records,
    else the program's (``--program``), else the partial description older folders keep; ``--flutes``
    and ``--helix`` override. Spindle speed per CL: ``--rpm`` for all, else the recorded one, else (a CL
    without one, or an older folder) the program's S word at the CL's line.
    """
    from fusioncut.analysis.feed import same_source_file
    from fusioncut.analysis.result_maps import engagement_maps_from_results, results_slice_height
    from fusioncut.errors import InputError
    from fusioncut.io.results import load_results

    results = load_results(results_dir)
    if not len(results.cl):
        raise InputError("the results hold no CL", results_dir)
    dz = results_slice_height(results, slice_height)
    maps = engagement_maps_from_results(results, dz)
    tp = None
    if program is not None:
        from fusioncut.io.gcode import read_gcode

        tp = read_gcode(program)
    tools: dict[str, Any] = {}
    groups: dict[str, list[int]] = {}
    for i, m in enumerate(maps):
        groups.setdefault(m.tool, []).append(i)
    for label in groups:
        tool = results.tools.get(label)
        if tool is None and tp is not None:
            tool = next((t for t in tp.tools.values() if t.label == label), None)
        if tool is None:
            tool = _tool_from_metadata(label, results.metadata)
        changes: dict[str, Any] = {}
        if flutes is not None:
            changes["flutes"] = flutes
        if helix is not None:
            changes["helix_angle"] = helix
        tools[label] = dataclasses.replace(tool, **changes) if changes else tool
    rpms: list[float | None]
    if rpm is not None:
        if not (rpm > 0 and math.isfinite(rpm)):
            raise InputError(f"--rpm must be > 0 rev/min, got {rpm}")
        rpms = [rpm] * len(maps)
    else:
        recorded = results.cl["spindle_rpm"].to_numpy(dtype=float)
        rpms = [None if math.isnan(n) else float(n) for n in recorded]
        if tp is not None:
            by_line = {m.source.line: m.spindle_rpm for m in tp.moves if m.spindle_rpm}
            rpms = [n if n is not None else by_line.get(m.source.line)
                    if same_source_file(str(m.source.file), str(program)) else None for n, m in zip(rpms, maps)]
        elif "spindle_rpm" in results.missing:
            raise InputError("the spindle speeds are not recorded (results written before they were): give --rpm "
                             "or the program (--program)", results_dir)
    return _Setup(results, maps, groups, tools, rpms, coefficients, dz, tp)


_MATERIAL_HELP = ("Work material / tool pair of the cutting coefficients (see fusioncut.analysis.materials; "
                  f"default {DEFAULT_MATERIAL}).")


_COEFFICIENTS_HELP = "Cutting coefficients file (JSON, as fusioncut calibrate writes it); not with --material."


def _tool_info(t: Any) -> dict[str, Any]:
    return {"kind": t.kind, "diameter_mm": t.diameter, "flute_length_mm": t.flute_length, "flutes": t.flutes,
            "helix_deg": t.helix_angle}


def _write_table(table: Any, stem: Path, columns: dict[str, tuple[str, str]], meta: dict[str, Any]) -> None:
    """``stem``.csv and ``stem``.parquet, the Parquet fields carrying their unit and meaning."""
    import json

    import pyarrow as pa
    import pyarrow.parquet as pq

    arrow = pa.Table.from_pandas(table.reset_index(drop=True), preserve_index=False)
    fields = []
    for f in arrow.schema:
        unit, desc = columns.get(f.name, ("", ""))
        fields.append(f.with_metadata({"unit": unit, "description": desc}))
    schema = pa.schema(fields, metadata={b"fusioncut": json.dumps(meta, sort_keys=True).encode()})
    arrow = arrow.cast(schema)
    stem.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(arrow, stem.with_suffix(".parquet"))
    table.to_csv(stem.with_suffix(".csv"), index=False, na_rep="", lineterminator="\n")


def _rpm_range(rpm_min: Optional[float], rpm_max: Optional[float]) -> Optional[tuple[float, float]]:
    """``--rpm-min``/``--rpm-max``: both or neither, ``0 < min < max``."""
    from fusioncut.errors import InputError

    if rpm_min is None and rpm_max is None:
        return None
    if rpm_min is None or rpm_max is None:
        raise InputError("give both --rpm-min and --rpm-max, or neither")
    if not (0 < rpm_min < rpm_max and math.isfinite(rpm_max)):
        raise InputError(f"need 0 < --rpm-min < --rpm-max, got {rpm_min:g}, {rpm_max:g}")
    return (rpm_min, rpm_max)


def _tool_dynamics(specs: list[str], tools: dict[str, Any], n_modes: Optional[int]) -> dict[str, Any]:
    """The dynamics of every tool label from ``--modes`` values: ``TOOL=FILE`` (TOOL a label or ``T<n>``)
    for one tool, a plain ``FILE`` for the others; each file read (and an FRF fitted) once."""
    from fusioncut.analysis.dynamics import read_dynamics
    from fusioncut.errors import InputError

    names = {label: label for label in tools}
    names.update({f"T{t.number}": label for label, t in tools.items() if t.number is not None})
    default: Optional[str] = None
    per_tool: dict[str, str] = {}
    for spec in specs:
        head, sep, tail = spec.partition("=")
        if sep and head.strip() in names:
            per_tool[names[head.strip()]] = tail
        elif default is not None:
            raise InputError(f"--modes {spec!r}: a second file for every tool (tools: {', '.join(sorted(names))}; "
                             "name one as TOOL=FILE)")
        else:
            default = spec
    read: dict[str, Any] = {}
    out = {}
    for label in tools:
        path = per_tool.get(label, default)
        if path is None:
            raise InputError(f"no --modes for tool {label!r}: give --modes FILE or --modes {label}=FILE")
        if path not in read:
            read[path] = read_dynamics(Path(path), n_modes)
            for d, fit in read[path][1].items():
                console.print(f"{escape(path)} FRF {escape(str(d))}: {len(fit.modes)} mode(s) " + ", ".join(
                    f"{m.fn_hz:.1f} Hz zeta {m.zeta:.4f} k {m.k_n_per_m:.4g} N/m" for m in fit.modes)
                    + f"; fit error {100 * fit.relative_rms_error:.2f} % (relative RMS)", highlight=False)
                if fit.relative_rms_error > 0.1:
                    console.print(f"[yellow]note:[/] the modal fit of {escape(str(d))} misses the FRF by "
                                  f"{100 * fit.relative_rms_error:.0f} %: check the modes (--fit-modes)",
                                  highlight=False)
        out[label] = read[path][0]
    return out
