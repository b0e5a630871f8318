"""Speed of sound in sea water from temperature, salinity and depth.

Mackenzie's nine-term equation (Mackenzie, K. V. 1981, "Nine-term equation for sound speed
in the oceans", J. Acoust. Soc. Am. 70(3), 807-812, doi:10.1121/1.386920), valid for
temperature -2 to 30 degC, salinity 25 to 40, depth 0 to 8000 m, standard error 0.07 m/s.
Clock synchronisation uses it when the water was measured instead of estimating the speed
from the sync tags' travel times (:func:`hmmtrack.sync.fit_clocks`).
"""

from __future__ import annotations

import numpy as np

#: the equation's stated range of validity: (low, high) per argument
MACKENZIE_RANGE = {"temperature": (-2.0, 30.0), "salinity": (25.0, 40.0), "depth": (0.0, 8000.0)}


def mackenzie_sound_speed(temperature, salinity, depth=0.0) -> np.ndarray:
    """Speed of sound (m/s) by Mackenzie's (1981) nine-term equation.

    Parameters
    ----------
    temperature : float or array
        Water temperature (degC).
    salinity : float or array
        Practical salinity (PSU, about parts per thousand).
    depth : float or array
        Depth (m, positive down).

    Returns
    -------
    ndarray
        Sound speed (m/s), the broadcast shape of the arguments.

    Raises
    ------
    ValueError
        If an argument lies outside the equation's range of validity
        (:data:`MACKENZIE_RANGE`).
    """
    values = {
        "temperature": np.asarray(temperature, dtype=float),
        "salinity": np.asarray(salinity, dtype=float),
        "depth": np.asarray(depth, dtype=float),
    }
    for name, value in values.items():
        low, high = MACKENZIE_RANGE[name]
        if np.any(~(value >= low) | ~(value <= high)):
            raise ValueError(
                f"mackenzie_sound_speed: {name} must be in [{low}, {high}] (the equation's "
                f"range of validity), got {value}"
            )
    t, s, d = values["temperature"], values["salinity"] - 35.0, values["depth"]
    return (
        1448.96
        + 4.591 * t
        - 5.304e-2 * t**2
        + 2.374e-4 * t**3
        + 1.340 * s
        + 1.630e-2 * d
        + 1.675e-7 * d**2
        - 1.025e-2 * t * s
        - 7.139e-13 * t * d**3
    )
