"""Optional dependencies: what each extra of ``pip install 'fusioncut[...]'`` brings, and a clear
error naming the extra where a command needs one that is not installed.

The core (``pip install fusioncut``) reads programs and computes engagement in one process: the
kernel (OCP), numpy, numba, pydantic, pandas, pyarrow and the command line. The extras:

* ``parallel``: Dask's distributed scheduler, for ``workers`` > 1 or a Dask ``scheduler``;
* ``viz``: matplotlib (plots) and trimesh (the 3D view's glTF scene);
* ``service``: the web service (FastAPI, uvicorn, python-multipart), its Dask cluster and scenes;
* ``all``: every one of them (``test`` installs ``all`` too).
"""
from __future__ import annotations

import importlib.util

from fusioncut.errors import FusionCutError

__all__ = ["EXTRAS", "MissingExtra", "require"]

# extra -> the modules it installs (import names)
EXTRAS: dict[str, tuple[str, ...]] = {
    "parallel": ("distributed",),
    "viz": ("matplotlib", "trimesh"),
    "service": ("fastapi", "uvicorn", "multipart", "distributed", "trimesh"),
}


class MissingExtra(FusionCutError):
    """A feature whose optional dependencies are not installed; the message says which extra brings them."""


def require(extra: str, feature: str) -> None:
    """Raise :class:`MissingExtra` naming ``extra`` and how to install it when a module of it is
    missing; ``feature`` says what needs it (``"--workers 2"``, ``"fusioncut serve"``)."""
    missing = [m for m in EXTRAS[extra] if importlib.util.find_spec(m) is None]
    if missing:
        raise MissingExtra(f"{feature} needs the [{extra}] extra ({', '.join(missing)} not installed): "
                           f"pip install 'fusioncut[{extra}]'")
