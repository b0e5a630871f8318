"""Every number the paper's "Results" section quotes, keyed by our scenario names.

Data only: the comparison table of ``summary.md`` and the figures put ours beside these.
"""

from __future__ import annotations

import pandas as pd

from hmmtrack.experiments import LOSS_BANDS

#: the paper's numbers, keyed by our scenario names (hmmtrack.scenarios)
PAPER = {
    "datasets": {
        "stationary-tag": "Long Beach",
        "swimmer": "Santa Elena Bay",
        "shark-pursuit": "Simulated (shark pursuit)",
    },
    # average error after convergence (the paper's "RMSE"), m
    "error": {
        "stationary-tag": {"baseline": 5.42, "velocity": 4.44, "hmm": 6.11},
        "swimmer": {"baseline": 11.22, "velocity": 12.31, "hmm": 8.78},
        "shark-pursuit": {"baseline": 970.46, "velocity": 30.77, "hmm": 13.62},
    },
    # average time to convergence, s (quoted for Santa Elena Bay only)
    "convergence": {"swimmer": {"baseline": 27.0, "velocity": 40.0, "hmm": 180.0}},
    # measurement-loss bands on the simulated dataset, HMM model
    "loss_bands": pd.DataFrame(
        {
            "convergence_mean": [43.8, 71.4, 1342.0],
            "convergence_max": [129.0, 249.0, 6785.0],
            "error_mean": [15.07, 37.68, 391.61],
            "error_max": [23.18, 61.24, 1835.55],
        },
        index=list(LOSS_BANDS),
    ),
    # percent error of a slant range taken as horizontal, tag at 10.7 m: range m -> %
    "depth_percent_error": {20.0: 18.4, 50.0: 2.4, 100.0: 0.6},
}


def dataset_name(scenario: str) -> str:
    """The paper's name of the dataset our ``scenario`` imitates (``scenario`` itself when
    the paper has none)."""
    return PAPER["datasets"].get(scenario, scenario)
