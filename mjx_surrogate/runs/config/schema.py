"""The whole config (:class:`Config`, one field per section) and its dict form: read
strictly from a run's ``config.json`` (:func:`from_dict`), written (:func:`to_dict`), and
upgraded from an earlier schema (:func:`upgrade`, :data:`MOVED`)."""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Annotated, Any, Dict, Literal, Tuple

import tyro

from mjx_surrogate.errors import ConfigError
from mjx_surrogate.runs.config.experiment import ExperimentConfig, ParallelConfig
from mjx_surrogate.runs.config.learning import AnalysisConfig, DataConfig, SurrogateConfig
from mjx_surrogate.runs.config.mpc import MPCConfig
from mjx_surrogate.runs.config.solver import SolverConfig, SysIdConfig
from mjx_surrogate.runs.config.system import SystemConfig
from mjx_surrogate.runs.config.task import TaskConfig


@dataclasses.dataclass(frozen=True)
class Config:
    system: SystemConfig = SystemConfig()
    task: TaskConfig = TaskConfig()
    solver: SolverConfig = SolverConfig()
    sysid: SysIdConfig = SysIdConfig()
    experiment: ExperimentConfig = ExperimentConfig()
    data: DataConfig = DataConfig()
    surrogate: SurrogateConfig = SurrogateConfig()
    analysis: AnalysisConfig = AnalysisConfig()
    mpc: MPCConfig = MPCConfig()
    parallel: ParallelConfig = ParallelConfig()
    # the settings of registered extensions, "<section>.<name>" -> values
    # (mjx_surrogate.runs.extension_settings); the command line sets them as
    # --sysid.<scheme>.<field>, --solver.<strategy>.<field>, --surrogate.<kind>.<field>,
    # --experiment.<kind>.<field>, --mpc.<planner>.<field>
    extensions: Annotated[Dict[str, Any], tyro.conf.Suppress] = dataclasses.field(default_factory=dict)

    def check(self) -> None:
        """Each section's own check (ConfigError naming the first bad field). The names of
        registered extensions and the rules across sections are
        :func:`mjx_surrogate.runs.validation.validate_static`'s."""
        for section in (
            self.experiment,
            self.parallel,
            self.mpc,
            self.solver,
            self.sysid,
            self.system,
            self.task,
            self.data,
            self.surrogate,
            self.analysis,
        ):
            section.check()


# Fields that 0.5.0 moved into the sysid sections (old dotted name -> new): a run folder
# written before keeps replaying (:func:`upgrade`), and an old flag is told where it went.
MOVED = {
    "solver.sysid": "sysid.scheme",
    "solver.n_samples": "sysid.n_samples",
    "solver.sigma_x": "sysid.sigma_x",
    "solver.sigma_u": "sysid.sigma_u",
    "solver.sysid_every": "sysid.every",
    "solver.sysid_design": "sysid.design",
    "solver.sysid_noise_floor": "sysid.noise_floor",
    "solver.sysid_significance": "sysid.significance",
    "solver.sysid_rank_tol": "sysid.rank_tol",
    "solver.sysid_perturb_x0": "sysid.perturb_x0",
    "solver.sysid_hold_limits": "sysid.hold_limits",
    "mpc.sysid": "mpc.sysid.scheme",
    "mpc.n_samples": "mpc.sysid.n_samples",
    "mpc.sysid_design": "mpc.sysid.design",
    "mpc.sysid_every": "mpc.sysid.every",
}


def upgrade(data: dict) -> dict:
    """A config dict of an earlier schema (a run's config.json before 0.5.0) with its
    moved fields (:data:`MOVED`) and its scheme's settings (``solver.<scheme>`` ->
    ``sysid.<scheme>``) where they are now; a current one is returned as it is."""
    solver, mpc = data.get("solver"), data.get("mpc")
    if "sysid" in data or not isinstance(solver, dict) or not isinstance(mpc, dict):
        return data
    out = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    moved = {"sysid": {}, "mpc.sysid": {}}
    for old, new in MOVED.items():
        section, field = old.split(".")
        if field in out[section]:
            target, name = new.rsplit(".", 1)
            moved[target][name] = out[section].pop(field)
    out["sysid"], out["mpc"]["sysid"] = moved["sysid"], moved["mpc.sysid"]
    scheme = solver.get("sysid")
    if isinstance(out.get("extensions"), dict) and f"solver.{scheme}" in out["extensions"]:
        ext = dict(out["extensions"])
        ext[f"sysid.{scheme}"] = ext.pop(f"solver.{scheme}")
        out["extensions"] = ext
    return out


def to_dict(cfg: Any) -> dict:
    """Config -> nested dict (tuples become lists); written with
    :func:`mjx_surrogate.runs.results.jsonable`, which keeps non-finite numbers loadable."""
    return dataclasses.asdict(cfg)


def _convert(value: Any, hint: Any, field: str) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _convert(value, inner[0], field)
    if origin is Literal:
        if value not in args:
            raise ConfigError(field, f"got {value!r}; valid: {', '.join(map(repr, args))}")
        return value
    if origin in (tuple, Tuple):
        if not isinstance(value, (list, tuple)):
            raise ConfigError(field, f"expected a list, got {value!r}")
        elem = args[0]
        return tuple(_convert(v, elem, f"{field}[{i}]") for i, v in enumerate(value))
    if dataclasses.is_dataclass(hint):
        return from_dict(hint, value, field)
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(field, f"expected true/false, got {value!r}")
        return value
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(field, f"expected an integer, got {value!r}")
        return value
    if hint is float:
        if isinstance(value, str) and value in ("nan", "inf", "-inf"):
            return float(value)  # how run folders write non-finite numbers
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(field, f"expected a number, got {value!r}")
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(field, f"expected a string, got {value!r}")
        return value
    return value


def from_dict(cls: type, data: Any, prefix: str = "", complete: bool = False) -> Any:
    """Nested dict (e.g. a run's config.json) -> config dataclass, strictly checked.

    complete: every field must be present (a run's config.json names them all; a missing
    one means a config from another version of the schema, reported rather than filled).
    """
    where = prefix or cls.__name__
    if not isinstance(data, dict):
        raise ConfigError(where, f"expected a mapping, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    names = [f.name for f in dataclasses.fields(cls)]
    kwargs = {}
    for key, value in data.items():
        field = f"{prefix}.{key}" if prefix else key
        if key not in names:
            if field in MOVED:
                raise ConfigError(field, f"moved to {MOVED[field]} in version 0.5.0")
            raise ConfigError(field, f"unknown field; valid: {', '.join(names)}")
        hint = hints[key]
        if complete and dataclasses.is_dataclass(hint):
            kwargs[key] = from_dict(hint, value, field, complete)
        else:
            kwargs[key] = _convert(value, hint, field)
    missing = [n for n in names if n not in data and n != "extensions"]  # older runs had none
    if complete and missing:
        raise ConfigError(
            prefix or "CONFIG",
            f"missing field(s) {', '.join(missing)}: a config from another schema version; "
            "add them or start from a preset",
        )
    return cls(**kwargs)
