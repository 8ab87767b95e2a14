"""Angle conventions. Every angle that FusionCut outputs says which of these it is.

**Immersion angle** ``phi`` (the milling literature, Altintas, *Manufacturing Automation*, ch. 2):
in the *feed frame* (feed along +x, tool axis +z) ``phi`` is measured from +y in the sense the teeth
turn: clockwise seen from +z for a clockwise (M3) spindle. A tooth at ``phi`` sits at
``(x, y) = r * (sin phi, cos phi)`` and cuts a chip ``h = c * sin(phi)`` (``c`` feed per tooth), so:

    up-milling (material on +y):     [0, arccos(1 - ae/R)]
    down-milling (material on -y):   [180 - arccos(1 - ae/R), 180]
    full slot:                       [0, 180]

For a counter-clockwise (M4) spindle the frame is mirrored (``phi`` counter-clockwise from -y), so the
chip formula and the up/down-milling intervals stay the same.

                 +y  phi = 0 (CW spindle)
                  |
        phi=270 --+-- phi = 90  --> feed (+x)
                  |
                 -y  phi = 180

**Machine angle** ``theta``: the ordinary polar angle in the machine XY plane, counter-clockwise from
+X seen from +Z, independent of feed and spindle. Both are in degrees in results; an interval
``(entry, exit)`` has ``0 <= entry < 360`` and ``entry < exit <= entry + 360`` in the direction the
teeth travel (immersion) or counter-clockwise (machine).
"""
from __future__ import annotations

import math

from fusioncut.model.tools import SpindleDirection


def immersion_from_machine(theta_deg: float, feed_angle_deg: float, spindle: SpindleDirection) -> float:
    """Immersion angle (deg, [0, 360)) of the tool point at machine angle ``theta_deg``.

    ``feed_angle_deg`` is the machine angle of the horizontal feed direction.
    """
    if spindle == SpindleDirection.CW:
        return (feed_angle_deg + 90.0 - theta_deg) % 360.0
    return (theta_deg - feed_angle_deg + 90.0) % 360.0


def machine_from_immersion(phi_deg: float, feed_angle_deg: float, spindle: SpindleDirection) -> float:
    """Inverse of :func:`immersion_from_machine`: machine angle (deg, [0, 360))."""
    if spindle == SpindleDirection.CW:
        return (feed_angle_deg + 90.0 - phi_deg) % 360.0
    return (phi_deg + feed_angle_deg - 90.0) % 360.0


def up_milling_exit(ae: float, radius: float) -> float:
    """Closed-form exit angle (deg) of up-milling with radial depth ``ae`` on a tool of ``radius``."""
    return math.degrees(math.acos(1.0 - ae / radius))
