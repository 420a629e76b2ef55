"""``study examples``: the example studies shipped with the package.

The files live once, in the repository's ``examples/`` folder, which is
installed as package data (``frictionregimes/examples``), so a non-editable
install can list them and write one out::

    study examples                              # names and descriptions
    study examples quickstart -o quickstart.toml
    study run quickstart.toml -o quickstart.nc
"""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

from frictionregimes import examples, examples_dir
from study.errors import StudyError


def describe(path: Path) -> str:
    """One line: a study's ``[study] description`` or a Markdown file's title."""
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".toml":
        try:
            return str(tomllib.loads(text).get("study", {}).get("description", ""))
        except tomllib.TOMLDecodeError:
            return ""
    for line in text.splitlines():
        if line.startswith("#"):
            return line.lstrip("# ").strip()
    return ""


def list_examples() -> str:
    """The table printed by ``study examples``."""
    found = examples()
    width = max(len(name) for name in found)
    lines = [f"examples in {examples_dir()}:"]
    for name, path in found.items():
        lines.append(f"  {name:<{width}}  {path.suffix[1:]:<4}  {describe(path)}")
    lines.append("write one out: study examples NAME -o FILE")
    return "\n".join(lines)


def write_example(name: str, output: Path | None = None) -> Path | None:
    """Write the example ``name`` (with or without its suffix) to ``output`` or stdout.

    Raises
    ------
    StudyError
        Unknown name, or ``output`` exists already (nothing is overwritten).
    """
    found = examples()
    key = Path(name).stem if Path(name).suffix in (".toml", ".md") else name
    if key not in found:
        raise StudyError("examples", f"no example {name!r}; one of: {', '.join(found)}")
    text = found[key].read_text(encoding="utf-8")
    if output is None:
        sys.stdout.write(text)
        return None
    if output.exists():
        raise StudyError("-o", f"{output} exists; remove it or choose another name")
    if not output.parent.is_dir():
        raise StudyError("-o", f"output directory does not exist: {output.parent}")
    output.write_text(text, encoding="utf-8")
    print(f"study: wrote {output}", file=sys.stderr)
    return output
