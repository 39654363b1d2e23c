"""MkDocs hook: put the generated API pages into the navigation under "API reference".

The nav in mkdocs.yml names ``api/index.md``; this adds one entry per package found by
``packages.py``, the same walk that generates the pages, so no module list is kept by hand.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from packages import packages, page_path  # noqa: E402

SECTION = "API reference"


def on_config(config, **kwargs):
    for entry in config["nav"] or []:
        if isinstance(entry, dict) and SECTION in entry:
            entry[SECTION] = ["api/index.md", *({p: page_path(p)} for p in packages())]
            return config
    raise ValueError(f"mkdocs.yml: the nav has no '{SECTION}' section for the generated API pages")
