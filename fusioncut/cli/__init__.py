"""The ``fusioncut`` command line.

Each public sub-module ``fusioncut/cli/<name>.py`` (no leading underscore) defines ``register(app)`` adding its commands, so that
commands can be written independently. Errors of the project's own types are printed as one clear
line (file:line or CL) with exit code 2, never as a traceback.
"""
from __future__ import annotations

import importlib
import pkgutil

import typer

# plain click help (rich_markup_mode=None): it wraps the option help in one column at any terminal width,
# where rich's option panels leave the help text a sliver of an 80-column terminal
app = typer.Typer(add_completion=False, no_args_is_help=True, rich_markup_mode=None,
                  help="Exact cutter-workpiece engagement for milling.")

for _mod in sorted(m.name for m in pkgutil.iter_modules(__path__) if not m.name.startswith("_")):
    importlib.import_module(f"{__name__}.{_mod}").register(app)
