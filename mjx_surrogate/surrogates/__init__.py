"""Global surrogates: SINDy-style least squares (:mod:`.sindy`) over feature libraries
(:mod:`.library`) and Flax MLPs (:mod:`.mlp`), behind one registry (:mod:`.registry`)."""

from mjx_surrogate.surrogates.registry import (
    SURROGATES,
    FitContext,
    Fitted,
    Surrogate,
    SurrogateKind,
    fit_all,
    fit_all_seeds,
    get_surrogate,
    register_surrogate,
)

__all__ = [
    "SURROGATES",
    "FitContext",
    "Fitted",
    "Surrogate",
    "SurrogateKind",
    "fit_all",
    "fit_all_seeds",
    "get_surrogate",
    "register_surrogate",
]
