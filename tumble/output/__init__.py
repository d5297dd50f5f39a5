"""Output: netCDF files with provenance, atomic writes, figures. Never imports the engine or measurements."""

#: The layer's modules the layers above use, each imported by name (``from tumble.output import io``: this package
#: imports nothing); ``attitude_figures`` and ``layout`` are ``figures``' helpers.
__all__ = ["check_figure", "figures", "io", "trajectory"]
