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
# # A movement HMM from irregular fixes: CRW imputation, a time-of-day formula, the figures
#
# Real tracks are rarely regular: fixes fail, and the tags that work come at jittered times.
# Here we simulate a two-state animal whose switching depends on the time of day, observe it
# the way a GPS collar would (half of the fixes lost, the others up to 200 s off schedule),
# and fit a movement HMM to it as momentuHMM users do:
#
# 1. regularise the fixes with a continuous-time correlated random walk (R's `crawl`),
#    `hmmtrack.hmm.crw.regularise`, which also says how uncertain each predicted position is;
# 2. fit the HMM with the transition probabilities on a cosinor formula of the hour;
# 3. draw the standard figures: state densities, pseudo-residuals, decoded track and the
#    transition and stationary probabilities against the hour with 95 % bands;
# 4. carry the positions' uncertainty into the estimates by multiple imputation
#    (`hmmtrack.hmm.crw.impute` + `hmmtrack.hmm.imputation.fit_imputed`, Rubin's rules);
# 5. check the fit from many starting values, and refit with a parameter fixed, a
#    stationary initial distribution and the state names saved in the model.

# %% tags=["parameters"]
seed = 1
n_steps = 1440  # 10 days at one fix per 10 min
fraction_kept = 0.5  # share of the scheduled fixes received
n_draws = 3  # imputed tracks of the multiple imputation
n_starts = 2  # EM starts of each fit
n_check = 8  # starts of the check of starting values
out = None  # folder to save the figures in, or None

# %%
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from hmmtrack import tracks
from hmmtrack.hmm import Gamma, MovementHMM, MovementHMMEstimator, VonMises, crw, diagnostics
from hmmtrack.hmm.formula import design
from hmmtrack.hmm.imputation import fit_imputed, pooled_table
from hmmtrack.plots import hmm as plots

STEP = 600.0  # s, the schedule and the grid we fit on
FORMULA = "~ cos(2*pi*hour/24) + sin(2*pi*hour/24)"
NAMES = ["foraging", "travelling"]
rng = np.random.default_rng(seed)


def hour_of(seconds):
    """Hour of the day (UTC) of epoch seconds."""
    return (np.asarray(seconds) % 86400.0) / 3600.0


# %% [markdown]
# ## A simulated animal and its collar
#
# State 1 (foraging: short steps, many reversals) and state 2 (travelling: long, straight
# steps). Travel starts more often around midday: the logit of each switch is a cosinor of
# the hour. The truth is a `MovementHMM` with that formula, simulated on the 10-min schedule.

# %%
schedule = 1.7e9 - 1.7e9 % 86400.0 + STEP * np.arange(n_steps)  # from midnight UTC
hours = pd.DataFrame({"hour": hour_of(schedule)})
truth = MovementHMM(
    initial=np.array([0.5, 0.5]),
    transition=None,
    step=Gamma(np.array([40.0, 400.0]), np.array([30.0, 200.0])),
    angle=VonMises(np.array([np.pi, 0.0]), np.array([0.5, 4.0])),
    coefficients=np.array([[-2.0, -1.2, 0.0], [-1.5, 1.0, 0.5]]),
    transition_design=design(FORMULA, hours),
    dt=STEP,
)
simulated = truth.simulate(rng, n_steps, hours)
heading = np.cumsum(simulated["angle"])
x = np.r_[0.0, np.cumsum(simulated["step"] * np.cos(heading))][:-1]
y = np.r_[0.0, np.cumsum(simulated["step"] * np.sin(heading))][:-1]
jitter = rng.uniform(-200.0, 200.0, n_steps)
jitter[[0, -1]] = 0.0
received = np.unique(
    np.r_[0, n_steps - 1, rng.choice(n_steps - 2, int(fraction_kept * n_steps), False) + 1]
)
fixes = pd.DataFrame({"id": "collar-1", "time": schedule + jitter, "x": x, "y": y}).iloc[received]
gaps = np.diff(fixes["time"])
print(f"{len(fixes)} fixes of {n_steps}; time between fixes {gaps.min():.0f}-{gaps.max():.0f} s")

# %% [markdown]
# ## Regularising with a continuous-time correlated random walk
#
# `crw.fit_tracks` fits the CRW (velocity an Ornstein-Uhlenbeck process, a Gaussian error per
# fix) by a Kalman filter; `crw.regularise` predicts the positions on the 10-min grid by the
# Kalman smoother, with their standard deviations: small next to a fix, large in long gaps.
# The hour is a column of the grid, computed from its times.

# %%
models = crw.fit_tracks(fixes)
grid = crw.regularise(fixes, STEP, models=models)
grid["hour"] = hour_of(grid["time"])
print(models["collar-1"])
print(
    f"predicted positions' sd: median {grid['sd_x'].median():.0f} m, max {grid['sd_x'].max():.0f} m"
)

# %% [markdown]
# ## The HMM with a time-of-day formula
#
# `formula` takes the same syntax as R (formulaic): here a cosinor of the hour. The
# coefficients are estimated on standardised columns and reported on the data's scale.

# %%
prepared = tracks.prepare(grid)
estimator = MovementHMMEstimator(2, formula=FORMULA, n_starts=n_starts, seed=1)
model = estimator.fit(prepared).model_
print(diagnostics.summary(model))
print("true coefficients on the data's scale:")
print(truth.coefficients_on_data_scale().round(3))

# %% [markdown]
# ## Figures
#
# `hmm_figures` draws the standard set (what `hmmtrack fit --plot` writes). The decoded states
# are numbered from 1 and named. The transition and stationary probabilities against the hour
# carry 95 % delta-method bands; the dashed lines are the truth.

# %%
states = model.viterbi(prepared)
figures = plots.hmm_figures(model, prepared, states, NAMES)
hour_grid = diagnostics.covariate_grid(model, prepared, "hour")
true_gamma = truth.transition_matrix(hour_grid)
for panel, ax in enumerate(figures["transition_hour.png"].axes):
    i, j = divmod(panel, 2)
    ax.plot(hour_grid["hour"], true_gamma[:, i, j], color="black", ls="--", lw=1)
if out is not None:
    Path(out).mkdir(parents=True, exist_ok=True)
    for name, figure in figures.items():
        figure.savefig(Path(out) / name, dpi=100)
agreement = np.mean(states == simulated["state"].to_numpy())
print(f"decoded states equal to the simulated ones at {agreement:.1%} of the grid times")
print(sorted(figures))

# %% [markdown]
# What the figures say: the travelling state and the time-of-day effect are recovered (the
# true curves run inside or along the bands), and the decoded states match the simulated ones
# at about nine grid times in ten. The foraging state is where a smoothed track misleads: the
# Kalman smoother draws the smoothest path through the fixes, so the simulated reversals
# (turning angles about π) come out as gentle turns about 0, and the pseudo-residuals of both
# streams are autocorrelated at lags 1-2 (`residuals.png`, ACF panels): neighbouring smoothed
# positions share the same fixes. Both are properties of the data processing, not of the
# animal; the residual figures are where to see them.
#
# ## Multiple imputation
#
# One predicted track hides how uncertain the positions between fixes are. Multiple
# imputation draws whole tracks from the CRW given the fixes (`crw.impute`), fits the HMM to
# each and pools the working-scale estimates by Rubin's rules. `fraction_missing` is the
# share of each parameter's variance due to the missing positions. Drawn tracks wiggle
# between fixes as a CRW does, so the short foraging steps come out longer than on the
# smoothed track: the imputation model should be as tortuous as the animal for them to agree.

# %%
draws = crw.impute(fixes, STEP, n_draws, rng, models=models)
tables = [tracks.prepare(d.assign(hour=hour_of(d["time"]))) for d in draws]
imputed = fit_imputed(tables, 2, seed=1, formula=FORMULA, n_starts=n_starts)
print("step means: smoothed track", model.step.mean.round(1), "; pooled over imputations",
      imputed.model.step.mean.round(1), "; truth", truth.step.mean)  # fmt: skip
pooled_table(imputed).round(3).head(6)

# %% [markdown]
# ## Trusting the fit, and constraining it
#
# EM climbs to a local maximum. `diagnostics.check_starts` fits from many random starting
# values (`hmmtrack fit --check-starts N`) and tabulates where each start ended; the figure
# shows the log-likelihood each reached and how far each parameter lies from the best start's.
# Starts that agree on the best optimum with the same parameters make the fit trustworthy.

# %%
starts = diagnostics.check_starts(prepared, 2, n_starts=n_check, rng=seed, formula=FORMULA)
figure = plots.starts_figure(starts)
if out is not None:
    figure.savefig(Path(out) / "starts.png", dpi=100)
starts[["start", "log_likelihood", "n_iter", "best", "step.mean[1]", "step.mean[2]"]]

# %% [markdown]
# The travelling state was simulated going straight on (turning-angle mean 0). Fixing that
# mean (`fixed={"angle.mean[2]": 0}`, states numbered from 1; `--fix 'angle.mean[2]=0'`)
# removes a parameter, and `stationary=True` makes the initial distribution the stationary
# distribution of the transition matrix at each track's first hour rather than a parameter
# (momentuHMM's `stationary = TRUE`). The fixed parameter prints "fixed" instead of a standard
# error; the control and the state names are saved in the model file.

# %%
constrained = MovementHMMEstimator(
    2, formula=FORMULA, fixed={"angle.mean[2]": 0.0}, stationary=True, state_names=NAMES,
    n_starts=n_starts, seed=1,
).fit(prepared).model_  # fmt: skip
print(diagnostics.summary(constrained, diagnostics.confidence_intervals(constrained, prepared)))
print(f"AIC free {model.aic:.2f}, constrained {constrained.aic:.2f}")
reloaded = MovementHMM.from_dict(constrained.to_dict())
print("saved:", reloaded.state_names, reloaded.control)

# %% [markdown]
# The share of time in each state against the hour, from the fit to the smoothed track, with
# its 95 % band (`diagnostics.covariate_effects`) and the truth (dashed):

# %%
effects = diagnostics.covariate_effects(model, prepared, "hour")
ax = plots.stationary_probability_plot(effects, "hour (UTC)", NAMES)
true_share = truth.stationary(hour_grid)
for k in range(2):
    ax.plot(hour_grid["hour"], true_share[:, k], color="black", ls="--", lw=1)
ax.set_xticks(range(0, 25, 6))
plt.show()
