"""Labels and fields of every paper panel against a saved run (a change to the steady-state search).

Run from the repository root::

    .venv/bin/python benchmarks/check_panels.py save before.npz [--size 100x40] [--code DIR]
        [--start rest] [--warm off] [--starts held,rest]
    .venv/bin/python benchmarks/check_panels.py save after.npz [--size 100x40]
    .venv/bin/python benchmarks/check_panels.py compare before.npz after.npz

``save`` classifies every scene of ``examples/fig*.toml`` (23 panels; held
start or ``--start rest``, preset ``balanced``, design quantities on) on a grid
of ``--size`` points over the panel's r and beta ranges (default: the
example's own 250 x 100), one call per panel in the study's order (r outer,
beta inner), and saves every field with the CPU seconds per panel; ``--code
DIR`` imports ``tasks`` from another checkout (e.g. main before a change);
``--warm on|off`` sets the warm starts (default: the checkout's default);
``--starts held,rest`` compares starts at every point (``start_dependent``,
``regime_rest``, ``regimes_reached`` are saved and compared too). ``compare``
prints, per panel, the points whose regime, stops or start fields differ (they
must be none), the largest difference of each other field relative to its
scale on the panel (``slip_amplitude``, ``stick_fraction``, ``amplitude``,
``contact_force_amplitude``, ``dissipation``: at most about the steady-state
tolerance), the mean cycles per point by regime class and the CPU time, before
and after.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
# --code DIR: import tasks from another checkout (e.g. main, before the change)
_CODE = sys.argv[sys.argv.index("--code") + 1] if "--code" in sys.argv else str(REPO)
sys.path.insert(0, _CODE)
sys.path.insert(1, str(REPO))

from study.definition import Study  # noqa: E402
from tasks import Scene, classify  # noqa: E402

FIELDS = (
    "regime",
    "stops_per_cycle",
    "cycles",
    "converged",
    "period",
    "asymptotic",
    "slip_amplitude",
    "stick_fraction",
    "amplitude",
    "contact_force_amplitude",
    "dissipation",
)
#: Fields of several starts (``--starts``), compared point for point when both runs have them.
START_FIELDS = ("regime_rest", "regimes_reached", "start_dependent")
#: Fields compared relative to their largest magnitude on the panel.
SCALED = ("slip_amplitude", "stick_fraction", "amplitude", "contact_force_amplitude", "dissipation")
CLASSES = {"no motion": 0, "stick-slip": 1, "continuous": 2}


def panels(size: tuple[int, int] | None):
    """``(name, scene, r, beta)`` of every scene of ``examples/fig*.toml``."""
    for path in sorted((REPO / "examples").glob("fig*.toml")):
        study = Study.from_toml(path)
        for spec in study.scenes:
            r_v, b_v = spec.r.values_array(), spec.beta.values_array()
            if size:
                r_v = np.linspace(r_v[0], r_v[-1], size[0])
                b_v = np.linspace(b_v[0], b_v[-1], size[1])
            r, beta = np.meshgrid(r_v, b_v, indexing="ij")
            yield f"{path.stem}/{spec.name}", spec.base_scene, r, beta


def save(
    output: Path, size: tuple[int, int] | None, only: str | None, start: str, settings: dict
) -> None:
    settings = {"design": True, **settings}  # the design fields compared too (off by default)
    classify(Scene("ground", dof=2), [0.5, 1.5], [0.1, 0.6], **settings)  # compile / load
    arrays = {}
    for name, scene, r, beta in panels(size):
        if only and only not in name:
            continue
        t0 = time.process_time()
        res = classify(scene, r, beta, initial_condition=start, **settings)
        cpu = time.process_time() - t0
        for field in FIELDS + (START_FIELDS if "starts" in settings else ()):
            arrays[f"{name}|{field}"] = np.asarray(getattr(res, field))
        arrays[f"{name}|cpu"] = np.array(cpu)
        print(f"{name}: {r.size} points, {cpu / r.size * 1e6:.0f} us/pt", flush=True)
    np.savez_compressed(output, **arrays)


def _scaled_diff(a: np.ndarray, b: np.ndarray) -> float:
    both = np.isfinite(a) & np.isfinite(b)
    if np.any(np.isfinite(a) != np.isfinite(b)):
        return np.inf
    if not np.any(both):
        return 0.0
    scale = max(np.max(np.abs(a[both])), 1e-300)
    return float(np.max(np.abs(a[both] - b[both])) / scale)


def compare(before: Path, after: Path) -> int:
    a, b = np.load(before), np.load(after)
    names = sorted({k.split("|")[0] for k in a.files} & {k.split("|")[0] for k in b.files})
    head = ["panel", "points", "regime differ", "stops differ"]
    head += [f"max rel {f}" for f in SCALED]
    head += [f"cycles {c}" for c in CLASSES] + ["us/pt before -> after"]
    print("| " + " | ".join(head) + " |\n|" + "---|" * len(head))
    bad = 0
    cpu = [0.0, 0.0]
    total = 0
    for name in names:
        ra, rb = a[f"{name}|regime"], b[f"{name}|regime"]
        sa, sb = a[f"{name}|stops_per_cycle"], b[f"{name}|stops_per_cycle"]
        n_reg = int(np.sum(ra != rb))
        n_stops = int(np.sum(sa != sb))
        for f in START_FIELDS:  # several starts: where both runs compared them
            if f"{name}|{f}" in a.files and f"{name}|{f}" in b.files:
                n_start = int(np.sum(a[f"{name}|{f}"] != b[f"{name}|{f}"]))
                n_reg += n_start
                if n_start:
                    print(f"    {name}: {n_start} points differ in {f}")
        bad += n_reg + n_stops
        cells = [name, str(ra.size), str(n_reg), str(n_stops)]
        cells += [f"{_scaled_diff(a[f'{name}|{f}'], b[f'{name}|{f}']):.1e}" for f in SCALED]
        for code in CLASSES.values():
            m = ra == code
            ca = a[f"{name}|cycles"][m].mean() if m.any() else 0.0
            cb = b[f"{name}|cycles"][m].mean() if m.any() else 0.0
            cells.append(f"{ca:.1f} -> {cb:.1f}")
        ta, tb = float(a[f"{name}|cpu"]), float(b[f"{name}|cpu"])
        cpu[0] += ta
        cpu[1] += tb
        total += ra.size
        cells.append(f"{ta / ra.size * 1e6:.0f} -> {tb / ra.size * 1e6:.0f}")
        print("| " + " | ".join(cells) + " |")
        if n_reg or n_stops:
            idx = np.argwhere((ra != rb) | (sa != sb))[:5]
            for i in idx:
                t = tuple(i)
                print(f"    {name} {t}: regime {ra[t]} -> {rb[t]}, stops {sa[t]} -> {sb[t]}")
    print(
        f"\n{total} points: {bad} label differences; CPU us/pt "
        f"{cpu[0] / total * 1e6:.0f} -> {cpu[1] / total * 1e6:.0f} ({cpu[0] / cpu[1]:.2f}x)"
    )
    return 1 if bad else 0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("save")
    s.add_argument("output", type=Path)
    s.add_argument("--size", default=None, help="N_RxN_BETA, e.g. 100x40 (default: the example's)")
    s.add_argument("--only", default=None, help="only panels whose name contains this")
    s.add_argument("--start", default="held", help="initial condition: held (default) or rest")
    s.add_argument("--code", default=None, help="import tasks from this checkout instead")
    s.add_argument(
        "--warm", choices=("on", "off"), default=None, help="warm starts (default: as set)"
    )
    s.add_argument("--starts", default=None, help="starts to compare, e.g. held,rest")
    c = sub.add_parser("compare")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = ap.parse_args()
    if args.cmd == "save":
        size = tuple(int(v) for v in args.size.split("x")) if args.size else None
        settings = {} if args.warm is None else {"warm": args.warm == "on"}
        if args.starts:
            settings["starts"] = tuple(args.starts.split(","))
        save(args.output, size, args.only, args.start, settings)
    else:
        sys.exit(compare(args.before, args.after))


if __name__ == "__main__":
    main()
