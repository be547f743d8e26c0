"""Clean data of one lab protocol, analysed as a lab would (a CSV with pose_id through
stiffcal.measured.discrepancy.analyse) and by the oracle that knows the rows' true covariance
(stiffcal.testing.rates.oracle_global_p: the same closed test on the rows whitened by it, the noise scale known),
seed by seed: how many false alarms each raises, how many they share, and the Spearman correlation of their global
p-values. An oracle rate near alpha with the analysis above it says the estimated error model is at fault; both above
alpha on the same seeds says the seeds are unlucky. An ablation beside them: the same analysis told the simulator's
true noise weights (1 / sigma of each row's reading, relative to the median row) and without the blunder screen,
which says how much of an excess the estimated noise weights (stiffcal.measured.discrepancy.variance_model and
residual_variance_model) bring; and the ratio of the error variance the tests divide by with the estimated weights to
that with the true ones (below 1: the weights, estimated from the same squared deviations, shrink it).
Run: .venv/bin/python benchmarks/oracle_false_alarms.py ARM "PROTOCOL" [SEEDS] [FIRST_SEED] [ALPHA]
(ARM: 2-link, 3-link or 6-axis; PROTOCOL a name of stiffcal.testing.rates.PROTOCOLS; defaults 300 seeds from 0,
alpha 0.01).
"""
import sys
import tempfile
import time
from contextlib import contextmanager
from pathlib import Path
from unittest import mock

import numpy as np
from scipy import stats

from stiffcal.measured import discrepancy as D
from stiffcal.testing import rates as R
from stiffcal.testing import truth as T
from stiffcal.measured.measurements import read_measurements

ROOT = Path(__file__).resolve().parents[1]


def main(arm: str, protocol: str, seeds: int = 300, first: int = 0, alpha: float = 0.01) -> None:
    robot = R.robots(ROOT)[arm]
    start = time.process_time()
    analysed, oracle, ablated, ratios = [], [], [], []
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(first, first + seeds):
            log, dp, _ = R.simulate_case(robot, protocol, (), seed)
            path = Path(tmp) / "case.csv"
            path.write_text(T.lab_csv(robot, log, dp, pose_id=True), encoding="utf-8")
            meas = read_measurements(path, robot)
            v = D.analyse(robot, meas, alpha, gain=False)
            analysed.append((v["cause"] != "none", v["p_value"]))
            ablated.append(_with_true_weights(robot, log, meas, alpha)["cause"] != "none")
            ratios.append(_s2_ratio(robot, log, meas, alpha))
            oracle.append(R.oracle_global_p(robot, log, dp, alpha))
    a = np.array([x for x, _ in analysed])
    o = np.array(oracle) <= alpha
    rho = stats.spearmanr([p for _, p in analysed], oracle)[0]

    def ci(k):
        r = stats.binomtest(int(k), seeds).proportion_ci(0.95)
        return f"{k}/{seeds} ({100 * k / seeds:.2f} %, 95 % CI {100 * r.low:.2f}-{100 * r.high:.2f} %)"
    print(f"{arm} | {protocol} | alpha {alpha}")
    print(f"analysis false alarms: {ci(a.sum())}")
    print(f"oracle (true covariance) false alarms: {ci(o.sum())}")
    print(f"analysis with the true noise weights, no blunder screen: {ci(int(np.sum(ablated)))}")
    print(f"error variance of the tests, estimated over true noise weights: median {np.median(ratios):.3f} "
          f"(quartiles {np.quantile(ratios, 0.25):.3f}-{np.quantile(ratios, 0.75):.3f})")
    print(f"both: {int((a & o).sum())}; analysis only: {int((a & ~o).sum())}; oracle only: {int((~a & o).sum())}; "
          f"Spearman rho of the global p-values {rho:.3f}")
    print(f"CPU {time.process_time() - start:.1f} s")


@contextmanager
def _true_weights(log: T.LabLog, meas):
    """Within: the analysis of ``meas`` (the loaded rows of ``log``, in its order) takes the noise weights the
    simulator used and screens no blunder (an ablation: its own weight estimates and screen patched out)."""
    weights = 1.0 / log.sigma[log.loaded]
    weights = weights / np.median(weights)
    if len(weights) != meas.n_rows:
        raise SystemExit(f"the log has {len(weights)} loaded rows, the data {meas.n_rows}")

    def told(robot, m, resid=None):
        return D.VarianceModel(weights, 0.0, float(weights.max() / weights.min()))
    with mock.patch.object(D, "variance_model", told), mock.patch.object(D, "residual_variance_model",
                                                                       lambda *a, **k: None), \
            mock.patch.object(D, "find_blunders", lambda *a, **k: []):
        yield


def _with_true_weights(robot, log: T.LabLog, meas, alpha: float) -> dict:
    """The verdict of ``meas`` under :func:`_true_weights`."""
    with _true_weights(log, meas):
        return D.analyse(robot, meas, alpha, gain=False)


def _s2_ratio(robot, log: T.LabLog, meas, alpha: float) -> float:
    """The error variance the tests divide by (``Noise.s2``, the median row's) with the estimated noise weights over
    that with the simulator's: below 1 when estimating the weights from the same residuals shrinks it."""
    with _true_weights(log, meas):
        true = D.prepare(robot, meas, alpha).noise.s2
    return D.prepare(robot, meas, alpha).noise.s2 / true


if __name__ == "__main__":
    args = sys.argv[1:]
    if len(args) < 2:
        sys.exit(__doc__)
    main(args[0], args[1], *(int(a) for a in args[2:4]), *(float(a) for a in args[4:5]))
