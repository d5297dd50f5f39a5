"""Physics: bodies and shapes, rotations, linear theory and the exact torque-free solution (numpy and the
closed-form kernels; no ensembles, no files)."""

#: The layer's modules, each imported by name (``from tumble.physics import exact``; this package imports nothing).
__all__ = ["bodies", "exact", "models", "rotations", "shapes", "system", "theory"]
