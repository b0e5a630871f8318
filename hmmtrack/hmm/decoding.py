"""Decoded states as a table aligned to the rows of the input file.

:func:`decode_table` is what a user of a fitted model reads: the prepared track's columns
with the Viterbi state numbered from 1 (1 = the state with the smallest mean step, as moveHMM
numbers them), an optional state name and the posterior probability of each state, one row per
row of the track file -- rows that have no state (fixes removed on reading, e.g. empty
coordinates with ``missing_coordinates="drop"``) are kept with missing values -- in file
order. Times stay UTC seconds (``hmmtrack.io.format_times`` writes them as calendar times,
as ``hmmtrack decode`` does: model code does not print times).

Not for the recursions themselves (:meth:`hmmtrack.hmm.model.MovementHMM.viterbi`,
:meth:`~hmmtrack.hmm.model.MovementHMM.state_probabilities`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from hmmtrack.hmm.model import MovementHMM, check_state_names


def decode_table(
    model: MovementHMM,
    prepared: pd.DataFrame,
    *,
    state_names: Sequence[str] | None = None,
    allow_other_step: bool = False,
) -> pd.DataFrame:
    """Viterbi states and state probabilities of a prepared track, one row per input row.

    Parameters
    ----------
    model : MovementHMM
    prepared : DataFrame
        Prepared track (:func:`hmmtrack.tracks.prepare`); read by :mod:`hmmtrack.io`, its
        index holds the file lines and ``attrs["dropped"]`` the lines removed on reading.
    state_names : sequence of str, optional
        One name per state (state 1 first), written in a ``state_name`` column; default the
        model's own (:attr:`~hmmtrack.hmm.model.MovementHMM.state_names`), if any.
    allow_other_step : bool
        Decode a track whose time step is not the model's
        (:meth:`~hmmtrack.hmm.model.MovementHMM.check_time_step`).

    Returns
    -------
    DataFrame
        The columns of ``prepared``, then ``state`` (nullable integer, 1..K), ``state_name``
        (with ``state_names``) and ``p_state1`` ... ``p_stateK``. Rows in index order, the
        dropped lines included with missing values (their ``state`` is ``<NA>``); the index
        is ``prepared``'s (file lines when read from a file).
    """
    if state_names is None:
        state_names = model.state_names
    check_state_names(model.n_states, state_names)
    states = model.viterbi(prepared, allow_other_step=allow_other_step)
    probabilities = model.state_probabilities(prepared, allow_other_step=True)
    out = prepared.copy()
    out["state"] = pd.array(states + 1, dtype="Int64")
    if state_names is not None:
        out["state_name"] = np.asarray(state_names, dtype=object)[states]
    for k in range(model.n_states):
        out[f"p_state{k + 1}"] = probabilities[:, k]
    dropped = [line for entry in prepared.attrs.get("dropped", []) for line in entry["rows"]]
    if dropped:
        out = pd.concat([out, pd.DataFrame(index=pd.Index(dropped, name=out.index.name))])
        out["state"] = out["state"].astype("Int64")
    return out.sort_index(kind="stable")
