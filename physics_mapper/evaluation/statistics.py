"""Statistics of estimate errors: paired and pooled tests of "with physics" against "without".

Errors are arrays indexed [run, iteration] (experiments) or one value per snapshot (evaluation),
in any one unit; the tests are scipy's, two-sided.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import kruskal, wilcoxon


def compare_errors(without: NDArray[np.float64], with_: NDArray[np.float64]) -> dict[str, Any]:
    """Compare two estimates' errors, indexed [run, iteration] and paired by run and iteration.

    * ``wilcoxon_paired_by_run``: the headline test, :func:`paired_by_run_test`.
    * ``kruskal_wallis_pooled``: the paper's test, :func:`pooled_kruskal_wallis`.
    * ``physics_lower`` / ``physics_higher`` / ``equal``: how many of the runs x iterations pairs
      have ``with_`` below, above or equal to ``without``.
    """
    difference = with_ - without
    return {
        "wilcoxon_paired_by_run": paired_by_run_test(without, with_),
        "kruskal_wallis_pooled": pooled_kruskal_wallis(without, with_),
        "physics_lower": int((difference < 0).sum()),
        "physics_higher": int((difference > 0).sum()),
        "equal": int((difference == 0).sum()),
    }


def reduction_percent(without: NDArray[np.float64], with_: NDArray[np.float64]) -> float:
    """How much lower, in percent, the mean of ``with_`` errors is than the mean of ``without`` errors."""
    return float(100.0 * (1.0 - with_.mean() / without.mean()))


def paired_by_run_test(without: NDArray[np.float64], with_: NDArray[np.float64]) -> dict[str, Any]:
    """Wilcoxon signed-rank test (:func:`paired_wilcoxon`) of the per-run mean errors, two-sided.

    The runs are independent, the iterations of one run are not (they share one filter), and
    both estimates of a run come from the same hypotheses: so each run gives one pair
    (mean_t without[r, t], mean_t with_[r, t]).
    """
    without_means, with_means = without.mean(axis=1), with_.mean(axis=1)
    paired = paired_wilcoxon(without_means, with_means)
    return {
        "test": "Wilcoxon signed-rank, two-sided, exact, on the per-run mean errors paired by run (zeros dropped)",
        "statistic": paired["statistic"],
        "p_value": paired["p_value"],
        "pairs": paired["pairs"],
        "nonzero_pairs": paired["nonzero_pairs"],
        "runs_physics_lower": paired["pairs_lower"],
        "runs_physics_higher": paired["pairs_higher"],
        "per_run_mean_cm": {"without_physics": without_means.tolist(), "with_physics": with_means.tolist()},
    }


#: Up to this many nonzero differences the Wilcoxon p-value comes from the exact null distribution
#: (milliseconds); above, from the normal approximation, which is close there and exact's cost grows
#: as n^3 (a second at n = 1000).
EXACT_WILCOXON_PAIRS = 200


def paired_wilcoxon(without: NDArray[np.float64], with_: NDArray[np.float64]) -> dict[str, Any]:
    """Wilcoxon signed-rank test (scipy), two-sided, of paired samples: ``with_[k]`` against ``without[k]``.

    Zero differences (pairs where the two estimates agree) are dropped, Wilcoxon's convention, and
    the p-value of the remaining n differences comes from the exact null distribution (exact while
    they are distinct, as differences of continuous errors are; scipy's default would switch to the
    normal approximation as soon as one difference is zero, which is poor in the tails at n = 20)
    up to :data:`EXACT_WILCOXON_PAIRS`, from the normal approximation above (``method`` says which).
    With no nonzero difference there is no evidence either way: statistic 0, p = 1.
    ``pairs_lower`` / ``pairs_higher``: pairs where ``with_`` is below / above ``without``.
    """
    difference = with_ - without
    nonzero = int(np.count_nonzero(difference))
    method = "exact" if nonzero <= EXACT_WILCOXON_PAIRS else "asymptotic"
    if nonzero:
        statistic, p_value = wilcoxon(with_, without, zero_method="wilcox", method=method)
    else:
        statistic, p_value = 0.0, 1.0
    return {
        "statistic": float(statistic),
        "p_value": float(p_value),
        "method": method,
        "pairs": int(difference.size),
        "nonzero_pairs": nonzero,
        "pairs_lower": int((difference < 0).sum()),
        "pairs_higher": int((difference > 0).sum()),
    }


def pooled_kruskal_wallis(without: NDArray[np.float64], with_: NDArray[np.float64]) -> dict[str, Any]:
    """Kruskal-Wallis test (scipy) of all runs x iterations pooled into one sample per estimate.

    The paper's test, kept for comparison with its p-value. It treats the samples as
    independent and unpaired, which they are not (see :func:`paired_by_run_test`).
    """
    statistic, p_value = kruskal(without.ravel(), with_.ravel())
    return {
        "test": "Kruskal-Wallis on all runs x iterations pooled (the paper's test; ignores pairing and runs)",
        "statistic": float(statistic),
        "p_value": float(p_value),
        "samples_per_group": int(without.size),
    }


def tests_text(comparison: dict[str, Any], estimate: str) -> str:
    """One sentence for people: the paired test (headline), then the paper's pooled test."""
    paired, pooled = comparison["wilcoxon_paired_by_run"], comparison["kruskal_wallis_pooled"]
    return (
        f"paired Wilcoxon signed-rank test on the {paired['pairs']} per-run means: p = {paired['p_value']:.2g} "
        f"({estimate} lower in {paired['runs_physics_lower']} of {paired['pairs']} runs, higher in "
        f"{paired['runs_physics_higher']}); the paper's test, Kruskal-Wallis on the "
        f"{pooled['samples_per_group']} runs x iterations pooled: p = {pooled['p_value']:.3g}"
    )
