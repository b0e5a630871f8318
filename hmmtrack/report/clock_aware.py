"""The clock-aware report (``reports/clock_aware.md``): arrival-time against range-rate tracking.

:func:`write_clock_aware` runs :func:`hmmtrack.experiments.arrival.arrival_study` and writes
its tables; :func:`read_filter_errors` reads the per-run filter errors back (the bound
report sets them beside the bounds). The filters' throughput is
``benchmarks/bench_arrival.py``'s.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from hmmtrack.experiments.arrival import ARRIVAL, ArrivalStudy, arrival_study
from hmmtrack.experiments.clock_runs import DURATION
from hmmtrack.io.outputs import atomic_files
from hmmtrack.report.markdown import frame_markdown
from hmmtrack.report.studies import provenance, run_timed
from hmmtrack.tracking.measurement.sequence import GROUPING_SHARE

#: the file name of the report in its folder
FILE_NAME = "clock_aware.md"

#: how both methods are set up and what the columns mean
SETUP = """Both methods see the same detections, mapped to the common time base with the
receiver-clock calibration the scenario provides (offset error 0.1 ms, drift error
0.02 ppm). The range-rate filter is the paper's: ΔTOF ranges from the best constant period
(the mean of the true emissions) and the true range at each receiver's first detection.
The arrival-time filter knows neither: the clock phase starts unknown, the period starts at
the mean period ± 8 ms, and both are tracked per particle; it also uses the detection
curve (log p(range) for each detection, log(1 − p) for each ping a receiver should have
heard). "converged": √λ₁ fell below 10 m at some time; "error after convergence" is the
paper's mean error from then on; "first 5 min", "first/last 30 min" are the same error over
the first 5 and 30 and the last 30 minutes after convergence; "error after 10 min" needs no
convergence.
"""

#: what the grouped-pings rows are and how they are set beside the arrival-time rows
GROUPING = """The same detections, grouped into pings (arrivals of one emission at several
receivers) and scored jointly against each particle's clock, the emission time integrated
out: `hmmtrack track --measurement ping-sequence --period P` with the mean period, the same
search box, particles, detection curve, smoother lag and seed as the arrival-time run. The
ratio is grouped / arrival-time of the filter's mean error from 10 min on, per seed.
"heard_by_3" is the share of the pings heard by three or more receivers; "pings_choose" is
the measurement `hmmtrack track --period P` chooses from that share when no measurement is
named (grouped where it is at least {share:.0f} %; `fixed_period_measurement`).
"""


def clock_aware_markdown(study: ArrivalStudy, written_by: str) -> str:
    """The report's Markdown: ``written_by`` (the provenance line), the setup, the summary,
    the grouped pings against arrival-time, the robustness table, the clocks of each run and
    every run."""
    return (
        "# Clock-aware tracking against the paper's range-rate method\n\n"
        f"{written_by}. Errors in metres.\n\n"
        + SETUP
        + "\n## Summary (mean over seeds)\n\n"
        + frame_markdown(study.summary)
        + "\n\n## Grouped pings (fixed period) against arrival-time\n\n"
        + GROUPING.format(share=100 * GROUPING_SHARE)
        + "\n"
        + frame_markdown(study.grouping)
        + "\n\nThe filters' throughput (arrival-time against range-rate, same particles, "
        "motion model, detections and machine) is measured by "
        "`python benchmarks/bench_arrival.py`.\n\n"
        "## Robustness: tag clocks unlike the filter's model\n\n"
        "The circling pursuit with other tag clocks, tracked with the default clock model "
        "(period random walk, 0.3 ms per ping) and with the integrated random walk sized "
        "from the real-tag facts (`EmissionClockModel.temperature_drift`); mean and worst "
        "seed:\n\n"
        + frame_markdown(study.robustness_summary)
        + "\n\n## Clocks of each run\n\n"
        + "\n".join(study.facts)
        + "\n\n## Every run\n\n"
        + frame_markdown(study.runs)
        + "\n\n### Robustness runs\n\n"
        + frame_markdown(study.robustness)
        + "\n"
    )


def write_clock_aware(
    out: Path | str,
    *,
    seeds: int = 2,
    particles: int = 3000,
    motion: str = "velocity",
    lag: int = 60,
    duration: float = DURATION,
) -> Path:
    """Run the clock-aware study and write ``out/clock_aware.md``.

    Parameters
    ----------
    out : path
        Folder (created if missing).
    seeds : int
        Scenario seeds ``0 .. seeds - 1``.
    particles : int
    motion : {"velocity", "hmm", "hmm-tc"}
    lag : int
        Smoother lag (s).
    duration : float
        Length of each run (s).

    Returns
    -------
    pathlib.Path
    """
    out = Path(out)
    study, seconds, load = run_timed(
        arrival_study,
        range(seeds),
        n_particles=particles,
        motion=motion,
        lag=lag,
        duration=duration,
    )
    command = (
        f"hmmtrack study arrival --seeds {seeds} --particles {particles} --motion {motion} "
        f"--lag {lag} --duration {duration:g}"
    )
    out.mkdir(parents=True, exist_ok=True)
    path = out / FILE_NAME
    with atomic_files(path) as (written,):
        written.write_text(clock_aware_markdown(study, provenance(command, seconds, load)))
    return path


def read_filter_errors(path: Path) -> pd.DataFrame | None:
    """Per-run arrival-time filter errors (m) from a clock-aware report, by case and seed.

    Returns
    -------
    pandas.DataFrame or None
        ``scenario``, ``seed``, ``pf_mean_after_10_min_m``,
        ``pf_smoothed_mean_after_10_min_m`` and, for the known-clock cases,
        ``pf_clock_known_mean_after_10_min_m``; None when ``path`` does not exist.
    """
    if not path.exists():
        return None
    lines = path.read_text().splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("| scenario | seed |"))
    rows = []
    for line in lines[start:]:
        if not line.startswith("|"):
            break
        rows.append([cell.strip() for cell in line.strip("|").split("|")])
    table = pd.DataFrame(rows[2:], columns=rows[0])
    out = []
    for (scenario, seed), group in table.groupby(["scenario", "seed"], sort=False):
        methods = dict(zip(group["method"], group.to_dict("records"), strict=True))
        if scenario.endswith(", true emission schedule given"):
            scenario = scenario.removeprefix("diagnostic: ").split(", true emission")[0]
        row = {"scenario": scenario, "seed": int(seed)}
        for method, record in methods.items():
            if method.startswith(ARRIVAL):
                row["pf_mean_after_10_min_m"] = float(record["error_after_10_min_m"])
                row["pf_smoothed_mean_after_10_min_m"] = float(record["smoothed_after_10_min_m"])
            elif method == "arrival-time, clock known":
                row["pf_clock_known_mean_after_10_min_m"] = float(record["error_after_10_min_m"])
        out.append(row)
    return pd.DataFrame(out).groupby(["scenario", "seed"], sort=False).first().reset_index()
