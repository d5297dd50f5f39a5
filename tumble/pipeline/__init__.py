"""The study pipeline: TOML study files to a resolved study, the one run flow, checkpoints, dask."""

#: The layer's modules, each imported by name (``from tumble.pipeline import runner``; this package imports nothing).
__all__ = ["checkpoint", "config", "distributed", "figure_process", "results", "runner"]
