"""Kernel helpers: the incremental volume, the sliver filter and the face merge, each guarding a
silent kernel error seen on the Titan-like benchmark."""
from __future__ import annotations

import pytest
from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut, BRepAlgoAPI_Fuse
from OCP.BRep import BRep_Builder
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
from OCP.TopoDS import TopoDS_Shell, TopoDS_Solid

from fusioncut.engines.base import EngineOptions
from fusioncut.engines.brep import occ
from fusioncut.engines.brep.engine import BRepEngine
from fusioncut.engines.brep.occ import compound, count_faces, faces, solids, unify, volume, volume_change, without_slivers


def box(x0, y0, z0, dx, dy, dz):
    return BRepPrimAPI_MakeBox(gp_Pnt(x0, y0, z0), dx, dy, dz).Shape()


def empty_solid():
    """A 'solid' bounded by one face and its own reverse: no volume, like the one OCCT's Cut once left."""
    face = next(faces(box(50, 0, 0, 1, 1, 1)))
    builder = BRep_Builder()
    shell, solid = TopoDS_Shell(), TopoDS_Solid()
    builder.MakeShell(shell)
    builder.Add(shell, face)
    builder.Add(shell, face.Reversed())
    builder.MakeSolid(solid)
    builder.Add(solid, shell)
    return solid


def test_volume_change_equals_the_difference_of_whole_volumes():
    old = box(0, 0, 0, 20, 10, 5)
    tool = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(10, 5, 2), gp_Dir(0, 0, 1)), 3.0, 10.0).Shape()
    new = BRepAlgoAPI_Cut(old, tool).Shape()
    assert volume_change(old, new) == pytest.approx(volume(new) - volume(old), abs=1e-9)
    assert volume_change(old, old) == 0.0


def test_empty_solids_a_boolean_left_are_dropped_and_real_ones_kept():
    old = box(0, 0, 0, 20, 10, 5)
    sliver = empty_solid()
    assert volume(sliver) == pytest.approx(0.0, abs=1e-12)
    cleaned = without_slivers(old, compound([old, sliver]))
    assert len(solids(cleaned)) == 1 and volume(cleaned) == pytest.approx(1000.0)
    # a real piece cut off the workpiece stays, however small its face count
    chip = box(30, 0, 0, 0.1, 0.1, 0.1)
    assert len(solids(without_slivers(old, compound([old, chip])))) == 2
    # nothing new: the shape is returned as it is
    assert without_slivers(old, old).IsSame(old)


def test_unify_merges_split_faces_and_keeps_the_volume():
    two = BRepAlgoAPI_Fuse(box(0, 0, 0, 10, 10, 5), box(10, 0, 0, 10, 10, 5)).Shape()
    merged = unify(two)
    assert count_faces(two) > 6 and count_faces(merged) == 6
    assert volume(merged) == pytest.approx(1000.0)


def test_unify_refuses_a_merge_that_changes_the_volume(monkeypatch):
    """The kernel's merge once returned an invalid workpiece 8.2 mm³ smaller, without an error."""
    two = BRepAlgoAPI_Fuse(box(0, 0, 0, 10, 10, 5), box(10, 0, 0, 10, 10, 5)).Shape()

    class WrongMerge:  # merges the faces, and loses a slice of material as the kernel once did
        def __init__(self, shape, *flags):
            pass

        def Build(self):
            pass

        def Shape(self):
            return box(0, 0, 0, 20, 10, 4.99)

    monkeypatch.setattr(occ, "ShapeUpgrade_UnifySameDomain", WrongMerge)
    assert occ.unify(two).IsSame(two)


def test_unify_keeps_the_faces_around_a_hole_and_merges_the_rest(monkeypatch):
    """The kernel's merge once dropped a face of a workpiece (a hole, 7.9 mm³ "lost"); refusing
    the whole merge then let the workpiece grow tenfold in faces. The faces around the hole stay
    as they are and the rest is merged."""
    row = box(0, 0, 0, 10, 10, 5)
    for k in range(1, 4):
        row = BRepAlgoAPI_Fuse(row, box(10 * k, 0, 0, 10, 10, 5)).Shape()
    real = occ.ShapeUpgrade_UnifySameDomain
    rounds = []

    class HoleyMerge:  # the first merge loses the end face at x = 0, later ones are the kernel's
        def __init__(self, shape, *flags):
            self.merge = real(shape, *flags)
            rounds.append(self)

        def KeepShape(self, shape):
            self.merge.KeepShape(shape)

        def Build(self):
            self.merge.Build()

        def Shape(self):
            merged = self.merge.Shape()
            if len(rounds) > 1:
                return merged
            builder = BRep_Builder()
            shell, solid = TopoDS_Shell(), TopoDS_Solid()
            builder.MakeShell(shell)
            for f in faces(merged):
                if occ.bounding_box(f)[1][0] > 1e-6:
                    builder.Add(shell, f)
            builder.MakeSolid(solid)
            builder.Add(solid, shell)
            return solid

    monkeypatch.setattr(occ, "ShapeUpgrade_UnifySameDomain", HoleyMerge)
    merged = occ.unify(row)
    assert len(rounds) == 2
    assert count_faces(row) == 18 and count_faces(merged) == 10  # the first box's faces are kept
    assert volume(merged) == pytest.approx(2000.0, rel=1e-12)
    assert BRepCheck_Analyzer(merged).IsValid()


def test_unify_leaves_its_argument_alone():
    """The kernel's merge edits the shape it is given (a helical entry's workpiece lost 10.5 mm³),
    and earlier workpieces share that shape's faces."""
    from test_helical_entry import STOCK, helical_entry

    engine = BRepEngine(EngineOptions(ramp_step=0.05, fuzzy=1e-6))
    engine.start(STOCK)
    for _, _m in zip(range(40), engine.process(helical_entry())):  # with the engine's own merges between
        ipw = engine.ipw
        faces_before, volume_before = count_faces(ipw), volume(ipw)
        unify(ipw)
        assert count_faces(ipw) == faces_before
        assert volume(ipw) == pytest.approx(volume_before, rel=1e-12)


def _ball_rows_before_any_merge():
    """A cell after two ball-end-mill rows of 1 mm CLs, cut with the cells' 1e-6 mm fuzzy value
    and never merged (as it stood before its first merge on the benchmark's finish)."""
    from fusioncut.model import BallEndMill, BoxStock, LinearMove, Toolpath

    block = BoxStock((0.0, 0.0, -10.0), (20.0, 20.0, 0.0))

    moves = []
    for k, y in enumerate((8.0, 9.5)):
        z = -0.3 - 0.1 * k
        moves.append(LinearMove((0.0, y, 5.0), (0.0, y, z), tool=1, feed=500.0))
        moves += [LinearMove((float(x), y, z), (float(x + 1), y, z), tool=1, feed=500.0) for x in range(20)]
    program = Toolpath(tuple(moves), {1: BallEndMill(6.0, 20.0, number=1)})
    engine = BRepEngine(EngineOptions(cell_size=20.0, merge_growth=1e9))
    assert all(m.status.value != "failed" for m in engine.run(program, block))
    (cell,) = [c for c in engine.cells if not c.empty]
    return cell.shape


def test_unify_takes_the_fuzzy_gap_of_the_booleans_that_built_the_shape():
    """Each CL's cylinder patch comes ~2e-6 mm longer than its 1 mm (the fuzzy Booleans glued them
    overlapping): the merge into one face per row moves the volume by more than 1e-9 of it, so
    without the gap it is refused, and the cell keeps a face per CL."""
    shape = _ball_rows_before_any_merge()
    n = count_faces(shape)
    assert n > 40
    assert count_faces(unify(shape, volume(shape))) == n
    merged = unify(shape, volume(shape), gap=1e-6)
    assert count_faces(merged) <= 10
    assert BRepCheck_Analyzer(merged).IsValid()
    assert abs(volume(merged) - volume(shape)) <= 2e-6 * occ.area(shape)
