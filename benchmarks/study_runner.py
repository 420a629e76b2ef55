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
where ``study`` was imported from). Imports and
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
            try:
                study_ = Study.from_toml(req["toml"])
                cpu, t = time.process_time(), time.perf_counter()
                run_study(study_, req["out"], client=client, progress=False, stream=log)
                wall, cpu = time.perf_counter() - t, time.process_time() - cpu
            finally:
                for obj, name, value in reversed(old):
                    setattr(obj, name, value)
            answer = {"wall": wall, "client_cpu": cpu, "log": log.getvalue()}
            print(json.dumps(answer), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
