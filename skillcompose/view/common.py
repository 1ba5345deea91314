"""What every page of the viewer shares: its header, how it shows an error (one line, never a
traceback), and how it names a file (as the person named the folder)."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from nicegui import ui

from skillcompose.errors import SkillcomposeError, clip, one_line, printable

from .trust import ViewerConfig

__all__ = ["MAX_ERROR_CHARS", "MAX_TASK_ERROR_CHARS", "error_text", "header", "rel_path",
           "reraise", "safe", "show_error", "shown_path"]

log = logging.getLogger("skillcompose.view")

MAX_ERROR_CHARS = 2000  # the most of an error message a page shows
MAX_TASK_ERROR_CHARS = 300  # ... of an error loading a task (it may quote other files)


def error_text(exc: BaseException, limit: int = MAX_ERROR_CHARS) -> str:
    """An error as a page shows it: printable (one line, or one line per problem listed),
    at most ``limit`` characters."""
    return clip(printable(exc), limit)


def show_error(text: str) -> None:
    ui.label(text).classes("text-red-700 whitespace-pre-wrap").props("data-testid=error")


def safe(where: str, build: Callable[[], None]) -> None:
    """Run a page part; show what went wrong as one line instead of a traceback."""
    try:
        build()
    except SkillcomposeError as exc:
        show_error(f"{where}: {error_text(exc)}")
    except Exception as exc:
        log.warning("%s: %s: %s", where, type(exc).__name__, clip(one_line(str(exc)), 300))
        show_error(f"{where}: unexpected {type(exc).__name__}: {error_text(exc, 300)}")


def reraise(exc: BaseException) -> None:
    raise exc


def header(active: str) -> None:
    with ui.header().classes("items-center bg-slate-800 py-2 px-4 gap-6"):
        ui.label("skillcompose view").classes("text-lg font-semibold text-white")
        for name, url in (("Runs", "/"), ("FSA", "/fsa"), ("Replay", "/replay"),
                          ("Live", "/live")):
            link = ui.link(name, url).classes("text-white no-underline text-base")
            if name == active:
                link.classes("border-b-2 border-amber-400 font-semibold")


def shown_path(config: ViewerConfig, path: Path) -> str:
    """``path`` as the person named it: below the root as given on the command line."""
    try:
        rel = path.resolve().relative_to(config.root.resolve())
    except (ValueError, OSError):
        return str(path)
    if not config.label:
        return str(path)
    return str(Path(config.label) / rel) if rel.parts else config.label


def rel_path(config: ViewerConfig, path: Path) -> str:
    """``path`` relative to the root, when it lies there."""
    try:
        return str(path.relative_to(config.root))
    except ValueError:
        return str(path)
