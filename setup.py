"""Build hook: record the git commit a wheel or sdist is built from.

Everything else is in pyproject.toml. The commit ends up in
``frictionregimes/_commit.txt`` inside the wheel (and the sdist), which
``frictionregimes.__version__`` reads where no git clone is at hand.
"""

import importlib.util
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py
from setuptools.command.sdist import sdist


def _commit() -> str | None:
    """The commit of this clone, by the same code as ``frictionregimes.__version__``."""
    root = Path(__file__).resolve().parent
    init = root / "frictionregimes" / "__init__.py"
    spec = importlib.util.spec_from_file_location("_fr_version", init)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module._git_commit(root)


def _write(folder: str) -> None:
    commit = _commit()
    target = Path(folder) / "frictionregimes"
    if commit and target.is_dir():
        (target / "_commit.txt").write_text(commit + "\n")


class BuildPy(build_py):
    def run(self):
        super().run()
        if not self.editable_mode:
            _write(self.build_lib)


class Sdist(sdist):
    def make_release_tree(self, base_dir, files):
        super().make_release_tree(base_dir, files)
        _write(base_dir)


setup(cmdclass={"build_py": BuildPy, "sdist": Sdist})
