# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Measurement loss
#
# The paper drops a growing share of the detections of its simulated shark pursuit, evenly
# through the log (at 50 % every other detection goes), and tracks with the HMM motion model.
# Below 20 % loss the filter converges quickly and stays accurate; between 20 % and 80 % it
# is slower and less accurate but usable; above 80 % it breaks down. This notebook reruns the
# sweep on our synthetic analogue of the shark pursuit with the paper's filter
# (`filter="paper"`: particles uniform in the search box, the whole cloud resampled) and puts
# our band summary beside the paper's. `hmmtrack reproduce` runs the same sweep with our
# configuration by default (`filter="mode-keeping", start_prior=True`; `reports/summary.md`).

# %% tags=["parameters"]
seed = 0
n_trials = 5  # trials per loss fraction
n_particles = 500
fractions = [0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.95, 1.0]
workers = 2  # local processes; 1 runs serially
duration = None  # seconds of the pursuit to track (None: all 150 min)
out = None  # folder to save the figure in, or None

# %%
from pathlib import Path

from hmmtrack import experiments
from hmmtrack.plots import results as result_plots
from hmmtrack.report import PAPER

scenario = experiments.paper_scenarios(seed, names=("shark_pursuit",), duration=duration)[
    "shark_pursuit"
]
sweep = experiments.loss_sweep(
    scenario,
    fractions=fractions,
    n_trials=n_trials,
    seed=seed,
    filter="paper",
    **experiments.run_options(workers, n_particles),
)
sweep.head()

# %% [markdown]
# ## The paper's bands
#
# Means and maxima over trials that converged (√λ₁ < 10 m at some point), ours first, then the
# paper's.

# %%
experiments.loss_bands(sweep)

# %%
PAPER["loss_bands"]

# %% [markdown]
# ## Log-scale plots
#
# Each dot is a trial; the black line is the mean over converged trials at each fraction; the
# purple segments are the paper's band means.

# %%
figure = result_plots.loss_figure(sweep, PAPER["loss_bands"])
if out is not None:
    Path(out).mkdir(parents=True, exist_ok=True)
    figure.savefig(Path(out) / "measurement_loss.png", dpi=100)
