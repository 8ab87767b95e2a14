"""``python -m fusioncut.service [options]`` is ``fusioncut serve [options]``."""
from __future__ import annotations

import sys

from fusioncut.cli import app

if __name__ == "__main__":
    app(["serve", *sys.argv[1:]], prog_name="fusioncut")
