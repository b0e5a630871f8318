"""Test-session settings shared by every test module.

Hypothesis: no per-example deadline. Its default (200 ms) fails tests on a busy machine
(CI, or two cores shared by several workers) where a slow example says nothing about
correctness; tests never assert on wall-clock time. The ``ci`` profile is loaded unless
``HYPOTHESIS_PROFILE`` names another (``dev``: fewer examples for a quick local run).
"""

import os

from hypothesis import settings

settings.register_profile("ci", deadline=None, print_blob=True)
settings.register_profile("dev", deadline=None, max_examples=20)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
