"""Build hooks; everything else is in pyproject.toml.

* The git commit a wheel or sdist is built from goes to
  ``frictionregimes/_commit.txt``, which ``frictionregimes.__version__`` reads
  where no git clone is at hand.
* The example studies live once, in ``examples/`` at the top of the
  repository (where a clone runs them); a wheel carries a copy of every file
  there as ``frictionregimes/examples/`` (``study examples``).
"""

import importlib.util
import shutil
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


def _copy_examples(build_lib: str) -> None:
    source = Path(__file__).resolve().parent / "examples"
    target = Path(build_lib) / "frictionregimes" / "examples"
    if source.is_dir():
        target.mkdir(parents=True, exist_ok=True)
        for path in sorted(source.iterdir()):
            if path.is_file():
                shutil.copy2(path, target / path.name)


class BuildPy(build_py):
    def run(self):
        super().run()
        if not self.editable_mode:  # an editable install reads the clone's examples/
            _write(self.build_lib)
            _copy_examples(self.build_lib)


class Sdist(sdist):
    def make_release_tree(self, base_dir, files):
        super().make_release_tree(base_dir, files)
        _write(base_dir)


setup(cmdclass={"build_py": BuildPy, "sdist": Sdist})
