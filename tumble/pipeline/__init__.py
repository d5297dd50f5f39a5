"""The study pipeline: TOML study files to a resolved study, the one run flow, checkpoints, dask."""
