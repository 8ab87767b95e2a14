"""The built-in demo as an ordinary service job: :func:`fusioncut.demo.demo_job` and its G-code.

The service runs only jobs made of files, so that a demo job is run, resumed, listed and downloaded
exactly like an uploaded one; ``fusioncut demo`` runs the same job (:mod:`fusioncut.demo` builds it).
"""
from __future__ import annotations

from fusioncut.demo import DEMO_FILE, DEMO_OPTIONS, demo_gcode, demo_job

__all__ = ["DEMO_FILE", "DEMO_OPTIONS", "demo_gcode", "demo_job"]
