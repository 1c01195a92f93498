"""MkDocs hook: show the docstrings' Sphinx roles (``:class:`~wbc.tasks.ComTask```) as code.

mkdocstrings renders a role as ``:class:<code>~wbc.tasks.ComTask</code>``; this keeps the
code span and drops the role (and, with ``~``, the module path), as Sphinx would display it.
"""

from __future__ import annotations

import re
from typing import Any

_ROLE = re.compile(r":(?:class|meth|func|mod|attr|data|exc|obj):<code>(~?)([^<]+)</code>")


def _shown(match: re.Match[str]) -> str:
    tilde, target = match.groups()
    return f"<code>{target.rsplit('.', 1)[-1] if tilde else target}</code>"


def on_page_content(html: str, **kwargs: Any) -> str:
    return _ROLE.sub(_shown, html)
