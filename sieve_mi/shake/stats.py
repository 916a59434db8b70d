"""Statistics of shake trials: pass fractions with Wilson intervals, times to pass, curves."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["Z95", "pass_curve", "summarize", "wilson"]

#: Standard normal quantile of a two-sided 95 % interval.
Z95 = 1.959963984540054


def wilson(k: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion ``k / n``.

    Parameters
    ----------
    k, n : int
        Successes and trials (n >= 1).
    z : float
        Normal quantile (default: 95 %).

    Returns
    -------
    (float, float)
        Lower and upper bound, in [0, 1].

    Examples
    --------
    >>> lo, hi = wilson(0, 200)
    >>> lo, round(hi, 4)
    (0.0, 0.0188)
    """
    if n <= 0:
        raise ValueError("wilson needs at least one trial")
    p = k / n
    den = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / den
    lo, hi = max(0.0, centre - half), min(1.0, centre + half)
    return (0.0 if k == 0 else lo), (1.0 if k == n else hi)


def summarize(outcomes: list) -> dict:
    """Counts, fraction passed with its 95 % Wilson interval, and times to pass.

    Parameters
    ----------
    outcomes : list of Outcome
        One part's trials (:class:`~sieve_mi.shake.trials.Outcome`), in trial order.

    Returns
    -------
    dict
        ``trials``, ``passed``, ``escaped``, ``fraction``, ``ci95`` ([lo, hi]),
        ``median_time_s`` (None when none passed), ``pass_times_s`` (seconds; None for a trial
        that did not pass, in trial order).
    """
    n = len(outcomes)
    times = [o.time if o.passed else None for o in outcomes]
    passed = [t for t in times if t is not None]
    lo, hi = wilson(len(passed), n)
    return {
        "trials": n,
        "passed": len(passed),
        "escaped": sum(bool(o.escaped) for o in outcomes),
        "fraction": len(passed) / n,
        "ci95": [lo, hi],
        "median_time_s": float(np.median(passed)) if passed else None,
        "pass_times_s": times,
    }


def pass_curve(times: list, trials: int, grid: np.ndarray) -> np.ndarray:
    """Fraction of trials passed by each time of ``grid``.

    Parameters
    ----------
    times : list of float or None
        Each trial's time to pass (None: did not pass).
    trials : int
    grid : (m,) float
        Seconds.

    Returns
    -------
    (m,) float
    """
    t = np.sort(np.array([x for x in times if x is not None], dtype=np.float64))
    return np.searchsorted(t, grid, side="right") / max(trials, 1)
