"""The verification sample of an adaptive map (:mod:`tasks.adaptive`): which inferred
points are simulated as a check, and what their agreement says.

Every point of a plane has a seeded priority (:func:`sample_priority`, a hash of its
index and the seed); the sample is the inferred points of priority below the
sample's fraction, at least a minimum (:func:`verification_sample`). The agreement
and its one-sided 95 % upper bound are a :class:`VerificationSummary`. No Dask, no
files.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def sample_priority(idx: np.ndarray, seed: int = 0) -> np.ndarray:
    """A seeded uniform number in [0, 1) for each flat index ``idx`` of a plane (a
    splitmix64 hash of index and seed): the verification sample takes the inferred
    points of least priority (:func:`verification_sample`). A point's priority does
    not depend on the other points, so a part of the plane (a tile, :mod:`tasks.tiles`)
    knows which of its inferred points the sample may take before the plane is done."""
    with np.errstate(over="ignore"):
        z = (np.asarray(idx, dtype=np.uint64) + np.uint64(1)) * np.uint64(0x9E3779B97F4A7C15)
        z = z ^ (np.uint64(seed) * np.uint64(0xD1B54A32D192ED03))
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        z = z ^ (z >> np.uint64(31))
    return (z >> np.uint64(11)).astype(np.float64) * 2.0**-53


def verification_sample(
    inferred: np.ndarray, fraction: float, minimum: int, seed: int = 0
) -> np.ndarray:
    """The verification sample of the inferred points ``inferred`` (flat indices): those
    whose :func:`sample_priority` is below ``fraction`` (each with that probability,
    independently), and at least ``minimum`` (those of least priority; all if fewer),
    sorted."""
    inferred = np.asarray(inferred, dtype=np.int64)
    u = sample_priority(inferred, seed)
    below = u < fraction
    n = min(inferred.size, int(minimum))
    if below.sum() >= n:
        return np.sort(inferred[below])
    return np.sort(inferred[np.argsort(u, kind="stable")[:n]])


@dataclass
class VerificationSummary:
    """Agreement of inferred labels with simulation on a seeded random sample."""

    inferred: int  #: points inferred (before the sample was simulated)
    sampled: int  #: inferred points simulated for the check
    agree: int  #: of which the inferred regime equals the simulated one
    upper_95: float  #: one-sided 95 % upper bound on the disagreement rate (Clopper-Pearson)

    @property
    def agreement(self) -> float:
        return self.agree / self.sampled if self.sampled else float("nan")

    def line(self) -> str:
        if not self.sampled:
            return "verification: no inferred points"
        return (
            f"verification: {self.sampled:,} of {self.inferred:,} inferred points simulated, "
            f"{self.agree:,} agree ({100 * self.agreement:.2f} %; disagreement below "
            f"{100 * self.upper_95:.2f} % at 95 % confidence)"
        )


def disagreement_upper_bound(sampled: int, wrong: int, confidence: float = 0.95) -> float:
    """One-sided Clopper-Pearson upper bound on a rate with ``wrong`` of ``sampled``."""
    if sampled == 0:
        return 1.0
    if wrong >= sampled:
        return 1.0
    from scipy.special import betaincinv

    return float(betaincinv(wrong + 1, sampled - wrong, confidence))
