"""The counts an adaptive scene's result file carries (:mod:`study.adaptive`).

Each finished plane is saved with its counts (refinement levels, points, the
verification sample's); the result's scene attributes sum them over the planes.
"""

from __future__ import annotations

import json

import numpy as np

from tasks.adaptive import disagreement_upper_bound

#: Seed of the verification sample (fixed: a rerun draws the same sample).
VERIFY_SEED = 0


def plane_stats(arrays: dict[str, np.ndarray]) -> dict[str, int]:
    """The counts saved with a plane (for the result's attributes)."""
    return {
        "points": int(arrays["n_points"]),
        "simulated": int(np.asarray(arrays["simulated"]).sum()),
        "waves": int(np.asarray(arrays["levels"]).size),
        "verify_inferred": int(arrays["verify_inferred"]),
        "verify_sampled": int(arrays["verify_sampled"]),
        "verify_agree": int(arrays["verify_agree"]),
    }


def result_attrs(plan, stats: list[dict[str, int]]) -> dict[str, object]:
    """Scene attributes of an adaptive result, summed over its planes."""
    spec = plan.spec
    tot = {k: sum(s[k] for s in stats) for k in stats[0]} if stats else {}
    sampled, agree = tot.get("verify_sampled", 0), tot.get("verify_agree", 0)
    return {
        "adaptive_coarse_step": spec.coarse_step,
        "adaptive_coarse_step_note": (
            "coarsest spacing in grid steps: a region containing a square of this many grid "
            "steps is sure to be found; narrower features may be missed (tasks.adaptive)"
        ),
        "adaptive_hint": spec.hint,
        "adaptive_points": tot.get("points", 0),
        "adaptive_points_simulated": tot.get("simulated", 0),
        "adaptive_simulated_fraction": tot.get("simulated", 0) / max(1, tot.get("points", 0)),
        "adaptive_waves_per_plane": json.dumps([s["waves"] for s in stats]),
        "verification_fraction": spec.verify_fraction,
        "verification_seed": VERIFY_SEED,
        "verification_inferred_points": tot.get("verify_inferred", 0),
        "verification_sampled": sampled,
        "verification_agree": agree,
        "verification_agreement": agree / sampled if sampled else float("nan"),
        "verification_disagreement_upper_95": disagreement_upper_bound(sampled, sampled - agree),
    }
