"""The notebooks run end to end with small parameters and write the figures they promise.

Each ``notebooks/*.py`` (jupytext percent format) is converted to a notebook, executed with
papermill (its ``parameters`` cell overridden) and checked for its saved figure and for the
outputs of its cells.
"""

from __future__ import annotations

from pathlib import Path

import pytest

jupytext = pytest.importorskip("jupytext")
papermill = pytest.importorskip("papermill")

NOTEBOOKS = Path(__file__).resolve().parents[1] / "notebooks"

#: small parameters per notebook, and the figures each must write into ``out``
CASES = {
    "01_fit_motion_hmm.py": (
        {"n_sharks": 4, "n_positions": 3000, "n_starts": 2, "seed": 1},
        ["white_shark_hmm.png"],
    ),
    "02_motion_model_comparison.py": (
        {"n_trials": 1, "n_particles": 100, "workers": 1, "duration": 600.0},
        ["motion_model_comparison.png", "example_trial.png"],
    ),
    "03_measurement_loss.py": (
        {
            "n_trials": 1,
            "n_particles": 100,
            "workers": 1,
            "fractions": [0.0, 0.5, 0.9],
            "duration": 900.0,
        },
        ["measurement_loss.png"],
    ),
    "04_depth_correction.py": (
        {"n_trials": 1, "n_particles": 100, "workers": 1, "duration": 900.0},
        ["depth.png"],
    ),
    "05_clock_aware_tracking.py": (
        {"seed": 1, "duration": 1200.0, "n_particles": 800},
        ["tag_clock.png", "clock_aware_tracking.png"],
    ),
    "06_movement_hmm_workflow.py": (
        {"seed": 1, "n_steps": 720, "n_draws": 2, "n_starts": 1, "n_check": 3},
        ["densities.png", "residuals.png", "tracks.png", "transition_hour.png", "starts.png"],
    ),
}


def test_every_notebook_has_a_case():
    assert sorted(p.name for p in NOTEBOOKS.glob("*.py")) == sorted(CASES)


@pytest.mark.parametrize("name", sorted(CASES))
def test_notebook_runs_and_writes_its_figures(name, tmp_path):
    parameters, figures = CASES[name]
    notebook = jupytext.read(NOTEBOOKS / name)
    tagged = [c for c in notebook.cells if "parameters" in c.get("metadata", {}).get("tags", [])]
    assert len(tagged) == 1, f"{name} needs exactly one cell tagged 'parameters'"
    source = tmp_path / name.replace(".py", ".ipynb")
    jupytext.write(notebook, source)
    out = tmp_path / "figures"
    executed = papermill.execute_notebook(
        str(source),
        str(tmp_path / ("run_" + source.name)),
        parameters={**parameters, "out": str(out)},
        kernel_name="python3",
        cwd=str(NOTEBOOKS),
        progress_bar=False,
    )
    for figure in figures:
        assert (out / figure).stat().st_size > 10_000, f"{name} did not write {figure}"
    code = [c for c in executed.cells if c.cell_type == "code"]
    assert all(c.metadata.papermill.exception is False for c in code)
    # the last cell of each notebook draws its figure inline
    assert any(o.get("output_type") == "display_data" for o in code[-1].outputs)
