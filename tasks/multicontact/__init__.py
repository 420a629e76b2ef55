"""Several Coulomb contacts: scenes, exact event-driven simulation, classification.

docs/contacts.md is the theory and the rules. Modules, one job each:

* :mod:`~tasks.multicontact.scene`: :class:`MultiScene` (from matrices, or a chain);
* :mod:`~tasks.multicontact.sets`: linear algebra of the 2^k stuck sets;
* :mod:`~tasks.multicontact.decide`: which contacts stick or slide after an event;
* :mod:`~tasks.multicontact.cycle`: one cycle, event by event (the single-contact
  kernel's closed-form propagation and event search, one observable per contact);
* :mod:`~tasks.multicontact.held`: the held forced response and its margins;
* :mod:`~tasks.multicontact.starts`: the start of a point (held, rest, random);
* :mod:`~tasks.multicontact.section`: the Poincare section: periods run from it,
  Newton on its map, the polish of a converged section state;
* :mod:`~tasks.multicontact.creep`: the settling rule of a creep in progress;
* :mod:`~tasks.multicontact.shifted`: that rule, every contact stuck, at a shifted section;
* :mod:`~tasks.multicontact.fields`: the result fields of a converged period;
* :mod:`~tasks.multicontact.steady`: steady state of a point, many points;
* :mod:`~tasks.multicontact.classify`: :func:`classify_multi` and its result;
* :mod:`~tasks.multicontact.reference`: an independent scipy integrator.

The compiled modules are cached by numba in a folder keyed by their sources and
those of the kernel they call (:data:`tasks.numba_cache.MULTICONTACT_SOURCES`).
"""

from __future__ import annotations

import tasks.kernel  # noqa: F401  (the kernel first: its own cache folder)
from tasks import numba_cache
from tasks.multicontact.scene import MAX_CONTACTS, MultiScene

with numba_cache.kernel_cache(sources=numba_cache.MULTICONTACT_SOURCES, name="multicontact"):
    from tasks.multicontact import cycle, decide, steady  # noqa: F401

from tasks.multicontact.classify import (  # noqa: E402
    MultiResult,
    classify_multi,
    combined_label,
)

__all__ = ["MAX_CONTACTS", "MultiResult", "MultiScene", "classify_multi", "combined_label"]
