"""Experiment kind "d2c" (filled in by the data-driven iLQR work)."""


def run(res, folder, key):
    raise NotImplementedError("the d2c experiment kind is not built yet")
