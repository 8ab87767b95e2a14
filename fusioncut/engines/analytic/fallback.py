"""A CL the analytic engine could not compute, computed by the B-Rep engine on a local workpiece.

The workpiece before CL k is the stock less the sweeps of CLs 0..k-1 (:mod:`.engine`), so the
material a CL can touch is known without the rest of the run: :func:`brep_fallback` builds it with
the B-Rep engine (:class:`~fusioncut.engines.brep.engine.BRepEngine`, which alone builds B-Rep
solids) on the stock box cropped to the CL's sweep footprint grown by :data:`MARGIN` mm (a round bar
whole: a stock model holds no cropped bar; the earlier CLs cut are still only the near ones),
cutting into it, in program order, the earlier CLs whose footprints meet that box, and then steps
the CL itself. Its map is the B-Rep engine's (``engine="brep"``, with a warning naming the analytic
engine's error), so it agrees with an all-B-Rep run to the Booleans' fuzzy values: the earlier CLs
are swept as the B-Rep engine sweeps them (a piece of a ramp as a level step, one of a steep helix
as its chord), and the cells' edges lie elsewhere. A map from here never raises: when the local
workpiece cannot be built (an earlier CL's Boolean fails) or the B-Rep engine fails the CL, the map
is FAILED, naming the CL and both reasons.

Mechanism invariants: nothing here changes the analytic engine's state (the caller indexes the CL's
sweep, so later CLs see it cut whatever happened here); the cost is that of the earlier CLs near the
CL, paid only for a CL that needed it. The kernel is imported on first use, so a run without such a
CL never loads it.
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import replace

from fusioncut.engines.base import EngineKind, EngineOptions
from fusioncut.engines.cl_maps import CL, CutOutcome, cl_base, engagement_map
from fusioncut.engines.segments import as_chord
from fusioncut.model.engagement import CLStatus, EngagementMap
from fusioncut.model.stock import BoxStock, CylinderStock, Stock

log = logging.getLogger("fusioncut.analytic")

MARGIN = 1.0  # mm around the CL's footprint: the local workpiece's walls stay clear of its sweep

Box = tuple[float, float, float, float]  # (x0, y0, x1, y1), mm


def _chorded(cl: CL) -> CL:
    """``cl`` as the B-Rep engine takes it: a piece of a steep helix as its chord
    (:func:`fusioncut.engines.segments.as_chord`, within the chord tolerance of it)."""
    return cl._replace(move=as_chord(cl.move))


def brep_fallback(cl: CL, box: Box, earlier: Sequence[tuple[CL, Box]], stock_model: Stock,
                  options: EngineOptions, why: str) -> EngagementMap:
    """The map of CL ``cl`` (footprint ``box``) by the B-Rep engine on a local workpiece: the
    stock (a box or a round bar) cropped to ``box`` grown by :data:`MARGIN` (a bar: not cropped), less
    the sweeps of ``earlier`` (the CLs before ``cl`` with their footprints, in program order) that
    meet that box. ``why``: the analytic engine's error, named in the map's warning or FAILED reason."""
    stock = stock_model.bounds
    x0, y0 = max(box[0] - MARGIN, stock[0]), max(box[1] - MARGIN, stock[1])
    x1, y1 = min(box[2] + MARGIN, stock[3]), min(box[3] + MARGIN, stock[4])
    base = cl_base(cl)
    if x0 >= x1 or y0 >= y1:  # the footprint misses the stock: nothing to cut, nothing to ask the kernel
        idle = CLStatus.RAPID if cl.move.is_rapid else CLStatus.AIR
        return replace(engagement_map(cl, CutOutcome(idle), [], []), engine=EngineKind.ANALYTIC.value)
    engine = None
    try:
        from fusioncut.engines.brep.engine import BRepEngine  # the kernel: only for a CL that needs it

        engine = BRepEngine(replace(options, engine=EngineKind.BREP))
        engine.start(stock_model if isinstance(stock_model, CylinderStock)
                     else BoxStock((x0, y0, stock[2]), (x1, y1, stock[5])))
        last = None
        for e, b in earlier:
            if b[0] > x1 or b[2] < x0 or b[1] > y1 or b[3] < y0 or min(e.move.start[2], e.move.end[2]) >= stock[5]:
                continue
            if last is None or e.index != last + 1:
                engine.cleared = None  # the tool the previous CL left is only known along the path
            outcome, _ = engine.cut(*_chorded(e))
            if outcome.status == CLStatus.FAILED:
                return EngagementMap(**base, status=CLStatus.FAILED, engine=EngineKind.BREP.value,
                                     reason=f"analytic engine: {why}; the B-Rep engine's local workpiece failed at "
                                            f"CL {e.index} ({e.move.source}): {outcome.reason}")
            last = e.index
        if last is None or cl.index != last + 1:
            engine.cleared = None
        m = engine.step(*_chorded(cl))
    except Exception as exc:  # noqa: BLE001 - the last net: this CL fails, the run goes on
        log.error("CL %d (%s): the B-Rep engine's fallback failed: %s", cl.index, cl.move.source, exc)
        return EngagementMap(**base, status=CLStatus.FAILED, engine=EngineKind.BREP.value,
                             reason=f"analytic engine: {why}; B-Rep engine: {type(exc).__name__}: {exc}")
    finally:
        if engine is not None:
            engine.close()  # ends its kernel's worker process (fusioncut.engines.brep.budget)
    if m.status == CLStatus.FAILED:
        return replace(m, engine=EngineKind.BREP.value, reason=f"analytic engine: {why}; B-Rep engine: {m.reason}")
    note = f"the analytic engine failed ({why}): computed by the B-Rep engine on a local workpiece"
    return replace(m, engine=EngineKind.BREP.value, warnings=(*m.warnings, note))
