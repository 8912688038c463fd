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
