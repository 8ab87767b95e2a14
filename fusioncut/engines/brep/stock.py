"""Stock to B-Rep solid."""
from __future__ import annotations

from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
from OCP.gp import gp_Ax2, gp_Dir
from OCP.IFSelect import IFSelect_RetDone
from OCP.STEPControl import STEPControl_Reader
from OCP.TopoDS import TopoDS_Shape

from fusioncut.engines.brep.occ import pnt, read_brep, solids, volume
from fusioncut.errors import InputError
from fusioncut.model.stock import BoxStock, CylinderStock, SolidStock, Stock


def stock_solid(stock: Stock) -> TopoDS_Shape:
    if isinstance(stock, BoxStock):
        lo, hi = stock.minimum, stock.maximum
        return BRepPrimAPI_MakeBox(pnt(lo), pnt(hi)).Shape()
    if isinstance(stock, CylinderStock):
        return BRepPrimAPI_MakeCylinder(gp_Ax2(pnt(stock.base_center), gp_Dir(0, 0, 1)), stock.radius, stock.height).Shape()
    if isinstance(stock, SolidStock):
        return _read_solid(stock)
    raise InputError(f"unknown stock type {type(stock).__name__}")


def _read_solid(stock: SolidStock) -> TopoDS_Shape:
    path = stock.path
    if not path.is_file():
        raise InputError("stock file not found", path)
    suffix = path.suffix.lower()
    if suffix in (".step", ".stp"):
        reader = STEPControl_Reader()
        if reader.ReadFile(str(path)) != IFSelect_RetDone:
            raise InputError("not a readable STEP file", path)
        reader.TransferRoots()
        shape = reader.OneShape()
    elif suffix == ".brep":
        shape = read_brep(str(path))
    else:
        raise InputError("stock solids are read from .step/.stp or .brep files", path)
    found = solids(shape)
    if not found:
        raise InputError("the file holds no solid (a stock must be a closed, manifold solid)", path)
    if not BRepCheck_Analyzer(shape).IsValid() or volume(shape) <= 0:
        raise InputError("the solid is not valid (open, non-manifold or inside out)", path)
    return shape
