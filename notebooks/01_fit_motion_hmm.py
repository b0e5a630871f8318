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
# # Fitting the white-shark motion HMM
#
# The paper fits a two-state HMM (gamma speeds, von Mises turning rates) to about 124,000
# positions of 22 white sharks and uses it as the motion model of its particle filter. Those
# tracks are not public, so hmmtrack simulates *synthetic historical tracks* from a documented
# ground-truth model, sampled the way a receiver array positions animals (fixes 1–3 min apart,
# a few metres of error, dropped stretches). Here we fit the HMM to them with the paper's
# recipe (split at gaps over 3 min, regular 60 s grid, step lengths and turning angles) and
# check what it recovers of the ground truth.

# %% tags=["parameters"]
seed = 2020  # seed of the synthetic tracks (2020 gives the bundled dataset)
n_sharks = 22
n_positions = 124_000
n_starts = 5  # EM starts of the fitter
fit_seed = 1
out = None  # folder to save the figure in, or None

# %%
from pathlib import Path

from hmmtrack.plots import results as result_plots
from hmmtrack.scenarios import white_shark_hmm, white_shark_tracks

tracks = white_shark_tracks(seed, n_animals=n_sharks, n_positions=n_positions)
print(f"{tracks['id'].nunique()} sharks, {len(tracks):,} positions")
tracks.head()

# %% [markdown]
# ## Fit
#
# Two states, ordered by mean step: 0 = resident (slow, tortuous), 1 = transit (fast,
# directed).

# %%
model = white_shark_hmm.fit_white_shark_hmm(tracks, n_starts=n_starts, seed=fit_seed)
print(f"log-likelihood {model.log_likelihood:.1f}, AIC {model.aic:.1f}, dt {model.dt:g} s")
model.transition_matrix()

# %% [markdown]
# ## Recovery of the ground truth
#
# The fit describes the *regularised* track: chords of a tortuous path between fixes are
# shorter and straighter than the path itself, so the resident state's steps come out shorter
# and its turns more concentrated than the simulation's; the nearly straight transit state is
# recovered closely.

# %%
white_shark_hmm.compare_with_ground_truth(model)

# %% [markdown]
# ## State-dependent densities
#
# Speeds (gamma) and turning rates (von Mises) of each state, weighted by the states'
# stationary probabilities, as in the paper's figure.

# %%
prepared = white_shark_hmm.prepare_white_shark_tracks(tracks)
figure = result_plots.motion_hmm_figure(model, prepared)
if out is not None:
    Path(out).mkdir(parents=True, exist_ok=True)
    figure.savefig(Path(out) / "white_shark_hmm.png", dpi=100)
