"""A generated 3D finishing set for the real-program benchmark (issue 26): ball and bull-nose tools on a
free-form surface, as raster, waterline and spiral (scallop-like) passes with a ramp and helical
entries, built in code so that the benchmark needs no file.

The surface is a bowl with a ripple over a 50 x 50 x 15 mm box stock (top at z = 0):

    z(x, y) = -8 + 6 (r / 25)² + 0.8 sin(x / 4) sin(y / 5),   r = |(x, y)|     (mm)

The tool tip follows it (no gouge check: the programs exercise the engine, they are not meant to be
cut). Raster: rows along x every 1 mm across the central 30 x 30 mm, points every 0.5 mm, a ramp into
the first row. Waterline: the bowl without the ripple has circular level lines, r = 25 sqrt((z + 8) /
6); one full circle per level from z = -2.5 down to -7.5 every 0.5 mm, each reached by a helical half
turn down from the one above. Spiral: an Archimedean spiral from the centre out to r = 14, 1 mm
apart, points every 0.5 mm of arc, on the rippled surface.

Beside them, a round bar (a cylinder stock of radius 25 mm, 30 mm high, its top at z = 0) under a
10 mm flat end mill (``gen_round_bar_flat``): the top faced 1 mm deep in rows 7 mm apart across the
whole bar, the outside taken down from radius 25 to 22, 21 and 20 in three full circles 8 mm deep
(each reached by a plunge beside the bar and a line in), and a slot 10 mm wide, 3 mm below the faced
top, across it at y = 2. It removes in all, in closed form, pi 25² 1 + pi (25² - 20²) 7 + 3 (F(7) -
F(-3)) mm³ with F(y) = y sqrt(20² - y²) + 20² asin(y / 20).
"""
from __future__ import annotations

import math

from fusioncut.model import (ArcMove, BallEndMill, BoxStock, BullNoseEndMill, CylinderStock, FlatEndMill,
                             LinearMove, MillingTool, Stock, Toolpath)

FEED = 1200.0  # mm/min
STOCK = BoxStock((-25.0, -25.0, -15.0), (25.0, 25.0, 0.0))
BALL = BallEndMill(6.0, 20.0, number=1)
BULL = BullNoseEndMill(6.0, 20.0, corner_radius=1.0, number=1)
BAR = CylinderStock((0.0, 0.0, -30.0), 25.0, 30.0)


def surface(x: float, y: float, ripple: float = 0.8) -> float:
    r2 = x * x + y * y
    return -8.0 + 6.0 * r2 / 625.0 + ripple * math.sin(x / 4.0) * math.sin(y / 5.0)


def _polyline(points: list[tuple[float, float, float]]) -> list[LinearMove]:
    return [LinearMove(a, b, feed=FEED, tool=1) for a, b in zip(points[:-1], points[1:])]


def raster() -> Toolpath:
    moves: list = []
    xs = [-15.0 + 0.5 * i for i in range(61)]
    for k, y in enumerate(-15.0 + 1.0 * j for j in range(31)):
        row = [(x, y, surface(x, y)) for x in (xs if k % 2 == 0 else xs[::-1])]
        if not moves:
            above = (row[0][0] - 10.0, y, 1.0)
            moves.append(LinearMove(above, row[0], feed=FEED, tool=1))  # the ramp in
        else:
            moves.append(LinearMove(moves[-1].end, row[0], feed=FEED, tool=1))  # the step over
        moves += _polyline(row)
    return Toolpath(tuple(moves), {1: BALL})


def waterline() -> Toolpath:
    moves: list = []
    levels = [-2.5 - 0.5 * k for k in range(11)]
    prev = None
    for z in levels:
        r = 25.0 * math.sqrt((z + 8.0) / 6.0)
        start = (r, 0.0, z)
        if prev is None:
            moves.append(LinearMove((r, 0.0, 1.0), start, feed=FEED, tool=1))  # a plunge to the first level
        else:
            # a helical half turn down to this level's radius, then back to angle 0 along a chord
            half = (-prev[0], 0.0, 0.5 * (prev[2] + z))
            moves.append(ArcMove(prev, half, feed=FEED, tool=1, center=(0.0, 0.0, prev[2]), clockwise=False))
            moves.append(LinearMove(half, (-r, 0.0, z), feed=FEED, tool=1))
            moves.append(ArcMove((-r, 0.0, z), start, feed=FEED, tool=1, center=(0.0, 0.0, z), clockwise=False))
        moves.append(ArcMove(start, start, feed=FEED, tool=1, center=(0.0, 0.0, z), clockwise=False))  # full circle
        prev = start
    return Toolpath(tuple(moves), {1: BULL})


def spiral() -> Toolpath:
    points = []
    a = 0.0
    while True:
        r = a / (2.0 * math.pi)  # 1 mm between turns
        if r > 14.0:
            break
        x, y = r * math.cos(a), r * math.sin(a)
        points.append((x, y, surface(x, y)))
        a += 0.5 / max(r, 0.5)  # 0.5 mm of arc
    entry = LinearMove((0.0, 0.0, 1.0), points[0], feed=FEED, tool=1)
    return Toolpath((entry, *_polyline(points)), {1: BALL})


def round_bar() -> Toolpath:
    face = []
    for k, y in enumerate(-21.0 + 7.0 * j for j in range(7)):  # facing, zigzag
        face += [(-32.0, y, -1.0), (32.0, y, -1.0)][::1 if k % 2 == 0 else -1]
    moves = [LinearMove((-32.0, -21.0, 5.0), face[0], feed=FEED, tool=1), *_polyline(face)]

    def go(point, rapid=False):
        moves.append(LinearMove(moves[-1].end, point, feed=None if rapid else FEED, tool=1, rapid=rapid))

    for r in (27.0, 26.0, 25.0):  # the outside down to radius r - 5
        go((moves[-1].end[0], moves[-1].end[1], 5.0), rapid=True)
        go((r, -15.0, 5.0), rapid=True)
        go((r, -15.0, -8.0))
        go((r, 0.0, -8.0))
        moves.append(ArcMove((r, 0.0, -8.0), (r, 0.0, -8.0), feed=FEED, tool=1, center=(0.0, 0.0, -8.0),
                             clockwise=False))
    go((25.0, 0.0, 5.0), rapid=True)
    go((-30.0, 2.0, 5.0), rapid=True)
    go((-30.0, 2.0, -4.0))
    go((30.0, 2.0, -4.0))  # the slot, 3 mm below the faced top
    return Toolpath(tuple(moves), {1: FlatEndMill(10.0, 20.0, number=1)})


GENERATED: dict[str, tuple] = {
    "gen_raster_ball": raster,
    "gen_waterline_bull": waterline,
    "gen_spiral_ball": spiral,
    "gen_round_bar_flat": round_bar,
}
STOCKS: dict[str, Stock] = {"gen_round_bar_flat": BAR}  # the others cut STOCK


def load(name: str) -> tuple[Toolpath, Stock, MillingTool | None]:
    return GENERATED[name](), STOCKS.get(name, STOCK), None
