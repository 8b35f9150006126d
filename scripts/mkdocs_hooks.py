"""mkdocs hooks of the documentation site (mkdocs.yml, ``hooks:``).

The docstrings use Sphinx roles (``:func:`quadrs.simulate```), which mkdocstrings renders as
the role's literal text before the code span (":func:quadrs.simulate" on the API pages). The
role is dropped here, keeping the code span.
"""

from __future__ import annotations

import re
from typing import Any

_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|attr|data|exc|obj|const):(?=<code)")


def strip_roles(html: str) -> str:
    """``:func:<code>x</code>`` -> ``<code>x</code>``."""
    return _ROLE.sub("", html)


def on_page_content(html: str, **_: Any) -> str:
    return strip_roles(html)
