"""Generator of a Titan-like milling program, written as real G-code so it goes through the reader.

Modelled on the published benchmark part (Titan-2M Setup 1): a 150 x 100 x 50 mm aluminium block,
top face at Z0, corner at the origin, and four operations:

* **Face** — T1, 12 mm flat end mill, zig-zag at Z-1, 9 mm step-over;
* **Adaptive** — T1, trochoidal loops (loop radius 2 mm, 1.45 mm advance per loop, ~0.5 mm chords)
  along zig-zag slots 14 mm apart, each depth level entered by a helix (G2 with Z, radius 4 mm,
  2 mm pitch) and linked by trochoidal step-overs at the same depth;
* **Contour** — T2, 10 mm flat end mill, three rounded-rectangle contours (G1 + G2 corners) at
  Z-5, -10, -15 around the block's edge;
* **Finish** — T3, 6 mm ball end mill, parallel raster passes over the pocket floor.

``scale=1.0`` gives the full size (~35,000 adaptive CLs); ``quick`` sizes shrink the adaptive region
and the depth levels. Written by hand because no library generates posted adaptive programs.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

STOCK_MIN = (0.0, 0.0, -50.0)
STOCK_MAX = (150.0, 100.0, 0.0)
TOOL_COMMENTS = (
    "(T1 D=12 CR=0 - ZMIN=-12 - flat end mill)",
    "(T2 D=10 CR=0 - ZMIN=-15 - flat end mill)",
    "(T3 D=6 CR=3 - ZMIN=-12.3 - ball end mill)",
)


@dataclass(frozen=True)
class ProgramSize:
    """How much of the Titan-like part to machine."""

    slot_length: float = 120.0  # mm along X
    slots: int = 5
    depths: tuple[float, ...] = (-4.0, -8.0, -12.0)
    finish_rows: int = 20
    contours: int = 3


FULL = ProgramSize()
# one depth level (its helical entry is most of the adaptive's time) and two finish rows, so that
# --quick takes a few minutes (docs/benchmark.md says which program older figures were taken on)
QUICK = ProgramSize(slot_length=16.0, slots=2, depths=(-4.0,), finish_rows=2, contours=1)


class _Writer:
    def __init__(self) -> None:
        self.lines: list[str] = []
        self.pos = (0.0, 0.0, 50.0)

    def emit(self, text: str) -> None:
        self.lines.append(text)

    def g(self, code: str, x: float | None = None, y: float | None = None, z: float | None = None,
          extra: str = "") -> None:
        words = [code]
        px, py, pz = self.pos
        if x is not None and abs(x - px) > 5e-4:
            words.append(f"X{x:.3f}")
            px = x
        if y is not None and abs(y - py) > 5e-4:
            words.append(f"Y{y:.3f}")
            py = y
        if z is not None and abs(z - pz) > 5e-4:
            words.append(f"Z{z:.3f}")
            pz = z
        if len(words) == 1 and not extra:
            return
        self.lines.append(" ".join(words) + (" " + extra if extra else ""))
        self.pos = (round(px, 3), round(py, 3), round(pz, 3))


def _face(w: _Writer) -> None:
    w.emit("(Face)")
    w.emit("T1 M6")
    w.emit("S12000 M3")
    w.g("G0", -10.0, 4.0, 5.0)
    w.g("G1", z=-1.0, extra="F3000")
    y, forward = 4.0, True
    while y <= 100.0:
        w.g("G1", 160.0 if forward else -10.0, y)
        y += 9.0
        if y <= 100.0:
            w.g("G1", y=y)
        forward = not forward
    w.g("G0", z=5.0)


def _trochoid(w: _Writer, start: tuple[float, float], end: tuple[float, float], z: float,
              loop_r: float = 2.0, advance: float = 1.45, chord: float = 0.5) -> None:
    """Trochoidal loops from ``start`` to ``end`` at depth ``z`` (G1 chords, like adaptive posts)."""
    dx, dy = end[0] - start[0], end[1] - start[1]
    length = math.hypot(dx, dy)
    ux, uy = dx / length, dy / length
    loops = max(1, round(length / advance))
    per_loop = max(8, math.ceil(2 * math.pi * loop_r / chord))
    for k in range(loops):
        for j in range(1, per_loop + 1):
            t = (k + j / per_loop) / loops
            phase = 2 * math.pi * j / per_loop
            # circle around the advancing centre, starting and ending on the centre line's left
            cx, cy = start[0] + t * dx, start[1] + t * dy
            off_a = loop_r * math.cos(phase) - loop_r
            off_n = loop_r * math.sin(phase)
            w.g("G1", cx + off_a * ux - off_n * uy, cy + off_a * uy + off_n * ux, z)


def _adaptive(w: _Writer, size: ProgramSize) -> None:
    w.emit("(Adaptive)")
    w.emit("S12000 M3")
    x0 = 15.0 + 8.0
    x1 = x0 + size.slot_length
    ys = [22.0 + 14.0 * k for k in range(size.slots)]
    for z in size.depths:
        top = z + 4.0
        helix_c = (x0 + 2.0, ys[0])
        w.g("G0", helix_c[0] - 4.0, helix_c[1], 5.0)
        w.g("G1", z=top + 0.5, extra="F1000")
        # helical entry: full turns of radius 4 mm at 2 mm pitch, G2 with Z
        turns = max(1, round((top + 0.5 - z) / 2.0))
        step = (top + 0.5 - z) / turns
        for _ in range(turns):
            z_next = round(w.pos[2] - step, 3)
            # a full turn ends where it starts: posts write X and Y anyway, as the arc needs them
            w.emit(f"G2 X{helix_c[0] - 4.0:.3f} Y{helix_c[1]:.3f} Z{z_next:.3f} I4.000 J0.000 F800")
            w.pos = (w.pos[0], w.pos[1], z_next)
        w.g("G1", x0, ys[0], z, extra="F2500")
        forward = True
        for k, y in enumerate(ys):
            a, b = (x0, x1) if forward else (x1, x0)
            _trochoid(w, (a, y), (b, y), z)
            if k + 1 < len(ys):
                _trochoid(w, (b, y), (b, ys[k + 1]), z)
            forward = not forward
        w.g("G0", z=5.0)


def _contour(w: _Writer, size: ProgramSize) -> None:
    w.emit("(Contour)")
    w.emit("T2 M6")
    w.emit("S10000 M3")
    r = 8.0  # corner radius of the path
    lo, hi = (5.0, 5.0), (145.0, 95.0)
    for z in (-5.0, -10.0, -15.0)[: size.contours]:
        w.g("G0", lo[0] + r, lo[1] - 15.0, 5.0)
        w.g("G1", z=z, extra="F1000")
        w.g("G1", lo[0] + r, lo[1], extra="F2000")
        w.g("G1", hi[0] - r, lo[1])
        w.g("G3", hi[0], lo[1] + r, extra=f"I0.000 J{r:.3f}")
        w.g("G1", hi[0], hi[1] - r)
        w.g("G3", hi[0] - r, hi[1], extra=f"I{-r:.3f} J0.000")
        w.g("G1", lo[0] + r, hi[1])
        w.g("G3", lo[0], hi[1] - r, extra=f"I0.000 J{-r:.3f}")
        w.g("G1", lo[0], lo[1] + r)
        w.g("G3", lo[0] + r, lo[1], extra=f"I{r:.3f} J0.000")
        w.g("G0", z=5.0)


def _finish(w: _Writer, size: ProgramSize) -> None:
    w.emit("(Finish)")
    w.emit("T3 M6")
    w.emit("S15000 M3")
    x0, x1 = 30.0, 70.0
    for k in range(size.finish_rows):
        y = 25.0 + 1.5 * k
        z = -12.3 + 0.1 * math.sin(k)  # rows at slightly different heights: a curved floor
        w.g("G0", x0, y, 5.0)
        w.g("G1", z=z, extra="F1500")
        x = x0
        while x < x1 - 1e-9:
            x = min(x1, x + 1.0)
            w.g("G1", x, extra="F3000")
        w.g("G0", z=5.0)


def titan_program(size: ProgramSize = FULL) -> str:
    """The whole program as G-code text (metric, absolute, XY plane)."""
    w = _Writer()
    w.emit("%")
    w.emit("O1001 (TITAN-LIKE BENCHMARK)")
    w.lines.extend(TOOL_COMMENTS)
    w.emit("G90 G94 G17 G21")
    w.emit("G54")
    _face(w)
    _adaptive(w, size)
    _contour(w, size)
    _finish(w, size)
    w.emit("M5")
    w.emit("M30")
    w.emit("%")
    return "\n".join(w.lines) + "\n"
