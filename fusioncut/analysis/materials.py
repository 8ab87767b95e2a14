"""A small library of published linear edge-force cutting coefficients.

Cutting coefficients depend on the work material *and* the tool (substrate, coating, rake and helix
angles, edge preparation, wear) and on the cutting speed; a published set is a starting point for an
order-of-magnitude estimate, not a substitute for calibrating your own tool with a few slot cuts
(:func:`fusioncut.analysis.calibrate.calibrate_from_slot_tests`, ``fusioncut calibrate``).

Only sets whose source we can name are listed. Units: ``ktc``, ``krc``, ``kac`` N/mm²;
``kte``, ``kre``, ``kae`` N/mm; axial sign convention ``Fz = +Fa`` (see
:mod:`fusioncut.analysis.forces`).
"""
from __future__ import annotations

from fusioncut.analysis.forces import CuttingCoefficients
from fusioncut.errors import InputError

AL7075_T6_CARBIDE = CuttingCoefficients(
    ktc=796.1,
    krc=168.8,
    kac=222.0,
    kte=27.7,
    kre=30.8,
    kae=1.4,
    name="Al7075-T6, carbide end mill",
    source=(
        "Y. Altintas, Manufacturing Automation: Metal Cutting Mechanics, Machine Tool Vibrations, and CNC "
        "Design, 2nd ed., Cambridge University Press, 2012, ch. 2 (mechanics of milling; identification "
        "of the linear edge-force coefficients from average forces of slot cuts at several feeds per "
        "tooth): Al7075-T6 work, carbide end mill of about 30 deg helix. Values as quoted in the "
        "project brief from that worked example; not re-checked against the book here. A later review "
        "(Chinese J. Mech. Eng. 34 (2021), doi:10.1186/s10033-021-00536-9, Table 5) quotes a set for "
        "Al7075-T6 / carbide with the same Krc, Kte, Kac but Ktc 767.01, Kre 26.6, Kae 0.7: check the "
        "edition you use."
    ),
)

MATERIALS: dict[str, CuttingCoefficients] = {
    "al7075-t6": AL7075_T6_CARBIDE,
}


def get_coefficients(name: str) -> CuttingCoefficients:
    """The coefficients listed under ``name`` (case-insensitive, e.g. ``"Al7075-T6"``)."""
    try:
        return MATERIALS[name.strip().lower()]
    except KeyError:
        known = ", ".join(sorted(MATERIALS))
        raise InputError(f"unknown material {name!r}; known: {known}") from None
