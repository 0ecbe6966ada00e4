"""Exceptions of the ow_faults package. Each message names the bad value and what was expected."""


class OwFaultsError(Exception):
    """Base class of every error raised by ow_faults."""


class FaultError(OwFaultsError):
    """A fault name is unknown, a value has the wrong type or is out of range, or a custom power
    profile is missing or malformed."""
