"""``hmmtrack reproduce --quick`` writes the summary, the trial tables and every figure."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from hmmtrack.cli import build_parser, main
from hmmtrack.cli.reproduce import FILTER_NAMES
from hmmtrack.experiments import MOTIONS
from hmmtrack.report import PAPER, QUICK
from hmmtrack.tracking.filter import FILTERS

FIGURES = (
    "datasets.png",
    "white_shark_hmm.png",
    "motion_model_comparison.png",
    "example_stationary-tag.png",
    "example_swimmer.png",
    "example_shark-pursuit.png",
    "measurement_loss.png",
    "depth.png",
)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reports")
    code = main(
        [
            "reproduce",
            "--quick",
            "--out",
            str(out),
            "--trials",
            "1",
            "--particles",
            "60",
            "--workers",
            "1",
            "--seed",
            "3",
            "--no-progress",
        ]
    )
    assert code == 0
    return out


def test_quick_run_writes_every_figure(quick_run):
    for name in FIGURES:
        path = quick_run / name
        assert path.is_file(), f"missing {name}"
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert 10_000 < path.stat().st_size < 1_000_000


def test_quick_run_tables_hold_every_trial(quick_run):
    comparison = pd.read_csv(quick_run / "motion_model_trials.csv")
    # one filter run per model on each of the quick run's synthetic datasets per scenario
    assert len(comparison) == 3 * QUICK.n_datasets * len(MOTIONS)
    assert set(comparison["scenario"]) == set(PAPER["datasets"])
    assert sorted(set(comparison["dataset"])) == list(range(QUICK.n_datasets))
    assert (comparison["n_particles"] == 60).all()
    loss = pd.read_csv(quick_run / "loss_sweep_trials.csv")
    assert sorted(loss["loss_fraction"]) == sorted(QUICK.loss_fractions)
    assert (loss["motion"] == "hmm").all()
    depth = pd.read_csv(quick_run / "depth_trials.csv")
    assert sorted(depth["depth_correction"]) == [False, True]


def test_summary_puts_our_numbers_beside_the_papers(quick_run):
    text = (quick_run / "summary.md").read_text()
    assert "synthetic analogues" in text
    for number in ("5.42", "12.31", "970", "13.6", "43.8", "1342", "391.6", "18.4"):
        assert number in text, number
    comparison = pd.read_csv(quick_run / "motion_model_trials.csv")
    hmm_shark = comparison[
        (comparison["scenario"] == "shark-pursuit") & (comparison["motion"] == "hmm")
    ]
    ours = hmm_shark["mean_error_after_convergence"].mean()  # the cell's mean over its trials
    assert f"| hmm | {ours:.3g} | 13.62 |" in text
    for name in FIGURES:
        assert f"]({name})" in text
    assert "The paper's findings on our analogues" in text
    # the run's configuration, by default the mode-keeping filter from the known start
    assert "filter = mode-keeping (acquisition + mixture + long_gap)" in text
    assert "start = the scenario's start region where it records one" in text
    assert "these runs start where the field team knew the tag to be" in text
    assert "## Spread between datasets and between filter runs" in text
    assert "## What the calibration figures rest on" in text
    assert f"With {QUICK.n_datasets} datasets a calibrated cell's share moves" in text


def test_bad_arguments_are_reported_without_traceback(capsys):
    assert main(["reproduce", "--trials", "0"]) == 2
    assert "--trials must be a positive integer" in capsys.readouterr().err


def _trials(errors: dict[str, list[float]], scenario: str = "shark-pursuit") -> pd.DataFrame:
    rows = [
        {
            "scenario": scenario,
            "motion": motion,
            "trial": k,
            "loss_fraction": 0.0,
            "depth_correction": False,
            "n_particles": 10,
            "time_to_convergence": 30.0,
            "converged": True,
            "mean_error_after_convergence": e,
            "rmse_after_convergence": e,
            "runtime": 0.0,
        }
        for motion, values in errors.items()
        for k, e in enumerate(values)
    ]
    return pd.DataFrame(rows)


def test_findings_hold_on_paper_like_tables_and_fail_otherwise():
    from hmmtrack.report import check_findings

    spread = np.linspace(0.0, 5.0, 12)
    paper_like = _trials(
        {
            "baseline": list(900 + 20 * spread),
            "velocity": list(30 + spread),
            "hmm": list(12 + spread),
        }
    )
    verdicts = {f.claim: f.holds for f in check_findings(paper_like, None)}
    assert all(verdicts.values()) and len(verdicts) == 2
    # the baseline does not diverge, and the velocity model beats the HMM
    unlike = _trials(
        {"baseline": list(40 + 2 * spread), "velocity": list(10 + spread), "hmm": list(12 + spread)}
    )
    findings = check_findings(unlike, None)
    assert [f.holds for f in findings] == [False, False]
    assert "velocity 12.5 m" in findings[0].evidence
    # two trials a model cannot decide which model is lowest, however far apart the means
    few = _trials({"baseline": [900.0, 1100.0], "velocity": [30.0, 35.0], "hmm": [12, 15]})
    assert [f.holds for f in check_findings(few, None)] == [None, True]


def _paired_trials(scenario, column, by_model, datasets):
    """Trials of ``datasets`` (one run each) whose ``column`` is ``by_model[m]`` (arrays in
    dataset order); the other figures fixed."""
    rows = []
    for motion, values in by_model.items():
        for d, value in zip(datasets, values, strict=True):
            rows.append(
                {
                    "scenario": scenario,
                    "dataset": d,
                    "motion": motion,
                    "trial": 0,
                    "loss_fraction": 0.0,
                    "depth_correction": False,
                    "n_particles": 10,
                    "time_to_convergence": 20.0,
                    "converged": True,
                    "mean_error_after_convergence": 5.0,
                    "rmse_after_convergence": 5.0,
                    "runtime": 0.0,
                    column: value,
                }
            )
    return pd.DataFrame(rows)


def test_lowest_error_is_tested_pair_by_pair_across_datasets():
    from scipy import stats

    from hmmtrack.report.findings import ranked_first

    rng = np.random.default_rng(3)
    column = "mean_error_after_convergence"
    dataset_effect = rng.gamma(2.0, 10.0, size=30)  # datasets differ by tens of metres
    hmm = dataset_effect + rng.normal(0.0, 0.05, size=30)
    velocity = dataset_effect + 0.1 + rng.normal(0.0, 0.05, size=30)
    baseline = dataset_effect + 50.0
    order = rng.permutation(30)  # rows of each model in another order: pairs are by dataset
    models = {"baseline": baseline, "velocity": velocity[order], "hmm": hmm}
    datasets = {"baseline": np.arange(30), "velocity": order, "hmm": np.arange(30)}
    rows = pd.concat(_paired_trials("swimmer", column, {m: models[m]}, datasets[m]) for m in models)
    holds, evidence = ranked_first(rows, "swimmer", column, "hmm")
    expected = stats.wilcoxon(hmm, velocity, alternative="less").pvalue
    assert holds is True and expected < 1e-4
    assert f"hmm against velocity over 30 datasets: p = {expected:.2g} (hmm lower)" in evidence
    # the same values unpaired (the velocity model's datasets shuffled) decide nothing
    shuffled = rows.assign(
        dataset=np.where(
            rows["motion"] == "velocity", rng.permutation(30)[rows["dataset"]], rows["dataset"]
        )
    )
    assert ranked_first(shuffled, "swimmer", column, "hmm")[0] is None
    # the reverse: the velocity model lower in every pair
    swapped = rows.assign(motion=rows["motion"].replace({"hmm": "velocity", "velocity": "hmm"}))
    assert ranked_first(swapped, "swimmer", column, "hmm")[0] is False


def test_a_tie_on_the_swimmer_reads_undecided_in_the_summary(tmp_path):
    from hmmtrack.report import write_summary
    from hmmtrack.report.markdown import fmt

    rng = np.random.default_rng(4)
    datasets = np.arange(40)
    errors = rng.gamma(2.0, 2.0, size=40)
    tie = {  # the HMM and the velocity model equal up to noise; the HMM converges slowest
        "baseline": errors + 20.0,
        "velocity": errors + rng.normal(0.0, 0.1, size=40),
        "hmm": errors + rng.normal(0.0, 0.1, size=40),
    }
    rows = _paired_trials("swimmer", "mean_error_after_convergence", tie, datasets)
    rows.loc[rows["motion"] == "hmm", "time_to_convergence"] = 30.0 + np.arange(40) / 40
    text = write_summary(tmp_path / "summary.md", comparison=rows).read_text()
    line = next(x for x in text.splitlines() if "Santa Elena Bay (swimmer): the HMM" in x)
    assert line.startswith("- **undecided by the trials**")
    assert "hmm against velocity over 40 datasets" in line
    velocity = fmt(float(np.mean(tie["velocity"])))
    assert f"the mean error after convergence is {velocity} m with the velocity model" in text


def test_loss_findings_use_the_paper_bands():
    from hmmtrack.report import check_findings

    def sweep(error_by_fraction):
        table = _trials({"hmm": list(error_by_fraction.values())})
        fraction = pd.Series(list(error_by_fraction), dtype=float)
        return table.assign(loss_fraction=fraction, time_to_convergence=40.0 * np.exp(5 * fraction))

    usable = sweep({0.0: 15.0, 0.1: 16.0, 0.5: 40.0, 0.8: 60.0, 0.9: 400.0, 1.0: 1800.0})
    assert [f.holds for f in check_findings(None, usable)] == [True, True, True]
    # unusable in the middle band; the error does not grow drastically above 80 %
    broken = sweep({0.0: 15.0, 0.5: 400.0, 0.9: 300.0})
    findings = check_findings(None, broken)
    assert [f.holds for f in findings] == [False, True, False]
    assert "20–80 % 400 m" in findings[2].evidence


def test_depth_finding_needs_a_paired_difference_beyond_the_trial_spread():
    from hmmtrack.report import check_findings

    def table(without, with_correction):
        rows = [(k, False, e) for k, e in enumerate(without)]
        rows += [(k, True, e) for k, e in enumerate(with_correction)]
        columns = ["trial", "depth_correction", "mean_error_after_convergence"]
        return pd.DataFrame(rows, columns=columns)

    bimodal = [9.0, 81.0, 78.0, 9.1, 81.2, 80.9, 78.5, 9.2, 81.1, 9.0]
    # pair by pair, the trials swap modes both ways: noise, not an effect
    shuffled = [9.2, 80.8, 9.3, 9.4, 76.7, 81.4, 9.3, 80.8, 9.3, 79.8]
    (noise,) = check_findings(None, None, table(bimodal, shuffled))
    assert noise.holds is False and "p = " in noise.evidence
    assert "paired trials" in noise.evidence
    # a small shift that every pair shows is an effect, although the modes swamp it unpaired
    shifted = [e - 1.0 for e in bimodal]
    (clear,) = check_findings(None, None, table(bimodal, shifted))
    assert clear.holds is True and "in 10 of 10 paired trials" in clear.evidence


def test_paired_p_value_equals_the_exact_sign_flip_distribution():
    from itertools import product

    from hmmtrack.report.findings import paired_lower_p_value

    rng = np.random.default_rng(4)
    a = rng.normal(0.0, 1.0, 9)
    b = a + rng.normal(0.4, 1.0, 9)
    d = a - b
    ranks = pd.Series(np.abs(d)).rank().to_numpy()
    observed = ranks[d > 0].sum()
    # under the null every sign pattern is equally likely: W+ at most the observed one
    flips = [ranks[np.array(signs, dtype=bool)].sum() for signs in product((0, 1), repeat=9)]
    exact = np.mean(np.array(flips) <= observed)
    assert paired_lower_p_value(a, b) == pytest.approx(exact, rel=1e-12)
    assert paired_lower_p_value(a, a) == 1.0
    with pytest.raises(ValueError, match="one shape"):
        paired_lower_p_value(a, b[:5])


def test_the_filter_option_offers_every_named_filter():
    assert FILTER_NAMES == tuple(FILTERS)
    parser = build_parser(["reproduce"])
    assert parser.parse_args(["reproduce"]).filter == "mode-keeping"
    assert parser.parse_args(["reproduce", "--filter", "paper"]).filter == "paper"
    assert parser.parse_args(["reproduce"]).start_prior
    assert not parser.parse_args(["reproduce", "--no-start-prior"]).start_prior


def test_the_measurement_option_is_the_gps_one_by_default_and_offers_the_paper_s():
    parser = build_parser(["reproduce"])
    assert parser.parse_args(["reproduce"]).measurement == "range-rate-gps"
    chosen = parser.parse_args(["reproduce", "--measurement", "range-rate"])
    assert chosen.measurement == "range-rate"
