"""What a saved run is, and checks that what is read back belongs to it.

A *run identity* is a hash of everything that determines a run's rows: the scenario (its
values, not their spelling), the seed, the controllers, whether spectra were kept, and the
quadrs version. Every file a run writes carries it; readers recompute it from the metadata and
refuse a file (or a checkpoint part) whose identity does not match, so rows from another seed,
scenario or version are never counted as ours, and edited metadata is caught.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from quadrs import _core
from quadrs.engine.calls import CONTROLLERS
from quadrs.scenario.scenario import Scenario

#: The engine's arithmetic modes: "exact" (default) and "fused" (fused multiply-adds).
ARITHMETIC = ("exact", "fused")


class CorruptRunError(ValueError):
    """A saved run (file, checkpoint part or manifest) is not what it claims to be: foreign,
    edited, or written by another quadrs version. The message names the file."""


def _canonical(value: Any) -> Any:
    """Numbers as floats (``1`` and ``1.0`` are the same scenario value), tables sorted."""
    if isinstance(value, Mapping):
        return {str(k): _canonical(v) for k, v in sorted(value.items())}
    if isinstance(value, list | tuple):
        return [_canonical(v) for v in value]
    if isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    return value


def run_identity(
    scenario: Scenario,
    seed: int,
    controllers: Sequence[str],
    spectra: bool,
    version: str | None = None,
    extra: Any = None,
    arithmetic: str = "exact",
) -> str:
    """The identity (hex SHA-256) of a run; see the module docstring. ``extra``: anything
    else (JSON-able) that determines the rows, e.g. a sweep's grid. ``arithmetic``: "exact"
    (the default mode, bit-identical on every machine) or "fused" (``monte_carlo(fused=True)``);
    only a fused run hashes it, so the identities of exact runs are what they always were."""
    if arithmetic not in ARITHMETIC:
        raise ValueError(f"arithmetic must be one of {ARITHMETIC}, got {arithmetic!r}")
    doc = {
        "extra": _canonical(extra),
        "scenario": _canonical(scenario.to_dict()),
        "seed": int(seed),
        "controllers": list(controllers),
        "spectra": bool(spectra),
        "version": _core.__version__ if version is None else version,
    }
    if arithmetic != "exact":
        doc["arithmetic"] = arithmetic
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


@dataclass(frozen=True)
class RunRecord:
    """What a saved run is, the one form every file of a run stores it in: the scenario, the
    master seed, the controllers, whether spectra were kept, ``extra`` (whatever else fixes
    the rows: a batch's sampling, a checkpoint's design, a sweep's grid), stored under
    ``extra_key``, the quadrs version and the arithmetic mode. Together they hash to
    :attr:`run`."""

    scenario: Scenario
    seed: int
    controllers: tuple[str, ...]
    spectra: bool
    extra_key: str
    extra: Any = None
    version: str = field(default=_core.__version__)
    #: "exact" (the default mode) or "fused" (``monte_carlo(fused=True)``).
    arithmetic: str = "exact"

    @property
    def run(self) -> str:
        """The run identity (see :func:`run_identity`)."""
        return run_identity(
            self.scenario, self.seed, self.controllers, self.spectra, self.version, self.extra,
            self.arithmetic,
        )  # fmt: skip

    def metadata(self, **fields: Any) -> dict[str, Any]:
        """The record as JSON-able file metadata, with ``fields`` (e.g. ``interrupted``) added
        or, for ``spectra``, replaced by what the file holds of them."""
        return {
            "version": self.version,
            "seed": self.seed,
            "controllers": list(self.controllers),
            "scenario": self.scenario.to_toml(),
            "spectra": self.spectra,
            "arithmetic": self.arithmetic,
            self.extra_key: self.extra,
            **fields,
            "run": self.run,
        }

    @classmethod
    def read(
        cls, meta: Any, path: str | Path, extra_key: str, keys: Mapping[str, Any] | None = None
    ) -> RunRecord:
        """The record of a file's metadata, validated (types, this quadrs version, the run
        identity, plus ``keys``: name -> required type); CorruptRunError naming ``path``
        otherwise."""
        scenario = check_run_metadata(meta, path, keys or {}, extra_key=extra_key)
        spectra = meta.get("spectra", True)
        return cls(
            scenario=scenario,
            seed=meta["seed"],
            controllers=tuple(meta["controllers"]),
            spectra=spectra is not None and spectra is not False,
            extra_key=extra_key,
            extra=meta.get(extra_key),
            version=meta["version"],
            arithmetic=meta.get("arithmetic", "exact"),
        )


def _fail(path: str | Path, what: str) -> CorruptRunError:
    return CorruptRunError(f"{str(path)!r}: {what}; refusing to read it")


def check_run_metadata(
    meta: Any, path: str | Path, keys: Mapping[str, Any], extra_key: str | None = None
) -> Scenario:
    """Validate the common fields of a run's metadata (types, required keys, the run identity):
    ``version`` (this quadrs), ``seed``, ``controllers``, ``scenario`` (TOML) and ``run``,
    plus ``keys`` (name -> required type). Returns the scenario."""
    if not isinstance(meta, dict):
        raise _fail(path, f"its quadrs metadata is not a table, got {type(meta).__name__}")
    required = {
        "version": str,
        "seed": int,
        "controllers": list,
        "scenario": str,
        "run": str,
        **keys,
    }
    for key, kind in required.items():
        if key not in meta:
            raise _fail(path, f"its metadata lacks {key!r}")
        value = meta[key]
        ok = isinstance(value, kind) and not (kind is int and isinstance(value, bool))
        if not ok:
            raise _fail(
                path, f"metadata {key!r} must be {kind.__name__}, got {type(value).__name__} "
                f"{value!r}"
            )  # fmt: skip
    if meta["version"] != _core.__version__:
        raise _fail(path, f"written by quadrs {meta['version']}, this is {_core.__version__}")
    if not 0 <= meta["seed"] < 2**64:
        raise _fail(path, f"metadata 'seed' out of range: {meta['seed']}")
    ctrls = meta["controllers"]
    if not ctrls or len(set(ctrls)) != len(ctrls) or any(c not in CONTROLLERS for c in ctrls):
        raise _fail(path, f"metadata 'controllers' must be distinct names of {CONTROLLERS}, "
                          f"got {ctrls!r}")  # fmt: skip
    try:
        scenario = Scenario.from_toml_string(meta["scenario"], source=str(path))
    except ValueError as e:
        raise _fail(path, f"its scenario is invalid ({e})") from None
    spectra = meta.get("spectra", True)
    has_spectra = spectra is not None and spectra is not False
    extra = meta.get(extra_key) if extra_key else None
    arithmetic = meta.get("arithmetic", "exact")
    if arithmetic not in ARITHMETIC:
        raise _fail(path, f"metadata 'arithmetic' must be one of {ARITHMETIC}, got {arithmetic!r}")
    run = run_identity(scenario, meta["seed"], ctrls, has_spectra, extra=extra,
                       arithmetic=arithmetic)  # fmt: skip
    if meta["run"] != run:
        raise _fail(path, "its run identity does not match its scenario, seed and controllers "
                          "(edited metadata?)")  # fmt: skip
    return scenario


def check_rows(
    runs: Any, path: str | Path, controllers: Sequence[str], phases: Sequence[str]
) -> None:
    """The rows hold the columns of a runs table, and only our controllers and phases."""
    need = {"realisation", "controller", "phase", "diverged", "diverged_at",
            *_core.METRIC_NAMES}  # fmt: skip
    missing = need - set(runs.columns)
    if missing:
        raise _fail(path, f"its rows lack the columns {sorted(missing)}")
    bad_c = set(runs["controller"].astype(str)) - set(controllers)
    bad_p = set(runs["phase"].astype(str)) - set(phases)
    if bad_c or bad_p:
        raise _fail(path, f"its rows name controllers {sorted(bad_c)} or phases {sorted(bad_p)} "
                          "that its metadata does not")  # fmt: skip
