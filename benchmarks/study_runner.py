"""A study client in a process of its own, for ``bench_adaptive.py --cluster``.

    python benchmarks/study_runner.py CHECKOUT SCHEDULER_ADDRESS

imports ``study`` and ``tasks`` from the checkout ``CHECKOUT`` (this one, or e.g.
main's: ``--code``), connects to the benchmark's scheduler and answers requests,
one JSON line each on standard input: ``{"toml": PATH, "out": PATH, "patch":
[[MODULE, "Class.attribute", VALUE], ...]}`` runs ``study.run_study`` on the
study file with those attributes set for that run only, and prints one JSON
line: ``wall`` (seconds of ``run_study``), ``client_cpu`` (CPU seconds of this
process meanwhile: the client alone, the scheduler runs in the benchmark's
process) and ``log`` (the first line, once connected: ``ready`` and ``module``,
where ``study`` was imported from); with ``"timeline": true`` also ``timeline``:
the workers' compute intervals (``distributed.get_task_stream``), each worker's
busy seconds, the end of the last tile, and the client's steps (arrivals, the
adaptive plan's refinement, sample, finish, the result file) with their start
and seconds, all from the start of ``run_study``. Imports and
the connection happen before the first request, outside the timings. Every
study client of a benchmark runs so, the checkout's own too: the same process
layout for every column.
"""

from __future__ import annotations

import importlib
import io
import json
import sys
import time


def _set(patch: list) -> list:
    """Set ``[module, "Class.attribute", value]`` items; the old values, to restore."""
    old = []
    for module, path, value in patch:
        obj = importlib.import_module(module)
        *owners, name = path.split(".")
        for owner in owners:
            obj = getattr(obj, owner)
        old.append((obj, name, getattr(obj, name)))
        setattr(obj, name, value)
    return old


#: Steps of the client timed by ``timeline`` requests: (module, "Class.method", label).
STEPS = (
    ("study.drive", "_Window.take", "arrival"),
    ("study.drive", "_Window.submit", "submit"),
    ("study.adaptive", "AdaptivePlan._replay", "refinement"),
    ("study.adaptive", "AdaptivePlan._verify", "sample drawn"),
    ("study.adaptive", "AdaptivePlan._finish", "plane finished"),
    ("tasks.adaptive", "Refinement._fill_inferred", "inferred fill"),
    ("study.run", "_assemble", "result file"),
)


def _watch(steps: list) -> list:
    """Wrap the :data:`STEPS` that exist in the checkout, appending ``(label, start,
    seconds, detail)`` to ``steps``; the old values, to restore."""
    import functools

    old = []
    for module, path, label in STEPS:
        obj = importlib.import_module(module)
        *owners, name = path.split(".")
        for owner in owners:
            obj = getattr(obj, owner, None)
        fn = getattr(obj, name, None)
        if fn is None:
            continue

        def timed(*a, _fn=fn, _label=label, **k):
            t = time.time()
            out = _fn(*a, **k)
            unit = a[2] if _label == "arrival" else None
            detail = f"{type(unit).__name__} {getattr(unit, 'phase', '')}" if unit else ""
            if _label == "submit":
                detail = f"{len(a[1])} units"
            steps.append((_label, t, time.time() - t, detail))
            return out

        old.append((obj, name, fn))
        setattr(obj, name, functools.wraps(fn)(timed))
    return old


def _stream(client, on: bool):
    import contextlib

    from distributed import get_task_stream

    return get_task_stream(client) if on else contextlib.nullcontext()


def _timeline(stream, steps: list, t0: float, main_cpu: float) -> dict:
    """The workers' compute intervals and the client's steps, from ``t0``."""
    tasks, busy, tile_end = [], {}, 0.0
    for d in stream.data:
        for x in d["startstops"]:
            if x["action"] != "compute":
                continue
            start, stop = x["start"] - t0, x["stop"] - t0
            tasks.append((start, stop, d["worker"][-5:], d["key"][-40:]))
            busy[d["worker"]] = busy.get(d["worker"], 0.0) + stop - start
            if "tile" in d["key"]:
                tile_end = max(tile_end, stop)
    steps = [(label, t - t0, dt, detail) for label, t, dt, detail in steps]
    return {
        "tasks": sorted(tasks),
        "busy": list(busy.values()),
        "tile_end": tile_end,
        "steps": steps,
        "main_cpu": main_cpu,
    }


def main(checkout: str, address: str) -> int:
    sys.path.insert(0, checkout)
    from distributed import Client

    import study
    from study import run_study
    from study.definition import Study

    with Client(address) as client:
        print(json.dumps({"ready": True, "module": study.__file__}), flush=True)
        for line in sys.stdin:
            req = json.loads(line)
            old = _set(req.get("patch", []))
            log = io.StringIO()
            steps: list = []
            if req.get("timeline"):
                old += _watch(steps)
            try:
                study_ = Study.from_toml(req["toml"])
                with _stream(client, req.get("timeline")) as stream:
                    cpu, t = time.process_time(), time.perf_counter()
                    main_cpu, t_wall = time.thread_time(), time.time()
                    run_study(study_, req["out"], client=client, progress=False, stream=log)
                    wall, cpu = time.perf_counter() - t, time.process_time() - cpu
                    main_cpu = time.thread_time() - main_cpu
            finally:
                for obj, name, value in reversed(old):
                    setattr(obj, name, value)
            answer = {"wall": wall, "client_cpu": cpu, "log": log.getvalue()}
            if req.get("timeline"):
                answer["timeline"] = _timeline(stream, steps, t_wall, main_cpu)
            print(json.dumps(answer), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
