"""Measurements: estimators of growth rates, frequencies and flips; scenes and scans against linear theory;
traces; work precision against SciPy."""

#: The layer's modules, each imported by name (``from tumble.measure import scans``; this package imports nothing,
#: so that importing one never rebinds the face's ``tumble.measure``, the function: see tumble/__init__.py).
__all__ = ["check", "estimators", "model_scenes", "planning", "precision", "records", "reduction", "regression",
           "running", "scans", "scene", "traces"]
