"""Measurements: estimators of growth rates, frequencies and flips; scenes and scans against linear theory;
traces; work precision against SciPy."""
