"""Exceptions of ow_runtime, and the base every package's configuration error derives from."""


class ConfigError(ValueError):
    """A configuration value is missing, of the wrong type or out of range.

    Each package's own ``ConfigError`` derives from this one, so that the bring-up can catch the
    configuration errors of every node it configures with one ``except``.
    """
