"""The ensemble engine: deterministic sampling of perturbed spins, ensemble runs through the kernels (or the
closed form) with on-the-fly observers, and :func:`tumble.integrate`."""

#: The layer's modules, each imported by name (``from tumble.engine import ensemble``; this package imports nothing).
__all__ = ["adaptive_runs", "chaos", "cost", "device", "ensemble", "integration", "model_ensemble", "progress",
           "sampling", "sections", "system_runs"]
