"""Write hmmtrack/data/white_shark_hmm.json: the bundled white-shark motion model.

Fits the paper's 2-state gamma / von Mises movement HMM with hmmtrack's own fitter to the
synthetic historical tracks in data/white_shark_tracks.csv.gz (split at gaps over 3 min,
regularised to 60 s; see ``hmmtrack.scenarios.white_shark_hmm``), saves it as package data
and prints the fitted parameters beside the ground truth. Run from the repository root,
after ``python data/make_white_shark_tracks.py``::

    python data/make_white_shark_hmm.py
"""

from __future__ import annotations

from pathlib import Path

from hmmtrack.io import read_tracks
from hmmtrack.scenarios.white_shark_hmm import compare_with_ground_truth, fit_white_shark_hmm
from hmmtrack.tracking.motion.registry import BUNDLED_MODEL

ROOT = Path(__file__).resolve().parents[1]
TRACKS = ROOT / "data" / "white_shark_tracks.csv.gz"
OUTPUT = ROOT / "hmmtrack" / "data" / BUNDLED_MODEL


def main() -> None:
    model = fit_white_shark_hmm(read_tracks(TRACKS), n_starts=5, seed=1)
    model.save(OUTPUT)
    print(f"wrote {OUTPUT}: log-likelihood {model.log_likelihood:.1f} on {model.n_obs} steps")
    print(compare_with_ground_truth(model).round(3).to_string(index=False))


if __name__ == "__main__":
    main()
