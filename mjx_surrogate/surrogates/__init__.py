"""Global surrogates: SINDy-style least squares (:mod:`.sindy`) over feature libraries
(:mod:`.library`) and Flax MLPs (:mod:`.mlp`)."""
