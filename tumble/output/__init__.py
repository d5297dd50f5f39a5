"""Output: netCDF files with provenance, atomic writes, figures. Never imports the engine or measurements."""
