"""Statistics of the campaign report."""
import math


def wilson_interval(successes, n, z=1.959963984540054):
    """Wilson score interval (95 % by default) of a binomial proportion; (0, 1) when n = 0.

    Wilson, E. B. (1927) Probable inference, the law of succession, and statistical inference.
    J Am Stat Assoc 22:209-212."""
    if n == 0:
        return (0.0, 1.0)
    p = successes / n
    denominator = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denominator
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denominator
    # The exact bounds at p = 0 and p = 1 (0 and 1), free of rounding.
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return (low, high)


def median(values):
    values = sorted(v for v in values if v is not None and not math.isnan(v))
    if not values:
        return None
    mid = len(values) // 2
    return values[mid] if len(values) % 2 else 0.5 * (values[mid - 1] + values[mid])


def fisher_exact(successes_a, n_a, successes_b, n_b):
    """Two-sided p of Fisher's exact test on two independent success counts (scipy), e.g. ours
    against the paper's; 1.0 when either group is empty."""
    if n_a == 0 or n_b == 0:
        return 1.0
    from scipy.stats import fisher_exact as fisher  # the kept library does the test
    return float(fisher([[successes_a, n_a - successes_a],
                         [successes_b, n_b - successes_b]], alternative='two-sided')[1])


def mcnemar_exact(only_a, only_b):
    """Two-sided p of McNemar's exact test for paired outcomes: the discordant pairs (only A
    succeeded, only B succeeded) against a fair coin (scipy's exact binomial test)."""
    if only_a + only_b == 0:
        return 1.0
    from scipy.stats import binomtest
    return float(binomtest(only_a, only_a + only_b, 0.5, alternative='two-sided').pvalue)


def paired_counts(rows_a, rows_b, key):
    """Pairs two lists of trial rows by `key` (e.g. seed and rpm); returns (pairs, both, only_a,
    only_b, neither) over the pairs where neither trial errored."""
    b_by_key = {key(r): r for r in rows_b if not r.get('error')}
    pairs = [(a, b_by_key[key(a)]) for a in rows_a
             if not a.get('error') and key(a) in b_by_key]
    both = sum(1 for a, b in pairs if a['success'] and b['success'])
    only_a = sum(1 for a, b in pairs if a['success'] and not b['success'])
    only_b = sum(1 for a, b in pairs if b['success'] and not a['success'])
    return len(pairs), both, only_a, only_b, len(pairs) - both - only_a - only_b


def holm(p_values):
    """Holm's step-down adjusted p values, in the order given: a conclusion holds at level alpha
    over the whole family when its adjusted p is below alpha.

    Holm, S. (1979) A simple sequentially rejective multiple test procedure. Scand J Stat
    6:65-70."""
    order = sorted(range(len(p_values)), key=lambda i: p_values[i])
    adjusted = [1.0] * len(p_values)
    running = 0.0
    for rank, i in enumerate(order):
        running = max(running, min(1.0, (len(p_values) - rank) * p_values[i]))
        adjusted[i] = running
    return adjusted


def normal_cdf(z):
    """The standard normal distribution function."""
    return 0.5 * math.erfc(-z / math.sqrt(2.0))


def normal_quantile(p):
    """The standard normal quantile function (the inverse of normal_cdf; scipy)."""
    from scipy.stats import norm
    return float(norm.ppf(p))
