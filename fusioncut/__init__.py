"""FusionCut: exact cutter-workpiece engagement (CWE) for milling on OpenCASCADE."""
__version__ = "0.1.0"
