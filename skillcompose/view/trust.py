"""What the viewer takes from a page's address or a run's files, and what it refuses.

A page's address and the files viewed may come from someone else (a link, a folder of runs
received), so everything in them is data, checked here before it is used:

- :func:`address_problem`: a value of a page's address is at most
  :data:`MAX_ADDRESS_VALUE` characters and holds no control character (``?path=%00``);
- :func:`file_below`: a file named by the address is the file given on the command line or a
  regular file inside the folder served (links followed; :mod:`.folder`);
- :func:`task_refusal` / :func:`request_refusal`: which task module a page may import (see
  docs/viewer.md, "What the viewer imports");
- :func:`checked_settings`: a task setting that names a file names one inside the folder;
- :func:`seed_of`: a seed is a whole number within ``MAX_SEED``.

Nothing here imports NiceGUI.
"""

from __future__ import annotations

import ipaddress
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from skillcompose.errors import clip, control_characters, one_line
from skillcompose.limits import MAX_SEED
from skillcompose.origins import inside, is_file_target, module_origins

from .folder import OutsideFolder, resolve_below

__all__ = ["MAX_ADDRESS_VALUE", "REFRESH_S", "ViewerConfig", "address_problem", "checked_settings",
           "file_below", "request_refusal", "seed_of", "task_refusal"]

REFRESH_S = 1.0
"""Seconds between two listings of the viewer's folder by default (``--refresh``): the
runs page reads the run directories again, the live page looks for new live files."""
MAX_ADDRESS_VALUE = 4096  # the longest value of a page's address the viewer reads


@dataclass(frozen=True)
class ViewerConfig:
    """What ``skillcompose view`` was asked to show, and how it serves it."""

    root: Path  # the folder whose runs, FSA files and live files are listed
    file: Path | None = None  # an FSA file given on the command line
    task: str | None = None  # a task module for units, validation and replays
    settings: Mapping[str, Any] = field(default_factory=dict)
    label: str = ""  # the root as the command line named it, for the pages to show
    token: str | None = None  # the access token every request must carry (None: none)
    remote: bool = False  # it listens beyond loopback (--allow-remote)
    port: int = 0  # the port it listens on (names the token's cookie)
    refresh: float = REFRESH_S  # seconds between two listings of the folder


def address_problem(name: str, value: str) -> str | None:
    """Why the value ``value`` of a page address's ``name`` cannot be used (None: it can):
    longer than :data:`MAX_ADDRESS_VALUE` characters, or holding a control character."""
    if len(value) > MAX_ADDRESS_VALUE:
        return (f"the address's {name} is {len(value)} characters long; the viewer reads at "
                f"most {MAX_ADDRESS_VALUE}")
    bad = control_characters(value)
    if bad:
        codes = ", ".join(dict.fromkeys(f"U+{ord(c):04X}" for c in bad))
        return (f"the address's {name} holds a control character ({codes}); no file, task or "
                "setting is named so")
    return None


def file_below(config: ViewerConfig, path: Path) -> Path | None:
    """The folder inside which ``path`` is read (the root, or the folder of the file given
    on the command line when ``path`` is that file), or None when the viewer does not show
    it: links followed, it leads outside the folder."""
    try:
        real = Path(os.path.realpath(path))
        if config.file is not None and real == Path(os.path.realpath(config.file)):
            return config.file.parent
        resolve_below(path, config.root)
    except (OSError, ValueError):
        return None
    return config.root


def seed_of(text: str) -> int | str:
    """The seed a page's address gives (default 0), or why it is not one."""
    text = text.strip() or "0"
    if not (text.isascii() and text.isdigit()) or len(text) > 19 or int(text) > MAX_SEED:
        return f"seed {clip(one_line(text), 40)!r} is not a whole number from 0 to {MAX_SEED}"
    return int(text)


def request_refusal(headers: Mapping[str, str]) -> str | None:
    """Why a page request may not have the viewer import a task it names (None: it may): it
    came from another site's page (the browser says so in ``Sec-Fetch-Site``; any page
    open in the person's browser can send a request to this machine), or it named a host
    that is not an address (a name of someone else's that was made to point at this
    machine)."""
    if headers.get("sec-fetch-site", "") in ("cross-site", "same-site"):
        return "the request came from another site's page"
    host = urlsplit("//" + headers.get("host", "")).hostname or ""
    if host != "localhost":
        try:
            ipaddress.ip_address(host)
        except ValueError:
            return f"the request named host {host!r}, not an address of this machine"
    return None


def task_refusal(config: ViewerConfig, target: str, request: str | None) -> str | None:
    """Why the viewer will not import task module ``target`` (None: it may). The task given
    on the command line always may. One named by a page's address or by a run's
    ``run.json`` only as a module name (not a file), found outside the folder being viewed
    (code that came with the runs viewed is never run), and only for a request of this
    viewer's own pages or the person's (``request``: :func:`request_refusal`'s answer)."""
    if config.task is not None and target == config.task:
        return None
    shown = clip(one_line(target), 200)
    fix = f"give it on the command line: skillcompose view ... --task {shown}"
    if request is not None:
        return f"task {shown} not imported: {request}; open the page from the viewer, or {fix}"
    if is_file_target(target):
        return (f"task {shown} not imported: the viewer imports a task file only when it is "
                f"given on its command line; {fix}")
    if not all(part.isidentifier() for part in target.split(".")):
        return f"task {shown} not imported: it is not a module name (such as examples.toy_task)"
    for origin in module_origins(target):
        if inside(origin, config.root) or (
                config.file is not None and inside(origin, config.file.parent)):
            return (f"task {shown} not imported: it would be imported from {origin}, inside "
                    "the folder being viewed, and code that came with the runs viewed is "
                    f"never run; check it, then {fix}")
    return None


def checked_settings(config: ViewerConfig, settings: Mapping[str, Any]
                     ) -> tuple[dict[str, Any], str | None]:
    """``settings`` a page's address or a run's ``run.json`` names for a task, as the task
    may get them, or why they are refused. A task may read a file a setting names (the
    stacking task's ``move_to_reach``), so a text value that names a path (it holds ``/``
    or ``\\``, or names a file in the folder or in the current directory) is taken relative
    to the folder served and must lead (links followed) to a regular file inside it; the
    task gets that file's full path. A value given on the command line (``--set``) is
    taken as it is."""
    out: dict[str, Any] = {}
    root = Path(os.path.realpath(config.root))
    for key, value in settings.items():
        if not isinstance(value, str) or config.settings.get(key, object()) == value:
            out[key] = value
            continue
        shown = f"task setting {clip(one_line(str(key)), 40)}={clip(one_line(value), 80)}"
        refused = (f"{shown} not used: it names a file outside the folder served ({root}); "
                   "the viewer hands a task only files inside it (give another file with "
                   "--set on the command line)")
        try:
            if address_problem(str(key), value) is not None:
                return {}, f"{shown} not used: it holds a control character or is too long"
            names_path = "/" in value or "\\" in value or value.startswith("~")
            if not names_path:
                if os.path.lexists(value) and not Path(os.path.realpath(value)).is_relative_to(
                        root):  # the task would read it from the current directory
                    return {}, refused
                names_path = (root / value).is_file()
            if not names_path:
                out[key] = value
                continue
            real = resolve_below(value, root)
        except (OutsideFolder, OSError, ValueError):
            return {}, refused
        if not real.is_file():
            return {}, f"{shown} not used: no such file inside the folder served ({root})"
        out[key] = str(real)
    return out, None
