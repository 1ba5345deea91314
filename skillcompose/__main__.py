"""``python -m skillcompose``: the same as the ``skillcompose`` command."""

from __future__ import annotations

from .cli import main

raise SystemExit(main())
