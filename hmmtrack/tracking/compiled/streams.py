"""Per-particle random streams and the samplers that compiled motion kernels draw from.

The compiled motion kernels (:mod:`hmmtrack.tracking.motion`) run over particles on several threads.
To give the same answer for the same seed whatever the number of threads, each particle
*slot* ``i`` owns its own random stream: a 64-bit SplitMix64 state ``streams[i]`` seeded once
from the filter's ``numpy.random.Generator``. A kernel reads the state into a register,
draws from it, and writes it back; no two threads ever share a stream. Streams stay with the
slot when particles are resampled, so copies of one ancestor diverge.

The scalar samplers below (uniform, standard normal pairs, gamma, von Mises, categorical)
are ``numba.njit`` functions that take and return the stream state. They are written from
the textbook algorithms: a 256-layer ziggurat for normals and Marsaglia & Tsang (2000) for
gamma, and for von Mises exact rejection from a 512-bin piecewise-constant envelope
whose bins are drawn with Walker's alias method. :func:`draw_uniforms` and the other ``draw_*``
helpers expose them as array functions so that tests can compare them with SciPy.

Each rejection sampler is split in two: a branch-free first try (``_normal_try``,
``_gamma_try``, ``_vonmises_try``, with a fixed number of draws and a squeeze that accepts
90-99 % of them) and the full loop (``_normal_loop``, ...) that starts again from the same
state. The scalar sampler runs the try and falls back to the loop; the motion kernels run
the tries over whole chunks of particles in vectorised loops (:func:`normals_into`) and the
loops only for the rejected few, which gives exactly the same draws.

This module does not move particles; it only makes random numbers for those that do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy import optimize, special

__all__ = [
    "draw_gamma",
    "draw_normal_pairs",
    "draw_uniforms",
    "draw_vonmises",
    "new_streams",
    "normal_pairs_into",
    "normals_into",
    "VonMisesTables",
    "alias_table",
]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_TWO_M53 = 1.0 / 9007199254740992.0  # 2**-53


def new_streams(rng: np.random.Generator, n: int) -> np.ndarray:
    """Seed ``n`` particle streams from ``rng``; returns a (n,) uint64 state array."""
    return rng.integers(0, np.iinfo(np.uint64).max, size=n, dtype=np.uint64, endpoint=True)


def _ziggurat_tables(n_layers: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """Layer edges ``x`` (n_layers + 1,) and heights ``f(x)`` of the normal ziggurat.

    ``f(x) = exp(-x^2 / 2)``; the base layer is the rectangle ``[0, r] x [0, f(r)]`` plus the
    tail beyond ``r`` and has area ``v``; every other layer is a rectangle of area ``v``
    stacked above, with ``x[0] = v / f(r)`` the base layer's virtual width and ``x[-1] = 0``.
    ``r`` is solved for so that the top layer closes exactly at height 1.
    """

    def f(x):
        return np.exp(-0.5 * x * x)

    def layers(r):
        v = r * f(r) + np.sqrt(np.pi / 2.0) * special.erfc(r / np.sqrt(2.0))
        x = np.empty(n_layers + 1)
        x[0], x[1] = v / f(r), r
        for i in range(1, n_layers):
            height = f(x[i]) + v / x[i]
            if height >= 1.0:
                return x, 1.0 - height - (n_layers - i)  # too few layers fit: r too small
            x[i + 1] = np.sqrt(-2.0 * np.log(height))
        return x, x[n_layers - 1] * (1.0 - f(x[n_layers - 1])) - v  # top layer's area error

    r = optimize.brentq(lambda r: layers(r)[1], 2.5, 5.0, xtol=1e-15)
    x = layers(r)[0]
    x[-1] = 0.0
    return x, f(x)


_ZIG_X, _ZIG_F = _ziggurat_tables()
_ZIG_R = float(_ZIG_X[1])
_S8 = np.uint64(8)
_LAYER = np.uint64(255)
_ONE = np.uint64(1)


@njit(cache=True, inline="always")
def _bits(state):
    state = state + _GOLDEN
    z = state
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31), state


@njit(cache=True, inline="always")
def uniform(state):
    """One uniform in ``(0, 1]`` (53 random bits) and the advanced state (SplitMix64)."""
    z, state = _bits(state)
    return ((z >> _S11) + _ONE) * _TWO_M53, state


@njit(cache=True)
def _normal_slow(layer, x, state):
    """Rejection part of the ziggurat for ``|x|`` outside layer ``layer``'s inner box."""
    if layer == 0:  # tail beyond r (Marsaglia's exponential method)
        while True:
            u1, state = uniform(state)
            u2, state = uniform(state)
            a = -np.log(u1) / _ZIG_R
            if -2.0 * np.log(u2) >= a * a:
                return _ZIG_R + a, True, state
    u, state = uniform(state)
    height = _ZIG_F[layer] + u * (_ZIG_F[layer + 1] - _ZIG_F[layer])
    return x, height < np.exp(-0.5 * x * x), state


@njit(cache=True, inline="always")
def _normal_from_bits(z):
    """The ziggurat's first try from 64 random bits ``z``: ``(x, accepted)``; ``x`` is a
    standard normal when ``accepted`` (about 99 % of draws: the point fell in its layer's
    inner box). Branch-free, so that loops of it vectorise."""
    layer = z & _LAYER
    x = ((z >> _S11) * _TWO_M53) * _ZIG_X[layer]
    return (-x if (z >> _S8) & _ONE else x), x < _ZIG_X[layer + 1]


@njit(cache=True, inline="always")
def _normal_try(state):
    """:func:`_normal_from_bits` of the next draw: ``(x, accepted, state)``."""
    z, state = _bits(state)
    x, accepted = _normal_from_bits(z)
    return x, accepted, state


@njit(cache=True)
def _normal_loop(state):
    """The whole ziggurat from ``state`` (its first try repeats :func:`_normal_try`)."""
    while True:
        z, state = _bits(state)
        layer = z & _LAYER
        x = ((z >> _S11) * _TWO_M53) * _ZIG_X[layer]
        if x >= _ZIG_X[layer + 1]:
            x, accepted, state = _normal_slow(layer, x, state)
            if not accepted:
                continue
        if (z >> _S8) & _ONE:
            return -x, state
        return x, state


@njit(cache=True, inline="always")
def normal(state):
    """One standard normal (256-layer ziggurat) and the advanced state."""
    x, accepted, advanced = _normal_try(state)
    if accepted:
        return x, advanced
    return _normal_loop(state)


@njit(cache=True, inline="always")
def normals_into(streams, out, retry):
    """``out[i]`` = one standard normal from ``streams[i]``, exactly as :func:`normal` draws
    it, advancing the streams; all arrays (n,) (pass slices for part of the particles).

    One branch-free (vectorised) pass of :func:`_normal_try`, then a scalar pass that
    redoes the few rejected draws; ``retry`` is boolean scratch.
    """
    for i in range(streams.size):
        old = streams[i]
        x, accepted, new = _normal_try(old)
        out[i] = x
        retry[i] = not accepted
        streams[i] = new if accepted else old
    for i in range(streams.size):
        if retry[i]:
            out[i], streams[i] = _normal_loop(streams[i])


@njit(cache=True, inline="always")
def normal_pair(state):
    """Two independent standard normals and the advanced state."""
    z1, state = normal(state)
    z2, state = normal(state)
    return z1, z2, state


@njit(cache=True, inline="always")
def normal_pairs_into(streams, first, second, retry):
    """``first[i], second[i]`` = the pair :func:`normal_pair` draws from ``streams[i]``,
    advancing the streams; all arrays (n,). The same draws as two calls of
    :func:`normals_into`, in one branch-free pass of two tries (a stream is read and
    written once) and a scalar pass that redraws both for the few whose either try was
    rejected; ``retry`` is boolean scratch."""
    for i in range(streams.size):
        old = streams[i]
        x1, accepted1, middle = _normal_try(old)
        x2, accepted2, new = _normal_try(middle)
        first[i] = x1
        second[i] = x2
        accepted = accepted1 and accepted2
        retry[i] = not accepted
        streams[i] = new if accepted else old
    for i in range(streams.size):
        if retry[i]:
            first[i], second[i], streams[i] = normal_pair(streams[i])


@njit(cache=True, inline="always")
def _log_series(y):
    """``2 (t + t^3/3 + t^5/5 + t^7/7)`` with ``t = (y - 1)/(y + 1)``, ``y > 0`` (the series
    of ``log y = 2 atanh t``), and ``t^2``. Every omitted term has the sign of ``t``, so the
    sum is below ``log y`` for ``y >= 1`` and above it for ``y <= 1``; for ``t^2 <= 1/4``
    (``1/3 <= y <= 3``) it is within ``2 |t|^9 (4/3) / 9`` of ``log y``."""
    t = (y - 1.0) / (y + 1.0)
    t2 = t * t
    return 2.0 * t * (1.0 + t2 * (1.0 / 3.0 + t2 * (0.2 + t2 * (1.0 / 7.0)))), t2


@njit(cache=True, inline="always")
def _gamma_from(shape_less_third, inv_sqrt_9d, scale, x, normal_accepted, u):
    """First try of Marsaglia & Tsang (no boost) from its normal ``x`` (and whether the
    normal's first try accepted it) and uniform ``u``: ``(value, accepted)``.

    The exact test is ``log u < x^2/2 + d (1 - v + log v)`` with ``v = (1 + c x)^3``. It is
    decided without calling ``log``: accepted when Marsaglia & Tsang's squeeze
    ``u < 1 - 0.0331 x^4`` holds (about 90 % of draws) or, failing that, when the test holds
    with ``log u`` replaced by an upper bound and ``log v`` by a lower bound
    (:func:`_log_series`, with a 1e-12 margin for rounding); only the few draws left (the
    test's own rejections and a sliver near its boundary) are not accepted here. An
    accepted try is always one the exact test accepts.
    """
    d = shape_less_third
    root = 1.0 + inv_sqrt_9d * x
    v = root * root * root
    x2 = x * x
    valid = normal_accepted and root > 0.0
    accepted = valid and u < 1.0 - 0.0331 * x2 * x2
    if valid and not accepted:
        log_u, _ = _log_series(u)  # an upper bound of log u (u <= 1)
        log_root, t2 = _log_series(root)
        t8 = t2 * t2 * t2 * t2
        below = log_root - (8.0 / 27.0) * math.sqrt(t2) * t8  # a lower bound of log(root)
        accepted = t2 <= 0.25 and log_u < 0.5 * x2 + d * (1.0 - v + 3.0 * below) - 1e-12
    return d * v * scale, accepted


@njit(cache=True, inline="always")
def _gamma_try(shape_less_third, inv_sqrt_9d, scale, state):
    """:func:`_gamma_from` of the next two draws (a normal, a uniform):
    ``(value, accepted, state)``."""
    x, normal_accepted, state = _normal_try(state)
    u, state = uniform(state)
    value, accepted = _gamma_from(shape_less_third, inv_sqrt_9d, scale, x, normal_accepted, u)
    return value, accepted, state


@njit(cache=True)
def _gamma_loop(d, c, scale, state):
    """Marsaglia & Tsang from ``state`` (its first try repeats :func:`_gamma_try`)."""
    while True:
        x, state = normal(state)
        v = 1.0 + c * x
        u, state = uniform(state)
        if v <= 0.0:
            continue
        v = v * v * v
        x2 = x * x
        if u < 1.0 - 0.0331 * x2 * x2 or np.log(u) < 0.5 * x2 + d * (1.0 - v + np.log(v)):
            return d * v * scale, state


@njit(cache=True, inline="always")
def gamma(shape_less_third, inv_sqrt_9d, boost_exponent, scale, state):
    """One gamma variate (Marsaglia & Tsang) and the advanced state.

    Parameters are precomputed per behavioural state by :func:`gamma_constants`:
    ``d = a - 1/3`` with ``a = shape`` (or ``shape + 1`` when ``shape < 1``),
    ``c = 1 / sqrt(9 d)``, and ``boost_exponent = 1/shape`` when ``shape < 1`` (a
    Gamma(shape + 1) draw times ``U**(1/shape)`` is Gamma(shape)), else 0. The result is
    multiplied by ``scale``. Each try draws one normal and one uniform.
    """
    value, accepted, advanced = _gamma_try(shape_less_third, inv_sqrt_9d, scale, state)
    if not accepted:
        value, advanced = _gamma_loop(shape_less_third, inv_sqrt_9d, scale, state)
    if boost_exponent > 0.0:
        u, advanced = uniform(advanced)
        value *= u**boost_exponent
    return value, advanced


def gamma_constants(shape: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-shape constants ``(d, c, boost_exponent)`` of :func:`gamma`, arrays like ``shape``."""
    shape = np.asarray(shape, dtype=np.float64)
    if np.any(~np.isfinite(shape) | (shape <= 0)):
        raise ValueError(f"gamma shapes must be finite and positive, got {shape}")
    boosted = shape < 1.0
    d = np.where(boosted, shape + 1.0, shape) - 1.0 / 3.0
    return d, 1.0 / np.sqrt(9.0 * d), np.where(boosted, 1.0 / shape, 0.0)


#: bins of the piecewise-constant envelope of the von Mises sampler (a power of two)
VONMISES_BINS = 512
_BIN = np.uint64(VONMISES_BINS - 1)  # the bin is drawn from the low 9 bits...
_S9 = np.uint64(9)  # ... and the sign from bit 9
#: the envelope stops where the density has fallen to exp(-_VONMISES_DROP) ~ 5e-32 of its
#: peak (when that happens before the antipode), i.e. ``kappa (1 - cos d) = 72``
_VONMISES_DROP = 72.0


@dataclass(frozen=True)
class VonMisesTables:
    """Per-state tables of :func:`vonmises`, each of shape ``(K, VONMISES_BINS)``.

    The deviation ``d = |angle - mean|`` has density ``f(d) = exp(kappa (cos d - 1))`` on
    ``[0, reach]``; bin ``b`` of width ``reach / VONMISES_BINS`` is enveloped by its left
    height ``f_left`` (``f`` decreases) and squeezed by its right height ``f_right``. Bins
    are chosen with Walker's alias method (``alias_cut``, ``alias``).
    """

    mean: np.ndarray  # (K,)
    concentration: np.ndarray  # (K,)
    width: np.ndarray  # (K,) bin width, rad
    f_left: np.ndarray
    f_right: np.ndarray
    alias_cut: np.ndarray
    alias: np.ndarray

    @classmethod
    def build(cls, mean, concentration) -> VonMisesTables:
        """Tables for von Mises distributions with the given means and concentrations (K,)."""
        mean = np.atleast_1d(np.asarray(mean, dtype=np.float64))
        kappa = np.atleast_1d(np.asarray(concentration, dtype=np.float64))
        if np.any(~np.isfinite(kappa) | (kappa < 0)) or np.any(~np.isfinite(mean)):
            raise ValueError(
                f"von Mises means must be finite and concentrations finite and >= 0, "
                f"got means {mean}, concentrations {kappa}"
            )
        far = kappa > _VONMISES_DROP / 2.0
        cos_reach = 1.0 - _VONMISES_DROP / np.where(far, kappa, _VONMISES_DROP / 2.0)
        reach = np.where(far, np.arccos(cos_reach), np.pi)
        edges = reach[:, None] * np.arange(VONMISES_BINS + 1)[None, :] / VONMISES_BINS
        height = np.exp(kappa[:, None] * (np.cos(edges) - 1.0))
        cut, alias = zip(*(alias_table(row) for row in height[:, :-1]), strict=True)
        return cls(
            mean=mean,
            concentration=kappa,
            width=reach / VONMISES_BINS,
            f_left=height[:, :-1].copy(),
            f_right=height[:, 1:].copy(),
            alias_cut=np.array(cut),
            alias=np.array(alias),
        )

    def as_tuple(self) -> tuple:
        """The arrays in the order :func:`vonmises` unpacks them; the per-bin tables
        flattened to ``(K * VONMISES_BINS,)`` (bin ``b`` of state ``k`` at
        ``k * VONMISES_BINS + b``: one-dimensional lookups are about twice as fast)."""
        return (
            self.mean,
            self.concentration,
            self.width,
            self.f_left.ravel(),
            self.f_right.ravel(),
            self.alias_cut.ravel(),
            self.alias.ravel(),
        )


def alias_table(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Walker/Vose alias table of ``weights`` (M,): draw ``b`` uniform, keep it with
    probability ``cut[b]``, else take ``alias[b]``; returns ``(cut, alias)``."""
    p = np.asarray(weights, dtype=np.float64)
    m = p.size
    scaled = p * m / p.sum()
    cut = np.ones(m)
    alias = np.arange(m)
    small = [i for i in range(m) if scaled[i] < 1.0]
    large = [i for i in range(m) if scaled[i] >= 1.0]
    while small and large:
        s, g = small.pop(), large.pop()
        cut[s], alias[s] = scaled[s], g
        scaled[g] -= 1.0 - scaled[s]
        (small if scaled[g] < 1.0 else large).append(g)
    return cut, alias


@njit(cache=True, inline="always")
def _vonmises_from(tables_row, k, z, u, v):
    """First try of :func:`vonmises` for state ``k`` from 64 random bits ``z`` (bin, alias
    choice and sign) and uniforms ``u`` (position in the bin) and ``v`` (height):
    ``(angle, accepted)``, accepted when the squeeze accepts (most draws). Branch-free.

    The drawn bin and its alias are both carried through (their positions and squeezes)
    and the alias choice selects between the results: a choice of the bin itself, whose
    only other operand is a loaded alias, is turned by LLVM's x86 back end into a
    branch, and that coin flip is mispredicted about half the time
    (``reports/decisions.md``, "The HMM draw pass's alias branch")."""
    mean, kappa, width, f_left, f_right, cut, alias = tables_row
    row = k * VONMISES_BINS
    b = np.int64(z & _BIN)
    other = alias[row + b]
    own = (z >> _S11) * _TWO_M53 < cut[row + b]
    x_own = (b + 1.0 - u) * width[k]  # 1 - u is in [0, 1)
    x_other = (other + 1.0 - u) * width[k]
    x = x_own if own else x_other
    own_accepted = v * f_left[row + b] <= f_right[row + b]
    other_accepted = v * f_left[row + other] <= f_right[row + other]
    accepted = own_accepted if own else other_accepted
    sign = 1.0 - 2.0 * np.float64((z >> _S9) & _ONE)  # -1 or 1: a product, not a branch
    angle = mean[k] + sign * x
    angle = angle - 2.0 * np.pi if angle > np.pi else angle
    angle = angle + 2.0 * np.pi if angle <= -np.pi else angle
    return angle, accepted


@njit(cache=True, inline="always")
def _vonmises_try(tables_row, k, state):
    """:func:`_vonmises_from` of the next three draws: ``(angle, accepted, state)``."""
    z, state = _bits(state)
    u, state = uniform(state)
    v, state = uniform(state)
    angle, accepted = _vonmises_from(tables_row, k, z, u, v)
    return angle, accepted, state


@njit(cache=True)
def _vonmises_loop(tables_row, k, state):
    """The whole von Mises rejection from ``state`` (its first try repeats
    :func:`_vonmises_try`)."""
    mean, kappa, width, f_left, f_right, cut, alias = tables_row
    row = k * VONMISES_BINS
    while True:
        z, state = _bits(state)
        b = np.int64(z & _BIN)
        if (z >> _S11) * _TWO_M53 >= cut[row + b]:
            b = alias[row + b]
        u, state = uniform(state)
        v, state = uniform(state)
        x = (b + 1.0 - u) * width[k]
        y = v * f_left[row + b]
        if y <= f_right[row + b] or y <= np.exp(kappa[k] * (np.cos(x) - 1.0)):
            break
    angle = mean[k] - x if (z >> _S9) & _ONE else mean[k] + x
    if angle > np.pi:
        angle -= 2.0 * np.pi
    elif angle <= -np.pi:
        angle += 2.0 * np.pi
    return angle, state


@njit(cache=True, inline="always")
def vonmises(tables_row, k, state):
    """One von Mises angle in ``(-pi, pi]`` for state ``k`` and the advanced state.

    Exact rejection sampling from the piecewise-constant envelope of
    :class:`VonMisesTables` (``tables_row`` is its tuple of arrays); the squeeze accepts
    most draws without evaluating the density.
    """
    angle, accepted, advanced = _vonmises_try(tables_row, k, state)
    if accepted:
        return angle, advanced
    return _vonmises_loop(tables_row, k, state)


@njit(cache=True, inline="always")
def categorical(cumulative_row, state):
    """Index ``j`` with probability ``row[j]``, given the row's cumulative sums (last = 1)."""
    u, state = uniform(state)
    k = cumulative_row.size
    for j in range(k - 1):
        if u <= cumulative_row[j]:
            return j, state
    return k - 1, state


@njit(cache=True)
def draw_uniforms(streams, n_per_stream):
    """``(n_per_stream, N)`` uniforms, advancing ``streams`` (N,) in place."""
    out = np.empty((n_per_stream, streams.size))
    for i in range(streams.size):
        s = streams[i]
        for k in range(n_per_stream):
            out[k, i], s = uniform(s)
        streams[i] = s
    return out


@njit(cache=True)
def draw_normal_pairs(streams):
    """One standard normal pair per stream, ``(2, N)``, advancing ``streams`` in place."""
    out = np.empty((2, streams.size))
    for i in range(streams.size):
        out[0, i], out[1, i], streams[i] = normal_pair(streams[i])
    return out


@njit(cache=True)
def _draw_gamma(streams, d, c, boost, scale):
    out = np.empty(streams.size)
    for i in range(streams.size):
        out[i], streams[i] = gamma(d, c, boost, scale, streams[i])
    return out


def draw_gamma(streams: np.ndarray, shape: float, scale: float) -> np.ndarray:
    """One Gamma(shape, scale) draw per stream, (N,), advancing ``streams`` in place."""
    d, c, boost = gamma_constants(np.array([shape]))
    return _draw_gamma(streams, d[0], c[0], boost[0], float(scale))


@njit(cache=True)
def _draw_vonmises(streams, tables_row):
    out = np.empty(streams.size)
    for i in range(streams.size):
        out[i], streams[i] = vonmises(tables_row, 0, streams[i])
    return out


def draw_vonmises(streams: np.ndarray, mean: float, concentration: float) -> np.ndarray:
    """One von Mises(mean, concentration) draw per stream, (N,), advancing ``streams``."""
    return _draw_vonmises(streams, VonMisesTables.build([mean], [concentration]).as_tuple())
