"""Test-wide settings.

CI (``.ci/run`` sets ``HYPOTHESIS_PROFILE=ci``) draws the same property-test examples every run, so
that a landing is red or green for the code, not for the draw; local runs draw new examples (and
replay the failures they found from ``.hypothesis/``).
"""
import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))
