"""The parameter checks of the Python plugins' declarations (PARAMETERS = {name: (type, default,
check)}, pd_campaign.plugin_params): check(value) -> bool, one definition each for every
recognizer and compensator."""
import math


def positive(value):
    """A finite number above 0 (inf and nan are refused)."""
    return math.isfinite(value) and value > 0


def fraction(value):
    """A finite number strictly between 0 and 1."""
    return math.isfinite(value) and 0 < value < 1


def at_least(low):
    """The check of a number not below `low`."""
    return lambda value: value >= low


def optional(check):
    """`check`, or None (the value left unset)."""
    return lambda value: value is None or check(value)
