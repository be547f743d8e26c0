"""The distribution functions of the measured-data analysis's tests, from :mod:`scipy.special`.

Each function equals the ``scipy.stats`` method named in its docstring to the bit on the arguments the analysis
passes (finite degrees of freedom > 0, probabilities in (0, 1); a statistic below the support's lower end gives
the survival 1, as scipy.stats does), checked in ``tests/test_distributions.py`` against scipy.stats itself.
They exist because importing ``scipy.stats`` costs about 0.4 s of CPU, a third of analysing a 200-row data set,
for functions that are one ufunc each (issue 27, item 3); :func:`rankdata` is scipy.stats.rankdata's average
ranks over axis 0. Shapes broadcast as numpy ufuncs do; results are float64 arrays or scalars.
"""

from __future__ import annotations

import numpy as np
from scipy import special as sc


def f_sf(x, dfn, dfd):
    """P(F > x) of Fisher's F on (dfn, dfd) degrees of freedom: ``scipy.stats.f.sf(x, dfn, dfd)``."""
    return sc.fdtrc(dfn, dfd, np.maximum(x, 0.0))


def f_isf(q, dfn, dfd):
    """The F value exceeded with probability q: ``scipy.stats.f.isf(q, dfn, dfd)``."""
    return sc.fdtri(dfn, dfd, 1.0 - np.asarray(q, float))


def chi2_sf(x, df):
    """P(chi^2_df > x): ``scipy.stats.chi2.sf(x, df)``."""
    return sc.chdtrc(df, np.maximum(x, 0.0))


def chi2_ppf(q, df):
    """The q-quantile of chi^2_df: ``scipy.stats.chi2.ppf(q, df)``."""
    return 2 * sc.gammaincinv(np.asarray(df, float) / 2, q)


def t_sf(x, df):
    """P(T > x) of Student's t on df degrees of freedom: ``scipy.stats.t.sf(x, df)``."""
    return sc.stdtr(df, -np.asarray(x, float))


def t_isf(q, df):
    """The t value exceeded with probability q: ``scipy.stats.t.isf(q, df)``."""
    return -sc.stdtrit(df, q)


def beta_ppf(q, a, b):
    """The q-quantile of Beta(a, b): ``scipy.stats.beta.ppf(q, a, b)``."""
    return sc.betaincinv(a, b, q)


def rankdata(a: np.ndarray) -> np.ndarray:
    """Ranks 1..n of every column of a (n, k) (or of a (n,)), ties given their average rank:
    ``scipy.stats.rankdata(a, axis=0)`` (method 'average'; a column holding a NaN is all NaN, as its default
    ``nan_policy='propagate'`` gives)."""
    a = np.asarray(a, float)
    flat = a.ndim == 1
    a = a.reshape(len(a), -1)
    n, k = a.shape
    order = np.argsort(a, axis=0, kind="mergesort")
    s = np.take_along_axis(a, order, axis=0)
    new = np.ones((n, k), bool)  # the first of each run of equal values
    new[1:] = s[1:] != s[:-1]
    ranks = np.empty((n, k))
    for j in range(k):
        starts = np.flatnonzero(new[:, j])
        ends = np.append(starts[1:], n)
        ranks[order[:, j], j] = np.repeat((starts + ends + 1) / 2.0, ends - starts)
    ranks[:, np.isnan(a).any(axis=0)] = np.nan
    return ranks[:, 0] if flat else ranks
