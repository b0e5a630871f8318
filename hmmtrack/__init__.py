"""hmmtrack: movement hidden Markov models and particle-filter tracking of tagged marine animals.

The package has three halves that meet in one file format:

* :mod:`hmmtrack.tracks` / :mod:`hmmtrack.io` read animal tracks and detection logs;
* :mod:`hmmtrack.hmm` fits movement HMMs (step length / turning angle) and saves them
  as versioned JSON (:class:`hmmtrack.hmm.MovementHMM`);
* :mod:`hmmtrack.tracking.filter` estimates where an acoustically tagged animal is from the
  detection times logged by single hydrophones, using a fitted HMM as motion prior.
"""

__version__ = "0.1.0"
