"""mkdocs hook: Sphinx roles in docstrings (``:class:`~a.b.C```) shown as code.

mkdocstrings renders numpy docstrings as Markdown, where a Sphinx role stays as
text (``:class:<code>~a.b.C</code>``). This turns each into ``<code>C</code>``
(the last component after ``~``, as Sphinx shows it; the full name otherwise).
"""

from __future__ import annotations

import re
from typing import Any

_ROLE = re.compile(
    r":(?:py:)?(?:class|func|meth|mod|attr|data|exc|obj|const|term):<code>(~?)([^<]+)</code>"
)


def _short(m: re.Match[str]) -> str:
    name = m.group(2).strip()
    if m.group(1):
        name = name.rsplit(".", 1)[-1]
    return f"<code>{name}</code>"


def on_page_content(html: str, **kwargs: Any) -> str:
    return _ROLE.sub(_short, html)
