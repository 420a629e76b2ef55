"""Closed-form boundaries of the motion regimes, agreement scores, figures and reports.

Pure functions; no Dask. Figures and reports take data in and write files out.
Public API::

    from analysis import boundaries, predict
    beta_continuous, beta_motion = boundaries(scene, r, method="paper")   # or "exact"
    codes = predict(scene, r, beta, method="exact")
"""

__all__ = ["boundaries", "predict"]


def __getattr__(name: str):
    if name in ("boundaries", "predict"):
        from analysis import closed_form

        return getattr(closed_form, name)
    raise AttributeError(name)
