"""Benchmark: one E-step pass (forward, backward, posteriors, expected transition counts)
over 100,000 observations, hmmtrack's numba kernels vs hmmlearn's compiled C++ recursions
(log space and scaled) on the same log-likelihood matrix, in the same run.

Run: ``python benchmarks/bench_inference.py [--n-obs 100000] [--repeats 20]``.
Prints milliseconds per pass (best of ``repeats``), the ratio hmmlearn / hmmtrack, and the
machine (CPU, cores, load) at the start and the end.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from hmmlearn import _hmmc
from machine import describe

from hmmtrack.hmm.inference import forward_backward, viterbi


def best_ms(function, repeats: int) -> float:
    """Best wall-clock time of ``repeats`` calls, in milliseconds (first call excluded)."""
    function()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return 1e3 * min(times)


def hmmlearn_log_pass(startprob, transmat, log_lik):
    total, fwd = _hmmc.forward_log(startprob, transmat, log_lik)
    bwd = _hmmc.backward_log(startprob, transmat, log_lik)
    posterior = np.exp(fwd + bwd - total)
    counts = np.exp(_hmmc.compute_log_xi_sum(fwd, transmat, bwd, log_lik))
    return total, posterior, counts


def hmmlearn_scaled_pass(startprob, transmat, log_lik):
    lik = np.exp(log_lik)  # hmmlearn's scaled path needs likelihoods, not logs
    total, fwd, scaling = _hmmc.forward_scaling(startprob, transmat, lik)
    bwd = _hmmc.backward_scaling(startprob, transmat, lik, scaling)
    posterior = fwd * bwd
    posterior /= posterior.sum(axis=1, keepdims=True)
    counts = _hmmc.compute_scaling_xi_sum(fwd, transmat, bwd, lik)
    return total, posterior, counts


def problem(rng: np.random.Generator, n_obs: int, n_states: int):
    transition = np.full((n_states, n_states), 0.1 / (n_states - 1))
    np.fill_diagonal(transition, 0.9)
    startprob = np.full(n_states, 1.0 / n_states)
    log_lik = rng.normal(scale=2.0, size=(n_obs, n_states))
    return startprob, transition, log_lik


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-obs", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print(describe("start"), flush=True)

    start = time.perf_counter()
    forward_backward(np.log([0.5, 0.5]), np.log([[0.9, 0.1], [0.1, 0.9]]), np.zeros((3, 2)))
    print(f"first call (compile or load numba cache): {time.perf_counter() - start:.2f} s")
    # warm up the allocator with the largest problem, so the first row is not penalised
    startprob, transmat, log_lik = problem(rng, args.n_obs, 3)
    for _ in range(3):
        forward_backward(np.log(startprob), np.log(transmat), log_lik)
        hmmlearn_log_pass(startprob, transmat, log_lik)
    print(f"{args.n_obs} observations, best of {args.repeats} passes")
    header = f"{'K':>2} {'hmmtrack fb':>12} {'viterbi':>9} {'hmmlearn log':>13} {'scaled':>9}"
    print(header + f" {'ratio log':>10} {'ratio scaled':>13}")
    for n_states in (2, 3):
        startprob, transmat, log_lik = problem(rng, args.n_obs, n_states)
        log_pi, log_a = np.log(startprob), np.log(transmat)
        ours = forward_backward(log_pi, log_a, log_lik)
        reference = hmmlearn_log_pass(startprob, transmat, log_lik)
        if not np.isclose(ours.log_likelihood, reference[0], rtol=1e-9):
            raise SystemExit(f"log-likelihoods differ: {ours.log_likelihood} vs {reference[0]}")
        ms_ours = best_ms(lambda: forward_backward(log_pi, log_a, log_lik), args.repeats)  # noqa: B023
        ms_viterbi = best_ms(lambda: viterbi(log_pi, log_a, log_lik), args.repeats)  # noqa: B023
        ms_log = best_ms(lambda: hmmlearn_log_pass(startprob, transmat, log_lik), args.repeats)  # noqa: B023
        ms_scaled = best_ms(
            lambda: hmmlearn_scaled_pass(startprob, transmat, log_lik),  # noqa: B023
            args.repeats,
        )
        print(
            f"{n_states:>2} {ms_ours:>9.2f} ms {ms_viterbi:>6.2f} ms {ms_log:>10.2f} ms "
            f"{ms_scaled:>6.2f} ms {ms_log / ms_ours:>9.1f}x {ms_scaled / ms_ours:>12.1f}x"
        )
    print(describe("end"))


if __name__ == "__main__":
    main()
