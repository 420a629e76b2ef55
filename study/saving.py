"""Saving arrived units in the work folder, off the client's loop.

:func:`study.drive.drive` hands every arrived result to a :class:`Saver`; one
background thread writes them (:meth:`study.store.WorkDir.save`: atomic,
flushed to disk, verified on reuse) while the client goes on refining and
submitting. The writer gathers the results arriving within
:data:`GATHER_SECONDS` of the first one it waits for (and all queued behind a
slow disk): results of units that a plan can merge (the point lists of one
adaptive plane, :meth:`study.adaptive.AdaptivePlan.merge`) become one file
(the Fig. 4 example: about ten files instead of one per point list, each
flushed to disk with fsync and deleted at the end).

What an interruption loses:

* Ctrl-C (SIGINT), SIGTERM, a unit that failed, a lost scheduler: nothing. The
  run writes every queued result before it stops (:meth:`Saver.close`).
* ``kill -9`` of the client: the results that arrived in the last
  :data:`GATHER_SECONDS` plus the write time of one file (well under a second
  on a local disk); a power cut, also the renames the disk had not recorded.
  They are computed again by the rerun, which gives the identical result (a
  plan's result does not depend on which units were saved).

A file is either complete under its final name or absent (a temporary file
left by a killed writer is deleted by the next run), and every file is checked
against its key and checksum before reuse (:mod:`study.verify`).
"""

from __future__ import annotations

import queue
import threading
import time

#: Seconds between two looks for Ctrl-C while the client waits for the writer.
POLL = 0.2
#: Seconds the writer gathers arriving results before it writes them: results of
#: units a plan can merge arriving within it make one file.
GATHER_SECONDS = 0.5


class Saver:
    """Saves ``(plan, unit, arrays)`` in ``work``, merging queued units of a plan.

    ``background=False`` saves at once in the caller's thread (a work folder in
    memory: nothing to wait for).
    """

    def __init__(self, work, done, background: bool = True) -> None:
        self.work = work
        self.done = done  # its ``saved`` counts units whose results are on disk
        self.error: BaseException | None = None
        self._queue: queue.SimpleQueue | None = None
        self._thread: threading.Thread | None = None
        if background:
            self._queue = queue.SimpleQueue()
            self._thread = threading.Thread(target=self._run, name="study-save", daemon=True)
            self._thread.start()

    def put(self, plan, unit, arrays: dict) -> None:
        """Queue one arrived unit (its arrays include what the unit adds, ``saved_with``)."""
        self.check()
        if self._queue is None:
            self._write([(plan, unit, arrays)])
        else:
            self._queue.put((plan, unit, arrays))

    def check(self) -> None:
        """Raise the writer's error (``StudyFailed``: the disk refused a file)."""
        if self.error is not None:
            raise self.error

    def close(self) -> None:
        """Write everything queued, stop the writer, raise its error if it had one."""
        if self._thread is not None:
            self._queue.put(None)
            while self._thread.is_alive():  # bounded waits: Ctrl-C is seen
                self._thread.join(POLL)
            self._thread = None
        self.check()

    def _run(self) -> None:
        stop = False
        while not stop:
            items = [self._queue.get()]
            until = time.monotonic() + GATHER_SECONDS
            while items[-1] is not None:  # every result arriving meanwhile
                try:
                    items.append(self._queue.get(timeout=max(0.0, until - time.monotonic())))
                except queue.Empty:
                    break
            if items[-1] is None:  # close(): write what is queued, then stop
                stop = True
                items.pop()
            if self.error is None:
                try:
                    self._write(items)
                except BaseException as exc:  # noqa: BLE001 - raised in the client's thread
                    self.error = exc

    def _write(self, items: list) -> None:
        groups: dict[object, list] = {}
        for plan, unit, arrays in items:
            merge = getattr(plan, "merge_group", None)
            group = merge(unit) if merge is not None else None
            key = (id(plan), group) if group is not None else (id(plan), "unit", unit.key)
            groups.setdefault(key, []).append((plan, unit, arrays))
        for members in groups.values():
            plan, unit, arrays = members[0]
            if len(members) > 1:
                key, arrays = plan.merge([m[1] for m in members], [m[2] for m in members])
            else:
                key = unit.key
            self.work.save(unit.scene, key, arrays)
            self.done.saved += len(members)
