"""The analysis's distribution functions and its Gamma GLM against the libraries they replace (scipy.stats,
statsmodels), to the bit, and the analysis's imports: it loads neither (issue 27, item 3)."""

import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy import stats

from stiffcal.measured import discrepancy as D
from stiffcal.measured import distributions as dist


def _args(seed: int, n: int = 20_000):
    rng = np.random.default_rng(seed)
    q = np.concatenate([rng.uniform(size=n - 6), [1e-12, 1e-6, 0.005, 0.025, 0.5, 0.995]])
    a = np.concatenate([rng.integers(1, 400, size=n // 2), rng.uniform(0.5, 2000.0, size=n - n // 2)]).astype(float)
    b = rng.permutation(a)
    x = np.concatenate([rng.exponential(3.0, size=n - 8), [0.0, -0.0, -1e-17, -3.0, 1e-300, 50.0, 1e4, np.inf]])
    return q, a, b, x


@pytest.mark.parametrize("seed", [0, 1])
def test_each_distribution_function_equals_scipy_stats_to_the_bit(seed):
    q, a, b, x = _args(seed)
    pairs = {
        "f_sf": (dist.f_sf(x, a, b), stats.f.sf(x, a, b)),
        "f_isf": (dist.f_isf(q, a, b), stats.f.isf(q, a, b)),
        "chi2_sf": (dist.chi2_sf(x * a, a), stats.chi2.sf(x * a, a)),
        "chi2_ppf": (dist.chi2_ppf(q, a), stats.chi2.ppf(q, a)),
        "t_sf": (dist.t_sf(x - 3.0, a), stats.t.sf(x - 3.0, a)),
        "t_isf": (dist.t_isf(q, a), stats.t.isf(q, a)),
        "beta_ppf": (dist.beta_ppf(q, a / 2, b / 2), stats.beta.ppf(q, a / 2, b / 2)),
    }
    for name, (ours, theirs) in pairs.items():
        assert np.array_equal(ours, theirs, equal_nan=True), name
    # scalars, as the analysis calls them
    assert float(dist.f_sf(2.5, 3, 40)) == float(stats.f.sf(2.5, 3, 40))
    assert float(dist.t_isf(0.025, 17)) == float(stats.t.isf(0.025, 17))
    assert float(dist.chi2_sf(-1e-16, 4)) == float(stats.chi2.sf(-1e-16, 4)) == 1.0


def test_rankdata_equals_scipy_stats_with_ties_and_nan():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(301, 5))
    A[:, 1] = np.round(A[:, 1], 1)  # many ties
    A[:, 2] = 7.0  # one value
    A[::7, 3] = A[0, 3]
    assert np.array_equal(dist.rankdata(A), stats.rankdata(A, axis=0))
    assert np.array_equal(dist.rankdata(A[:, 1]), stats.rankdata(A[:, 1]))
    A[5, 4] = np.nan
    assert np.array_equal(dist.rankdata(A), stats.rankdata(A, axis=0), equal_nan=True)
    assert np.isnan(dist.rankdata(A)[:, 4]).all() and not np.isnan(dist.rankdata(A)[:, :4]).any()


def _statsmodels_gamma(s2, Z, df):
    import statsmodels.api as sm

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return sm.GLM(s2, Z, family=sm.families.Gamma(sm.families.links.Log()), var_weights=df).fit(scale=2.0)


def test_the_gamma_glm_is_statsmodels_to_the_bit():
    """Relative variances of replicate groups as variance_model makes them (chi-square on df, a log-linear trend
    in the covariates, scaled by their median): coefficients and deviances equal statsmodels' to the bit."""
    rng = np.random.default_rng(11)
    for _ in range(200):
        k, c = int(rng.integers(8, 80)), int(rng.integers(1, 6))
        Z = np.column_stack([np.ones(k), rng.normal(size=(k, c - 1))])
        df = rng.integers(1, 12, size=k).astype(float)
        s2 = rng.chisquare(df) / df * np.exp(Z @ rng.normal(scale=0.7, size=c))
        s2 /= np.median(s2)
        ours, theirs = D._gamma_fit(s2, Z, df), _statsmodels_gamma(s2, Z, df)
        assert np.array_equal(ours.params, theirs.params)
        assert ours.deviance == theirs.deviance


def test_the_gamma_glm_refuses_what_statsmodels_refuses():
    Z = np.column_stack([np.ones(10), np.arange(10.0)])
    exact = np.exp(0.3 * np.arange(10.0))  # a perfect fit: statsmodels warns, and so do we (an error to callers)
    with pytest.raises(Warning):
        _statsmodels_gamma(exact, Z, np.ones(10))
    with pytest.raises(Warning):
        D._gamma_fit(exact, Z, np.ones(10))
    bad = np.ones(10)
    bad[3] = np.nan
    for fit in (_statsmodels_gamma, D._gamma_fit):
        with pytest.raises((ValueError, Warning)):
            fit(bad, Z, np.ones(10))


@pytest.mark.parametrize("case", ["discrepancy/case4_kuka_coupling.a.csv", "lab-references/P3_backlash_1/data.csv"])
def test_the_analysis_imports_neither_scipy_stats_nor_statsmodels(case):
    """A whole verdict without a test pose (reading, the noise and error model, closed testing, the extended model
    and its held-out check, the calibrated model) loads neither library (their imports were 1.2 s of a 200-row
    analysis's 1.6 s) nor matplotlib (loaded when the figures are written). With a test pose the gain's
    candidate poses are Sobol points of scipy.stats.qmc, which loads scipy.stats."""
    data = f"tests/data/{case}"
    robot = data.replace(".a.csv", ".robot.yaml") if case.startswith("discrepancy") else data.replace("data.csv",
                                                                                                        "robot.yaml")
    code = ("import sys, numpy as np\n"
            "from stiffcal.model.robot import load_robot\n"
            "from stiffcal import discrepancy as D, measurements as M, calibrated\n"
            f"robot = load_robot({robot!r})\n"
            f"meas = M.read_measurements({data!r}, robot)\n"
            "pre = D.prepare(robot, meas, 0.01, None, None)\n"
            "v = D.verdict_of(robot, pre, 0.01, None, None)\n"
            f"calibrated.from_analysis(robot, pre, v, {data!r})\n"
            "print(sorted(m for m in ('scipy.stats', 'statsmodels', 'matplotlib') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.strip().splitlines()[-1] == "[]", out.stdout + out.stderr


def test_the_held_out_shift_is_the_fit_without_each_variance():
    """stiffcal.measured.discrepancy._held_out_shift (each variance's log-variance from the Gamma GLM fitted without
    it, minus the full fit's) against statsmodels' GLM refitted without each variance in turn, on 40 configurations of
    chi-square variances with a trend; and its sign: a variance above its fit pulled the fit up, so held out the fit
    there is lower."""
    rng = np.random.default_rng(7)
    k = 40
    Z = np.column_stack([np.ones(k), rng.uniform(-1, 1, (k, 3))])
    df = rng.integers(3, 12, k).astype(float)
    s2 = np.exp(Z @ np.array([0.0, 0.8, -0.4, 0.3])) * rng.chisquare(df) / df
    full = D._gamma_fit(s2, Z, df)
    ours = D._held_out_shift(full, s2, Z, df)
    import statsmodels.api as sm

    def converged(s2, Z, df):  # statsmodels' IRLS run to its fixed point (its default stops at a deviance change
        family = sm.families.Gamma(sm.families.links.Log())  # of 1e-8, some 1e-6 from it in the coefficients)
        return sm.GLM(s2, Z, family=family, var_weights=df).fit(scale=2.0, tol=1e-14, maxiter=500).params

    theirs = np.empty(k)
    eta = Z @ converged(s2, Z, df)
    for i in range(k):
        keep = np.arange(k) != i
        theirs[i] = Z[i] @ converged(s2[keep], Z[keep], df[keep]) - eta[i]
    np.testing.assert_allclose(ours, theirs, atol=1e-9)
    assert np.abs(theirs).max() > 0.05  # the shifts are not all negligible
    above = s2 > np.exp(Z @ full.params)
    assert np.all(ours[above] < 0) and np.all(ours[~above] > 0)
