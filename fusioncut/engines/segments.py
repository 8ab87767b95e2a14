"""Cutting a toolpath into CL segments (pure geometry, no kernel).

A CL segment is one motion the engine evaluates; the engagement is reported with the tool at its end.
Lines and XY arcs are exact sweeps; helices and arcs in the ZX / YZ planes are replaced by chords
whose distance from the true path is at most ``chord_tolerance`` mm (the sagitta
``rho * (1 - cos(dtheta / 2))``), so the swept solid differs from the exact one by at most that
distance (Hausdorff). Every chord end lies exactly on the programmed path.
"""
from __future__ import annotations

import math
from dataclasses import replace

from fusioncut.model.moves import ArcMove, ArcPlane, LinearMove, Move


def chords(arc: ArcMove, chord_tolerance: float) -> list[LinearMove]:
    """Chords of a helix or ZX/YZ arc with sagitta <= ``chord_tolerance`` (mm)."""
    rho = max(arc.radius, arc.end_radius)
    if chord_tolerance >= rho:
        n = max(1, math.ceil(abs(arc.sweep) / math.pi))
    else:
        dmax = 2 * math.acos(1 - chord_tolerance / rho)
        n = max(1, math.ceil(abs(arc.sweep) / dmax - 1e-12))
    pts = [arc.point_at(k / n) for k in range(n + 1)]
    pts[-1] = arc.end
    return [
        LinearMove(pts[k], pts[k + 1], feed=arc.feed, spindle_rpm=arc.spindle_rpm, tool=arc.tool,
                   operation=arc.operation, source=arc.source)
        for k in range(n)
    ]


def cl_segments(moves: list[Move] | tuple[Move, ...], max_segment_length: float | None = None,
                chord_tolerance: float = 1e-3) -> list[Move]:
    """The CL segments of ``moves``, in order; no move is dropped (a zero-length one stays a segment)."""
    out: list[Move] = []
    for m in moves:
        if isinstance(m, ArcMove) and (m.is_helix or m.plane != ArcPlane.XY):
            for c in chords(m, chord_tolerance):
                out += c.split(max_segment_length)
        else:
            out += m.split(max_segment_length)
    return out


def horizontal_direction(move: Move) -> tuple[float, float] | None:
    """Unit horizontal direction of motion at the end of ``move``; ``None`` for vertical moves."""
    t = move.tangent_at(1.0)
    h = math.hypot(t[0], t[1])
    if h < 1e-9:
        return None
    return (t[0] / h, t[1] / h)


__all__ = ["chords", "cl_segments", "horizontal_direction", "replace"]
