"""The ground-truth white-shark movement model: a documented 2-state HMM that simulations draw from.

The paper fits its motion model to 124k positions of 22 white sharks that are not public. We
replace them with tracks drawn from a known model, so that the fitter can be checked against
the truth. The model is the moveHMM-style correlated random walk on a fixed time step
``dt``: at each vertex a behavioural state is drawn from a Markov chain, the heading turns by
a von Mises angle of that state and the animal swims a straight gamma-distributed step. The
path between vertices is a straight line at constant speed, so positions are exact at any
time (:class:`~hmmtrack.scenarios.trajectory.Trajectory`) and sampling at irregular times is
faithful. Observed at exactly ``dt`` on the simulation grid, the steps and turning angles are
the model's own draws, which makes parameter recovery a sharp test.

Parameters of :data:`WHITE_SHARK_GROUND_TRUTH` (``dt`` = 60 s) and why:

* *resident* (state 0): slow and tortuous, as white sharks patrolling a small stretch of
  coast: mean step 27 m (0.45 m/s), sd 18 m; turning angle von Mises(0, 0.8), so headings
  decorrelate within a few minutes;
* *transit* (state 1): fast and directed, cruising at about 1.1 m/s (the ~1 m/s cruising
  speed of white sharks): mean step 66 m, sd 21 m; von Mises(0, 8), a typical turn of
  ~20 degrees per minute;
* transition probabilities per minute: stay resident 0.96 (mean bout 25 min), stay in
  transit 0.94 (mean bout 17 min), so about 60 % of the time is spent resident and bouts are
  long compared with the 1-3 min between fixes of a receiver array.

This module is for *simulating* movement; fitting is :mod:`hmmtrack.hmm` and sampling like a
receiver array is :mod:`hmmtrack.scenarios.historical`.
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from hmmtrack.scenarios.trajectory import Trajectory


@dataclass(frozen=True)
class SharkMotionModel:
    """A K-state movement HMM with gamma steps and von Mises turning angles of mean 0.

    Parameters
    ----------
    dt : float
        Time step (s) between vertices.
    initial : (K,) float array
        Probabilities of the first state.
    transition : (K, K) float array
        ``transition[i, j]`` = P(state j at the next vertex | state i), per ``dt``.
    step_mean, step_sd : (K,) float arrays
        Mean and standard deviation (m) of the gamma step length per state.
    angle_concentration : (K,) float array
        von Mises concentration of the turning angle (rad) per state; the mean is 0.
    state_names : tuple of str
        A name per state.
    """

    dt: float
    initial: np.ndarray
    transition: np.ndarray
    step_mean: np.ndarray
    step_sd: np.ndarray
    angle_concentration: np.ndarray
    state_names: tuple[str, ...]

    def __post_init__(self) -> None:
        for name in ("initial", "transition", "step_mean", "step_sd", "angle_concentration"):
            values = np.array(getattr(self, name), dtype=float)
            values.setflags(write=False)
            object.__setattr__(self, name, values)
        k = self.initial.size
        shapes = {
            "transition": (k, k),
            "step_mean": (k,),
            "step_sd": (k,),
            "angle_concentration": (k,),
        }
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ValueError(
                    f"SharkMotionModel: {name} has shape {getattr(self, name).shape}, "
                    f"expected {shape} for {k} states"
                )
        if len(self.state_names) != k:
            raise ValueError(f"SharkMotionModel: {len(self.state_names)} state names, {k} states")
        if not np.allclose(self.transition.sum(axis=1), 1.0) or not np.isclose(
            self.initial.sum(), 1.0
        ):
            raise ValueError("SharkMotionModel: initial and transition rows must sum to 1")
        if self.dt <= 0 or np.any(self.step_mean <= 0) or np.any(self.step_sd <= 0):
            raise ValueError("SharkMotionModel: dt, step_mean and step_sd must be positive")

    @property
    def n_states(self) -> int:
        """Number of behavioural states K."""
        return self.initial.size

    @property
    def speed_mean(self) -> np.ndarray:
        """Mean swimming speed per state (m/s), ``step_mean / dt``; shape (K,)."""
        return self.step_mean / self.dt

    def stationary(self) -> np.ndarray:
        """Stationary distribution of the state chain, shape (K,)."""
        values, vectors = np.linalg.eig(self.transition.T)
        vector = np.real(vectors[:, np.argmin(np.abs(values - 1.0))])
        return vector / vector.sum()

    def simulate_states(self, rng: np.random.Generator, n: int) -> np.ndarray:
        """Draw a state sequence of length ``n`` (ints in ``0..K-1``) from the Markov chain."""
        last = self.n_states - 1
        cumulative = np.cumsum(self.transition, axis=1).tolist()
        u = rng.random(n).tolist()
        state = min(bisect.bisect_right(np.cumsum(self.initial).tolist(), u[0]), last)
        states = [state]
        for draw in u[1:]:
            state = min(bisect.bisect_right(cumulative[state], draw), last)
            states.append(state)
        return np.array(states, dtype=np.int64)

    def simulate_path(
        self,
        rng: np.random.Generator,
        n_steps: int,
        *,
        start_time: float,
        start_x: float = 0.0,
        start_y: float = 0.0,
    ) -> tuple[Trajectory, np.ndarray]:
        """Simulate a continuous path of ``n_steps`` steps of ``dt`` seconds.

        Parameters
        ----------
        rng : numpy.random.Generator
        n_steps : int
            Number of steps; the path has ``n_steps + 1`` vertices at
            ``start_time + k * dt``.
        start_time : float
            Time (UTC s) of the first vertex.
        start_x, start_y : float
            Position (m) of the first vertex; the first heading is uniform.

        Returns
        -------
        path : Trajectory
            Straight lines at constant speed between the vertices.
        states : (n_steps,) int array
            State of each step: step ``k`` (vertex ``k`` to ``k + 1``) and the turn at vertex
            ``k`` (between steps ``k - 1`` and ``k``) belong to ``states[k]``.
        """
        if n_steps < 1:
            raise ValueError(f"simulate_path: n_steps must be >= 1, got {n_steps}")
        states = self.simulate_states(rng, n_steps)
        mean, sd = self.step_mean[states], self.step_sd[states]
        steps = rng.gamma(shape=(mean / sd) ** 2, scale=sd**2 / mean)
        turns = rng.vonmises(0.0, self.angle_concentration[states])
        turns[0] = rng.uniform(-np.pi, np.pi)  # the first heading, not a turn
        heading = np.cumsum(turns)
        x = start_x + np.concatenate([[0.0], np.cumsum(steps * np.cos(heading))])
        y = start_y + np.concatenate([[0.0], np.cumsum(steps * np.sin(heading))])
        time = start_time + self.dt * np.arange(n_steps + 1)
        return Trajectory(time, x, y), states


#: the documented ground truth of the synthetic white-shark tracks (see the module docstring)
WHITE_SHARK_GROUND_TRUTH = SharkMotionModel(
    dt=60.0,
    initial=np.array([0.6, 0.4]),
    transition=np.array([[0.96, 0.04], [0.06, 0.94]]),
    step_mean=np.array([27.0, 66.0]),
    step_sd=np.array([18.0, 21.0]),
    angle_concentration=np.array([0.8, 8.0]),
    state_names=("resident", "transit"),
)
