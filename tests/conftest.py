"""Test-session settings shared by every test module.

Hypothesis: no per-example deadline. Its default (200 ms) fails tests on a busy machine
(CI, or two cores shared by several workers) where a slow example says nothing about
correctness; tests never assert on wall-clock time. The ``ci`` profile is loaded unless
``HYPOTHESIS_PROFILE`` names another.

- ``ci`` (the default, and what ``.ci/run`` uses): derandomised, so every run draws the same
  examples and a CI run cannot fail on an example no earlier run saw (sessions 7-8 had two
  such failures, each a test's own tolerance bug found by chance in CI).
- ``explore``: random examples and 10x as many, to hunt for new failures locally
  (``HYPOTHESIS_PROFILE=explore pytest tests/test_x.py``); a failure prints the
  ``@reproduce_failure`` blob to pin it.
- ``dev``: fewer examples for a quick local run.
"""

import os

from hypothesis import settings

settings.register_profile("ci", deadline=None, derandomize=True, print_blob=True)
settings.register_profile("explore", deadline=None, max_examples=1000, print_blob=True)
settings.register_profile("dev", deadline=None, max_examples=20)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))
