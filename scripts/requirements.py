"""Print the requirements of pyproject.toml (the dependencies and the named extras), one per
line, so scripts/test.sh can install them while the engine compiles."""

from __future__ import annotations

import sys
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: nothing to pre-install, the wheel's install does it
    sys.exit(0)

project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())["project"]
wanted = list(project["dependencies"])
for extra in sys.argv[1:]:
    wanted += project["optional-dependencies"][extra]
print("\n".join(wanted))
