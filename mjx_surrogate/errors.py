"""Errors raised for bad user input, before anything is compiled."""


class ConfigError(ValueError):
    """One-line message naming the offending field and what would be valid."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(f"{field}: {message}")
