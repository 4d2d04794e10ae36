"""Every tutorial downloadable as a Jupyter notebook (used by ``docs/conf.py``).

myst-nb reads each tutorial (a MyST-markdown notebook, ``file_format: mystnb``), executes it
in this build and writes the executed notebook to the build folder's ``jupyter_execute/``;
:func:`copy_tutorial_notebooks` copies it next to the page's HTML and
:func:`add_notebook_link` links the page to it under its title. No Sphinx import at module
level, so that the tests can check these functions without the docs extra.
"""

import shutil
from pathlib import Path

TUTORIALS = "tutorials"


def tutorial_notebook_name(pagename: str):
    """The notebook file of a tutorial page (``tutorials/01-first-orbit`` ->
    ``01-first-orbit.ipynb``), ``None`` for any other page."""
    folder, _, stem = pagename.rpartition("/")
    return f"{stem}.ipynb" if folder == TUTORIALS else None


def add_notebook_link(body: str, name: str) -> str:
    """The page's HTML body with a download link to its notebook after the title."""
    link = (f'<p class="nb-download"><a class="reference download" href="{name}" download="{name}">'
            f'Download this tutorial as a Jupyter notebook ({name})</a>, executed when these pages were '
            "built.</p>")
    head, sep, rest = body.partition("</h1>")
    return head + sep + link + rest if sep else link + body


def copy_tutorial_notebooks(srcdir, outdir, executed) -> list:
    """Copy each tutorial's executed notebook (``<executed>/tutorials/``, myst-nb's output
    folder) next to its page (``<outdir>/tutorials/``); returns the copies. A tutorial
    without its notebook is an error (the page would link to nothing)."""
    src = Path(executed) / TUTORIALS
    dest = Path(outdir) / TUTORIALS
    pages = sorted((Path(srcdir) / TUTORIALS).glob("*.md"))
    missing = [p.name for p in pages if not (src / f"{p.stem}.ipynb").is_file()]
    if missing:
        try:  # sphinx's own error inside a build; the tests check this without the docs extra
            from sphinx.errors import ExtensionError as Missing
        except ImportError:
            Missing = RuntimeError  # type: ignore[misc,assignment]
        raise Missing(f"no executed notebook in {src} for the tutorials {missing}: were they read by "
                             "myst-nb (file_format: mystnb)?")
    dest.mkdir(parents=True, exist_ok=True)
    return [Path(shutil.copyfile(src / f"{p.stem}.ipynb", dest / f"{p.stem}.ipynb")) for p in pages]
