"""MkDocs hook for the API reference: the source under its import names, and Sphinx roles.

The repository keeps its packages in top-level folders (``models/``, ``reference_ode/``,
``mujoco_runner/``, ``compare/``) and installs them as ``tippetop.models`` and so on
(pyproject.toml's ``package-dir``). griffe, which reads the source for mkdocstrings, finds a
package by its folder's name, so this hook links the folders under
``build/docs-api/tippetop/`` (``build/`` is ignored by git), the search path properdocs.yml gives
the python handler. The links are made at start-up (:func:`on_startup`), before mkdocstrings
reads its paths.

The docstrings name other objects with Sphinx roles (``:func:`simulate_ode```), which the Google
style renders as text: the API pages drop the role and keep the name in code (``~`` and a
leading ``.`` of a relative name too).
"""

from __future__ import annotations

import os
import re
import shutil
import sys
from pathlib import Path

from mkdocs.config.defaults import MkDocsConfig
from mkdocs.exceptions import PluginError
from mkdocs.structure.files import Files
from mkdocs.structure.pages import Page

#: The packages: import name under ``tippetop`` -> folder in the repository.
PACKAGES = ("models", "reference_ode", "mujoco_runner", "compare")

#: The search path, relative to properdocs.yml (the python handler's ``paths``).
API_SRC = Path("build") / "docs-api"


def on_startup(command: str, dirty: bool) -> None:
    """Link each package folder as ``build/docs-api/tippetop/<name>``.

    At start-up, before any plugin's ``on_config``: mkdocstrings resolves the handler's
    ``paths`` there, and leaves out one that does not exist yet (a fresh clone's first build).
    """
    link_packages(Path(__file__).resolve().parents[2])


def link_packages(root: Path) -> None:
    """Link each package folder of the repository at ``root`` under ``build/docs-api``."""
    ns = root / API_SRC / "tippetop"
    if ns.is_symlink() or ns.is_file():
        ns.unlink()
    ns.mkdir(parents=True, exist_ok=True)
    for name in PACKAGES:
        src, link = root / name, ns / name
        if not (src / "__init__.py").is_file():
            raise PluginError(f"docs: package folder {src} is missing")
        if link.is_symlink() and Path(os.readlink(link)) == src:
            continue
        if link.is_symlink() or link.is_file():
            link.unlink()
        elif link.is_dir():
            shutil.rmtree(link)
        link.symlink_to(src, target_is_directory=True)
    # `properdocs` (or `mkdocs`) run as a console script has its bin folder first on
    # sys.path, and in it the `tippetop` script, which griffe would take for a portion of the
    # namespace package
    sys.path[:] = [p for p in sys.path if not (Path(p or ".") / "tippetop").is_file()]


#: A Sphinx role in front of the code it names, as the page's HTML has it.
_ROLE = re.compile(r":(?:py:)?(?:func|meth|class|mod|data|attr|exc|obj|const):<code>~?\.?")


def on_page_content(html: str, page: Page, config: MkDocsConfig, files: Files) -> str:
    """Drop the Sphinx roles of the docstrings on the API pages."""
    if not page.file.src_uri.startswith("api/"):
        return html
    return _ROLE.sub("<code>", html)
