"""Errors raised for bad user input, before anything is compiled."""


class ConfigError(ValueError):
    """One-line message naming the offending field and what would be valid."""

    def __init__(self, field: str, message: str):
        self.field = field
        super().__init__(f"{field}: {message}")


def registered(registry: dict, name: str, field: str, what: str):
    """``registry[name]``, or a ConfigError naming ``field`` and the registered names
    (``what``: the kind of thing the registry holds, e.g. "identification scheme")."""
    if name not in registry:
        raise ConfigError(field, f"unknown {what} {name!r}; valid: {', '.join(registry)}")
    return registry[name]


def describe(exc: BaseException) -> str:
    """``Type: message`` of an exception. An exception raised inside a host callback (a
    user's black box) reaches the caller as a runtime error holding the whole traceback;
    its last line, the original exception, is what it says."""
    text = f"{type(exc).__name__}: {exc}"
    if "callback" in text and "Traceback" in text:
        lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
        return f"{type(exc).__name__} in a host callback: {lines[-1]}"
    return text
