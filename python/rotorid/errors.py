"""Exceptions raised by rotorid. All derive from ValueError so that bad input is catchable the
usual way; IdentifiabilityError marks sets of runs/tests that cannot identify the coefficients."""


class RotoridError(ValueError):
    """Bad input to a rotorid function: the message names the argument and what is wrong."""


class IdentifiabilityError(RotoridError):
    """The given runs or impact tests cannot identify all bearing coefficients."""
