"""Build step beyond pyproject.toml: the user pages of ``docs/`` (every ``docs/*.md`` but the
index and the API page, which are Sphinx scaffolding) go into the wheel as package data,
``taylorball/_pages/*.md``, so that ``taylorball docs TOPIC`` prints them from an installed
wheel. Everything else is configured in pyproject.toml."""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

SKIP = {"index", "api"}


class BuildPyWithPages(build_py):
    def run(self):
        super().run()
        pages = sorted(p for p in Path("docs").glob("*.md") if p.stem not in SKIP)
        dest = Path(self.build_lib) / "taylorball" / "_pages"
        self.mkpath(str(dest))
        for page in pages:
            self.copy_file(str(page), str(dest / page.name))


setup(cmdclass={"build_py": BuildPyWithPages})
