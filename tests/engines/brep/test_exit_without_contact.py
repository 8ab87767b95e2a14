"""A CL that leaves the material removes it on its way and ends clear of it: the map says so (engaged,
its removed volume, no slice at the end, a warning naming the volume) instead of passing in silence."""
import math

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.model import BoxStock, CLStatus, FlatEndMill, LinearMove, Toolpath


def test_slot_exit_removes_material_and_ends_clear():
    tool = FlatEndMill(diameter=10, flute_length=20)
    stock = BoxStock((0, 0, -20), (100, 50, 0))
    path = Toolpath((LinearMove((-10, 25, -3), (95, 25, -3), feed=600, tool=1),
                     LinearMove((95, 25, -3), (106, 25, -3), feed=600, tool=1)), {1: tool})
    maps = list(BRepEngine(EngineOptions()).run(path, stock))
    exit_cl = maps[-1]
    # the slot's end beyond the half disk the tool stood in at x = 95: 3 mm deep, 10 wide, 5 long
    expected = 3 * (10 * 5 - math.pi * 5**2 / 2)
    assert exit_cl.status == CLStatus.ENGAGED
    assert math.isclose(exit_cl.removed_volume, expected, rel_tol=1e-6)
    assert exit_cl.engaged_slices == ()
    assert any("ends clear of the material" in w and f"{expected:.4g}" in w for w in exit_cl.warnings)
    assert not any("ends clear" in w for w in maps[0].warnings)  # the slot itself ends in material
