"""The reproduction report: our results beside the paper's, and whether its findings hold.

* :mod:`~hmmtrack.report.paper` — :data:`PAPER`, every number the paper's "Results" quotes;
* :mod:`~hmmtrack.report.findings` — :func:`check_findings`, the paper's qualitative claims
  tested on our tables;
* :mod:`~hmmtrack.report.summary` — :func:`write_summary`, ``reports/summary.md`` with a
  plain statement that the data are synthetic analogues of the paper's;
* :mod:`~hmmtrack.report.pipeline` — :func:`reproduce`, the whole run behind
  ``hmmtrack reproduce``, and :func:`save_figures`.

The trials are run by :mod:`hmmtrack.experiments` and every figure is drawn by a plotting
function; this package orchestrates, formats and judges.
"""

from hmmtrack.report.findings import DIVERGED_ERROR, Finding, check_findings
from hmmtrack.report.paper import PAPER
from hmmtrack.report.pipeline import FULL, QUICK, RunSize, reproduce, save_figures
from hmmtrack.report.summary import write_summary

__all__ = [
    "DIVERGED_ERROR",
    "FULL",
    "PAPER",
    "QUICK",
    "Finding",
    "RunSize",
    "check_findings",
    "reproduce",
    "save_figures",
    "write_summary",
]
