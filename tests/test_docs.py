"""The README and docs/ are true: every snippet runs, every table matches the code and a file.

- every ```python block of README.md and docs/*.md runs as a script (``python
  snippet.py``, so a snippet that starts Dask worker processes needs its
  ``__main__`` guard, as a user's script does) in a folder holding ``examples/``
  and the ``quickstart.nc`` the README's commands write;
- every ``study ...`` line of a ```bash block runs through the CLI, block by
  block, in a fresh folder (exit code 0);
- every ```toml block is a valid study (or scene);
- the variable, coordinate and attribute tables of docs/results.md match
  ``tasks.result.FIELDS``, the adaptive and trace fields, and a file written by
  ``study run`` (name, dtype, dims of every variable);
- the module list of docs/development.md is the code's, every relative link
  resolves, and the README stays a front door.
"""

from __future__ import annotations

import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from conftest import ROOT, assert_documented_lines_ran, docs_env, study_cli

from study import Study
from study.trace import TRACE_FIELDS
from tasks.adaptive import ADAPTIVE_FIELDS
from tasks.result import FIELDS, field_attrs

PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)
#: A commit hash: 7-40 hex digits with a letter and a digit.
HASH = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")
SNIPPET_TIMEOUT = 600  # seconds; the first simulation of a fresh checkout compiles
#: The README's command that writes the file the python snippets read.
RUN_QUICKSTART = "study run examples/quickstart.toml -o quickstart.nc"


def blocks(lang: str) -> list[tuple[str, str]]:
    """(id, text) of every fenced block of ``lang`` in the README and docs/."""
    out = []
    for page in PAGES:
        found = [m.group(2) for m in FENCE.finditer(page.read_text()) if m.group(1) == lang]
        out += [(f"{page.relative_to(ROOT)}#{i}", text) for i, text in enumerate(found)]
    return out


def study_lines(text: str) -> list[str]:
    return [line.strip() for line in text.splitlines() if line.strip().startswith("study ")]


BASH = [(w, t) for w, t in blocks("bash") if study_lines(t)]


@pytest.fixture(scope="module")
def quickstart(documented_runs) -> Path:
    """The workspace where the README's block of ``study`` commands ran: it holds the
    ``quickstart.nc`` they write (the same run test_study_commands_run checks)."""
    lines = study_lines(next(t for _, t in BASH if RUN_QUICKSTART in t))
    ws, procs = documented_runs(lines)
    assert_documented_lines_ran(lines, procs, "README")
    return ws


# --------------------------------------------------------------------------- snippets
@pytest.mark.parametrize(("where", "code"), blocks("python"), ids=[b[0] for b in blocks("python")])
def test_python_snippet_runs_as_a_script(where, code, quickstart, tmp_path):
    script = tmp_path / "snippet.py"
    script.write_text(code)
    done = subprocess.run(
        [sys.executable, str(script)],
        cwd=quickstart,
        env=docs_env(),
        capture_output=True,
        text=True,
        timeout=SNIPPET_TIMEOUT,
    )
    assert done.returncode == 0, f"{where}:\n{code}\n{done.stderr[-3000:]}"
    assert "Traceback" not in done.stderr, f"{where}:\n{done.stderr[-3000:]}"


@pytest.mark.parametrize(("where", "text"), BASH, ids=[b[0] for b in BASH])
def test_study_commands_run(where, text, documented_runs):
    """Each block's lines in order in a fresh folder (once per session: tests of what
    a documented command wrote look at the same run)."""
    lines = study_lines(text)
    _, procs = documented_runs(lines)
    assert_documented_lines_ran(lines, procs, where)


def test_the_readme_commands_are_the_documented_ones():
    """The README's first block sets up and runs the quickstart and the tests; CI runs
    the same test command (the commands themselves run in test_study_commands_run)."""
    first = blocks("bash")[0][1]
    assert "study run examples/quickstart.toml -o quickstart.nc" in first
    assert 'pip install -e ".[test]" && ruff check . && python -m pytest -q' in first
    assert "python -m pytest -q" in (ROOT / ".ci" / "run").read_text()


@pytest.mark.parametrize(("where", "text"), blocks("toml"), ids=[b[0] for b in blocks("toml")])
def test_toml_snippet_is_a_valid_study(where, text):
    study = Study.from_dict(tomllib.loads(text))
    assert study.scenes


def test_labelled_plot_snippet_has_the_guard_and_regime_names():
    """Pasted into a script, the plot snippet must not start workers at import, and its
    colour bar names the regimes instead of -0.5 / 0.5 / 1.5 / 2.5."""
    (plot,) = [c for w, c in blocks("python") if "run_study(" in c and w.startswith("README")]
    assert 'if __name__ == "__main__":' in plot
    assert plot.index('if __name__ == "__main__":') < plot.index("run_study(Study")
    assert "set_ticklabels" in plot and '"no motion"' in plot


# --------------------------------------------------------------------------- results.md
def md_table(text: str, header_start: str) -> list[list[str]]:
    """Rows (cells stripped) of the markdown table whose header starts with ``header_start``."""
    lines = text[text.index(header_start) :].splitlines()
    rows = []
    for line in lines[2:]:
        if not line.startswith("|"):
            break
        rows.append([c.strip() for c in re.split(r"(?<!\\)\|", line.strip())[1:-1]])
    return rows


def names(cell: str) -> list[str]:
    return re.findall(r"`([^`]+)`", cell)


def dims_of(cell: str) -> tuple[str, ...] | None:
    """``(mass, beta, r)`` -> ("mass", "beta", "r"); ``-`` -> None."""
    m = re.search(r"`\(([^)]*)\)`", cell)
    if m is None:
        assert cell.strip() == "-", cell
        return None
    return tuple(d.strip() for d in m.group(1).split(",") if d.strip())


RESULTS = (ROOT / "docs" / "results.md").read_text()
VARIABLES = {
    name: row for row in md_table(RESULTS, "| variable | dtype |") for name in names(row[0])
}
TINY = """
[study]
name = "tiny"

[settings]
design = true  # the variable tables list the design quantities too

[[scene]]
name = "grid"
contact = "ground"
dof = 2
kappa = {values = [0.5, 1.0]}
r = {start = 0.5, stop = 1.5, num = 4}
beta = {start = 0.0, stop = 1.2, num = 3}

[[scene]]
name = "points"
contact = "mass"
dof = 2
points = [[0.4, 0.1], [0.9, 0.05]]

[[scene]]
name = "adaptive"
contact = "ground"
dof = 1
mode = "adaptive"
coarse_step = 4
r = {start = 0.5, stop = 1.5, num = 9}
beta = {start = 0.0, stop = 1.5, num = 9}

[[scene]]
name = "matrices"
contact = {between = [0, 1]}
damping = {rayleigh = [0.05, 0.0]}
r = {start = 0.5, stop = 1.5, num = 3}
beta = {start = 0.0, stop = 1.2, num = 3}
[scene.matrices]
mass = [[1.0, 0.0], [0.0, 2.0]]
stiffness = [[2.0, -1.0], [-1.0, 1.0]]
load = [1.0, 0.0]

[[scene]]
name = "contacts"
contact = "ground"
dof = 2
contact_mass = [1, 2]
beta_ratio = [1.0, 0.5]
r = {start = 0.5, stop = 1.5, num = 3}
beta = {start = 0.0, stop = 1.2, num = 3}

[[scene]]
name = "contacts_points"
contact = [{ground = 0}, {between = [0, 1]}]
beta_ratio = [1.0, 2.0]
points = [[0.4, 0.1], [0.9, 0.05]]
[scene.matrices]
mass = [[1.0, 0.0], [0.0, 2.0]]
stiffness = [[2.0, -1.0], [-1.0, 1.0]]
load = [1.0, 0.0]
"""
STRUCTURE_TABLE = {
    name: row
    for row in md_table(RESULTS, "| structure variable | dtype |")
    for name in names(row[0])
}


@pytest.fixture(scope="module")
def written(tmp_path_factory) -> xr.DataTree:
    """A grid with a sweep, a point list and an adaptive map, written by ``study run``."""
    ws = tmp_path_factory.mktemp("written")
    (ws / "tiny.toml").write_text(TINY)
    done = study_cli("study run tiny.toml -o tiny.nc --quiet", ws)  # small: in this process
    assert done.returncode == 0, done.stderr
    tree = xr.open_datatree(ws / "tiny.nc")
    yield tree
    tree.close()


def test_variable_table_matches_the_fields_of_the_code():
    every = {**FIELDS, **ADAPTIVE_FIELDS, **TRACE_FIELDS}
    boundaries = {f"beta_{b}_{m}" for b in ("continuous", "motion") for m in ("paper", "exact")}
    assert set(VARIABLES) == set(every) | boundaries
    for name, (dtype, _) in every.items():
        assert VARIABLES[name][1] == dtype, name
    for name in FIELDS:  # the meaning starts with the stored long_name
        assert VARIABLES[name][5].startswith(str(field_attrs(name)["long_name"])), name
        assert dims_of(VARIABLES[name][4]) is None  # not in a traced scene
    for name in TRACE_FIELDS:
        assert dims_of(VARIABLES[name][4]) == ("r",)
        assert dims_of(VARIABLES[name][2]) is None and dims_of(VARIABLES[name][3]) is None


@pytest.mark.parametrize(
    ("scene", "column"), [("grid", 2), ("points", 3), ("adaptive", 2), ("matrices", 2)]
)
def test_variable_table_matches_a_written_file(written, scene, column):
    ds = written[scene].to_dataset().drop_vars(STRUCTURE_TABLE, errors="ignore")
    sweeps = {"gamma", "kappa"}
    expected = {
        name
        for name, row in VARIABLES.items()
        if dims_of(row[column]) is not None
        and (scene == "adaptive" or "adaptive only" not in row[column])
        and "with a rest start" not in row[column]  # TINY has the default start only
    }
    assert set(ds.data_vars) == expected
    for name in ds.data_vars:
        var = ds[name]
        row = VARIABLES[name]
        assert str(var.dtype) == row[1], name
        assert tuple(d for d in var.dims if d not in sweeps) == dims_of(row[column]), name
        if var.dtype.kind != "f":  # codes stay codes: no fill value, never decoded to float
            assert var.encoding.get("_FillValue") is None, name
    for name in ds.data_vars:  # swept ratios come first
        dims = ds[name].dims
        assert [d for d in dims if d in sweeps] == list(dims[: len(set(dims) & sweeps)]), name


def test_structure_table_matches_the_code_and_a_written_file(written):
    """A scene of matrices stores its matrices (results.md); the chain scenes do not."""
    from study.structures import STRUCTURE_VARIABLES

    assert set(STRUCTURE_TABLE) == set(STRUCTURE_VARIABLES)
    ds = written["matrices"].to_dataset()
    for name, row in STRUCTURE_TABLE.items():
        assert str(ds[name].dtype) == row[1], name
        assert ds[name].dims == dims_of(row[2]) == STRUCTURE_VARIABLES[name][0], name
    assert ds.damping_matrix.attrs["damping"] == "rayleigh 0.05 0.0"
    for scene in ("grid", "points", "adaptive"):
        assert not set(STRUCTURE_TABLE) & set(written[scene].to_dataset().data_vars), scene


def test_coordinate_table_matches_a_written_file(written):
    rows = {n: row for row in md_table(RESULTS, "| coordinate | dtype |") for n in names(row[0])}
    seen = set()
    for scene in ("grid", "points", "adaptive", "matrices"):
        ds = written[scene].to_dataset()
        for name in ds.coords:
            assert name in rows, name
            assert str(ds[name].dtype) == rows[name][1], name
            seen.add(name)
    assert seen == set(rows)


def test_every_written_attribute_is_documented(written):
    section = RESULTS[RESULTS.index("## Attributes") : RESULTS.index("## Figures")]
    documented = set(re.findall(r"`([A-Za-z_0-9]+)`", section))
    for scene in ("grid", "points", "adaptive", "matrices"):
        missing = set(written[scene].to_dataset().attrs) - documented
        assert not missing, (scene, missing)
    assert not set(written.attrs) - documented


@pytest.mark.parametrize(("scene", "column"), [("contacts", 2), ("contacts_points", 3)])
def test_contact_tables_match_the_code_and_a_written_file(written, scene, column):
    """Scenes with several contacts (results.md): variables, dims, coordinates, attributes."""
    from study.contacts import MULTI_DTYPES

    rows = {
        n: row for row in md_table(RESULTS, "| contact variable | dtype |") for n in names(row[0])
    }
    ds = written[scene].to_dataset()
    assert set(ds.data_vars) == {n for n in rows if "with a rest start" not in rows[n][column]}
    assert set(MULTI_DTYPES) == {n for n in rows if "dof" not in rows[n][2]}
    for name in ds.data_vars:
        assert str(ds[name].dtype) == rows[name][1], name
        assert ds[name].dims == dims_of(rows[name][column]), name
    coords = {
        n: row for row in md_table(RESULTS, "| contact coordinate | dtype |") for n in names(row[0])
    }
    plain = {"r", "beta", "point"}
    assert set(ds.coords) - plain == set(coords)
    for name, row in coords.items():
        assert ds[name].dims == dims_of(row[2]), name
    section = RESULTS[RESULTS.index("## Attributes") : RESULTS.index("## Figures")]
    assert not set(ds.attrs) - set(re.findall(r"`([A-Za-z_0-9]+)`", section))
    assert "n_contacts" in ds.attrs and "contact_mass" not in ds.attrs


def test_regime_stays_int8_codes_in_a_written_file(written):
    """results.md: no fill value, int8 codes, never not_computed in ``regime``; the bit
    mask of ``regimes_reached`` has CF flag_masks."""
    ds = written["grid"].to_dataset()
    assert ds.regime.dtype == np.int8 and int(ds.regime.min()) >= -5
    assert "flag_values" in ds.regime.attrs
    masks = ds.regimes_reached.attrs["flag_masks"]
    assert list(masks) == [1, 2, 4, 8]
    assert ds.regimes_reached.attrs["flag_meanings"].split()[-1] == "undetermined"


# --------------------------------------------------------------------------- structure
def test_development_lists_every_module():
    text = (ROOT / "docs" / "development.md").read_text()
    layout = next(
        b for lang, b in ((m.group(1), m.group(2)) for m in FENCE.finditer(text)) if not lang
    )
    listed: dict[str, set[str]] = {}
    package = None
    for line in layout.splitlines():
        if re.match(r"^(tasks|analysis|study)/", line):
            package = line.split("/")[0]
            listed[package] = set()
        elif package and line.startswith("  ") and line.strip():
            listed[package].add(line.split()[0])
        elif line and not line.startswith(" "):
            package = None
    for package in ("tasks", "analysis", "study"):
        modules = {p.name for p in (ROOT / package).glob("*.py") if p.name != "__init__.py"}
        modules |= {
            f"{p.name}/" for p in (ROOT / package).iterdir() if (p / "__init__.py").exists()
        }
        assert listed[package] == modules, (package, listed[package] ^ modules)


def slug(title: str) -> str:
    """GitHub's anchor of a heading."""
    title = re.sub(r"[^\w\- ]", "", title.strip().lower())
    return title.replace(" ", "-")


def test_relative_links_resolve():
    for page in PAGES:
        text = page.read_text()
        for target in re.findall(r"\]\(([^)\s]+)\)", text):
            if re.match(r"^[a-z]+:", target):
                continue
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page
            assert dest.exists(), (page.name, target)
            if anchor and dest.suffix == ".md":
                heads = re.findall(r"^#+ (.+)$", dest.read_text(), re.M)
                assert anchor in {slug(h) for h in heads}, (page.name, target)


def test_readme_is_a_front_door():
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) <= 300
    assert not HASH.search(text)  # no commit hashes, no history
    assert "this round" not in text.lower() and "(before" not in text
    tables = [line for line in text.splitlines() if line.startswith("|---")]
    assert len(tables) == 2  # the measurements and the documentation index


def test_benchmarks_page_names_a_script_for_every_measurement():
    text = (ROOT / "docs" / "benchmarks.md").read_text()
    sections = re.split(r"^## ", text, flags=re.M)[1:]
    for section in sections:
        scripts = re.findall(r"benchmarks/(\w+\.py)|`(study (?:bench|run|report)) ", section)
        assert scripts, section.splitlines()[0]
        for script, _ in scripts:
            assert not script or (ROOT / "benchmarks" / script).exists(), script
    assert not HASH.search(text) and "this round" not in text and "(before" not in text


def test_preset_table_is_the_code():
    from tasks import PRESETS

    rows = md_table((ROOT / "docs" / "api.md").read_text(), "| setting | fast | balanced |")
    assert rows
    for row in rows:
        (name,) = names(row[0])
        for preset, cell in zip(("fast", "balanced", "exact"), row[1:4], strict=True):
            assert float(cell) == float(getattr(PRESETS[preset], name)), (name, preset)
