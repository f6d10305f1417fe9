"""An mkdocs hook: the 404 page with links relative to the site's root, like every other page.

mkdocs writes ``404.html`` with absolute links (``/assets/...``, ``/gallery/``): they break when the
site is served under a sub-path (a project site, ``https://host/pinnedballs/``) or opened from disk.
``404.html`` sits at the site's root, so a link relative to it reaches the same file from there.
"""

from __future__ import annotations

import re
from pathlib import Path

_ABSOLUTE = re.compile(r'(href|src)="/(?!/)')


def relative(html: str) -> str:
    """``html`` with its root-absolute links (``href="/x"``, ``src="/x"``) and material's ``"base": "/"`` made
    relative."""
    html = _ABSOLUTE.sub(r'\1="./', html)
    return html.replace('"base": "/"', '"base": "."')


def on_post_build(config, **kwargs) -> None:
    page = Path(config["site_dir"]) / "404.html"
    if page.exists():
        page.write_text(relative(page.read_text(encoding="utf-8")), encoding="utf-8")
