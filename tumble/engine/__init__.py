"""The ensemble engine: deterministic sampling of perturbed spins, ensemble runs through the kernels (or the
closed form) with on-the-fly observers, and :func:`tumble.integrate`."""
