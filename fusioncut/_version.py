"""The package version, in one module that imports nothing (the package, runner and results read it)."""
__version__ = "0.1.0"
