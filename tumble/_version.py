"""The installed version of tumble, read once from the package metadata (no module imports the face)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("tumble")
except PackageNotFoundError:  # running from a source tree that was not installed
    __version__ = "0+unknown"
