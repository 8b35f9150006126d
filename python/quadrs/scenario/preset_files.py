"""Where a scenario's text comes from: the presets shipped with quadrs, a scenario file read
with its size bounded, and the preset a file bases on."""

from __future__ import annotations

import os
import sys
from importlib import resources
from pathlib import Path

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover  (Python 3.10: the same parser, as a package)
    import tomli as tomllib

from quadrs.scenario.keys import ScenarioError

_PRESET_DIR = "presets"
_BASE_KEY = "base"


#: Largest scenario file read (bytes): a binary or endless file is refused, not read forever.
MAX_FILE_BYTES = 1 << 20
#: Largest scenario text parsed (characters). Text quadrs wrote itself (the scenario a saved
#: result or checkpoint carries, ``to_toml``, a scenario re-read after its route or wind table
#: was read in) holds every row of its wind table and route, so it may be far larger than a
#: file a user writes; this only guards against absurd sizes.
MAX_TEXT_CHARS = 256 << 20


def presets() -> list[str]:
    """Names of the presets shipped with quadrs."""
    files = resources.files("quadrs").joinpath(_PRESET_DIR).iterdir()
    return sorted(f.name.removesuffix(".toml") for f in files if f.name.endswith(".toml"))


def _preset_text(name: str) -> str:
    if name not in presets():
        raise ScenarioError(f"preset must be one of {presets()}, got {name!r}")
    return resources.files("quadrs").joinpath(_PRESET_DIR).joinpath(f"{name}.toml").read_text()


def base_preset(path: str | Path) -> str | None:
    """The preset a scenario file starts from: its ``base`` if that names a preset, followed
    through files that base on other files; None if there is none or the file is unreadable
    (reading the scenario itself reports why)."""
    path, seen = Path(path), set()
    while _real(path) not in seen:
        seen.add(_real(path))
        try:
            base = tomllib.loads(_read_text(path)).get(_BASE_KEY)
        except (OSError, ValueError, RecursionError):
            return None
        if not isinstance(base, str):
            return None
        if base in presets():
            return base
        path = path.parent / base
    return None


def _real(path: Path) -> Path:
    """``path`` with its symlinks resolved as far as they go (a loop does not raise: reading
    the file then reports it)."""
    return Path(os.path.realpath(path))


def _read_text(path: Path) -> str:
    """A scenario file's text, read as every input file is (quadrs.io.files.read_input_text):
    at most MAX_FILE_BYTES (a device such as /dev/zero is refused, not read forever; a pipe,
    ``<(...)``, is read); UTF-8. ScenarioError naming the file otherwise."""
    from quadrs.scenario.input_files import InputFileError, read_input_text

    try:
        return read_input_text(path, "scenario file", MAX_FILE_BYTES, streams=True)
    except InputFileError as e:
        raise ScenarioError(f"{e}: not a scenario") from None
    except OSError as e:
        raise ScenarioError(
            f"scenario file {str(path)!r} cannot be read: {e.strerror or e}"
        ) from None
