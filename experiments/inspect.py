"""Print a model's state map and limits: ``python -m experiments.inspect MODEL.xml``.

MODEL is an MJCF file or a registered system name (``pendulum``, ``swimmer6``...).
``--json`` prints the same as JSON. Bad input exits with status 2 and one line.
"""

from __future__ import annotations

import json
import os
import sys

from mjx_surrogate.errors import ConfigError


def main(argv: list[str] | None = None) -> int:
    from mjx_surrogate.systems.inspection import describe, render
    from mjx_surrogate.systems.registry import default_config
    from mjx_surrogate.systems.system import compile_mjcf

    argv = sys.argv[1:] if argv is None else argv
    as_json = "--json" in argv
    args = [a for a in argv if a != "--json"]
    if len(args) != 1 or args[0].startswith("-"):
        print("usage: python -m experiments.inspect MODEL.xml|SYSTEM [--json]", file=sys.stderr)
        return 2
    spec = args[0]
    try:
        if spec.endswith(".xml") or os.path.sep in spec:
            if not os.path.isfile(spec):
                raise ConfigError("MODEL", f"no such file {spec!r}")
            model, _ = compile_mjcf(None, "MODEL", path=spec, need_controls=False)
        else:
            model, _ = compile_mjcf(default_config(spec).xml(), "MODEL")
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    info = describe(model)
    print(json.dumps(info, indent=1) if as_json else render(info))
    return 0


if __name__ == "__main__":
    sys.exit(main())
